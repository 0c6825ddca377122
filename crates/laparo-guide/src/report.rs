//! The HTML report of a `laparo guide` run: one section per stage (images by relative links), a
//! table of the stage errors and times. The scenario's input images are copied next to it so the
//! folder is self-contained.
use crate::error::Result;
use crate::pipeline::GuideReport;
use laparo_core::atomic::write_atomic;
use std::path::Path;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A figure for the page: integers as integers (counts), other numbers to 3 decimals (0 at ≥ 100),
/// booleans as yes/no, a missing figure as "n/a".
fn num(v: &serde_json::Value) -> String {
    if let Some(i) = v.as_u64() {
        return i.to_string();
    }
    if let Some(i) = v.as_i64() {
        return i.to_string();
    }
    match v {
        serde_json::Value::Bool(b) => (if *b { "yes" } else { "no" }).into(),
        serde_json::Value::Null => "n/a".into(),
        _ => match v.as_f64() {
            Some(x) if x.abs() >= 100.0 => format!("{x:.0}"),
            Some(x) => format!("{x:.3}"),
            None => esc(&v.to_string()),
        },
    }
}

/// `num(obj[key])`, followed by "(not measurable: reason)" when `obj[key_reason]` says why it is missing.
fn fig(obj: &serde_json::Value, key: &str) -> String {
    match obj[format!("{key}_reason")].as_str() {
        Some(r) if obj[key].is_null() => format!("n/a (not measurable: {})", esc(r)),
        _ => num(&obj[key]),
    }
}

/// The warnings of a route's summary as an HTML list (empty when there is none).
fn warnings_html(summary: &serde_json::Value) -> String {
    let w: Vec<&str> = summary["warnings"].as_array().into_iter().flatten().filter_map(|w| w.as_str()).collect();
    if w.is_empty() {
        return String::new();
    }
    let mut h = format!(
        "<div style=\"border:2px solid #c00;padding:4px 12px;background:#fff4f4\"><b>{} warning{}</b><ul>",
        w.len(),
        if w.len() == 1 { "" } else { "s" }
    );
    for x in w {
        h.push_str(&format!("<li>{}</li>", esc(x)));
    }
    h.push_str("</ul></div>\n");
    h
}

/// The table of every stage against the one before (`summary.stage_comparison`).
fn comparison_html(summary: &serde_json::Value) -> String {
    let mut h = String::from(
        "<h2>Each stage against the one before</h2><table><tr><th>stage</th><th>previous</th><th>figure</th><th>before</th><th>after</th><th>change</th><th>verdict</th></tr>\n",
    );
    for c in summary["stage_comparison"].as_array().into_iter().flatten() {
        let verdict = match c["worse"].as_bool() {
            Some(true) => "<b style=\"color:#c00\">WORSE</b>".to_string(),
            Some(false) => "better or equal".to_string(),
            None => format!("n/a ({})", esc(c["worse_reason"].as_str().unwrap_or(""))),
        };
        let change = c["change"].as_f64().map_or("n/a".into(), |d| format!("{d:+.3}"));
        h.push_str(&format!(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{change}</td><td>{verdict}</td></tr>\n",
            esc(c["stage"].as_str().unwrap_or("")),
            esc(c["previous"].as_str().unwrap_or("")),
            esc(c["figure"].as_str().unwrap_or("")),
            num(&c["before"]),
            num(&c["after"])
        ));
    }
    h.push_str("</table>\n");
    match summary["registration_improves_on_rigid_near_incision"].as_bool() {
        Some(true) => {
            h.push_str("<p>The deformable registration improves on the rigid alignment near the incision.</p>\n")
        }
        Some(false) => h.push_str(
            "<p><b>The deformable registration does not improve on the rigid alignment near the incision.</b></p>\n",
        ),
        None => h.push_str(&format!(
            "<p>Near the incision the two cannot be compared: {}.</p>\n",
            esc(summary["registration_improves_on_rigid_near_incision_reason"].as_str().unwrap_or("no figure"))
        )),
    }
    h
}

/// "lip 0 (cyan): 0.412 mm; lip 1 (magenta): 13.0 mm" from a stage's `lips` list and one of its fields.
fn lips_text(m: &serde_json::Value, key: &str, unit: &str) -> String {
    m["lips"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|l| {
            let colour = l["colour"].as_str().map_or(String::new(), |c| format!(" ({c})"));
            format!("{}{colour}: {}{unit}", esc(l["lip"].as_str().unwrap_or("?")), num(&l[key]))
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Copy the scenario inputs shown in the report into `out/inputs/` and write `out/report.html`.
pub fn write_html(out: &Path, r: &GuideReport, scenario: &Path) -> Result<()> {
    let inputs = out.join("inputs");
    std::fs::create_dir_all(&inputs).map_err(|e| laparo_core::CoreError::io(&inputs, e))?;
    for n in ["past_left.png", "past_right.png", "present_left.png", "present_right.png"] {
        let bytes = std::fs::read(scenario.join(n)).map_err(|e| laparo_core::CoreError::io(scenario.join(n), e))?;
        write_atomic(&inputs.join(n), &bytes)?;
    }
    let img = |src: &str, cap: &str| {
        format!("<figure><img src=\"{src}\" alt=\"{cap}\"><figcaption>{cap}</figcaption></figure>")
    };
    let mut h = String::new();
    h.push_str("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>laparo guide</title><style>body{font-family:sans-serif;max-width:1400px;margin:auto}figure{display:inline-block;margin:4px;width:32%}img{width:100%}table{border-collapse:collapse}td,th{border:1px solid #aaa;padding:3px 8px;text-align:right}td:first-child{text-align:left}</style></head><body>\n");
    h.push_str("<h1>laparo guide — guidance pipeline in silico (thesis §5.4.3, Fig. 5.10)</h1>\n");
    h.push_str(&format!(
        "<p>Scenario <code>{}</code>, stereo route <b>{:?}</b>, total {:.1} s, peak memory {} MiB.</p>\n",
        esc(&r.scenario),
        r.config.route,
        r.total_seconds,
        r.peak_memory_mib.map_or("?".into(), |m| format!("{m:.0}"))
    ));
    h.push_str(&warnings_html(&r.summary));
    h.push_str("<h2>Stage errors and times</h2><table><tr><th>stage</th><th>time (s)</th><th>errors against the ground truth</th></tr>\n");
    for s in &r.stages {
        let m = &s.metrics;
        let e = match s.name.as_str() {
            n if n.starts_with("stereo") => format!(
                "depth |error| mean {} mm, median {} mm, p95 {} mm, coverage {} of the liver",
                fig(&m["depth_error"], "mean_abs_mm"),
                num(&m["depth_error"]["median_abs_mm"]),
                num(&m["depth_error"]["p95_abs_mm"]),
                num(&m["depth_error"]["coverage"])
            ),
            "rigid alignment" => format!(
                "rotation {} °, translation {} mm, mean vertex {} mm (initial pose: {} mm, {} °)",
                num(&m["rotation_error_deg"]),
                num(&m["translation_error_mm"]),
                num(&m["mean_vertex_error_mm"]),
                num(&m["initial_mean_vertex_error_mm"]),
                num(&m["initial_rotation_error_deg"])
            ),
            "source landmarks" => format!("points per lip: {}", lips_text(m, "points", "")),
            "target lips" => format!(
                "lifted lip to the true lip, mean: {}; points without depth: {}",
                lips_text(m, "mean_distance_to_true_lip_mm", " mm"),
                lips_text(m, "points_without_depth", "")
            ),
            "RODS-MPM registration" => format!(
                "mean landmark distance {} → {} mm, {} particles, {} iterations",
                num(&m["mean_landmark_distance_mm"][0]),
                num(&m["mean_landmark_distance_mm"][1]),
                num(&m["particles"]),
                num(&m["iterations"])
            ),
            "transfer + evaluation" => format!(
                "TRE mean {} / near {} / far {} mm (rigid only: {} / {} / {}); tumour centroid {} mm (rigid only {}); outline {} px @1920 (rigid only {}); tumour vertices outside the particles: {} of {}",
                fig(&m["tre_registered"], "mean_mm"),
                fig(&m["tre_registered"], "near_mm"),
                fig(&m["tre_registered"], "far_mm"),
                fig(&m["tre_rigid_only"], "mean_mm"),
                fig(&m["tre_rigid_only"], "near_mm"),
                fig(&m["tre_rigid_only"], "far_mm"),
                num(&m["tumour_centroid_error_mm"]),
                num(&m["tumour_centroid_error_rigid_only_mm"]),
                fig(m, "tumour_outline_error_px_1920"),
                fig(m, "tumour_outline_error_rigid_only_px_1920"),
                num(&m["tumour_vertices_outside_particles"]),
                num(&m["tumour_vertices"])
            ),
            _ => String::new(),
        };
        h.push_str(&format!(
            "<tr><td>{}</td><td>{:.2}</td><td style=\"text-align:left\">{}</td></tr>\n",
            esc(&s.name),
            s.seconds,
            e
        ));
    }
    h.push_str("</table>\n");
    let slowest =
        r.stages.iter().max_by(|a, b| a.seconds.total_cmp(&b.seconds)).map(|s| s.name.clone()).unwrap_or_default();
    h.push_str(&format!(
        "<p>Goals: tumour centroid ≤ 3 mm: <b>{}</b>; projected outline ≤ 10 px at 1920×1080: <b>{}</b>. Slowest stage: {}.</p>\n",
        num(&r.summary["goals"]["tumour_centroid_within_3mm"]),
        fig(&r.summary["goals"], "outline_within_10px"),
        esc(&slowest)
    ));
    h.push_str(&comparison_html(&r.summary));
    h.push_str("<h2>1. Stereo pairs (input)</h2>");
    h.push_str(&img("inputs/past_left.png", "past left (before the incision)"));
    h.push_str(&img("inputs/past_right.png", "past right (uncalibrated: rotated, principal point shifted)"));
    h.push_str(&img("inputs/present_left.png", "present left (after the incision)"));
    h.push_str("<h2>2. Stereo matching → depth</h2>");
    h.push_str(&img("past_depth.png", "past depth (mm, viridis over the prior range)"));
    h.push_str(&img("past_depth_error.png", "past |depth error| on the liver (0–5 mm, magma)"));
    h.push_str(&img("present_depth.png", "present depth"));
    h.push_str(&img("present_depth_error.png", "present |depth error| (0–5 mm)"));
    h.push_str("<p>Point clouds: <a href=\"past_cloud.ply\">past_cloud.ply</a>, <a href=\"present_cloud.ply\">present_cloud.ply</a>.</p>");
    h.push_str("<h2>3. Rigid alignment of the preoperative model (ICP)</h2>");
    h.push_str(&img("rigid_overlay.png", "aligned model over the past left image"));
    h.push_str("<p><a href=\"model_aligned.obj\">model_aligned.obj</a>, <a href=\"rigid.json\">rigid.json</a></p>");
    h.push_str("<h2>4. Incision → source landmarks; lips → targets</h2>");
    h.push_str(&img("incision_past.png", "incision drawn on the past left image"));
    h.push_str(&img("lips_present.png", "lips drawn on the present left image"));
    h.push_str("<p><a href=\"source_landmarks.ply\">source_landmarks.ply</a>, <a href=\"target_lips.ply\">target_lips.ply</a>, <a href=\"target_surface.ply\">target_surface.ply</a></p>");
    h.push_str("<h2>5. RODS-MPM registration</h2>");
    h.push_str(&img("registration/loss.png", "mean landmark distance per iteration"));
    h.push_str("<p><a href=\"registration/report.json\">registration/report.json</a>, <a href=\"registration/surface_registered.ply\">surface_registered.ply</a>, <a href=\"liver_registered.obj\">liver_registered.obj</a></p>");
    h.push_str("<h2>6. Overlay</h2>");
    h.push_str("<figure style=\"width:98%\"><img src=\"overlay.png\" alt=\"overlay\"><figcaption>registered liver (blue) and tumour (yellow) on the present left image; green: true tumour outline</figcaption></figure>");
    h.push_str("<h2>Summary</h2><pre>");
    h.push_str(&esc(&serde_json::to_string_pretty(&r.summary).unwrap_or_default()));
    h.push_str("</pre></body></html>\n");
    write_atomic(&out.join("report.html"), h.as_bytes())?;
    Ok(())
}

/// The index of an end-to-end run (`out/index.html`): the ground truth, the time of every step, the
/// stage errors of each route side by side, the difference in final TRE, and links to each route's
/// full report.
pub fn write_index(out: &Path, r: &crate::end_to_end::EndToEndReport, routes: &[(&str, &GuideReport)]) -> Result<()> {
    let mut h = String::new();
    h.push_str("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>laparo guide: end to end</title><style>body{font-family:sans-serif;max-width:1400px;margin:auto}figure{display:inline-block;margin:4px;width:48%}img{width:100%}table{border-collapse:collapse}td,th{border:1px solid #aaa;padding:3px 8px;text-align:right}td:first-child{text-align:left}</style></head><body>\n");
    h.push_str("<h1>laparo guide — from a stereo pair to the registered liver and its tumour (thesis §5.4.3)</h1>\n");
    let g = &r.ground_truth;
    h.push_str(&format!(
        "<p>Incision: <b>{}</b>; FEM ground truth (TET10 Neo-Hookean, E 4.1 kPa, ν 0.49, calibrated crack pressure): {} nodes / {} tetrahedra at {} mm, lip gap {} mm at {} kPa, max |u| {} mm, min J {}. Total {:.1} s, peak memory {} MiB.</p>\n",
        esc(&r.config.incision),
        num(&g["mesh"]["nodes"]),
        num(&g["mesh"]["tets"]),
        r.config.edge_mm,
        num(&g["report"]["max_gap_mm"]),
        num(&g["report"]["pressure_kpa"]),
        num(&g["report"]["max_displacement_mm"]),
        num(&g["report"]["min_j"]),
        r.total_seconds,
        r.peak_memory_mib.map_or("?".into(), |m| format!("{m:.0}"))
    ));
    h.push_str("<h2>Steps</h2><table><tr><th>step</th><th>time (s)</th><th>result</th></tr>\n");
    for s in &r.steps {
        h.push_str(&format!(
            "<tr><td>{}</td><td>{:.1}</td><td style=\"text-align:left\">{}</td></tr>\n",
            esc(&s.name),
            s.seconds,
            esc(&s.detail)
        ));
    }
    h.push_str("</table>\n<h2>Stage errors against the ground truth, per stereo route</h2><table><tr><th>error</th>");
    for (name, _) in routes {
        h.push_str(&format!("<th><a href=\"{name}/report.html\">{name}</a></th>"));
    }
    h.push_str("</tr>\n");
    let rows = [
        ("past depth |error| mean (mm)", "depth_error_past_mean_abs_mm"),
        ("present depth |error| mean (mm)", "depth_error_present_mean_abs_mm"),
        ("rigid rotation error (°)", "rigid_rotation_error_deg"),
        ("rigid mean vertex error (mm)", "rigid_mean_vertex_error_mm"),
        ("TRE, rigid only, mean (mm)", "tre_rigid_only_mean_mm"),
        ("TRE after RODS-MPM, mean (mm)", "tre_mean_mm"),
        ("TRE near the incision (mm)", "tre_near_mm"),
        ("TRE far from it (mm)", "tre_far_mm"),
        ("tumour centroid error (mm; goal ≤ 3)", "tumour_centroid_error_mm"),
        ("tumour outline error (px at 1920×1080; goal ≤ 10)", "tumour_outline_error_px_1920"),
    ];
    for (label, key) in rows {
        h.push_str(&format!("<tr><td>{}</td>", esc(label)));
        for (_, g) in routes {
            h.push_str(&format!("<td>{}</td>", fig(&g.summary, key)));
        }
        h.push_str("</tr>\n");
    }
    for (label, key) in [
        ("regressions over the previous stage", "regressions"),
        ("tumour vertices outside the particles", "tumour_vertices_outside_particles"),
    ] {
        h.push_str(&format!("<tr><td>{}</td>", esc(label)));
        for (_, g) in routes {
            h.push_str(&format!("<td>{}</td>", num(&g.summary[key])));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("<tr><td>slowest stage</td>");
    for (_, g) in routes {
        let s = g.stages.iter().max_by(|a, b| a.seconds.total_cmp(&b.seconds));
        h.push_str(&format!(
            "<td>{}</td>",
            s.map_or(String::new(), |s| format!("{} ({:.1} s)", esc(&s.name), s.seconds))
        ));
    }
    h.push_str("</tr></table>\n");
    match (r.tre_difference_mm, &r.tre_difference_reason) {
        (Some(d), _) => h.push_str(&format!("<p>Final TRE, self-rectified minus calibrated: <b>{d:+.2} mm</b>.</p>\n")),
        (None, Some(why)) => {
            h.push_str(&format!("<p>Final TRE difference between the routes: n/a ({}).</p>\n", esc(why)))
        }
        (None, None) => {}
    }
    for (name, g) in routes {
        let w = warnings_html(&g.summary);
        if !w.is_empty() {
            h.push_str(&format!("<h3>{name}</h3>{w}"));
        }
        if g.summary["registration_improves_on_rigid_near_incision"].as_bool() == Some(false) {
            h.push_str(&format!(
                "<p><b>{name}: the deformable registration does not improve on the rigid alignment near the incision</b> ({} → {} mm).</p>\n",
                num(&g.summary["tre_rigid_only_near_mm"]),
                num(&g.summary["tre_near_mm"])
            ));
        }
    }
    h.push_str("<h2>Overlays</h2>");
    for (name, _) in routes {
        h.push_str(&format!(
            "<figure><img src=\"{name}/overlay.png\" alt=\"{name} overlay\"><figcaption>{name}: registered liver (blue) and tumour (yellow); green: true tumour outline. <a href=\"{name}/report.html\">every stage</a></figcaption></figure>"
        ));
    }
    h.push_str("<h2>Scenario</h2>");
    for (f, cap) in [
        ("scenario/past_left.png", "past left (before the incision)"),
        ("scenario/present_left.png", "present left (after the incision, FEM ground truth)"),
    ] {
        h.push_str(&format!("<figure><img src=\"{f}\" alt=\"{cap}\"><figcaption>{cap}</figcaption></figure>"));
    }
    h.push_str("<p><a href=\"summary.json\">summary.json</a>, <a href=\"ground-truth/ground_truth.json\">ground-truth/ground_truth.json</a></p></body></html>\n");
    write_atomic(&out.join("index.html"), h.as_bytes())?;
    Ok(())
}
