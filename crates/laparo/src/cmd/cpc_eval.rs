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
        let mut s = EvalSettings::default();
        if !(self.roi_erosion >= 0.0 && self.eps > 0.0 && self.ubc >= 1.0) {
            bail!("--roi-erosion must be >= 0, --eps > 0 and --ubc >= 1");
        }
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

fn pose_json(p: &Se3) -> Value {
    let r = p.rotation.to_rotation_matrix();
    let t = p.translation.vector;
    json!({"R": [[r[(0,0)], r[(0,1)], r[(0,2)]], [r[(1,0)], r[(1,1)], r[(1,2)]], [r[(2,0)], r[(2,1)], r[(2,2)]]],
           "t_mm": [t.x, t.y, t.z]})
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
    let num = |x: &Value| x.as_f64();
    let r: Option<Vec<f64>> = p.get("R").and_then(|r| r.as_array()).map(|rows| {
        rows.iter().flat_map(|row| row.as_array().cloned().unwrap_or_default()).filter_map(|x| num(&x)).collect()
    });
    let t: Option<Vec<f64>> = p.get("t_mm").and_then(|t| t.as_array()).map(|t| t.iter().filter_map(num).collect());
    let (Some(r), Some(t)) = (r, t) else {
        bail!("poses {}: {view}.cam_from_world needs \"R\" (3x3) and \"t_mm\" (3)", path.display());
    };
    if r.len() != 9 || t.len() != 3 || r.iter().chain(&t).any(|x| !x.is_finite()) {
        bail!("poses {}: {view}.cam_from_world needs a finite 3x3 \"R\" and 3-vector \"t_mm\"", path.display());
    }
    let m = Matrix3::from_row_slice(&r);
    if (m.transpose() * m - Matrix3::identity()).abs().max() > 1e-6 || m.determinant() < 0.0 {
        bail!("poses {}: {view}.cam_from_world.R is not a rotation", path.display());
    }
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Ok(Isometry3::from_parts(Translation3::from(Vector3::new(t[0], t[1], t[2])), rot))
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
    let txt = std::fs::read_to_string(&a.poses).with_context(|| format!("reading poses {}", a.poses.display()))?;
    let pj: Value = serde_json::from_str(&txt).with_context(|| format!("parsing poses {}", a.poses.display()))?;
    let (p1, p2) = (read_pose(&a.poses, &pj, "view1")?, read_pose(&a.poses, &pj, "view2")?);
    let k2 = a.intrinsics2.as_ref().unwrap_or(&a.intrinsics);
    let l1 = load_view(&a.image1, &a.depth1, &a.mask1, a.depth_unit, &a.intrinsics, p1)?;
    let l2 = load_view(&a.image2, &a.depth2, &a.mask2, a.depth_unit, k2, p2)?;
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

pub fn sequence_cmd(a: SequenceArgs) -> Result<()> {
    if a.frames < 2 {
        bail!("--frames must be at least 2");
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
