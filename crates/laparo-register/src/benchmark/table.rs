//! Table 5.1 from stored runs: TRE mean ± std (mm) per method and column. Over the noise seeds of a
//! column, the cell reports the mean of the per-seed node means ± the mean of the per-seed node standard
//! deviations (the thesis' ± is a spread over nodes), and separately the spread of the means over seeds.
use super::protocol::Column;
use super::store::RunResult;

/// One cell of Table 5.1.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Cell {
    /// Scenario.
    pub scenario: String,
    /// Method.
    pub method: String,
    /// Column.
    pub column: Column,
    /// Seeds pooled.
    pub seeds: usize,
    /// Mean over seeds of the volume-node TRE mean (mm).
    pub mean_mm: f64,
    /// Mean over seeds of the volume-node TRE standard deviation (mm).
    pub std_mm: f64,
    /// Standard deviation over seeds of the TRE mean (mm).
    pub seed_std_mm: f64,
    /// Mean over seeds of the surface-node TRE mean (mm).
    pub surface_mean_mm: f64,
    /// Mean over seeds of the per-bin TRE means (Fig. 5.8), NaN for an empty bin.
    pub bin_means_mm: Vec<f64>,
    /// Mean wall time per run (s).
    pub seconds: f64,
    /// The v2 figures at the common evaluation points (None for runs scored at the nodes only).
    pub points: Option<PointCell>,
}

/// A [`Cell`]'s figures at the common evaluation points (v2 protocol), pooled over seeds like the cell.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PointCell {
    /// Mean over seeds of the TRE mean over every point (mm).
    pub mean_mm: f64,
    /// Mean over seeds of the crack-face points' TRE (mm).
    pub crack_face_mean_mm: f64,
    /// Per distance-to-lip bin: mean TRE (mm; NaN when empty) and point count.
    pub lip_bin_means_mm: Vec<f64>,
    /// Points per distance-to-lip bin.
    pub lip_bin_n: Vec<usize>,
    /// Per distance-to-crack bin: mean TRE (mm; NaN when empty).
    pub crack_bin_means_mm: Vec<f64>,
    /// Points per distance-to-crack bin.
    pub crack_bin_n: Vec<usize>,
    /// Mean TRE within 10 mm of the lips (the 0–5 and 5–10 mm bins pooled by count, mm).
    pub near_lip_mm: f64,
    /// Mean TRE within 10 mm of the true crack (mm).
    pub near_crack_mm: f64,
    /// Mean TRE at least 40 mm from the lips minus "none"'s there (mm; NaN without a "none" row).
    pub far_excess_mm: f64,
    /// The floor row bounding this method (None for floors and "none").
    pub floor: Option<String>,
    /// Per distance-to-lip bin: whether this row's floor is ≤ ¼ of "none"'s TRE there (true without a floor).
    pub floor_ok: Vec<bool>,
    /// Per-seed paired ratio of the 0–10 mm TRE to François et al.'s on the same seed: mean and 95 % interval
    /// (Student t over seeds; the interval is the mean itself with one seed). None without a François row.
    pub ratio_vs_francois: Option<[f64; 3]>,
    /// Configuration hash of the runs (the first run's; every pooled run shares it).
    pub config_hash: String,
}

/// The row name of the reference method of the paired ratios.
pub const FRANCOIS_NAME: &str = "François et al.";
/// The row name of no registration.
pub const NONE_NAME: &str = "none (rest)";
/// A bin is comparable only where every floor is at most this share of "none"'s TRE (issue: floors).
pub const FLOOR_SHARE: f64 = 0.25;

/// Pool the runs of each (scenario, method, column) in the order methods and columns first appear.
pub fn aggregate(results: &[RunResult]) -> Vec<Cell> {
    let mut keys: Vec<(String, String, Column)> = Vec::new();
    for r in results {
        let k = (r.key.scenario.clone(), r.key.method.clone(), r.key.column);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    keys.into_iter()
        .map(|(scenario, method, column)| {
            let rs: Vec<&RunResult> = results
                .iter()
                .filter(|r| r.key.scenario == scenario && r.key.method == method && r.key.column == column)
                .collect();
            let n = rs.len() as f64;
            let mean_mm = rs.iter().map(|r| r.tre_volume.mean).sum::<f64>() / n;
            let seed_var = rs.iter().map(|r| (r.tre_volume.mean - mean_mm).powi(2)).sum::<f64>() / n;
            let nb = rs.iter().map(|r| r.bins.len()).max().unwrap_or(0);
            let bin_means_mm = (0..nb)
                .map(|b| {
                    let v: Vec<f64> = rs
                        .iter()
                        .filter_map(|r| r.bins.get(b))
                        .filter(|s| s.stats.n > 0)
                        .map(|s| s.stats.mean)
                        .collect();
                    if v.is_empty() {
                        f64::NAN
                    } else {
                        v.iter().sum::<f64>() / v.len() as f64
                    }
                })
                .collect();
            Cell {
                scenario,
                method,
                column,
                seeds: rs.len(),
                mean_mm,
                std_mm: rs.iter().map(|r| r.tre_volume.std).sum::<f64>() / n,
                seed_std_mm: seed_var.sqrt(),
                surface_mean_mm: rs.iter().map(|r| r.tre_surface.mean).sum::<f64>() / n,
                bin_means_mm,
                seconds: rs.iter().map(|r| r.seconds).sum::<f64>() / n,
                points: point_cell(&rs),
            }
        })
        .collect::<Vec<Cell>>()
        .pipe(|cells| with_references(cells, results))
}

/// Pipe a value through a function (keeps [`aggregate`] one expression).
trait Pipe: Sized {
    fn pipe<T>(self, f: impl FnOnce(Self) -> T) -> T {
        f(self)
    }
}
impl<T> Pipe for T {}

fn mean_of(v: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = v.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// The seed-pooled point figures of one cell's runs (None when a run has no point scores).
fn point_cell(rs: &[&RunResult]) -> Option<PointCell> {
    let ps: Vec<&super::tre::PointScores> = rs.iter().map(|r| r.points.as_ref()).collect::<Option<_>>()?;
    let first = ps.first()?;
    let bins = |f: &dyn Fn(&super::tre::PointScores) -> &Vec<super::tre::BinStats>| -> (Vec<f64>, Vec<usize>) {
        let nb = f(first).len();
        let means = (0..nb).map(|b| mean_of(ps.iter().filter(|p| f(p)[b].stats.n > 0).map(|p| f(p)[b].stats.mean)));
        (means.collect(), f(first).iter().map(|b| b.stats.n).collect())
    };
    let (lip_bin_means_mm, lip_bin_n) = bins(&|p| &p.bins_lip);
    let (crack_bin_means_mm, crack_bin_n) = bins(&|p| &p.bins_crack);
    Some(PointCell {
        mean_mm: mean_of(ps.iter().map(|p| p.tre.mean)),
        crack_face_mean_mm: mean_of(ps.iter().map(|p| p.crack_faces.mean)),
        lip_bin_means_mm,
        lip_bin_n,
        crack_bin_means_mm,
        crack_bin_n,
        near_lip_mm: mean_of(ps.iter().map(|p| p.near_lip_mean_mm(10.0))),
        near_crack_mm: mean_of(ps.iter().map(|p| p.near_crack_mean_mm(10.0))),
        far_excess_mm: f64::NAN,
        floor: rs[0].floor.clone(),
        floor_ok: vec![true; first.bins_lip.len()],
        ratio_vs_francois: None,
        config_hash: rs[0].config_hash.clone(),
    })
}

/// Fill the figures that compare a cell with other rows of its (scenario, column): the far-field excess over
/// "none", the floor gate (the cell's floor row ≤ [`FLOOR_SHARE`] × "none" per bin) and the per-seed paired
/// ratio to François et al.
fn with_references(mut cells: Vec<Cell>, results: &[RunResult]) -> Vec<Cell> {
    let snapshot = cells.clone();
    let find = |sc: &str, m: &str, col: Column| {
        snapshot.iter().find(|c| c.scenario == sc && c.method == m && c.column == col).and_then(|c| c.points.clone())
    };
    let near = |r: &RunResult| r.points.as_ref().map_or(f64::NAN, |p| p.near_lip_mean_mm(10.0));
    for c in cells.iter_mut() {
        let (sc, col, method) = (c.scenario.clone(), c.column, c.method.clone());
        let none = find(&sc, NONE_NAME, col);
        let Some(p) = c.points.as_mut() else { continue };
        if let Some(nn) = &none {
            let far_none = |cell: &PointCell| pooled_from(&cell.lip_bin_means_mm, &cell.lip_bin_n, 3);
            p.far_excess_mm = far_none(p) - far_none(nn);
            if let Some(floor) = p.floor.clone().and_then(|f| find(&sc, &f, col)) {
                p.floor_ok = floor
                    .lip_bin_means_mm
                    .iter()
                    .zip(&nn.lip_bin_means_mm)
                    .map(|(f, n)| !(f > &(FLOOR_SHARE * n)))
                    .collect();
            }
        }
        // per-seed paired ratios to François et al. (the same seeds, the same landmarks)
        let fr: Vec<(u64, f64)> = results
            .iter()
            .filter(|r| r.key.scenario == sc && r.key.column == col && r.key.method == FRANCOIS_NAME)
            .map(|r| (r.key.seed, near(r)))
            .collect();
        let ratios: Vec<f64> = results
            .iter()
            .filter(|r| r.key.scenario == sc && r.key.column == col && r.key.method == method)
            .filter_map(|r| fr.iter().find(|f| f.0 == r.key.seed).map(|f| near(r) / f.1))
            .filter(|x| x.is_finite())
            .collect();
        if !ratios.is_empty() && !fr.is_empty() {
            p.ratio_vs_francois = Some(mean_interval_95(&ratios));
        }
    }
    cells
}

/// The floor line of the v2 protocol: in every case and column, each RODS-MPM floor row (a method name
/// starting with `floor: RODS`) within 0–5 and 5–10 mm of the lips must be at most [`FLOOR_SHARE`] × "none"'s
/// TRE there. The first violation is an [`RegisterError::InvalidParameter`] on `spacing_mm` naming the case,
/// the bin and both figures (the particles cannot represent what the comparison reads there).
pub fn check_floor_line(results: &[RunResult], spacing_mm: f64) -> crate::error::Result<()> {
    for r in results.iter().filter(|r| r.key.method.starts_with("floor: RODS")) {
        let none = results
            .iter()
            .find(|n| n.key.method == NONE_NAME && n.key.scenario == r.key.scenario && n.key.column == r.key.column);
        let (Some(f), Some(n)) = (r.points.as_ref(), none.and_then(|n| n.points.as_ref())) else { continue };
        for k in 0..2.min(f.bins_lip.len()).min(n.bins_lip.len()) {
            let (fl, nn) = (f.bins_lip[k].stats.mean, n.bins_lip[k].stats.mean);
            if fl > FLOOR_SHARE * nn {
                return Err(crate::error::RegisterError::param(
                    "spacing_mm",
                    spacing_mm,
                    format!(
                        "RODS-MPM's floor (the ground truth read back through its particles) is {fl:.3} mm within {}–{} mm of the lips of {} ({}), above {FLOOR_SHARE} × \"none\"'s {nn:.3} mm: the particles cannot represent what the comparison reads there; choose a finer spacing",
                        f.bins_lip[k].lo_mm,
                        f.bins_lip[k].hi_mm,
                        r.key.scenario,
                        r.key.column.label()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Mean over the bins from index `from` on, pooled by their counts (NaN without a point).
fn pooled_from(means: &[f64], n: &[usize], from: usize) -> f64 {
    let (k, s) = means
        .iter()
        .zip(n)
        .skip(from)
        .filter(|(m, n)| m.is_finite() && **n > 0)
        .fold((0usize, 0.0), |(k, s), (m, n)| (k + n, s + m * *n as f64));
    if k == 0 {
        f64::NAN
    } else {
        s / k as f64
    }
}

/// Mean and two-sided 95 % Student-t interval of `v` ([mean, lo, hi]; lo = hi = mean for one value).
pub fn mean_interval_95(v: &[f64]) -> [f64; 3] {
    let n = v.len();
    let m = v.iter().sum::<f64>() / n.max(1) as f64;
    if n < 2 {
        return [m, m, m];
    }
    let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    // t_{0.975, n−1} for n − 1 = 1 … 30, then the normal quantile
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
        2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
    ];
    let t = T.get(n - 2).copied().unwrap_or(1.96);
    let h = t * sd / (n as f64).sqrt();
    [m, m - h, m + h]
}

fn distinct<T: PartialEq + Clone>(it: impl Iterator<Item = T>) -> Vec<T> {
    let mut v = Vec::new();
    for x in it {
        if !v.contains(&x) {
            v.push(x);
        }
    }
    v
}

/// Table 5.1 as markdown, one table per scenario: rows = methods, columns = Table 5.1 columns, cells
/// `mean ± std`; the best mean of each column in bold.
pub fn table_markdown(cells: &[Cell]) -> String {
    let mut s = String::new();
    for scenario in distinct(cells.iter().map(|c| c.scenario.clone())) {
        let cs: Vec<&Cell> = cells.iter().filter(|c| c.scenario == scenario).collect();
        let methods = distinct(cs.iter().map(|c| c.method.clone()));
        let columns = distinct(cs.iter().map(|c| c.column));
        s.push_str(&format!("**{scenario}** — TRE at volume nodes, mean ± std (mm)\n\n| method |"));
        for c in &columns {
            s.push_str(&format!(" {} |", c.label()));
        }
        s.push_str("\n|---|");
        s.push_str(&"---|".repeat(columns.len()));
        s.push('\n');
        for m in &methods {
            s.push_str(&format!("| {m} |"));
            for c in &columns {
                let cell = cs.iter().find(|x| &x.method == m && x.column == *c);
                let best = cs.iter().filter(|x| x.column == *c).map(|x| x.mean_mm).fold(f64::INFINITY, f64::min);
                match cell {
                    Some(x) if x.mean_mm == best => s.push_str(&format!(" **{:.2}** ± {:.2} |", x.mean_mm, x.std_mm)),
                    Some(x) => s.push_str(&format!(" {:.2} ± {:.2} |", x.mean_mm, x.std_mm)),
                    None => s.push_str(" – |"),
                }
            }
            s.push('\n');
        }
        s.push('\n');
    }
    s.push_str(&ruler_markdown(cells));
    s
}

fn fmt_mm(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.2}")
    } else {
        "–".into()
    }
}

/// The v2 tables at the common evaluation points, one block per scenario (empty when no cell has points):
/// the 0–10 mm TRE of every column, then per column the TRE by distance to the lips with the floor gate
/// (a `†` marks a bin where the row's floor exceeds ¼ of "none"'s TRE: not comparable there), the crack
/// distance, the far-field excess over "none" and the per-seed paired ratio to François et al.
pub fn ruler_markdown(cells: &[Cell]) -> String {
    let mut s = String::new();
    let edges = super::tre::DISTANCE_BIN_EDGES_MM;
    let bin = |k: usize| {
        if edges[k + 1].is_finite() {
            format!("{}–{}", edges[k], edges[k + 1])
        } else {
            format!("> {}", edges[k])
        }
    };
    for scenario in distinct(cells.iter().map(|c| c.scenario.clone())) {
        let cs: Vec<&Cell> = cells.iter().filter(|c| c.scenario == scenario && c.points.is_some()).collect();
        if cs.is_empty() {
            continue;
        }
        let methods = distinct(cs.iter().map(|c| c.method.clone()));
        let columns = distinct(cs.iter().map(|c| c.column));
        s.push_str(&format!(
            "**{scenario}** — v2: TRE within 10 mm of the source lips at the common points, mean (mm); all points in brackets\n\n| method |"
        ));
        columns.iter().for_each(|c| s.push_str(&format!(" {} |", c.label())));
        s.push_str("\n|---|");
        s.push_str(&"---|".repeat(columns.len()));
        s.push('\n');
        for m in &methods {
            s.push_str(&format!("| {m} |"));
            for c in &columns {
                match cs.iter().find(|x| &x.method == m && x.column == *c).and_then(|x| x.points.as_ref()) {
                    Some(p) => s.push_str(&format!(" {} ({}) |", fmt_mm(p.near_lip_mm), fmt_mm(p.mean_mm))),
                    None => s.push_str(" – |"),
                }
            }
            s.push('\n');
        }
        s.push('\n');
        for col in &columns {
            let row: Vec<&Cell> = cs.iter().copied().filter(|c| c.column == *col).collect();
            let Some(first) = row.first().and_then(|c| c.points.as_ref()) else { continue };
            s.push_str(&format!(
                "**{scenario}, {}** — TRE by distance to the source lips (mm; n points per bin); † = the row's floor exceeds ¼ of \"none\" there (not comparable)\n\n| method | all |",
                col.label()
            ));
            for k in 0..first.lip_bin_n.len() {
                s.push_str(&format!(" {} mm (n {}) |", bin(k), first.lip_bin_n[k]));
            }
            s.push_str(" ≤ 10 mm of crack | crack faces | far excess (≥ 40 mm) | 0–10 mm / François (95 % CI) | config |\n|---|---|");
            s.push_str(&"---|".repeat(first.lip_bin_n.len() + 5));
            s.push('\n');
            let mut comparable = vec![true; first.lip_bin_n.len()];
            for c in &row {
                let Some(p) = &c.points else { continue };
                s.push_str(&format!("| {} | {} |", c.method, fmt_mm(p.mean_mm)));
                for (k, m) in p.lip_bin_means_mm.iter().enumerate() {
                    let ok = p.floor_ok.get(k).copied().unwrap_or(true);
                    comparable[k] &= ok;
                    s.push_str(&format!(" {}{} |", fmt_mm(*m), if ok { "" } else { "†" }));
                }
                let ratio = match p.ratio_vs_francois {
                    Some([m, lo, hi]) if lo < hi => format!("{m:.2} ({lo:.2}–{hi:.2})"),
                    Some([m, ..]) => format!("{m:.2} (1 seed)"),
                    None => "–".into(),
                };
                s.push_str(&format!(
                    " {} | {} | {} | {ratio} | `{}` |\n",
                    fmt_mm(p.near_crack_mm),
                    fmt_mm(p.crack_face_mean_mm),
                    if p.far_excess_mm.is_finite() { format!("{:+.2}", p.far_excess_mm) } else { "–".into() },
                    &p.config_hash.get(..8).unwrap_or("")
                ));
            }
            s.push_str(
                "
Comparable bins (every row's floor ≤ ¼ \"none\"): ",
            );
            let list: Vec<String> = comparable
                .iter()
                .enumerate()
                .map(|(k, ok)| format!("{} mm {}", bin(k), if *ok { "yes" } else { "no" }))
                .collect();
            s.push_str(&list.join(", "));
            s.push_str("\n\n");
        }
    }
    s
}

/// Every cell as CSV (one row per cell, bins as columns `bin0_mm` …).
pub fn table_csv(cells: &[Cell]) -> String {
    let nb = cells.iter().map(|c| c.bin_means_mm.len()).max().unwrap_or(0);
    let mut s = String::from(
        "scenario,method,landmarks,noise_sigma_mm,seeds,tre_mean_mm,tre_std_mm,tre_seed_std_mm,surface_tre_mean_mm,seconds",
    );
    for b in 0..nb {
        s.push_str(&format!(",bin{b}_mean_mm"));
    }
    let np = cells.iter().filter_map(|c| c.points.as_ref()).map(|p| p.lip_bin_means_mm.len()).max().unwrap_or(0);
    if np > 0 {
        s.push_str(",points_tre_mean_mm,near_lip_10mm_mm,near_crack_10mm_mm,crack_face_mean_mm,far_excess_mm,ratio_vs_francois,ratio_lo95,ratio_hi95,config_hash");
        for b in 0..np {
            s.push_str(&format!(",lip_bin{b}_mean_mm,lip_bin{b}_n,lip_bin{b}_floor_ok"));
        }
        for b in 0..np {
            s.push_str(&format!(",crack_bin{b}_mean_mm,crack_bin{b}_n"));
        }
    }
    s.push('\n');
    for c in cells {
        s.push_str(&format!(
            "{},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.3}",
            c.scenario,
            c.method,
            c.column.landmarks,
            c.column.noise_sigma_mm,
            c.seeds,
            c.mean_mm,
            c.std_mm,
            c.seed_std_mm,
            c.surface_mean_mm,
            c.seconds
        ));
        for b in 0..nb {
            s.push_str(&format!(",{:.6}", c.bin_means_mm.get(b).copied().unwrap_or(f64::NAN)));
        }
        if let (true, Some(p)) = (np > 0, &c.points) {
            let r = p.ratio_vs_francois.unwrap_or([f64::NAN; 3]);
            s.push_str(&format!(
                ",{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{}",
                p.mean_mm,
                p.near_lip_mm,
                p.near_crack_mm,
                p.crack_face_mean_mm,
                p.far_excess_mm,
                r[0],
                r[1],
                r[2],
                p.config_hash
            ));
            for b in 0..np {
                s.push_str(&format!(
                    ",{:.6},{},{}",
                    p.lip_bin_means_mm.get(b).copied().unwrap_or(f64::NAN),
                    p.lip_bin_n.get(b).copied().unwrap_or(0),
                    p.floor_ok.get(b).copied().unwrap_or(true)
                ));
            }
            for b in 0..np {
                s.push_str(&format!(
                    ",{:.6},{}",
                    p.crack_bin_means_mm.get(b).copied().unwrap_or(f64::NAN),
                    p.crack_bin_n.get(b).copied().unwrap_or(0)
                ));
            }
        }
        s.push('\n');
    }
    s
}

/// Every cell as pretty JSON (NaN bins as null).
pub fn table_json(cells: &[Cell]) -> String {
    let v: Vec<serde_json::Value> = cells
        .iter()
        .map(|c| {
            let mut j = serde_json::to_value(c).unwrap_or(serde_json::Value::Null);
            j["bin_means_mm"] = c
                .bin_means_mm
                .iter()
                .map(|&x| if x.is_finite() { serde_json::json!(x) } else { serde_json::Value::Null })
                .collect();
            j
        })
        .collect();
    serde_json::to_string_pretty(&v).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::super::store::RunKey;
    use super::super::tre::{BinStats, Stats};
    use super::*;

    fn run(method: &str, sigma: f64, seed: u64, mean: f64, std: f64) -> RunResult {
        RunResult {
            key: RunKey {
                scenario: "anatomical".into(),
                method: method.into(),
                column: Column { landmarks: 50, noise_sigma_mm: sigma },
                seed,
            },
            tre_volume: Stats { n: 10, mean, std, ..Default::default() },
            tre_surface: Stats { n: 4, mean: 2.0 * mean, ..Default::default() },
            bins: vec![BinStats {
                lo_mm: 0.0,
                hi_mm: 5.0,
                stats: Stats { n: 1, mean: mean + 1.0, ..Default::default() },
            }],
            max_gt_displacement_mm: 10.0,
            landmark_distance_mm: 0.1,
            seconds: 2.0,
            notes: vec![],
            provenance: Default::default(),
            config_hash: String::new(),
            points: None,
            floor: None,
            energy: None,
        }
    }

    #[test]
    fn pooling_over_seeds_by_hand() {
        let rs = vec![run("ARAP", 5.0, 0, 1.0, 0.5), run("ARAP", 5.0, 1, 3.0, 1.5), run("RODS-MPM", 5.0, 0, 0.5, 0.1)];
        let c = aggregate(&rs);
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].seeds, 2);
        assert_eq!(c[0].mean_mm, 2.0);
        assert_eq!(c[0].std_mm, 1.0);
        assert_eq!(c[0].seed_std_mm, 1.0);
        assert_eq!(c[0].surface_mean_mm, 4.0);
        assert_eq!(c[0].bin_means_mm, vec![3.0]);
        let md = table_markdown(&c);
        assert!(md.contains("| ARAP | 2.00 ± 1.00 |"), "{md}");
        assert!(md.contains("| RODS-MPM | **0.50** ± 0.10 |"), "{md}");
        let csv = table_csv(&c);
        assert_eq!(csv.lines().count(), 3);
        assert!(csv.lines().nth(1).unwrap().starts_with("anatomical,ARAP,50,5,2,2.000000,1.000000,1.000000,4.000000"));
        let j: serde_json::Value = serde_json::from_str(&table_json(&c)).unwrap();
        assert_eq!(j[1]["mean_mm"], 0.5);
    }
}
