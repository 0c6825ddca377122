//! `laparo cpc pair | eval | sequence`: does CPC help keypoint matching? (thesis §4.5, Table 4.1,
//! Figs. 4.8, 4.9, 4.12).
//!
//! * `pair`: render a two-view scene with exact ground truth (bumpy organ-like surface, real
//!   texture): image1/2.png, depth1/2.npy (mm, NaN off the surface), mask1/2.png,
//!   intrinsics.json, poses.json;
//! * `eval`: SIFT and ORB without and with CPC on such a pair (or any pair with depth, masks,
//!   intrinsics and poses): Table 4.1-shaped table (md, csv, json) and match pictures; with
//!   `--lambda-sweep`, #correct against λ (Fig. 4.12);
//! * `sequence`: a rendered orbit, every frame against the keyframe (Fig. 4.9).
use anyhow::{bail, Context, Result};
use clap::Args;
use laparo_core::atomic::write_atomic;
use laparo_core::camera::Intrinsics;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::{Image, Mask};
use laparo_core::io;
use laparo_core::se3::Se3;
use laparo_cpc::eval::{self, EvalSettings, Method, View};
use laparo_cpc::lambda::default_lambda_grid;
use laparo_cpc::pipeline::LambdaChoice;
use laparo_cpc::scene::{self, PairKind, Scene, Texture};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct PairArgs {
    /// easy (≈ 7° viewpoint change) or hard (≈ 55°, view 2 oblique).
    #[arg(long, default_value = "hard")]
    pub kind: String,
    /// Texture: a photograph name in ../shared/data/textures (falls back to procedural), or procedural.
    #[arg(long, default_value = "retina.jpg")]
    pub texture: String,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// Settings shared by `eval` and `sequence`.
#[derive(Args, Clone)]
pub struct EvalOpts {
    /// Keep keypoints in the ROI eroded by this disk radius (px; thesis code: 25).
    #[arg(long, default_value_t = 25.0)]
    pub roi_erosion: f64,
    /// vl_ubcmatch threshold for SIFT (squared distances; 2.8 ≡ Lowe ratio 0.598; thesis code: 2.8).
    #[arg(long, default_value_t = 2.8)]
    pub ubc: f32,
    /// Correct iff the two-way averaged transfer error is below this (px).
    #[arg(long, default_value_t = 3.0)]
    pub eps: f64,
    /// Fixed λ for CPC (default: automatic, §4.5.4).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// CPC grid step (px).
    #[arg(long, default_value_t = 4)]
    pub grid_step: usize,
    /// CPC magnification guard (multiple of the median triangle magnification); 0 disables.
    #[arg(long, default_value_t = laparo_cpc::pipeline::DEFAULT_MAX_REL_MAGNIFICATION)]
    pub max_magnification: f64,
    /// Scale of the warped image: resolution (no minification at the median triangle), area
    /// (original total ROI area) or raw (the solve of eq. 4.11 as it is).
    #[arg(long, default_value = "resolution")]
    pub scale: String,
}

impl EvalOpts {
    fn settings(&self) -> Result<EvalSettings> {
        use super::check::number;
        let mut s = EvalSettings::default();
        number("--roi-erosion", self.roi_erosion, 0.0..=1000.0)?;
        number("--eps", self.eps, (std::ops::Bound::Excluded(0.0), std::ops::Bound::Included(1000.0)))?;
        number("--ubc", self.ubc as f64, 1.0..=1000.0)?;
        number("--grid-step", self.grid_step as f64, 1.0..=256.0)?;
        number("--max-magnification", self.max_magnification, 0.0..)?;
        s.methods = vec![Method::sift_ubcmatch(self.ubc), Method::orb_nn()];
        s.roi_erosion_px = self.roi_erosion;
        s.gt.eps_px = self.eps;
        if let Some(l) = self.lambda {
            laparo_cpc::solve::validate_lambda(l)?;
            s.cpc.lambda = LambdaChoice::Fixed(l);
        }
        s.cpc.mesh.grid_step_px = self.grid_step;
        s.cpc.max_rel_magnification = (self.max_magnification > 0.0).then_some(self.max_magnification);
        s.cpc.scale = self.scale.parse()?;
        Ok(s)
    }
}

#[derive(Args)]
pub struct EvalArgs {
    #[arg(long)]
    pub image1: PathBuf,
    /// Depth of view 1 (npy, npz, pfm, tif, 16-bit png), z along the optical axis.
    #[arg(long)]
    pub depth1: PathBuf,
    /// ROI mask of view 1 (the surface); the depth must be finite inside it.
    #[arg(long)]
    pub mask1: PathBuf,
    #[arg(long)]
    pub image2: PathBuf,
    #[arg(long)]
    pub depth2: PathBuf,
    #[arg(long)]
    pub mask2: PathBuf,
    /// Unit of both depth files (m or mm).
    #[arg(long, default_value = "mm")]
    pub depth_unit: DepthUnit,
    /// Intrinsics of both views (JSON fx..cy or K, YAML, COLMAP ...).
    #[arg(long)]
    pub intrinsics: PathBuf,
    /// Intrinsics of view 2 when they differ.
    #[arg(long)]
    pub intrinsics2: Option<PathBuf>,
    /// Poses JSON: {"view1": {"cam_from_world": {"R": 3x3, "t_mm": [x, y, z]}}, "view2": {...}}.
    #[arg(long)]
    pub poses: PathBuf,
    #[command(flatten)]
    pub opts: EvalOpts,
    /// Also sweep λ (same λ on both views) and plot #correct against λ (Fig. 4.12).
    #[arg(long)]
    pub lambda_sweep: bool,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args)]
pub struct SequenceArgs {
    /// Frames of the rendered orbit (frame 0 = keyframe).
    #[arg(long, default_value_t = 10)]
    pub frames: usize,
    /// Tilt (deg) of the last frame; frame i is at tilt0 + i·(max − tilt0)/(frames − 1).
    #[arg(long, default_value_t = 66.0)]
    pub max_tilt: f64,
    /// Tilt (deg) of the keyframe.
    #[arg(long, default_value_t = 10.0)]
    pub tilt0: f64,
    /// Texture (as for `pair`).
    #[arg(long, default_value = "retina.jpg")]
    pub texture: String,
    #[command(flatten)]
    pub opts: EvalOpts,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// The texture of `--texture`.
pub fn texture(name: &str) -> Texture {
    match name {
        "procedural" => Texture::Procedural { seed: 1 },
        "checker" => Texture::Checker { square_mm: 5.0 },
        n => match crate::demo::shared_data(&format!("textures/{n}")) {
            Some(p) => scene::photo_or_procedural(&p, 1),
            None => {
                eprintln!("note: texture {n} not found in ../shared/data/textures; using the procedural texture");
                Texture::Procedural { seed: 1 }
            }
        },
    }
}

/// A world → camera pose in laparo's one transform form (`laparo_core::se3::se3_json`: "R" rows, "t_mm",
/// "scale", "T"), under the key `cam_from_world`.
fn pose_json(p: &Se3) -> Value {
    laparo_core::se3::se3_json(p)
}

fn write_view(out: &Path, i: usize, sc: &Scene) -> Result<()> {
    io::write_png(out.join(format!("image{i}.png")), &sc.image)?;
    io::write_npy_f64(out.join(format!("depth{i}.npy")), &sc.depth.to_image())?;
    io::write_png(out.join(format!("mask{i}.png")), &sc.roi.map(|b| if b { 255u8 } else { 0 }))?;
    Ok(())
}

pub fn pair(a: PairArgs) -> Result<()> {
    let kind: PairKind = a.kind.parse()?;
    let p = scene::render_pair(&scene::pair_spec(kind, texture(&a.texture)))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    write_view(&a.out, 1, &p.view1)?;
    write_view(&a.out, 2, &p.view2)?;
    write_atomic(&a.out.join("intrinsics.json"), serde_json::to_string_pretty(&p.view1.intrinsics)?.as_bytes())?;
    let [(t1, y1), (t2, y2)] = kind.tilts_yaws_deg();
    let poses = json!({
        "world": "surface patch frame (mm); X_cam = R X_world + t",
        "kind": a.kind, "texture": a.texture, "viewpoint_change_deg": p.viewpoint_change_deg,
        "view1": {"cam_from_world": pose_json(&p.view1.pose), "tilt_deg": t1, "yaw_deg": y1},
        "view2": {"cam_from_world": pose_json(&p.view2.pose), "tilt_deg": t2, "yaw_deg": y2},
    });
    write_atomic(&a.out.join("poses.json"), serde_json::to_string_pretty(&poses)?.as_bytes())?;
    println!("{} pair (viewpoint change {:.1}°) written to {}", a.kind, p.viewpoint_change_deg, a.out.display());
    Ok(())
}

/// Read `view` ("view1"/"view2") of a poses JSON: `cam_from_world` {"R", "t_mm"}; errors name the file and view.
pub fn read_pose(path: &Path, v: &Value, view: &str) -> Result<Se3> {
    let p = v
        .get(view)
        .and_then(|x| x.get("cam_from_world"))
        .with_context(|| format!("poses {}: missing {view} pose ({view}.cam_from_world)", path.display()))?;
    let what = |field: &str| format!("poses {}: {view}.cam_from_world.{field}", path.display());
    // Every entry a number (no string, null or nested array skipped), rows of exactly 3.
    let numbers = |v: Option<&Value>, field: &str| -> Result<Vec<f64>> {
        let a = v.and_then(Value::as_array).with_context(|| format!("{}: missing or not an array", what(field)))?;
        a.iter()
            .enumerate()
            .map(|(i, x)| x.as_f64().with_context(|| format!("{}[{i}]: {x} is not a number", what(field))))
            .collect()
    };
    let rows = p.get("R").and_then(Value::as_array).with_context(|| format!("{}: missing 3x3 array", what("R")))?;
    if rows.len() != 3 {
        bail!("{}: expected 3 rows, got {}", what("R"), rows.len());
    }
    let mut r = Vec::with_capacity(9);
    for (i, row) in rows.iter().enumerate() {
        let row = numbers(Some(row), &format!("R[{i}]"))?;
        if row.len() != 3 {
            bail!("{}: expected 3 numbers, got {} (ragged rows)", what(&format!("R[{i}]")), row.len());
        }
        r.extend(row);
    }
    let t = numbers(p.get("t_mm"), "t_mm")?;
    if t.len() != 3 {
        bail!("{}: expected 3 numbers, got {}", what("t_mm"), t.len());
    }
    // JSON numbers are finite; 1e308 is not a distance: the camera must see the scene (z > 0) and
    // lie within 10 m of the world origin.
    for (i, &x) in t.iter().enumerate() {
        super::check::number(&what(&format!("t_mm[{i}]")), x, -MAX_POSE_MM..=MAX_POSE_MM)?;
    }
    let m = Matrix3::from_row_slice(&r);
    if (m.transpose() * m - Matrix3::identity()).abs().max() > 1e-6 || m.determinant() < 0.0 {
        bail!("poses {}: {view}.cam_from_world.R is not a rotation", path.display());
    }
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Ok(Isometry3::from_parts(Translation3::from(Vector3::new(t[0], t[1], t[2])), rot))
}

/// Largest |t_mm| component of a pose (10 m): a scene further away is a unit error.
pub const MAX_POSE_MM: f64 = 1e4;

/// A pose must see the scene: the other view's surface points (its ROI back-projected with its
/// depth and intrinsics, then taken to the world by its pose) must lie in front of this camera at a
/// depth comparable to their own, not behind it or around it (a sign error in t, R and t of
/// camera-to-world instead of world-to-camera, t = 0 in a world whose origin is on the surface).
fn check_pose_sees(path: &Path, view: &str, pose: &Se3, other: &LoadedView) -> Result<()> {
    let (w, k) = (other.depth.width, &other.k);
    let step = (other.roi.n_pixels() / 4000).max(1);
    let (mut own, mut here) = (Vec::new(), Vec::new());
    for i in (0..other.roi.n_pixels()).step_by(step) {
        if !other.roi.data[i * other.roi.channels] {
            continue;
        }
        let z = other.depth.data[i];
        let (u, v) = ((i % w) as f64, (i / w) as f64);
        let xc = nalgebra::Point3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
        own.push(z);
        here.push(pose.transform_point(&other.pose.inverse_transform_point(&xc)).z);
    }
    if own.is_empty() {
        return Ok(());
    }
    let (z_own, z_here) = (laparo_core::stats::median(&mut own), laparo_core::stats::median(&mut here));
    if z_here.is_nan() || z_here <= 0.05 * z_own {
        bail!(
            "poses {}: {view}.cam_from_world puts the other view's surface at a median depth of {z_here:.3} mm (it is \
             {z_own:.3} mm from its own camera): the scene is behind or around this camera; check the sign of t_mm \
             and that R, t map world to camera",
            path.display()
        );
    }
    Ok(())
}

struct LoadedView {
    image: Image<u8>,
    depth: DepthMap,
    k: Intrinsics,
    roi: Mask,
    pose: Se3,
}

impl LoadedView {
    fn view(&self) -> View<'_> {
        View { image: &self.image, depth: &self.depth, intrinsics: &self.k, roi: &self.roi, cam_from_world: self.pose }
    }
}

fn load_view(image: &Path, depth: &Path, mask: &Path, unit: DepthUnit, k: &Path, pose: Se3) -> Result<LoadedView> {
    let img = io::read_image(image).with_context(|| format!("reading image {}", image.display()))?;
    let d = io::read_depth(depth, unit).with_context(|| format!("reading depth {}", depth.display()))?;
    let roi = io::read_mask(mask).with_context(|| format!("reading mask {}", mask.display()))?;
    if (d.width, d.height) != (img.width, img.height) || (roi.width, roi.height) != (img.width, img.height) {
        bail!(
            "image {} is {}x{}, depth {} is {}x{}, mask {} is {}x{}: they must agree",
            image.display(),
            img.width,
            img.height,
            depth.display(),
            d.width,
            d.height,
            mask.display(),
            roi.width,
            roi.height
        );
    }
    let nan = (0..roi.n_pixels())
        .filter(|&i| roi.data[i * roi.channels] && !(d.data[i].is_finite() && d.data[i] > 0.0))
        .count();
    if nan > 0 {
        bail!(
            "depth {}: {nan} pixels inside mask {} are NaN, infinite or <= 0 (fix the depth or the mask)",
            depth.display(),
            mask.display()
        );
    }
    let cam = io::read_camera(k).with_context(|| format!("reading intrinsics {}", k.display()))?;
    let k = cam.intrinsics_undistorted(Some((img.width, img.height)), "cpc eval")?;
    Ok(LoadedView { image: img, depth: d, k, roi, pose })
}

fn method_slug(name: &str) -> String {
    name.to_ascii_lowercase().replace('+', "_")
}

/// Write table.{md,csv,json} and the match pictures of one evaluated pair.
fn write_pair_outputs(
    out: &Path,
    v1: &View,
    v2: &View,
    e: &eval::PairEval,
    settings: &EvalSettings,
    extra: Value,
) -> Result<()> {
    let rows = e.rows();
    let table = eval::pair_table(&rows);
    write_atomic(&out.join("table.md"), table.to_markdown().as_bytes())?;
    write_atomic(&out.join("table.csv"), eval::rows_csv(&rows).as_bytes())?;
    for run in &e.runs {
        let name = format!("matches_{}{}.png", if run.row.cpc { "cpc_" } else { "" }, method_slug(&run.row.method));
        io::write_png(out.join(name), &eval::match_picture(v1.image, v2.image, run))?;
    }
    io::write_png(out.join("warped1.png"), &e.cpc[0].warped)?;
    io::write_png(out.join("warped2.png"), &e.cpc[1].warped)?;
    let gains: Value = settings
        .methods
        .iter()
        .map(|m| (m.name.clone(), json!(e.gain(&m.name))))
        .collect::<serde_json::Map<_, _>>()
        .into();
    let j = json!({
        "rows": rows, "gain_correct": gains, "cpc": e.cpc_stats,
        "settings": {"methods": settings.methods, "roi_erosion_px": settings.roi_erosion_px,
            "warped_mask_erosion_px": settings.warped_mask_erosion_px, "eps_px": settings.gt.eps_px,
            "occlusion_tol_mm": settings.gt.occlusion_tol_mm, "cpc": settings.cpc},
        "match_colours": "green correct, red wrong, yellow unverifiable",
        "inputs": extra,
    });
    write_atomic(&out.join("table.json"), serde_json::to_string_pretty(&j)?.as_bytes())?;
    for s in &e.cpc_stats {
        for w in &s.warnings {
            eprintln!("warning: {w}");
        }
    }
    Ok(())
}

pub fn eval_cmd(a: EvalArgs) -> Result<()> {
    let settings = a.opts.settings()?;
    let k2 = a.intrinsics2.as_ref().unwrap_or(&a.intrinsics);
    let inputs: Vec<&Path> =
        [&a.image1, &a.depth1, &a.mask1, &a.image2, &a.depth2, &a.mask2, &a.intrinsics, k2, &a.poses]
            .into_iter()
            .map(PathBuf::as_path)
            .collect();
    let mut outputs: Vec<String> =
        ["table.md", "table.csv", "table.json", "warped1.png", "warped2.png"].into_iter().map(String::from).collect();
    for m in &settings.methods {
        for cpc in ["", "cpc_"] {
            outputs.push(format!("matches_{cpc}{}.png", method_slug(&m.name)));
        }
    }
    if a.lambda_sweep {
        outputs.extend(["lambda_matching.csv", "lambda_matching.json", "lambda_matching.png"].map(String::from));
    }
    let names: Vec<&str> = outputs.iter().map(String::as_str).collect();
    laparo_core::atomic::refuse_overwrite_in(&a.out, &names, &inputs).context("--out")?;
    let txt = std::fs::read_to_string(&a.poses).with_context(|| format!("reading poses {}", a.poses.display()))?;
    let pj: Value = serde_json::from_str(&txt).with_context(|| format!("parsing poses {}", a.poses.display()))?;
    let (p1, p2) = (read_pose(&a.poses, &pj, "view1")?, read_pose(&a.poses, &pj, "view2")?);
    let l1 = load_view(&a.image1, &a.depth1, &a.mask1, a.depth_unit, &a.intrinsics, p1)?;
    let l2 = load_view(&a.image2, &a.depth2, &a.mask2, a.depth_unit, k2, p2)?;
    check_pose_sees(&a.poses, "view2", &p2, &l1)?;
    check_pose_sees(&a.poses, "view1", &p1, &l2)?;
    let (v1, v2) = (l1.view(), l2.view());
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let e = eval::evaluate_pair(&v1, &v2, &settings)?;
    let inputs = json!({"image1": a.image1, "depth1": a.depth1, "mask1": a.mask1, "image2": a.image2,
        "depth2": a.depth2, "mask2": a.mask2, "intrinsics": a.intrinsics, "poses": a.poses});
    write_pair_outputs(&a.out, &v1, &v2, &e, &settings, inputs)?;
    println!("{}", eval::pair_table(&e.rows()).to_markdown());
    for m in &settings.methods {
        if let Some(g) = e.gain(&m.name) {
            println!("CPC changes #correct of {} by {:+.1} %", m.name, 100.0 * g);
        }
    }
    if a.lambda_sweep {
        let pb = indicatif::ProgressBar::new_spinner();
        pb.set_message("λ sweep (Fig. 4.12)");
        pb.enable_steady_tick(std::time::Duration::from_millis(200));
        let grid: Vec<f64> =
            default_lambda_grid().into_iter().filter(|&l| (l * 20.0).fract() == 0.0 || l >= 0.96).collect();
        let s = eval::lambda_match_sweep(&v1, &v2, &settings, &grid)?;
        pb.finish_and_clear();
        write_atomic(&a.out.join("lambda_matching.csv"), s.to_csv().as_bytes())?;
        write_atomic(&a.out.join("lambda_matching.json"), serde_json::to_string_pretty(&s)?.as_bytes())?;
        s.plot_png(&a.out.join("lambda_matching.png"))?;
        for (i, m) in s.methods.iter().enumerate() {
            let mx = s.max_correct(i);
            println!(
                "λ sweep {m}: #correct at the automatic ℓ ({:.3}, {:.3}) = {}, sweep maximum {} ({:.0} %), without CPC {}",
                s.ell[0],
                s.ell[1],
                s.n_correct_auto[i],
                mx,
                100.0 * s.n_correct_auto[i] as f64 / mx.max(1) as f64,
                s.n_correct_plain[i]
            );
        }
    }
    println!("written to {}", a.out.display());
    Ok(())
}

/// Largest tilt (deg) of a rendered orbit frame: beyond it the patch is seen at grazing angles.
pub const MAX_TILT_DEG: f64 = 70.0;
/// Most frames of one orbit (each is rendered, kept in memory and matched against the keyframe).
pub const MAX_FRAMES: usize = 200;

pub fn sequence_cmd(a: SequenceArgs) -> Result<()> {
    use super::check::number;
    number("--frames", a.frames as f64, 2.0..=MAX_FRAMES as f64)?;
    number("--tilt0", a.tilt0, 0.0..=MAX_TILT_DEG)?;
    number("--max-tilt", a.max_tilt, 0.0..=MAX_TILT_DEG)?;
    if a.max_tilt <= a.tilt0 {
        bail!("--max-tilt {} must exceed --tilt0 {}: the orbit tilts away from the keyframe", a.max_tilt, a.tilt0);
    }
    let settings = a.opts.settings()?;
    let tex = texture(&a.texture);
    let mut base = scene::bumpy_bowl_spec();
    base.texture = tex;
    let pb = indicatif::ProgressBar::new(a.frames as u64);
    pb.set_message("rendering the orbit");
    let scenes: Vec<Scene> = (0..a.frames)
        .map(|i| {
            let t = a.tilt0 + (a.max_tilt - a.tilt0) * i as f64 / (a.frames - 1) as f64;
            let spec = scene::SceneSpec { pose: scene::tilted_pose_xy(t, 0.3 * (t - a.tilt0), 100.0), ..base.clone() };
            pb.inc(1);
            spec.render()
        })
        .collect::<laparo_cpc::Result<_>>()?;
    pb.finish_and_clear();
    let views: Vec<View> = scenes
        .iter()
        .map(|s| View {
            image: &s.image,
            depth: &s.depth,
            intrinsics: &s.intrinsics,
            roi: &s.roi,
            cam_from_world: s.pose,
        })
        .collect();
    let rows = eval::evaluate_sequence(&views, 0, &settings)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    write_atomic(&a.out.join("sequence.csv"), eval::sequence_csv(&rows).as_bytes())?;
    eval::plot_sequence_png(&rows, &a.out.join("sequence.png"))?;
    for (i, s) in scenes.iter().enumerate() {
        io::write_png(a.out.join(format!("frame{i:02}.png")), &s.image)?;
    }
    let mut t = laparo_core::table::Table::new(["frame", "method", "#correct", "#correct CPC", "ratio"]);
    for r in &rows {
        t.push_row([
            r.frame.to_string(),
            r.method.clone(),
            r.n_correct.to_string(),
            r.n_correct_cpc.to_string(),
            format!("{:.2}", r.ratio),
        ]);
    }
    println!("{}", t.to_markdown());
    println!("written to {}", a.out.display());
    Ok(())
}
