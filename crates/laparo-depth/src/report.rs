//! Reports of a RoDEM evaluation: `results.json`, a per-image CSV, markdown tables shaped like
//! thesis Tables 3.3–3.5 (accuracy and robustness per alignment) and C.3–C.16 (per
//! perturbation and severity), radar charts (Fig. 3.4) and colour error maps (Fig. C.1).
//!
//! Length (~690 lines): text outputs (JSON, CSV, markdown, terminal; first half) and figures (radar
//! charts, error maps; second half) of one evaluation share the [`Summary`] types and the
//! figure/table naming; both halves are under 450 lines. To be split into `report/{text,figures}`
//! once the radar-chart rework of issue 10 has landed.
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
    /// Method name.
    pub method: String,
    /// Number of images averaged.
    pub n_images: usize,
    /// Sum of invalid predictions on valid GT pixels over all images.
    pub n_invalid_pred: usize,
    /// Means of the metrics in [`METRIC_NAMES`] order (scale/shift: mean of the fits).
    pub mean: Metrics,
}

/// Accuracy and robustness of every method under one alignment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlignmentSummary {
    /// The alignment these results are for.
    pub alignment: Alignment,
    /// Mean accuracy of every method.
    pub means: Vec<MethodMeans>,
    /// Robustness of every method against the baseline.
    pub robustness: Vec<MethodRobustness>,
}

/// The summary of an evaluation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Baseline method of mCE.
    pub baseline: String,
    /// Results per alignment.
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

// ---------------------------------------------------------------------------------------------
// Figures: radar charts (Fig. 3.4) and colour error maps (Fig. C.1).

use crate::eval::{load_gt, read_prediction};
use crate::manifest::Manifest;
use crate::metrics::aligned_depth_map;
use laparo_core::colormap::{colorize, Colormap};
use laparo_core::image::Image;
use laparo_core::plot::with_colorbar;
use laparo_core::plot::PlotResult;
use plotters::coord::Shift;
use plotters::prelude::*;

/// A file-name-safe version of `s` (`/` and other separators become `_`).
pub fn file_stem(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '.' { c } else { '_' }).collect()
}

/// One radar panel: per-perturbation CE and RR for one error metric.
struct RadarPanel {
    title: String,
    axes: Vec<String>,
    ce: Vec<Option<f64>>,
    rr: Vec<Option<f64>>,
}

fn radar_panels(r: &MethodRobustness) -> Vec<RadarPanel> {
    ErrorMetric::ALL
        .iter()
        .map(|&e| RadarPanel {
            title: format!("E = {}", e.title()),
            axes: r.perturbations.iter().map(|p| perturbation_title(&p.perturbation)).collect(),
            ce: r.perturbations.iter().map(|p| p.ce.get(e)).collect(),
            rr: r.perturbations.iter().map(|p| p.rr.get(e)).collect(),
        })
        .collect()
}

/// Ring (or tick) values of a radar/bar scale covering `0..=vmax`: a "nice" step (1, 2, 2.5 or 5
/// × 10^k, at least 0.25) giving at most [`MAX_RINGS`] rings; returns (rings, outer radius value).
pub fn radar_rings(vmax: f64) -> (Vec<f64>, f64) {
    let vmax = if vmax.is_finite() && vmax > 0.0 { vmax } else { 1.0 };
    let raw = vmax * 1.05 / MAX_RINGS as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|&s| s >= raw).unwrap_or(10.0 * mag).max(0.25);
    let n = ((vmax * 1.05) / step).ceil().max(1.0) as usize;
    let rings: Vec<f64> = (1..=n).map(|k| k as f64 * step).collect();
    let rmax = *rings.last().expect("n >= 1");
    (rings, rmax)
}

/// At most this many rings (or ticks) on a radar or bar chart.
pub const MAX_RINGS: usize = 6;

fn ring_label(v: f64) -> String {
    if v >= 1000.0 || (v - v.round()).abs() < 1e-9 {
        format!("{v:.0}")
    } else if (v * 10.0 - (v * 10.0).round()).abs() < 1e-9 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

fn panel_vmax(p: &RadarPanel) -> f64 {
    p.ce.iter().chain(&p.rr).flatten().fold(1.2f64, |a, &b| if b.is_finite() { a.max(b) } else { a })
}

fn axis_label(p: &RadarPanel, k: usize) -> String {
    format!(
        "{} ({}/{})",
        p.axes[k],
        p.ce[k].map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into()),
        p.rr[k].map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into())
    )
}

fn draw_legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, ce_col: RGBColor, rr_col: RGBColor) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let (aw, ah) = area.dim_in_pixel();
    let ly = ah as i32 - 22;
    area.draw(&Rectangle::new([(10, ly), (24, ly + 10)], ce_col.filled()))?;
    area.draw(&Text::new("perturbation error CE (eq. 3.3)", (28, ly - 2), ("sans-serif", 12).into_font()))?;
    area.draw(&Rectangle::new([(aw as i32 / 2 + 10, ly), (aw as i32 / 2 + 24, ly + 10)], rr_col.filled()))?;
    area.draw(&Text::new(
        "resilience rate RR (eq. 3.4)",
        (aw as i32 / 2 + 28, ly - 2),
        ("sans-serif", 12).into_font(),
    ))?;
    Ok(())
}

/// Grouped bars (CE, RR) per perturbation: the radar's fallback for fewer than three axes,
/// where a polygon cannot be drawn.
fn draw_bars<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &RadarPanel) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let ce_col = RGBColor(214, 39, 40);
    let rr_col = RGBColor(31, 119, 180);
    let (aw, ah) = area.dim_in_pixel();
    let (rings, rmax) = radar_rings(panel_vmax(p));
    area.draw(&Text::new(p.title.clone(), (10, 4), ("sans-serif", 16).into_font()))?;
    let (x0, x1, y0, y1) = (60i32, aw as i32 - 20, 40i32, ah as i32 - 70);
    let ypx = |v: f64| y1 - ((y1 - y0) as f64 * (v / rmax).clamp(0.0, 1.0)).round() as i32;
    for &t in std::iter::once(&0.0).chain(&rings) {
        let style =
            if (t - 1.0).abs() < 1e-9 { BLACK.mix(0.6).stroke_width(1) } else { BLACK.mix(0.15).stroke_width(1) };
        area.draw(&PathElement::new(vec![(x0, ypx(t)), (x1, ypx(t))], style))?;
        area.draw(&Text::new(ring_label(t), (8, ypx(t) - 6), ("sans-serif", 11).into_font().color(&BLACK.mix(0.6))))?;
    }
    if rings.iter().all(|&t| (t - 1.0).abs() > 1e-9) && 1.0 < rmax {
        area.draw(&PathElement::new(vec![(x0, ypx(1.0)), (x1, ypx(1.0))], BLACK.mix(0.6).stroke_width(1)))?;
    }
    let n = p.axes.len().max(1) as i32;
    let slot = (x1 - x0) / n;
    for k in 0..p.axes.len() {
        let sx = x0 + slot * k as i32;
        let bw = (slot / 4).max(4);
        for (j, (v, col)) in [(p.ce[k], ce_col), (p.rr[k], rr_col)].into_iter().enumerate() {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                let bx = sx + slot / 2 - bw + j as i32 * bw;
                area.draw(&Rectangle::new([(bx, ypx(v)), (bx + bw - 2, y1)], col.filled()))?;
            }
        }
        let lab = axis_label(p, k);
        let tw = (lab.chars().count() as i32 * 6) / 2;
        area.draw(&Text::new(lab, (sx + slot / 2 - tw, y1 + 8), ("sans-serif", 12).into_font()))?;
    }
    draw_legend(area, ce_col, rr_col)
}

fn draw_radar<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, panels: &[RadarPanel]) -> PlotResult
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    root.draw(&Text::new(title.to_string(), (12, 8), ("sans-serif", 20).into_font()))?;
    let areas = root.margin(36, 0, 0, 0).split_evenly((1, panels.len().max(1)));
    let ce_col = RGBColor(214, 39, 40);
    let rr_col = RGBColor(31, 119, 180);
    for (area, p) in areas.iter().zip(panels) {
        if p.axes.len() < 3 {
            draw_bars(area, p)?;
            continue;
        }
        let (aw, ah) = area.dim_in_pixel();
        let (cx, cy) = (aw as f64 / 2.0, ah as f64 / 2.0 + 10.0);
        let radius = (aw.min(ah) as f64 / 2.0 - 70.0).max(20.0);
        // A handful of rings scaled to the data (CE can be in the thousands for a degenerate
        // method; one ring per 0.25 would fill the disc).
        let (rings, rmax) = radar_rings(panel_vmax(p));
        area.draw(&Text::new(p.title.clone(), (10, 4), ("sans-serif", 16).into_font()))?;
        let n = p.axes.len();
        let pt = |k: usize, v: f64| -> (i32, i32) {
            let a = -std::f64::consts::FRAC_PI_2 + 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            let r = radius * (v / rmax).clamp(0.0, 1.0);
            ((cx + r * a.cos()).round() as i32, (cy + r * a.sin()).round() as i32)
        };
        let circle = |ring: f64| -> Vec<(i32, i32)> {
            (0..=72)
                .map(|i| {
                    let a = 2.0 * std::f64::consts::PI * i as f64 / 72.0;
                    let r = radius * ring / rmax;
                    ((cx + r * a.cos()).round() as i32, (cy + r * a.sin()).round() as i32)
                })
                .collect()
        };
        // Rings, labelled, and the value 1 highlighted (CE = 1 is the baseline, RR = 1 no
        // degradation) whether or not it is one of the rings.
        for &ring in &rings {
            let style = if (ring - 1.0).abs() < 1e-9 {
                BLACK.mix(0.6).stroke_width(1)
            } else {
                BLACK.mix(0.15).stroke_width(1)
            };
            area.draw(&PathElement::new(circle(ring), style))?;
            let (x, y) = (cx as i32 + 3, (cy - radius * ring / rmax) as i32 - 12);
            area.draw(&Text::new(ring_label(ring), (x, y), ("sans-serif", 11).into_font().color(&BLACK.mix(0.6))))?;
        }
        if rings.iter().all(|&r| (r - 1.0).abs() > 1e-9) && 1.0 < rmax {
            area.draw(&PathElement::new(circle(1.0), BLACK.mix(0.6).stroke_width(1)))?;
        }
        for k in 0..n {
            area.draw(&PathElement::new(vec![pt(k, 0.0), pt(k, rmax)], BLACK.mix(0.3)))?;
            let (x, y) = pt(k, rmax * 1.12);
            let lab = axis_label(p, k);
            let tw = (lab.chars().count() as i32 * 6) / 2;
            area.draw(&Text::new(lab, (x - tw, y - 6), ("sans-serif", 12).into_font()))?;
        }
        for (vals, col) in [(&p.ce, ce_col), (&p.rr, rr_col)] {
            let mut pts: Vec<(i32, i32)> = vals.iter().enumerate().map(|(k, v)| pt(k, v.unwrap_or(0.0))).collect();
            area.draw(&Polygon::new(pts.clone(), col.mix(0.15)))?;
            pts.push(pts[0]);
            area.draw(&PathElement::new(pts.clone(), col.stroke_width(2)))?;
            for q in &pts {
                area.draw(&Circle::new(*q, 3, col.filled()))?;
            }
        }
        draw_legend(area, ce_col, rr_col)?;
    }
    Ok(())
}

/// Radar chart of one method under one alignment as PNG and SVG (thesis Fig. 3.4): per
/// perturbation (averaged over scenes) CE and RR, for E = Abs Rel and E = 1 − δ0.25. Axis labels
/// read "name (CE/RR)". With fewer than three perturbations the panels are grouped bars.
pub fn write_radar(dir: &Path, r: &MethodRobustness, alignment: Alignment) -> Result<Vec<PathBuf>> {
    let panels = radar_panels(r);
    let title = format!("{} — {} (baseline {})", r.method, alignment.title(), r.baseline);
    let stem = format!("{}_{}", file_stem(&r.method), alignment.key());
    let (w, h) = (1100u32, 560u32);
    let png = dir.join(format!("{stem}.png"));
    laparo_core::plot::draw_png(&png, w, h, |root| draw_radar(&root, &title, &panels))?;
    let svg = dir.join(format!("{stem}.svg"));
    laparo_core::plot::draw_svg(&svg, w, h, |root| draw_radar(&root, &title, &panels))?;
    Ok(vec![png, svg])
}

/// Signed depth error `z* − ẑ` (mm) of every method on one frame after `alignment`, and the
/// frame's RGB image when readable.
type FrameErrors = (Option<Image<u8>>, Vec<(String, Image<f64>)>);

fn frame_errors(manifest: &Manifest, out: &EvalOutput, frame_id: &str, alignment: Alignment) -> Result<FrameErrors> {
    let f = out.frames.iter().find(|f| f.id == frame_id).ok_or_else(|| {
        DepthError::invalid("error-map frame", format!("'{frame_id}' is not a frame of the manifest"))
    })?;
    let spec = &manifest.frames[f.index];
    let gt = load_gt(&f.gt, f.gt_unit, f.mask.as_deref())?;
    let opts = crate::metrics::PairOptions { alignments: vec![alignment], ..out.options.clone() };
    let mut maps = Vec::new();
    for m in &out.methods {
        let pp = manifest.prediction_path(m, f, spec);
        let pred = read_prediction(&pp)?;
        if pred.size() != gt.gt_m.size() {
            return Err(DepthError::file(&pp, "size mismatch with the ground truth"));
        }
        let (z, _) = aligned_depth_map(
            &pred.data,
            m.kind,
            &gt.gt_m.data,
            gt.mask.as_ref().map(|k| k.data.as_slice()),
            alignment,
            &opts,
        )
        .map_err(|e| DepthError::file(&pp, e.to_string()))?;
        let err: Vec<f64> = z.iter().zip(&gt.gt_m.data).map(|(zh, zg)| (zg - zh) * 1000.0).collect();
        maps.push((m.name.clone(), Image { width: gt.gt_m.width, height: gt.gt_m.height, channels: 1, data: err }));
    }
    let rgb = match laparo_core::io::read_rgb8(&f.rgb) {
        Ok(im) if im.size() == gt.gt_m.size() => Some(im),
        _ => None,
    };
    Ok((rgb, maps))
}

/// Symmetric colour range: 98th percentile of |error| (at least 0.5 mm).
fn error_range<'a>(maps: impl Iterator<Item = &'a Image<f64>>) -> f64 {
    let mut abs: Vec<f64> = maps.flat_map(|m| m.data.iter().filter(|v| v.is_finite()).map(|v| v.abs())).collect();
    abs.sort_by(f64::total_cmp);
    abs.get(((abs.len() as f64 * 0.98) as usize).min(abs.len().saturating_sub(1))).copied().unwrap_or(1.0).max(0.5)
}

const ERROR_LABEL: &str = "z* - z_pred [mm] (red: pred. shallower)";

/// Colour error maps (thesis Fig. C.1) of one frame for every method: `z* − ẑ` in mm after
/// `alignment` (red: prediction shallower than the GT, blue: deeper), one symmetric colour range
/// per frame (98th percentile of |error| over the methods) with a colour bar; plus the RGB image.
pub fn write_error_maps(
    dir: &Path,
    manifest: &Manifest,
    out: &EvalOutput,
    frame_id: &str,
    alignment: Alignment,
) -> Result<Vec<PathBuf>> {
    let (rgb, maps) = frame_errors(manifest, out, frame_id, alignment)?;
    let a = error_range(maps.iter().map(|m| &m.1));
    let stem = file_stem(frame_id);
    let mut written = Vec::new();
    if let Some(rgb) = rgb {
        let p = dir.join(format!("{stem}_rgb.png"));
        laparo_core::io::write_png(&p, &rgb)?;
        written.push(p);
    }
    for (name, err) in maps {
        // Turbo: low (blue) = prediction deeper than the GT, high (red) = shallower.
        let fig = with_colorbar(&colorize(&err, -a, a, Colormap::Turbo), -a, a, Colormap::Turbo, ERROR_LABEL);
        let p = dir.join(format!("{stem}_{}_{}.png", file_stem(&name), alignment.key()));
        laparo_core::io::write_png(&p, &fig)?;
        written.push(p);
    }
    Ok(written)
}

/// Fig. C.1-like grid: one column per frame (RGB on top), one row per method, a common
/// symmetric colour range and one colour bar. Row order = method order of the evaluation.
pub fn write_error_grid(
    path: &Path,
    manifest: &Manifest,
    out: &EvalOutput,
    frame_ids: &[String],
    alignment: Alignment,
) -> Result<()> {
    let cols: Vec<FrameErrors> =
        frame_ids.iter().map(|id| frame_errors(manifest, out, id, alignment)).collect::<Result<_>>()?;
    let a = error_range(cols.iter().flat_map(|c| c.1.iter().map(|m| &m.1)));
    let (tw, th) =
        cols.iter().flat_map(|c| c.1.iter().map(|m| m.1.size())).fold((1, 1), |x, y| (x.0.max(y.0), x.1.max(y.1)));
    let gap = 4;
    let rows = out.methods.len() + 1;
    let (gw, gh) = (cols.len() * (tw + gap) + gap, rows * (th + gap) + gap);
    let mut grid = Image::filled(gw, gh, 3, 255u8);
    let mut blit = |img: &Image<u8>, c: usize, r: usize| {
        let (x0, y0) = (gap + c * (tw + gap), gap + r * (th + gap));
        for y in 0..img.height.min(th) {
            for x in 0..img.width.min(tw) {
                for k in 0..3 {
                    grid.set(x0 + x, y0 + y, k, img.get(x, y, k.min(img.channels - 1)));
                }
            }
        }
    };
    for (c, (rgb, maps)) in cols.iter().enumerate() {
        if let Some(rgb) = rgb {
            blit(rgb, c, 0);
        }
        for (r, (_, err)) in maps.iter().enumerate() {
            blit(&colorize(err, -a, a, Colormap::Turbo), c, r + 1);
        }
    }
    let fig = with_colorbar(&grid, -a, a, Colormap::Turbo, ERROR_LABEL);
    laparo_core::io::write_png(path, &fig)?;
    Ok(())
}

/// Radar charts for every method and alignment under `dir/radar/`, and error maps of
/// `error_map_frames` under `dir/error_maps/`.
pub fn write_figures(
    dir: &Path,
    manifest: &Manifest,
    out: &EvalOutput,
    summary: &Summary,
    error_map_frames: &[String],
    error_alignment: Alignment,
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for al in &summary.alignments {
        for r in &al.robustness {
            written.extend(write_radar(&dir.join("radar"), r, al.alignment)?);
        }
    }
    for id in error_map_frames {
        written.extend(write_error_maps(&dir.join("error_maps"), manifest, out, id, error_alignment)?);
    }
    if !error_map_frames.is_empty() {
        // Rows: RGB, then the methods in evaluation order (listed in the file name's sidecar text).
        let p = dir.join("error_maps").join(format!("grid_{}.png", error_alignment.key()));
        write_error_grid(&p, manifest, out, error_map_frames, error_alignment)?;
        let legend = std::iter::once("row 1: RGB".to_string())
            .chain(out.methods.iter().enumerate().map(|(i, m)| format!("row {}: {}", i + 2, m.name)))
            .chain(std::iter::once(format!("columns: {}", error_map_frames.join(", "))))
            .collect::<Vec<_>>()
            .join("\n");
        let lp = dir.join("error_maps").join(format!("grid_{}.txt", error_alignment.key()));
        write_text(&lp, &(legend + "\n"))?;
        written.push(p);
        written.push(lp);
    }
    Ok(written)
}
