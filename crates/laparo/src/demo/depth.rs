//! Demo section "depth" (RoDEM, thesis §3.2): a built-in synthetic organ scene is perturbed
//! (smoke, blood, illumination, blur, lens dirt at 3 severities; deformation and incision
//! sequences), four synthetic "methods" predict depth/disparity, and the RoDEM evaluation
//! (alignment, metrics, CE/mCE, RR/mRR) is run through a manifest exactly as `laparo depth eval`
//! would. Intermediate files go to `<out>/depth/work/` and are removed at the end.
use super::DemoSection;
use anyhow::{Context, Result};
use laparo_core::colormap::{colorize, Colormap};
use laparo_core::plot::with_colorbar;
use laparo_core::table::Table;
use laparo_core::Image;
use laparo_depth::align::Alignment;
use laparo_depth::eval::{evaluate_manifest, EvalConfig};
use laparo_depth::manifest::{perturbation_title, FrameSpec, Manifest, MethodSpec, SequenceSpec};
use laparo_depth::perturb::{self as pt, Perturbation};
use laparo_depth::report::{self, AlignmentSummary, Summary};
use laparo_depth::synthetic::{self as syn, Gesture, SyntheticMethod};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const W: usize = 320;
const H: usize = 240;
const SCENES: [(&str, u64); 2] = [("organ-a", 11), ("organ-b", 12)];
const SEQ_FRAMES: usize = 5;
const GESTURE_FRAME: usize = 2;
const BASELINE: &str = "SfM-like";

/// One frame of the demo benchmark, in memory.
struct DemoFrame {
    spec: FrameSpec,
    /// Image the degradation of the synthetic methods is measured against.
    reference: Image<u8>,
    rgb: Image<u8>,
    gt: laparo_core::DepthMap,
}

fn frame(scene: &str, pert: &str, level: &str, name: &str, severity: Option<u32>, seq: Option<&str>) -> FrameSpec {
    let id = format!("{scene}/{pert}/{level}/{name}");
    FrameSpec {
        rgb: PathBuf::from(format!("{id}.png")),
        gt: PathBuf::from(format!("{id}.gt.npy")),
        id,
        scene: scene.into(),
        perturbation: pert.into(),
        severity,
        sequence: seq.map(String::from),
        name: Some(name.into()),
        mask: None,
        gt_unit: None,
    }
}

/// Frames, sequences, and the clean RGB image and depth of the first scene.
type BenchmarkFrames = (Vec<DemoFrame>, Vec<SequenceSpec>, Image<u8>, laparo_core::DepthMap);

/// Build all frames of the synthetic benchmark.
fn build_frames() -> Result<BenchmarkFrames> {
    let mut frames = Vec::new();
    let mut seqs = Vec::new();
    let mut first = None;
    for (scene, seed) in SCENES {
        let sc = syn::organ_scene(W, H, seed)?;
        frames.push(DemoFrame {
            spec: frame(scene, "clean", "s0", "000", Some(0), None),
            reference: sc.rgb.clone(),
            rgb: sc.rgb.clone(),
            gt: sc.depth.clone(),
        });
        let jobs: Vec<(Perturbation, u8)> =
            Perturbation::ALL.iter().flat_map(|&k| (1..=3u8).map(move |s| (k, s))).collect();
        let imgs: Vec<Image<u8>> = jobs
            .par_iter()
            .map(|&(k, s)| pt::apply(&sc.rgb, k, s, pt::item_seed(seed, scene, k)))
            .collect::<laparo_core::Result<_>>()?;
        for ((k, s), img) in jobs.into_iter().zip(imgs) {
            frames.push(DemoFrame {
                spec: frame(scene, k.name(), &format!("s{s}"), "000", Some(s as u32), None),
                reference: sc.rgb.clone(),
                rgb: img,
                gt: sc.depth.clone(),
            });
        }
        for g in [Gesture::Deformation, Gesture::Incision] {
            let sq = syn::organ_sequence(W, H, SEQ_FRAMES, GESTURE_FRAME, g, seed)?;
            let seq_name = format!("seq-{}", g.name());
            seqs.push(SequenceSpec {
                scene: scene.into(),
                perturbation: g.name().into(),
                name: seq_name.clone(),
                gesture_start: format!("{GESTURE_FRAME:03}"),
            });
            for (i, f) in sq.frames.into_iter().enumerate() {
                frames.push(DemoFrame {
                    spec: frame(scene, g.name(), &seq_name, &format!("{i:03}"), None, Some(&seq_name)),
                    reference: sc.rgb.clone(),
                    rgb: f.rgb,
                    gt: f.depth,
                });
            }
        }
        if first.is_none() {
            first = Some((sc.rgb, sc.depth));
        }
    }
    let (rgb, depth) = first.expect("at least one scene");
    Ok((frames, seqs, rgb, depth))
}

fn pred_path(method: &str, id: &str) -> PathBuf {
    PathBuf::from(format!("pred/{method}/{id}.npy"))
}

fn seed_of(method: usize, frame: usize) -> u64 {
    (method as u64) << 32 | frame as u64
}

/// Write RGB, GT and predictions of every frame, and the manifest.
fn write_benchmark(
    work: &Path,
    frames: &[DemoFrame],
    seqs: &[SequenceSpec],
    methods: &[SyntheticMethod],
) -> Result<PathBuf> {
    frames.par_iter().enumerate().try_for_each(|(fi, f)| -> Result<()> {
        laparo_core::io::write_png(work.join(&f.spec.rgb), &f.rgb)?;
        laparo_core::io::write_npy_f64(work.join(&f.spec.gt), &f.gt.to_image())?;
        for (mi, m) in methods.iter().enumerate() {
            let p = m.predict(&f.gt, &f.reference, &f.rgb, seed_of(mi, fi))?;
            laparo_core::io::write_npy_f32(work.join(pred_path(&m.name, &f.spec.id)), &p.map(|v| v as f32))?;
        }
        Ok(())
    })?;
    let manifest = Manifest {
        version: 1,
        gt_unit: laparo_core::DepthUnit::M,
        depth_min_m: None,
        depth_max_m: None,
        baseline: Some(BASELINE.into()),
        error_map_frames: Vec::new(),
        methods: methods
            .iter()
            .map(|m| MethodSpec {
                name: m.name.clone(),
                kind: m.kind,
                predictions: format!("pred/{}/{{id}}.npy", m.name),
            })
            .collect(),
        sequences: seqs.to_vec(),
        frames: frames.iter().map(|f| f.spec.clone()).collect(),
        base_dir: work.to_path_buf(),
        source: work.join("manifest.toml"),
    };
    let mp = work.join("manifest.toml");
    manifest.write(&mp)?;
    Ok(mp)
}

fn fmt(v: Option<f64>) -> String {
    v.filter(|x| x.is_finite()).map(|x| format!("{x:.3}")).unwrap_or_else(|| "-".into())
}

/// Per-method accuracy (Abs Rel, δ) and robustness (mCE, mRR) of one alignment, as data.
fn alignment_table(al: &AlignmentSummary, methods: &[SyntheticMethod]) -> Table {
    let kind = |name: &str| methods.iter().find(|m| m.name == name).map(|m| m.kind.to_string()).unwrap_or_default();
    let mut t = Table::new([
        "method",
        "output",
        "Abs Rel ↓",
        "δ_0.25 ↑",
        "δ_1 ↑",
        "clean Abs Rel ↓",
        "mCE (Abs Rel) ↓",
        "mRR (Abs Rel) ↑",
        "clean 1−δ_0.25 ↓",
        "mCE (1−δ_0.25) ↓",
        "mRR (1−δ_0.25) ↑",
    ]);
    for (mm, r) in al.means.iter().zip(&al.robustness) {
        t.push_row([
            mm.method.clone(),
            kind(&mm.method),
            format!("{:.3}", mm.mean.abs_rel),
            format!("{:.3}", mm.mean.delta_0_25),
            format!("{:.3}", mm.mean.delta_1),
            fmt(r.clean_error.abs_rel),
            fmt(r.mce.abs_rel),
            fmt(r.mrr.abs_rel),
            fmt(r.clean_error.one_minus_delta),
            fmt(r.mce.one_minus_delta),
            fmt(r.mrr.one_minus_delta),
        ]);
    }
    t
}

/// HTML tables: one [`alignment_table`] per alignment, with its heading.
fn tables_html(summary: &Summary, methods: &[SyntheticMethod]) -> String {
    let mut s = String::new();
    for al in &summary.alignments {
        let _ = write!(
            s,
            "<h4>{} — accuracy (mean over all frames) and robustness (baseline {})</h4>\n{}",
            al.alignment.title().replace('&', "&amp;"),
            summary.baseline,
            alignment_table(al, methods).to_html()
        );
    }
    s
}

/// The demo section.
pub fn section(out: &Path) -> Result<DemoSection> {
    let dir = out.join("depth");
    let work = dir.join("work");
    if work.exists() {
        std::fs::remove_dir_all(&work).with_context(|| format!("removing {}", work.display()))?;
    }
    let methods = syn::default_methods();
    let (frames, seqs, clean_rgb, clean_depth) = build_frames()?;
    let mp = write_benchmark(&work, &frames, &seqs, &methods)?;
    let manifest = Manifest::read(&mp)?;
    let eval = evaluate_manifest(&manifest, &EvalConfig::default(), &|_| {})?;
    let summary = report::summarize(&eval, BASELINE)?;
    report::write_reports(&dir, &eval, &summary)?;

    // Figures.
    laparo_core::io::write_png(dir.join("clean.png"), &clean_rgb)?;
    let (zlo, zhi) = (syn::SCENE_DEPTH_RANGE_M.0 * 1e3, syn::SCENE_DEPTH_RANGE_M.1 * 1e3);
    let dimg = clean_depth.to_unit(laparo_core::DepthUnit::Mm).to_image();
    laparo_core::io::write_png(
        dir.join("gt_depth.png"),
        &with_colorbar(&colorize(&dimg, zlo, zhi, Colormap::Turbo), zlo, zhi, Colormap::Turbo, "depth (mm)"),
    )?;
    // GT preparation (§3.2.6): the scene's depth seen as depth-sensor data 1.5 cm beside a
    // laparoscope with a narrower field of view, reprojected with the z-buffered triangle raster.
    let sensor_k = syn::default_intrinsics(W, H)?;
    let lap_k = laparo_core::Intrinsics::new(sensor_k.fx * 1.3, sensor_k.fy * 1.3, sensor_k.cx, sensor_k.cy, W, H)?;
    let t_ds_l = laparo_core::se3::se3_from_rt(
        &laparo_core::se3::rotation_zyx(0.0, 0.08, 0.0),
        &laparo_core::Se3::translation(-0.015, 0.0, 0.0).translation.vector,
    );
    let (lap_depth, rstats) = laparo_depth::reproject::reproject_depth(
        &clean_depth,
        &sensor_k,
        &t_ds_l,
        &laparo_depth::reproject::TargetCamera { intrinsics: lap_k, distortion: None },
        None,
        &Default::default(),
    )?;
    let limg = lap_depth.to_unit(laparo_core::DepthUnit::Mm).to_image();
    laparo_core::io::write_png(
        dir.join("reprojected_depth.png"),
        &with_colorbar(&colorize(&limg, zlo, zhi, Colormap::Turbo), zlo, zhi, Colormap::Turbo, "depth (mm)"),
    )?;
    let scene0 = SCENES[0].0;
    let mut rows: Vec<(String, Vec<Image<u8>>)> = Vec::new();
    for k in Perturbation::ALL {
        let mut r = vec![clean_rgb.clone()];
        r.extend(
            frames.iter().filter(|f| f.spec.scene == scene0 && f.spec.perturbation == k.name()).map(|f| f.rgb.clone()),
        );
        rows.push((perturbation_title(k.name()), r));
    }
    for g in [Gesture::Deformation, Gesture::Incision] {
        let r: Vec<Image<u8>> = frames
            .iter()
            .filter(|f| f.spec.scene == scene0 && f.spec.perturbation == g.name())
            .filter(|f| f.spec.name.as_deref().is_some_and(|n| n == "000" || n >= "002"))
            .map(|f| f.rgb.clone())
            .collect();
        rows.push((perturbation_title(g.name()), r));
    }
    let cols: Vec<String> = ["clean", "severity 1", "severity 2", "severity 3"].map(String::from).to_vec();
    laparo_core::io::write_png(dir.join("perturbations.png"), &pt::contact_sheet(&rows, &cols, 200)?)?;

    // Radar charts (Fig. 3.4) under s&t alignment, and error maps (Fig. C.1/C.2) of every method
    // on defocus severity 3, drawn by the evaluation's report module.
    let st = summary.alignments.iter().find(|a| a.alignment == Alignment::ScaleShift).context("s&t summary")?;
    let mut radar = Vec::new();
    for r in &st.robustness {
        let files = report::write_radar(&dir.join("radar"), r, Alignment::ScaleShift)?;
        radar.extend(files.into_iter().filter(|p| p.extension().is_some_and(|e| e == "png")));
    }
    let target = frames
        .iter()
        .find(|f| f.spec.scene == scene0 && f.spec.perturbation == "defocus" && f.spec.severity == Some(3))
        .context("defocus s3 frame")?;
    let err_figs =
        report::write_error_maps(&dir.join("error_maps"), &manifest, &eval, &target.spec.id, Alignment::ScaleShift)?;

    std::fs::remove_dir_all(&work).with_context(|| format!("removing {}", work.display()))?;

    // HTML.
    let mut html = String::new();
    let _ = write!(
        html,
        "<p>RoDEM (thesis §3.2) on built-in data: {n_sc} procedural organ scenes ({W}×{H}, metric depth 5–20 cm), \
         the seeded perturbations of <code>laparo depth perturb</code> (7 kinds × 3 severities) plus deformation and \
         incision sequences ({SEQ_FRAMES} frames, gesture at frame {GESTURE_FRAME}: earlier frames are the clean \
         reference), {nf} frames in total. Four synthetic methods with known output kind, scale, shift, noise, \
         flattening and sensitivity to image degradation stand in for networks; they are evaluated from files \
         through a manifest, as <code>laparo depth eval</code> does. Baseline of mCE: {BASELINE}.</p>\n\
         <figure><img src=\"depth/clean.png\" width=\"320\"><figcaption>clean image</figcaption></figure>\
         <figure><img src=\"depth/gt_depth.png\" width=\"400\"><figcaption>ground-truth depth</figcaption></figure>\n\
         <figure><img src=\"depth/perturbations.png\"><figcaption>perturbations at severities 1–3 \
         (gesture rows: frames 0, 2, 3, 4)</figcaption></figure>\n",
        n_sc = SCENES.len(),
        nf = frames.len()
    );
    let _ = writeln!(
        html,
        "<figure><img src=\"depth/reprojected_depth.png\" width=\"400\"><figcaption>GT preparation (§3.2.6): the depth \
         above as depth-sensor data, reprojected into a laparoscope 1.5 cm to the side, rotated 4.6° and with a 1.3× focal \
         length: {valid} valid px ({pct:.1}%), {drop} sensor triangles dropped at depth discontinuities; dark grey = \
         disoccluded (no sensor measurement), never filled</figcaption></figure>",
        valid = rstats.valid,
        pct = 100.0 * rstats.valid as f64 / (W * H) as f64,
        drop = rstats.triangles_dropped_jump
    );
    html.push_str(&tables_html(&summary, &methods));
    html.push_str("<h4>Robustness per perturbation, s&amp;t-alignment (cf. Fig. 3.4): CE (red) and RR (blue)</h4>\n");
    for p in &radar {
        let rel = p.strip_prefix(out).unwrap_or(p).display().to_string();
        let _ = writeln!(html, "<figure><img src=\"{rel}\" width=\"560\"></figure>");
    }
    html.push_str(
        "<h4>Error maps z*−ẑ (mm) after s&amp;t alignment, defocus severity 3 (cf. Fig. C.2): \
         blue = prediction deeper than GT, red = shallower</h4>\n",
    );
    for p in &err_figs {
        let rel = p.strip_prefix(out).unwrap_or(p).display().to_string();
        let cap = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let _ = writeln!(html, "<figure><img src=\"{rel}\" width=\"300\"><figcaption>{cap}</figcaption></figure>");
    }
    let _ = writeln!(
        html,
        "<p>Full tables (Tables 3.3–3.5 and C.3–C.16 layout): <a href=\"depth/tables.md\">tables.md</a>, \
         <a href=\"depth/results.json\">results.json</a>, <a href=\"depth/per_image.csv\">per_image.csv</a>.</p>"
    );

    let summ = serde_json::json!({
        "frames": frames.len(),
        "reprojection": rstats,
        "scenes": SCENES.len(),
        "methods": methods,
        "baseline": BASELINE,
        "alignments": summary.alignments.iter().map(|a| serde_json::json!({
            "alignment": a.alignment.key(),
            "methods": a.means.iter().zip(&a.robustness).map(|(m, r)| serde_json::json!({
                "method": m.method,
                "abs_rel": m.mean.abs_rel,
                "delta_0.25": m.mean.delta_0_25,
                "clean_abs_rel": r.clean_error.abs_rel,
                "mce_abs_rel": r.mce.abs_rel,
                "mrr_abs_rel": r.mrr.abs_rel,
                "mce_one_minus_delta_0.25": r.mce.one_minus_delta,
                "mrr_one_minus_delta_0.25": r.mrr.one_minus_delta,
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    });
    Ok(DemoSection { title: "Depth robustness (RoDEM)".into(), html, summary: summ })
}
