//! Robustness of depth estimation to perturbations (thesis §3.2.7, eqs. 3.3–3.4).
//!
//! For scene `i`, perturbation `j` and severity `l ≥ 1`, `E_{i,j,l}` is the mean per-image
//! error (Abs Rel, or 1 − δ_0.25) over the frames of that cell; severity 0 marks the clean
//! reference frames of the cell (for deformation/incision sequences: the frames before the
//! gesture). When a cell has no severity-0 frames, the scene's frames of the perturbation
//! named [`CLEAN`] are its clean reference.
//!
//! * Corruption error `CE_{i,j} = Σ_l E_{i,j,l} / Σ_l E^{baseline}_{i,j,l}`, `mCE` = mean over
//!   the (scene, perturbation) cells (eq. 3.3);
//! * resilience rate `RR_{i,j} = Σ_l (1 − E_{i,j,l}) / (L (1 − E_{clean,i,j}))`, `mRR` = mean
//!   over the cells (eq. 3.4).
//!
//! A ratio whose denominator is 0 is undefined (`None`, shown as "-" as in Table 3.3); a mean
//! over cells is undefined when any of its cells is. The clean error of a method is the mean
//! error over all distinct clean frames.
use crate::metrics::{ErrorMetric, Metrics};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// Name of the scene-level clean reference set.
pub const CLEAN: &str = "clean";

/// A value for each error metric `E` of the thesis tables.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ByError<T> {
    /// E = Abs Rel.
    pub abs_rel: T,
    /// E = 1 − δ_0.25.
    #[serde(rename = "one_minus_delta_0.25")]
    pub one_minus_delta: T,
}

impl<T: Copy> ByError<T> {
    /// The value for `e`.
    pub fn get(&self, e: ErrorMetric) -> T {
        match e {
            ErrorMetric::AbsRel => self.abs_rel,
            ErrorMetric::OneMinusDelta025 => self.one_minus_delta,
        }
    }
    /// Apply `f` to both.
    pub fn map<U>(&self, f: impl Fn(ErrorMetric, T) -> U) -> ByError<U> {
        ByError {
            abs_rel: f(ErrorMetric::AbsRel, self.abs_rel),
            one_minus_delta: f(ErrorMetric::OneMinusDelta025, self.one_minus_delta),
        }
    }
}

impl ByError<f64> {
    /// Both errors of one image.
    pub fn of(m: &Metrics) -> Self {
        ByError { abs_rel: m.error(ErrorMetric::AbsRel), one_minus_delta: m.error(ErrorMetric::OneMinusDelta025) }
    }
}

/// The per-image errors of one method on one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// Scene index in [`Layout::scenes`].
    pub scene: usize,
    /// Perturbation index in [`Layout::perturbations`].
    pub perturbation: usize,
    /// Severity level (0 = clean reference).
    pub severity: u32,
    /// Frame index (distinct frames are counted once for the clean error).
    pub frame: usize,
    /// Errors of the image.
    pub error: ByError<f64>,
}

/// Names of scenes and perturbations referenced by [`Observation`] indices.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    /// Scene names.
    pub scenes: Vec<String>,
    /// Perturbation names.
    pub perturbations: Vec<String>,
}

/// Mean error of one severity level of one (scene, perturbation) cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SeverityError {
    /// Severity level (0 = clean reference).
    pub severity: u32,
    /// Frames averaged.
    pub n_frames: usize,
    /// Mean error of those frames.
    pub mean: ByError<f64>,
}

/// Robustness of one method on one (scene, perturbation) cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellRobustness {
    /// Scene name.
    pub scene: String,
    /// Perturbation name.
    pub perturbation: String,
    /// Mean error of the clean reference (None when the cell has none).
    pub clean: Option<ByError<f64>>,
    /// Number of clean reference frames.
    pub n_clean: usize,
    /// `E_{i,j,l}` for l = 1..L.
    pub severities: Vec<SeverityError>,
    /// CE_{i,j} (eq. 3.3).
    pub ce: ByError<Option<f64>>,
    /// RR_{i,j} (eq. 3.4).
    pub rr: ByError<Option<f64>>,
}

/// Per-perturbation robustness averaged over scenes (the axes of the radar charts, Fig. 3.4).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PerturbationRobustness {
    /// Perturbation name.
    pub perturbation: String,
    /// CE (eq. 3.3) averaged over scenes.
    pub ce: ByError<Option<f64>>,
    /// RR (eq. 3.4) averaged over scenes.
    pub rr: ByError<Option<f64>>,
    /// Mean error per severity over scenes, severity 0 = clean reference (Tables C.3–C.16).
    pub by_severity: Vec<SeverityError>,
}

/// Accuracy and robustness of one method (one row of Tables 3.3–3.5).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodRobustness {
    /// Method name.
    pub method: String,
    /// Baseline method of CE/mCE.
    pub baseline: String,
    /// Mean error over the distinct clean frames.
    pub clean_error: ByError<Option<f64>>,
    /// Number of distinct clean frames.
    pub n_clean_frames: usize,
    /// mCE (eq. 3.3).
    pub mce: ByError<Option<f64>>,
    /// mRR (eq. 3.4).
    pub mrr: ByError<Option<f64>>,
    /// Robustness per (scene, perturbation) cell.
    pub cells: Vec<CellRobustness>,
    /// Robustness per perturbation (averaged over scenes).
    pub perturbations: Vec<PerturbationRobustness>,
}

#[derive(Default, Clone, Copy)]
struct Acc {
    sum: ByError<f64>,
    n: usize,
}

impl Acc {
    fn add(&mut self, e: ByError<f64>) {
        self.sum.abs_rel += e.abs_rel;
        self.sum.one_minus_delta += e.one_minus_delta;
        self.n += 1;
    }
    fn mean(&self) -> Option<ByError<f64>> {
        (self.n > 0).then(|| self.sum.map(|_, s| s / self.n as f64))
    }
}

/// Means per (scene, perturbation, severity).
fn cell_means(obs: &[Observation]) -> BTreeMap<(usize, usize, u32), Acc> {
    let mut m: BTreeMap<(usize, usize, u32), Acc> = BTreeMap::new();
    for o in obs {
        m.entry((o.scene, o.perturbation, o.severity)).or_default().add(o.error);
    }
    m
}

fn ratio(num: f64, den: f64) -> Option<f64> {
    (den != 0.0 && num.is_finite() && den.is_finite()).then(|| num / den)
}

/// Mean of the values; None if empty or if any is None.
fn mean_all(v: impl IntoIterator<Item = Option<f64>>) -> Option<f64> {
    let mut s = 0.0;
    let mut n = 0usize;
    for x in v {
        s += x?;
        n += 1;
    }
    (n > 0).then(|| s / n as f64)
}

/// Accuracy and robustness of `method` (observations `obs`) against `baseline` (observations
/// of the baseline on the same frames), eqs. 3.3–3.4.
pub fn method_robustness(
    method: &str,
    obs: &[Observation],
    baseline: &str,
    baseline_obs: &[Observation],
    layout: &Layout,
) -> MethodRobustness {
    let means = cell_means(obs);
    let base = cell_means(baseline_obs);
    let clean_idx = layout.perturbations.iter().position(|p| p == CLEAN);

    // Clean error over distinct clean frames.
    let mut clean_frames: BTreeMap<usize, ByError<f64>> = BTreeMap::new();
    for o in obs.iter().filter(|o| o.severity == 0) {
        clean_frames.insert(o.frame, o.error);
    }
    let mut acc = Acc::default();
    clean_frames.values().for_each(|e| acc.add(*e));
    let clean_error = match acc.mean() {
        Some(m) => m.map(|_, v| Some(v)),
        None => ByError { abs_rel: None, one_minus_delta: None },
    };

    // Cells: (scene, perturbation) with at least one perturbed frame, perturbation != clean.
    let cells_keys: BTreeSet<(usize, usize)> =
        means.keys().filter(|k| k.2 >= 1 && Some(k.1) != clean_idx).map(|k| (k.0, k.1)).collect();
    let mut cells = Vec::new();
    for &(i, j) in &cells_keys {
        let sev: Vec<(u32, Acc)> = means.range((i, j, 1)..=(i, j, u32::MAX)).map(|(k, a)| (k.2, *a)).collect();
        let l = sev.len() as f64;
        let clean_acc = means
            .get(&(i, j, 0))
            .copied()
            .or_else(|| clean_idx.and_then(|c| merged_clean(&means, i, c)))
            .unwrap_or_default();
        let clean = clean_acc.mean();
        let ce = ByError::<Option<f64>>::default().map(|e, _| {
            let num: f64 = sev.iter().map(|(_, a)| a.mean().unwrap().get(e)).sum();
            let mut den = 0.0;
            for (s, _) in &sev {
                den += base.get(&(i, j, *s))?.mean()?.get(e);
            }
            ratio(num, den)
        });
        let rr = ByError::<Option<f64>>::default().map(|e, _| {
            let c = clean?.get(e);
            let num: f64 = sev.iter().map(|(_, a)| 1.0 - a.mean().unwrap().get(e)).sum();
            ratio(num, l * (1.0 - c))
        });
        cells.push(CellRobustness {
            scene: layout.scenes[i].clone(),
            perturbation: layout.perturbations[j].clone(),
            clean,
            n_clean: clean_acc.n,
            severities: sev
                .iter()
                .map(|(s, a)| SeverityError { severity: *s, n_frames: a.n, mean: a.mean().unwrap() })
                .collect(),
            ce,
            rr,
        });
    }
    let mce = ByError::<Option<f64>>::default().map(|e, _| mean_all(cells.iter().map(|c| c.ce.get(e))));
    let mrr = ByError::<Option<f64>>::default().map(|e, _| mean_all(cells.iter().map(|c| c.rr.get(e))));

    // Per perturbation, averaged over scenes.
    let perts: BTreeSet<usize> = cells_keys.iter().map(|k| k.1).collect();
    let mut perturbations = Vec::new();
    for &j in &perts {
        let these: Vec<&CellRobustness> = cells.iter().filter(|c| c.perturbation == layout.perturbations[j]).collect();
        let ce = ByError::<Option<f64>>::default().map(|e, _| mean_all(these.iter().map(|c| c.ce.get(e))));
        let rr = ByError::<Option<f64>>::default().map(|e, _| mean_all(these.iter().map(|c| c.rr.get(e))));
        let mut by_sev: BTreeMap<u32, (Acc, usize)> = BTreeMap::new();
        for c in &these {
            if let Some(cl) = c.clean {
                let ent = by_sev.entry(0).or_default();
                ent.0.add(cl);
                ent.1 += c.n_clean;
            }
            for s in &c.severities {
                let ent = by_sev.entry(s.severity).or_default();
                ent.0.add(s.mean);
                ent.1 += s.n_frames;
            }
        }
        perturbations.push(PerturbationRobustness {
            perturbation: layout.perturbations[j].clone(),
            ce,
            rr,
            by_severity: by_sev
                .into_iter()
                .map(|(s, (a, n))| SeverityError { severity: s, n_frames: n, mean: a.mean().unwrap() })
                .collect(),
        });
    }
    MethodRobustness {
        method: method.to_string(),
        baseline: baseline.to_string(),
        clean_error,
        n_clean_frames: clean_frames.len(),
        mce,
        mrr,
        cells,
        perturbations,
    }
}

/// All frames of scene `i`'s clean set (perturbation index `c`, any severity), as one mean.
fn merged_clean(means: &BTreeMap<(usize, usize, u32), Acc>, i: usize, c: usize) -> Option<Acc> {
    let mut out = Acc::default();
    for (_, a) in means.range((i, c, 0)..=(i, c, u32::MAX)) {
        out.sum.abs_rel += a.sum.abs_rel;
        out.sum.one_minus_delta += a.sum.one_minus_delta;
        out.n += a.n;
    }
    (out.n > 0).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ob(scene: usize, perturbation: usize, severity: u32, frame: usize, abs_rel: f64, omd: f64) -> Observation {
        Observation { scene, perturbation, severity, frame, error: ByError { abs_rel, one_minus_delta: omd } }
    }

    fn layout() -> Layout {
        Layout {
            scenes: vec!["a".into(), "b".into()],
            perturbations: vec!["smoke".into(), "clean".into(), "blood".into()],
        }
    }

    #[test]
    fn ce_and_rr_by_hand() {
        // Scene a, smoke: clean 0.1 (frame 0), severities 1, 2 with errors 0.2 and (0.3, 0.5) -> mean 0.4.
        let m = vec![
            ob(0, 0, 0, 0, 0.1, 0.5),
            ob(0, 0, 1, 1, 0.2, 0.6),
            ob(0, 0, 2, 2, 0.3, 0.7),
            ob(0, 0, 2, 3, 0.5, 0.9),
        ];
        let b = vec![
            ob(0, 0, 0, 0, 0.1, 0.5),
            ob(0, 0, 1, 1, 0.4, 0.8),
            ob(0, 0, 2, 2, 0.4, 0.8),
            ob(0, 0, 2, 3, 0.4, 0.8),
        ];
        let r = method_robustness("m", &m, "base", &b, &layout());
        assert_eq!(r.cells.len(), 1);
        let c = &r.cells[0];
        // CE = (0.2 + 0.4) / (0.4 + 0.4) = 0.75
        assert!((c.ce.abs_rel.unwrap() - 0.75).abs() < 1e-12);
        // RR = ((1 − 0.2) + (1 − 0.4)) / (2 (1 − 0.1)) = 1.4 / 1.8
        assert!((c.rr.abs_rel.unwrap() - 1.4 / 1.8).abs() < 1e-12);
        // 1 − δ: CE = (0.6 + 0.8) / 1.6, RR = (0.4 + 0.2) / (2 · 0.5)
        assert!((c.ce.one_minus_delta.unwrap() - 1.4 / 1.6).abs() < 1e-12);
        assert!((c.rr.one_minus_delta.unwrap() - 0.6).abs() < 1e-12);
        assert_eq!(r.mce.abs_rel, c.ce.abs_rel);
        assert!((r.clean_error.abs_rel.unwrap() - 0.1).abs() < 1e-15);
        // The baseline against itself has CE = 1.
        let rb = method_robustness("base", &b, "base", &b, &layout());
        assert_eq!(rb.mce.abs_rel, Some(1.0));
        assert_eq!(r.perturbations[0].by_severity.iter().map(|s| s.severity).collect::<Vec<_>>(), vec![0, 1, 2]);
    }

    #[test]
    fn mean_over_cells_scene_clean_set_and_undefined_ratios() {
        // Scene a: smoke (own clean frame), blood (uses scene a's "clean" set); scene b: blood.
        let m = vec![
            ob(0, 0, 0, 0, 0.1, 0.0),
            ob(0, 0, 1, 1, 0.2, 0.0),
            ob(0, 1, 0, 2, 0.2, 0.0),
            ob(0, 1, 0, 3, 0.4, 0.0),
            ob(0, 2, 1, 4, 0.3, 0.0),
            ob(1, 2, 1, 5, 0.5, 0.0),
        ];
        let r = method_robustness("m", &m, "m", &m, &layout());
        assert_eq!(r.cells.len(), 3);
        // Blood in scene a: clean = mean(0.2, 0.4) = 0.3 -> RR = 0.7 / 0.7 = 1.
        let blood_a = r.cells.iter().find(|c| c.scene == "a" && c.perturbation == "blood").unwrap();
        assert!((blood_a.clean.unwrap().abs_rel - 0.3).abs() < 1e-12 && blood_a.n_clean == 2);
        assert!((blood_a.rr.abs_rel.unwrap() - 1.0).abs() < 1e-12);
        // Scene b has no clean reference -> RR undefined -> mRR undefined; CE against itself = 1.
        assert_eq!(r.mrr.abs_rel, None);
        assert_eq!(r.mce.abs_rel, Some(1.0));
        // δ never reached: 1 − δ = 0 for all: baseline denominators 0 -> CE undefined.
        assert_eq!(r.mce.one_minus_delta, None);
        // Clean error: frames 0, 2, 3 -> (0.1 + 0.2 + 0.4) / 3.
        assert!((r.clean_error.abs_rel.unwrap() - 0.7 / 3.0).abs() < 1e-12 && r.n_clean_frames == 3);
    }
}
