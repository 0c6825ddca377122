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
}

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
            }
        })
        .collect()
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
