//! `laparo cpc ...`: Conformal Perspective Correction (thesis Ch. 4).
//!
//! * `warp`: CPC on one frame (image + metric depth + intrinsics + ROI) → warped PNG, validity mask,
//!   dense coordinate maps (.npy) and `stats.json`;
//! * `lambda`: the λ sweep of §4.5.4 (δ_area curve, Gompertz/exponential fit, ℓ) as CSV + PNG;
//! * `scene`: render a synthetic scene (plane, cylinder, bumpy bowl) to files usable by `warp`.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use laparo_core::atomic::write_atomic;
use laparo_core::camera::Intrinsics;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::{Image, Mask};
use laparo_core::io;
use laparo_cpc::lambda::{auto_lambda, default_lambda_grid};
use laparo_cpc::pipeline::LambdaChoice;
use laparo_cpc::scene::{self, SceneSpec, Surface, Texture};
use laparo_cpc::{cpc_warp, ConformalParams, CpcMesh, CpcParams, CpcSystem, MeshParams};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum CpcCmd {
    /// CPC-warp one frame: warped image, mask, coordinate maps and stats.json.
    Warp(WarpArgs),
    /// Sweep λ, fit the Gompertz/exponential model (eq. 4.14) and report ℓ (§4.5.4).
    Lambda(LambdaArgs),
    /// Render a synthetic textured surface (image.png, depth.npy in mm, mask.png, intrinsics.json, pose.json).
    Scene(SceneArgs),
}

#[derive(Args, Clone)]
pub struct InputArgs {
    /// Depth map (npy, npz, pfm, tif/tiff, 16-bit png), z along the optical axis.
    #[arg(long)]
    pub depth: PathBuf,
    /// Unit of the depth file (m or mm).
    #[arg(long, default_value = "mm")]
    pub depth_unit: DepthUnit,
    /// Intrinsics (px): JSON {"fx","fy","cx","cy"} or {"K": 3x3}, numbers or numeric strings, optional "width"/"height" and distortion; ROS camera_info / OpenCV YAML; COLMAP cameras.txt. The size defaults to the depth map's; a camera with lens
    /// distortion is refused (undistort first).
    #[arg(long)]
    pub intrinsics: PathBuf,
    /// ROI mask (PNG/JPEG/TIFF: channel 0 non-zero; npy/npz/PFM/EXR: finite and non-zero); default: every pixel with valid depth.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Grid step in px.
    #[arg(long, default_value_t = 4)]
    pub grid_step: usize,
    /// Drop triangles seen beyond this angle (deg) between normal and viewing ray (flip guard); 90 disables.
    #[arg(long, default_value_t = 85.0)]
    pub max_view_angle: f64,
    /// Drop triangles with a relative depth jump above this along an edge.
    #[arg(long, default_value_t = 0.1)]
    pub max_depth_jump: f64,
    /// Angle θ (deg) of the conformal basis (generalised eq. 4.2).
    #[arg(long, default_value_t = 90.0)]
    pub theta_deg: f64,
}

#[derive(Args)]
pub struct WarpArgs {
    /// Input image (PNG/JPEG/TIFF, 8-bit).
    #[arg(long)]
    pub image: PathBuf,
    #[command(flatten)]
    pub input: InputArgs,
    /// λ ∈ [0, 1) (default 0.95 unless --auto-lambda).
    #[arg(long, conflicts_with = "auto_lambda")]
    pub lambda: Option<f64>,
    /// Select λ automatically (§4.5.4).
    #[arg(long)]
    pub auto_lambda: bool,
    /// Refine with the equiareal formulation (eq. 4.9) after the convex solve.
    #[arg(long)]
    pub equiareal: bool,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args)]
pub struct LambdaArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// λ values of the sweep (comma separated); default 0..0.95 by 0.05 and 0.96..0.999.
    #[arg(long, value_delimiter = ',')]
    pub lambdas: Vec<f64>,
    /// Output folder (lambda_sweep.csv, lambda_sweep.png, lambda.json).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args)]
pub struct SceneArgs {
    /// Surface: plane, cylinder, bumpy (organ-like bowl), bowl (scene.py's bumpy bowl, exact).
    #[arg(long, default_value = "bumpy")]
    pub surface: String,
    /// Tilt (deg) of the patch normal from the optical axis (about the camera x axis).
    #[arg(long, default_value_t = 58.0)]
    pub tilt: f64,
    /// Additional yaw (deg) about the camera y axis.
    #[arg(long, default_value_t = 0.0)]
    pub yaw: f64,
    /// Distance (mm) from the camera to the patch centre.
    #[arg(long, default_value_t = 100.0)]
    pub dist: f64,
    /// Texture: checker, procedural, or a photograph name in ../shared/data/textures (falls back to procedural).
    #[arg(long, default_value = "retina.jpg")]
    pub texture: String,
    /// Image width and height (px); the focal length scales with the width (500 px at 640).
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    #[arg(long, default_value_t = 480)]
    pub height: usize,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(c: CpcCmd) -> Result<()> {
    match c {
        CpcCmd::Warp(a) => warp(a),
        CpcCmd::Lambda(a) => lambda(a),
        CpcCmd::Scene(a) => render_scene(a),
    }
}

/// The intrinsics of `--intrinsics` for a `w`×`h` depth map, through the shared camera reader
/// (JSON `fx..cy` or `K`, numbers or numeric strings, ROS / OpenCV YAML, COLMAP, EndoVis). The CPC
/// warp models a pinhole camera: a file with lens distortion is refused with a clear error.
fn read_intrinsics(path: &Path, w: usize, h: usize) -> Result<Intrinsics> {
    let cam = io::read_camera(path).with_context(|| format!("reading intrinsics {}", path.display()))?;
    Ok(cam.intrinsics_undistorted(Some((w, h)), "cpc warp")?)
}

fn read_mask(path: &Path) -> Result<Mask> {
    io::read_mask(path).with_context(|| format!("reading mask {}", path.display()))
}

struct Inputs {
    depth: DepthMap,
    k: Intrinsics,
    roi: Mask,
    params: CpcParams,
}

fn load_inputs(a: &InputArgs) -> Result<Inputs> {
    let depth =
        io::read_depth(&a.depth, a.depth_unit).with_context(|| format!("reading depth {}", a.depth.display()))?;
    let k = read_intrinsics(&a.intrinsics, depth.width, depth.height)?;
    let roi = match &a.mask {
        Some(p) => read_mask(p)?,
        None => depth.valid_mask(),
    };
    if roi.width != depth.width || roi.height != depth.height {
        bail!(
            "mask {} is {}x{}, depth {} is {}x{}",
            a.mask.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
            roi.width,
            roi.height,
            a.depth.display(),
            depth.width,
            depth.height
        );
    }
    let params = CpcParams {
        mesh: MeshParams {
            grid_step_px: a.grid_step,
            max_rel_depth_jump: a.max_depth_jump,
            max_view_angle_deg: if a.max_view_angle >= 90.0 { None } else { Some(a.max_view_angle) },
            ..MeshParams::default()
        },
        conformal: ConformalParams { theta_rad: a.theta_deg.to_radians(), ..ConformalParams::default() },
        ..CpcParams::default()
    };
    Ok(Inputs { depth, k, roi, params })
}

fn f32_map(m: &Image<f64>) -> Image<f32> {
    m.map(|v| v as f32)
}

fn warp(a: WarpArgs) -> Result<()> {
    let t0 = Instant::now();
    let image = io::read_image(&a.image).with_context(|| format!("reading image {}", a.image.display()))?;
    let mut inp = load_inputs(&a.input)?;
    let t_read = t0.elapsed().as_secs_f64() * 1e3;
    inp.params.lambda = if a.auto_lambda {
        CpcParams::auto_lambda()
    } else {
        LambdaChoice::Fixed(a.lambda.unwrap_or(laparo_cpc::pipeline::DEFAULT_LAMBDA))
    };
    if a.equiareal {
        inp.params.equiareal = Some(Default::default());
    }
    let mut r = cpc_warp(&image, &inp.depth, &inp.k, &inp.roi, &inp.params)?;
    let t = Instant::now();
    let out = &a.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    io::write_png(out.join("warped.png"), &r.warped)?;
    io::write_png(out.join("mask.png"), &r.mask.map(|b| if b { 255u8 } else { 0 }))?;
    let maps = r.warp.maps();
    io::write_npy_f32(out.join("map_backward.npy"), &f32_map(&maps.backward))?;
    io::write_npy_f32(out.join("map_forward.npy"), &f32_map(&maps.forward))?;
    if let Some(s) = &r.sweep {
        write_atomic(&out.join("lambda_sweep.csv"), s.to_csv().as_bytes())?;
        s.plot_png(&out.join("lambda_sweep.png"))?;
    }
    r.stats.timings_ms.insert("read".into(), t_read);
    r.stats.timings_ms.insert("write".into(), t.elapsed().as_secs_f64() * 1e3);
    let mut stats = serde_json::to_value(&r.stats)?;
    stats["inputs"] = json!({"image": a.image, "depth": a.input.depth, "depth_unit": a.input.depth_unit.to_string(),
        "intrinsics": a.input.intrinsics, "mask": a.input.mask});
    stats["maps"] = json!({
        "map_backward.npy": "HxWx2 float32, canvas pixel -> original (x, y) px, NaN where invalid",
        "map_forward.npy": "HxWx2 float32 (original size), original pixel -> canvas (x, y) px, NaN outside the mesh"
    });
    write_atomic(&out.join("stats.json"), serde_json::to_string_pretty(&stats)?.as_bytes())?;
    let s = &r.stats;
    if s.mesh.component_triangles.len() > 1 {
        eprintln!(
            "note: the mesh has {} connected components (triangles: {:?}); each is solved on its own",
            s.n_components, s.mesh.component_triangles
        );
    }
    let dropped = s.mesh.dropped_invalid_depth
        + s.mesh.dropped_depth_jump
        + s.mesh.dropped_degenerate
        + s.mesh.dropped_grazing
        + s.mesh.dropped_small_components;
    if dropped > 0 {
        eprintln!(
            "note: dropped {dropped} triangles ({} invalid depth, {} depth jump, {} degenerate, {} grazing, {} small components)",
            s.mesh.dropped_invalid_depth, s.mesh.dropped_depth_jump, s.mesh.dropped_degenerate, s.mesh.dropped_grazing, s.mesh.dropped_small_components
        );
    }
    if s.n_flipped > 0 {
        eprintln!("warning: {} flipped triangles (lower λ or --max-view-angle)", s.n_flipped);
    }
    println!(
        "λ = {:.4}: {} vertices, {} triangles, angle error {:.2}° -> {:.2}°, δ_area {:.3}, {} flipped; canvas {}x{}; written to {}",
        s.lambda, s.n_vertices, s.n_triangles, s.angle_error_deg_before, s.angle_error_deg_after, s.delta_area, s.n_flipped,
        s.canvas_width, s.canvas_height, out.display()
    );
    Ok(())
}

fn lambda(a: LambdaArgs) -> Result<()> {
    let inp = load_inputs(&a.input)?;
    let grid = if a.lambdas.is_empty() { default_lambda_grid() } else { a.lambdas.clone() };
    for &l in &grid {
        laparo_cpc::solve::validate_lambda(l)?;
    }
    let mesh = CpcMesh::build(&inp.roi, &inp.depth, &inp.k, &inp.params.mesh)?;
    let sys = CpcSystem::assemble(&mesh, &inp.params.conformal)?;
    let s = auto_lambda(&sys, &mesh, &grid)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    write_atomic(&a.out.join("lambda_sweep.csv"), s.to_csv().as_bytes())?;
    s.plot_png(&a.out.join("lambda_sweep.png"))?;
    write_atomic(&a.out.join("lambda.json"), serde_json::to_string_pretty(&s)?.as_bytes())?;
    println!("ℓ = {:.4} (fit RMSE {:.4}); written to {}", s.ell, s.fit.rmse, a.out.display());
    Ok(())
}

fn render_scene(a: SceneArgs) -> Result<()> {
    let f = 500.0 * a.width as f64 / 640.0;
    let k = Intrinsics::new(f, f, (a.width as f64) / 2.0, (a.height as f64) / 2.0, a.width, a.height)?;
    let mut spec = scene::bumpy_bowl_spec();
    spec.intrinsics = k;
    spec.pose = scene::tilted_pose_xy(a.tilt, a.yaw, a.dist);
    spec.surface = match a.surface.as_str() {
        "plane" => Surface::Plane,
        "cylinder" => Surface::Cylinder { radius_mm: 80.0 },
        "bumpy" | "bowl" => spec.surface.clone(),
        other => bail!("unknown --surface '{other}' (plane, cylinder, bumpy, bowl)"),
    };
    spec.texture = match a.texture.as_str() {
        "checker" => Texture::Checker { square_mm: 5.0 },
        "procedural" => Texture::Procedural { seed: 1 },
        name => match crate::demo::shared_data(&format!("textures/{name}")) {
            Some(p) => scene::photo_or_procedural(&p, 1),
            None => Texture::Procedural { seed: 1 },
        },
    };
    if a.surface == "bowl" {
        spec.texture = Texture::Checker { square_mm: 5.0 };
    }
    let sc: scene::Scene = SceneSpec { ..spec }.render()?;
    let out = &a.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    io::write_png(out.join("image.png"), &sc.image)?;
    io::write_npy_f64(out.join("depth.npy"), &sc.depth.to_image())?;
    io::write_png(out.join("mask.png"), &sc.roi.map(|b| if b { 255u8 } else { 0 }))?;
    write_atomic(&out.join("intrinsics.json"), serde_json::to_string_pretty(&sc.intrinsics)?.as_bytes())?;
    let r = sc.pose.rotation.to_rotation_matrix();
    let t = sc.pose.translation.vector;
    let pose = json!({"camera_from_surface": {"R": [[r[(0,0)], r[(0,1)], r[(0,2)]], [r[(1,0)], r[(1,1)], r[(1,2)]], [r[(2,0)], r[(2,1)], r[(2,2)]]], "t_mm": [t.x, t.y, t.z]},
        "surface": a.surface, "tilt_deg": a.tilt, "yaw_deg": a.yaw, "dist_mm": a.dist});
    write_atomic(&out.join("pose.json"), serde_json::to_string_pretty(&pose)?.as_bytes())?;
    io::write_npy_f32(out.join("surface_xy.npy"), &f32_map(&sc.surface_xy))?;
    println!("scene {} ({} ROI px) written to {}", a.surface, sc.roi.count(), out.display());
    Ok(())
}
