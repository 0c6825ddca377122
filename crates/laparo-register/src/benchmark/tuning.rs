//! No test-set tuning (incision benchmark v2): every hyperparameter of the compared methods is chosen on a
//! separate *tuning case* (another blade position, another liver) and frozen in a file before the test run; a
//! test run refuses a frozen file made on its own case. The grid ([`TuningGrid`]) and the selection rule
//! ([`select`]: the lowest mean TRE within 10 mm of the source lips at the common points, 50 noiseless
//! landmarks) live here, so the CLI, the Python package and the bench share them.
use super::table::Cell;
use crate::error::{RegisterError, Result};

/// The hyperparameters the benchmark freezes (the a-priori defaults when nothing was tuned).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Hyperparameters {
    /// François et al.: assumed cut depth under the source lip (mm).
    pub francois_depth_mm: f64,
    /// DRBC (and François et al.'s DRBC): the elastic weight λ as a factor of DRBC's default
    /// (0.01 K L² / (V μ)).
    pub drbc_lambda_factor: f64,
    /// LDDMM kernel width σ_K (mm).
    pub lddmm_sigma_mm: f64,
    /// RODS-MPM least-action prior κ (0 = the thesis' unregularised loss).
    pub rods_kinetic_weight: f64,
}

impl Default for Hyperparameters {
    /// The a-priori values (register.md §4: François depth 20 mm, DRBC's default λ, LDDMM 20 mm, κ = 0).
    fn default() -> Self {
        Hyperparameters {
            francois_depth_mm: 20.0,
            drbc_lambda_factor: 1.0,
            lddmm_sigma_mm: 20.0,
            rods_kinetic_weight: 0.0,
        }
    }
}

/// A frozen settings file: the hyperparameters, the case they were tuned on (its ground-truth fingerprint per
/// scenario and a description) and every candidate's score, so a reader can see the choice.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrozenSettings {
    /// The chosen values.
    pub hyperparameters: Hyperparameters,
    /// Fingerprints of the tuning case's ground truths (one per scenario tuned on).
    pub tuning_case_fingerprints: Vec<String>,
    /// What the tuning case was (liver, blade), for people.
    pub tuning_case: String,
    /// (method row, its 0–10 mm TRE in mm) of every candidate, in grid order.
    pub candidates: Vec<(String, f64)>,
}

impl FrozenSettings {
    /// Refuse a test case equal to the tuning case (the same ground-truth fingerprint): hyperparameters chosen
    /// on the test set are no test.
    pub fn check_test_case(&self, test_fingerprint: &str, what: &str) -> Result<()> {
        if self.tuning_case_fingerprints.iter().any(|f| f == test_fingerprint) {
            return Err(RegisterError::bad(
                what,
                format!(
                    "is the tuning case of these frozen settings ({}; ground truth {test_fingerprint}): tune on another blade position or liver",
                    self.tuning_case
                ),
            ));
        }
        Ok(())
    }

    /// Read a frozen settings file, naming it on error.
    pub fn read(path: &std::path::Path) -> Result<FrozenSettings> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| RegisterError::bad(path.display().to_string(), format!("cannot read: {e}")))?;
        let f: FrozenSettings = serde_json::from_str(&text)
            .map_err(|e| RegisterError::bad(path.display().to_string(), format!("not a frozen settings file: {e}")))?;
        let h = &f.hyperparameters;
        for (name, v, ok) in [
            ("francois_depth_mm", h.francois_depth_mm, h.francois_depth_mm > 0.0),
            ("drbc_lambda_factor", h.drbc_lambda_factor, h.drbc_lambda_factor > 0.0),
            ("lddmm_sigma_mm", h.lddmm_sigma_mm, h.lddmm_sigma_mm > 0.0),
            ("rods_kinetic_weight", h.rods_kinetic_weight, h.rods_kinetic_weight >= 0.0),
        ] {
            if !(v.is_finite() && ok) {
                return Err(RegisterError::param(format!("{}: {name}", path.display()), v, "out of range"));
            }
        }
        Ok(f)
    }
}

/// The candidates tried on the tuning case, one parameter at a time around the a-priori defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct TuningGrid {
    /// François et al.'s assumed depths (mm).
    pub francois_depth_mm: Vec<f64>,
    /// DRBC λ factors.
    pub drbc_lambda_factor: Vec<f64>,
    /// LDDMM widths (mm).
    pub lddmm_sigma_mm: Vec<f64>,
    /// RODS-MPM κ.
    pub rods_kinetic_weight: Vec<f64>,
}

impl Default for TuningGrid {
    fn default() -> Self {
        TuningGrid {
            francois_depth_mm: vec![10.0, 15.0, 20.0, 30.0, 40.0],
            drbc_lambda_factor: vec![0.1, 0.3, 1.0, 3.0, 10.0],
            lddmm_sigma_mm: vec![10.0, 20.0, 30.0, 40.0],
            rods_kinetic_weight: vec![0.0, 1e-3, 1e-2, 1e-1],
        }
    }
}

/// Which hyperparameter a tuning row varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Knob {
    /// [`Hyperparameters::francois_depth_mm`].
    FrancoisDepth,
    /// [`Hyperparameters::drbc_lambda_factor`].
    DrbcLambda,
    /// [`Hyperparameters::lddmm_sigma_mm`].
    LddmmSigma,
    /// [`Hyperparameters::rods_kinetic_weight`].
    RodsKinetic,
}

impl TuningGrid {
    /// Every (knob, value) candidate in order.
    pub fn candidates(&self) -> Vec<(Knob, f64)> {
        let mut v = Vec::new();
        v.extend(self.francois_depth_mm.iter().map(|&x| (Knob::FrancoisDepth, x)));
        v.extend(self.drbc_lambda_factor.iter().map(|&x| (Knob::DrbcLambda, x)));
        v.extend(self.lddmm_sigma_mm.iter().map(|&x| (Knob::LddmmSigma, x)));
        v.extend(self.rods_kinetic_weight.iter().map(|&x| (Knob::RodsKinetic, x)));
        v
    }
}

/// The name of a tuning row: the knob and its value (`tune: François depth 15 mm`).
pub fn tuning_row_name(knob: Knob, value: f64) -> String {
    match knob {
        Knob::FrancoisDepth => format!("tune: François depth {value} mm"),
        Knob::DrbcLambda => format!("tune: DRBC λ × {value}"),
        Knob::LddmmSigma => format!("tune: LDDMM σ {value} mm"),
        Knob::RodsKinetic => format!("tune: RODS-MPM κ {value}"),
    }
}

/// Choose each knob's value with the lowest mean TRE within 10 mm of the lips among `cells` (the tuning rows
/// of [`tuning_row_name`], v2 point scores); a knob without a scored candidate keeps its default. Ties go to
/// the earlier candidate. Returns the hyperparameters and every candidate's score.
pub fn select(grid: &TuningGrid, cells: &[Cell]) -> Result<(Hyperparameters, Vec<(String, f64)>)> {
    let mut h = Hyperparameters::default();
    let mut scores = Vec::new();
    let mut best: [Option<(f64, f64)>; 4] = [None; 4];
    for (knob, value) in grid.candidates() {
        let name = tuning_row_name(knob, value);
        let Some(c) = cells.iter().find(|c| c.method == name) else { continue };
        let Some(p) = &c.points else {
            return Err(RegisterError::bad(&name, "scored without the common evaluation points"));
        };
        scores.push((name, p.near_lip_mm));
        let k = knob as usize;
        if p.near_lip_mm.is_finite() && best[k].is_none_or(|(s, _)| p.near_lip_mm < s) {
            best[k] = Some((p.near_lip_mm, value));
        }
    }
    if let Some((_, v)) = best[Knob::FrancoisDepth as usize] {
        h.francois_depth_mm = v;
    }
    if let Some((_, v)) = best[Knob::DrbcLambda as usize] {
        h.drbc_lambda_factor = v;
    }
    if let Some((_, v)) = best[Knob::LddmmSigma as usize] {
        h.lddmm_sigma_mm = v;
    }
    if let Some((_, v)) = best[Knob::RodsKinetic as usize] {
        h.rods_kinetic_weight = v;
    }
    Ok((h, scores))
}

#[cfg(test)]
mod tests {
    use super::super::protocol::Column;
    use super::super::table::PointCell;
    use super::*;

    fn cell(method: &str, near: f64) -> Cell {
        Cell {
            scenario: "s".into(),
            method: method.into(),
            column: Column { landmarks: 50, noise_sigma_mm: 0.0 },
            seeds: 1,
            mean_mm: 0.0,
            std_mm: 0.0,
            seed_std_mm: 0.0,
            surface_mean_mm: 0.0,
            bin_means_mm: vec![],
            seconds: 0.0,
            points: Some(PointCell {
                mean_mm: 0.0,
                crack_face_mean_mm: 0.0,
                lip_bin_means_mm: vec![],
                lip_bin_n: vec![],
                crack_bin_means_mm: vec![],
                crack_bin_n: vec![],
                near_lip_mm: near,
                near_crack_mm: 0.0,
                far_excess_mm: 0.0,
                floor: None,
                floor_ok: vec![],
                ratio_vs_francois: None,
                config_hash: String::new(),
            }),
        }
    }

    #[test]
    fn selection_by_hand_and_the_test_case_check() {
        let grid = TuningGrid {
            francois_depth_mm: vec![10.0, 20.0, 30.0],
            drbc_lambda_factor: vec![0.1, 1.0],
            lddmm_sigma_mm: vec![],
            rods_kinetic_weight: vec![0.0, 0.01],
        };
        let cells = vec![
            cell(&tuning_row_name(Knob::FrancoisDepth, 10.0), 2.0),
            cell(&tuning_row_name(Knob::FrancoisDepth, 20.0), 1.5),
            cell(&tuning_row_name(Knob::FrancoisDepth, 30.0), 1.5),
            cell(&tuning_row_name(Knob::DrbcLambda, 0.1), 0.9),
            cell(&tuning_row_name(Knob::DrbcLambda, 1.0), 1.1),
            cell(&tuning_row_name(Knob::RodsKinetic, 0.01), 3.0),
        ];
        let (h, scores) = select(&grid, &cells).unwrap();
        assert_eq!(h.francois_depth_mm, 20.0, "a tie goes to the earlier candidate");
        assert_eq!(h.drbc_lambda_factor, 0.1);
        assert_eq!(h.lddmm_sigma_mm, 20.0, "no candidate: the default");
        assert_eq!(h.rods_kinetic_weight, 0.01, "the only scored candidate");
        assert_eq!(scores.len(), 6);
        let f = FrozenSettings {
            hyperparameters: h,
            tuning_case_fingerprints: vec!["abc".into()],
            tuning_case: "offset 20 mm".into(),
            candidates: scores,
        };
        let e = f.check_test_case("abc", "non-anatomical").unwrap_err().to_string();
        assert!(e.contains("non-anatomical") && e.contains("tuning case"), "{e}");
        f.check_test_case("abd", "non-anatomical").unwrap();
        // round trip through a file, and a bad value named
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("frozen.json");
        std::fs::write(&p, serde_json::to_string(&f).unwrap()).unwrap();
        assert_eq!(FrozenSettings::read(&p).unwrap(), f);
        let mut bad = f.clone();
        bad.hyperparameters.lddmm_sigma_mm = -1.0;
        std::fs::write(&p, serde_json::to_string(&bad).unwrap()).unwrap();
        let e = FrozenSettings::read(&p).unwrap_err().to_string();
        assert!(e.contains("lddmm_sigma_mm") && e.contains("frozen.json"), "{e}");
    }
}
