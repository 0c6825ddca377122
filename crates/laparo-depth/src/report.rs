//! Reports of a RoDEM evaluation: `results.json`, a per-image CSV, markdown tables shaped like
//! thesis Tables 3.3–3.5 (accuracy and robustness per alignment) and C.3–C.16 (per
//! perturbation and severity), radar charts (Fig. 3.4) and colour error maps (Fig. C.1).
use crate::align::Alignment;
use crate::error::{DepthError, Result};
use crate::eval::EvalOutput;
use crate::manifest::perturbation_title;
use crate::metrics::{ErrorMetric, Metrics, METRIC_NAMES};
use crate::robustness::{method_robustness, ByError, MethodRobustness, Observation};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Mean of every metric over all images of a method (one alignment).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodMeans {
    pub method: String,
    pub n_images: usize,
    /// Sum of invalid predictions on valid GT pixels over all images.
    pub n_invalid_pred: usize,
    /// Means of the metrics in [`METRIC_NAMES`] order (scale/shift: mean of the fits).
    pub mean: Metrics,
}

/// Accuracy and robustness of every method under one alignment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlignmentSummary {
    pub alignment: Alignment,
    pub means: Vec<MethodMeans>,
    pub robustness: Vec<MethodRobustness>,
}

/// The summary of an evaluation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    pub baseline: String,
    pub alignments: Vec<AlignmentSummary>,
}

fn mean_metrics(ms: &[&Metrics]) -> Metrics {
    let n = ms.len().max(1) as f64;
    let mut acc = [0.0; 12];
    for m in ms {
        for (a, v) in acc.iter_mut().zip(m.values()) {
            *a += v;
        }
    }
    let a = acc.map(|v| v / n);
    Metrics {
        abs_rel: a[0],
        sq_rel: a[1],
        rmse: a[2],
        rmse_log: a[3],
        silog: a[4],
        delta_0_25: a[5],
        delta_0_5: a[6],
        delta_1: a[7],
        delta_2: a[8],
        delta_3: a[9],
        scale: a[10],
        shift: a[11],
    }
}

/// Accuracy (means) and robustness (eqs. 3.3–3.4) of every method against `baseline`.
pub fn summarize(out: &EvalOutput, baseline: &str) -> Result<Summary> {
    let b = out.methods.iter().position(|m| m.name == baseline).ok_or_else(|| {
        DepthError::invalid(
            "baseline",
            format!(
                "'{baseline}' is not among the evaluated methods ({})",
                out.methods.iter().map(|m| m.name.as_str()).collect::<Vec<_>>().join(", ")
            ),
        )
    })?;
    let mut alignments = Vec::new();
    for &a in &out.alignments {
        let obs = |k: usize| -> Vec<Observation> {
            out.images
                .iter()
                .filter(|r| r.method == k)
                .filter_map(|r| {
                    let f = &out.frames[r.frame];
                    r.metrics.get(a).map(|m| Observation {
                        scene: f.scene,
                        perturbation: f.perturbation,
                        severity: f.severity,
                        frame: r.frame,
                        error: ByError::of(m),
                    })
                })
                .collect()
        };
        let base_obs = obs(b);
        let mut means = Vec::new();
        let mut robustness = Vec::new();
        for (k, m) in out.methods.iter().enumerate() {
            let imgs: Vec<_> = out.images.iter().filter(|r| r.method == k).collect();
            let ms: Vec<&Metrics> = imgs.iter().filter_map(|r| r.metrics.get(a)).collect();
            means.push(MethodMeans {
                method: m.name.clone(),
                n_images: ms.len(),
                n_invalid_pred: imgs.iter().map(|r| r.metrics.n_invalid_pred).sum(),
                mean: mean_metrics(&ms),
            });
            robustness.push(method_robustness(&m.name, &obs(k), baseline, &base_obs, &out.layout));
        }
        alignments.push(AlignmentSummary { alignment: a, means, robustness });
    }
    Ok(Summary { baseline: baseline.to_string(), alignments })
}

/// `results.json`: configuration, layout and summary (`"complete": true` is only ever written
/// by a finished run).
pub fn results_json(out: &EvalOutput, summary: &Summary) -> Result<String> {
    let v = serde_json::json!({
        "tool": "laparo depth eval",
        "version": env!("CARGO_PKG_VERSION"),
        "complete": true,
        "manifest": out.manifest.display().to_string(),
        "methods": out.methods.iter().map(|m| serde_json::json!({"name": m.name, "kind": m.kind})).collect::<Vec<_>>(),
        "alignments": out.alignments,
        "baseline": summary.baseline,
        "depth_range_m": [out.options.range.min_m, out.options.range.max_m],
        "invalid_pred_policy": out.options.invalid_pred,
        "scenes": out.layout.scenes,
        "perturbations": out.layout.perturbations,
        "n_frames": out.frames.len(),
        "n_images": out.images.len(),
        "summary": summary,
    });
    serde_json::to_string_pretty(&v).map_err(|e| DepthError::invalid("results", e.to_string()))
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        String::new()
    }
}

/// Per-image CSV: one row per (frame, method, alignment), frame order of the manifest.
pub fn per_image_csv(out: &EvalOutput) -> String {
    let mut s = String::from("frame,scene,perturbation,severity,method,alignment,n_valid,n_invalid_pred");
    for n in METRIC_NAMES {
        s.push(',');
        s.push_str(n);
    }
    s.push('\n');
    for r in &out.images {
        let f = &out.frames[r.frame];
        for &a in &out.alignments {
            if let Some(m) = r.metrics.get(a) {
                let _ = write!(
                    s,
                    "{},{},{},{},{},{},{},{}",
                    csv_field(&f.id),
                    csv_field(&out.layout.scenes[f.scene]),
                    csv_field(&out.layout.perturbations[f.perturbation]),
                    f.severity,
                    csv_field(&out.methods[r.method].name),
                    a.key(),
                    r.metrics.n_valid,
                    r.metrics.n_invalid_pred
                );
                for v in m.values() {
                    s.push(',');
                    s.push_str(&num(v));
                }
                s.push('\n');
            }
        }
    }
    s
}

/// Format with 3 decimals ("-" when undefined), bold the best and underline the second best.
fn ranked(values: &[Option<f64>], lower_is_better: bool) -> Vec<String> {
    let mut order: Vec<(usize, f64)> =
        values.iter().enumerate().filter_map(|(i, v)| v.filter(|x| x.is_finite()).map(|x| (i, x))).collect();
    order.sort_by(|a, b| if lower_is_better { a.1.total_cmp(&b.1) } else { b.1.total_cmp(&a.1) });
    values
        .iter()
        .enumerate()
        .map(|(i, v)| match v {
            Some(x) if x.is_finite() => {
                let t = format!("{x:.3}");
                if values.len() > 1 && order.first().map(|o| o.0) == Some(i) {
                    format!("**{t}**")
                } else if values.len() > 2 && order.get(1).map(|o| o.0) == Some(i) {
                    format!("<u>{t}</u>")
                } else {
                    t
                }
            }
            _ => "-".to_string(),
        })
        .collect()
}

fn table_number(a: Alignment) -> &'static str {
    match a {
        Alignment::None => "3.3",
        Alignment::Scale => "3.4",
        Alignment::ScaleShift => "3.5",
    }
}

/// Markdown tables: per alignment the accuracy/robustness table (Tables 3.3–3.5), the mean of
/// every metric, and per perturbation δ_0.25 and Abs Rel by severity (Tables C.3–C.16).
pub fn markdown_tables(out: &EvalOutput, summary: &Summary) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# RoDEM evaluation\n");
    let _ = writeln!(
        s,
        "Manifest `{}`; {} frames, {} methods; baseline of mCE: **{}**; aligned depth clamped to [{}, {}] m; \
         best in bold, second underlined.\n",
        out.manifest.display(),
        out.frames.len(),
        out.methods.len(),
        summary.baseline,
        out.options.range.min_m,
        out.options.range.max_m
    );
    for al in &summary.alignments {
        let a = al.alignment;
        let _ = writeln!(s, "## Accuracy and robustness, {} (cf. thesis Table {})\n", a.title(), table_number(a));
        let _ = writeln!(
            s,
            "| Method | Abs Rel: Clean Error ↓ | mCE ↓ | mRR ↑ | 1 − δ0.25: Clean Error ↓ | mCE ↓ | mRR ↑ |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|");
        let mut cols: Vec<Vec<String>> = Vec::new();
        for e in ErrorMetric::ALL {
            cols.push(ranked(&al.robustness.iter().map(|r| r.clean_error.get(e)).collect::<Vec<_>>(), true));
            cols.push(ranked(&al.robustness.iter().map(|r| r.mce.get(e)).collect::<Vec<_>>(), true));
            cols.push(ranked(&al.robustness.iter().map(|r| r.mrr.get(e)).collect::<Vec<_>>(), false));
        }
        for (i, r) in al.robustness.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {} | {} |",
                r.method,
                cols.iter().map(|c| c[i].as_str()).collect::<Vec<_>>().join(" | ")
            );
        }
        let _ = writeln!(s, "\n### All metrics, mean over all images, {}\n", a.title());
        let _ = writeln!(s, "| Method | images | Abs Rel ↓ | Sq Rel (m) ↓ | RMSE (m) ↓ | RMSE log ↓ | SILog ↓ | δ0.25 ↑ | δ0.5 ↑ | δ1 ↑ | δ2 ↑ | δ3 ↑ | invalid pred. px |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        let mcols: Vec<Vec<String>> = (0..10)
            .map(|k| ranked(&al.means.iter().map(|m| Some(m.mean.values()[k])).collect::<Vec<_>>(), k < 5))
            .collect();
        for (i, m) in al.means.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                m.method,
                m.n_images,
                mcols.iter().map(|c| c[i].as_str()).collect::<Vec<_>>().join(" | "),
                m.n_invalid_pred
            );
        }
        let _ = writeln!(s);
        // Per perturbation and severity (Tables C.3–C.16).
        let perts: Vec<String> = out
            .layout
            .perturbations
            .iter()
            .filter(|p| al.robustness.iter().any(|r| r.perturbations.iter().any(|q| &q.perturbation == *p)))
            .cloned()
            .collect();
        for p in perts {
            for (label, e, higher) in
                [("δ0.25", ErrorMetric::OneMinusDelta025, true), ("Abs Rel", ErrorMetric::AbsRel, false)]
            {
                let _ = writeln!(
                    s,
                    "### {}: {label} with {} per severity (cf. Tables C.3–C.16)\n",
                    perturbation_title(&p),
                    a.title()
                );
                let _ = writeln!(
                    s,
                    "| | {} |",
                    al.robustness.iter().map(|r| r.method.as_str()).collect::<Vec<_>>().join(" | ")
                );
                let _ = writeln!(s, "|---|{}", "---|".repeat(al.robustness.len()));
                let mut sevs: Vec<u32> = al
                    .robustness
                    .iter()
                    .flat_map(|r| r.perturbations.iter().filter(|q| q.perturbation == p))
                    .flat_map(|q| q.by_severity.iter().map(|b| b.severity))
                    .collect();
                sevs.sort();
                sevs.dedup();
                for sv in sevs {
                    let vals: Vec<Option<f64>> = al
                        .robustness
                        .iter()
                        .map(|r| {
                            r.perturbations
                                .iter()
                                .find(|q| q.perturbation == p)
                                .and_then(|q| q.by_severity.iter().find(|b| b.severity == sv))
                                .map(|b| {
                                    let v = b.mean.get(e);
                                    if higher {
                                        1.0 - v
                                    } else {
                                        v
                                    }
                                })
                        })
                        .collect();
                    let _ = writeln!(s, "| s{sv} | {} |", ranked(&vals, !higher).join(" | "));
                }
                let _ = writeln!(s);
            }
        }
    }
    s
}

/// Plain-text summary for the terminal (Tables 3.3–3.5 without markup).
pub fn terminal_summary(summary: &Summary) -> String {
    let f = |v: Option<f64>| v.filter(|x| x.is_finite()).map(|x| format!("{x:.3}")).unwrap_or_else(|| "-".into());
    let mut s = String::new();
    for al in &summary.alignments {
        let w = al.robustness.iter().map(|r| r.method.len()).max().unwrap_or(6).max(6);
        let _ = writeln!(s, "{} (baseline {}):", al.alignment.title(), summary.baseline);
        let _ = writeln!(
            s,
            "  {:w$}  {:>8} {:>7} {:>7}   {:>8} {:>7} {:>7}",
            "method", "AbsRel", "mCE", "mRR", "1-δ0.25", "mCE", "mRR"
        );
        for r in &al.robustness {
            let e1 = ErrorMetric::AbsRel;
            let e2 = ErrorMetric::OneMinusDelta025;
            let _ = writeln!(
                s,
                "  {:w$}  {:>8} {:>7} {:>7}   {:>8} {:>7} {:>7}",
                r.method,
                f(r.clean_error.get(e1)),
                f(r.mce.get(e1)),
                f(r.mrr.get(e1)),
                f(r.clean_error.get(e2)),
                f(r.mce.get(e2)),
                f(r.mrr.get(e2))
            );
        }
    }
    s
}

/// Write `text` to `path` atomically.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    laparo_core::atomic::write_atomic(path, text.as_bytes())?;
    Ok(())
}

/// Output files of [`write_reports`].
pub const RESULTS_JSON: &str = "results.json";

/// Write per_image.csv, tables.md and finally results.json (atomically, each) under `dir`.
/// Call [`remove_stale_results`] before the evaluation so a failed run leaves no results.json.
pub fn write_reports(dir: &Path, out: &EvalOutput, summary: &Summary) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    let p = dir.join("per_image.csv");
    write_text(&p, &per_image_csv(out))?;
    written.push(p);
    let p = dir.join("tables.md");
    write_text(&p, &markdown_tables(out, summary))?;
    written.push(p);
    let p = dir.join(RESULTS_JSON);
    write_text(&p, &results_json(out, summary)?)?;
    written.push(p);
    Ok(written)
}

/// Remove a results.json left by an earlier run in `dir` (so that a failing run cannot leave
/// an old, complete-looking result behind).
pub fn remove_stale_results(dir: &Path) -> Result<()> {
    let p = dir.join(RESULTS_JSON);
    if p.exists() {
        std::fs::remove_file(&p).map_err(|e| laparo_core::CoreError::io(&p, e))?;
    }
    Ok(())
}
