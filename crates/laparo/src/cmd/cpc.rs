//! `laparo cpc ...`: Conformal Perspective Correction (thesis Ch. 4).
//!
//! * `warp`: CPC on one frame (image + metric depth + intrinsics + ROI) → warped PNG, validity mask,
//!   dense coordinate maps (.npy) and `stats.json`;
//! * `lambda`: the λ sweep of §4.5.4 (δ_area curve, Gompertz/exponential fit, ℓ) as CSV + PNG;
//! * `scene`: render a synthetic scene (plane, cylinder, bumpy bowl) to files usable by `warp`.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::atomic::write_atomic;
use laparo_core::camera::{Distortion, Intrinsics};
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::{Image, Mask};
use laparo_core::io;
use laparo_core::remap::{remap, CoordMap, Interp};
use laparo_cpc::lambda::{auto_lambda, default_lambda_grid};
use laparo_cpc::pipeline::LambdaChoice;
use laparo_cpc::scene::{self, SceneSpec, Surface, Texture};
use laparo_cpc::{ConformalParams, CpcMesh, CpcParams, CpcSolver, CpcSystem, MeshParams};
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
    /// Render a two-view pair with exact ground truth (easy or hard viewpoint change).
    Pair(super::cpc_eval::PairArgs),
    /// SIFT/ORB matching without and with CPC against ground truth (Table 4.1, Fig. 4.8; λ sweep, Fig. 4.12).
    Eval(super::cpc_eval::EvalArgs),
    /// Every frame of a rendered orbit against the keyframe, without and with CPC (Fig. 4.9).
    Sequence(super::cpc_eval::SequenceArgs),
}

#[derive(Args, Clone)]
pub struct InputArgs {
    /// Depth map (npy, npz, pfm, tif/tiff, 16-bit png), z along the optical axis.
    #[arg(long)]
    pub depth: PathBuf,
    /// Unit of the depth file (m or mm).
    #[arg(long, default_value = "mm")]
    pub depth_unit: DepthUnit,
    /// Intrinsics (px): JSON {"fx","fy","cx","cy"} or {"K": 3x3}, numbers or numeric strings, optional "width"/"height" and distortion; ROS camera_info / OpenCV YAML; COLMAP cameras.txt. The size defaults to the depth map's. With lens
    /// distortion, image, depth and mask are undistorted first (same K; written as undistorted.png) and every output is in that pinhole frame.
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
    /// Mask out warped pixels of triangles magnified more than this multiple of the median
    /// triangle (near-grazing rim spikes); 0 disables.
    #[arg(long, default_value_t = laparo_cpc::pipeline::DEFAULT_MAX_REL_MAGNIFICATION)]
    pub max_magnification: f64,
    /// Scale of the warped image: resolution (no minification at the median triangle), area
    /// (original total ROI area) or raw (the solve of eq. 4.11 as it is).
    #[arg(long, default_value = "resolution")]
    pub scale: String,
}

#[derive(Args)]
pub struct WarpArgs {
    /// Input image (PNG/JPEG/TIFF, 8-bit), or a folder of frames: then --depth is a folder of
    /// depth maps with the same stems, outputs go to `OUT/<stem>/`, and the mesh topology
    /// (ordering, symbolic factorisation) is reused across frames whose mesh has not changed.
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
    /// Resize a depth map whose size differs from the image's (a prediction at network
    /// resolution): bilinear or nearest, pixel centres aligned. Without it a mismatch is an error.
    #[arg(long, value_name = "FILTER", alias = "resize-pred")]
    pub resize_depth: Option<laparo_depth::eval::ResizeFilter>,
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
        CpcCmd::Pair(a) => super::cpc_eval::pair(a),
        CpcCmd::Eval(a) => super::cpc_eval::eval_cmd(a),
        CpcCmd::Sequence(a) => super::cpc_eval::sequence_cmd(a),
    }
}

/// The intrinsics of `--intrinsics` for a `w`×`h` depth map, through the shared camera reader
/// (JSON `fx..cy` or `K`, numbers or numeric strings, ROS / OpenCV YAML, COLMAP, EndoVis), and
/// its lens distortion if it has one (CPC models a pinhole camera: the inputs are undistorted).
fn read_intrinsics(path: &Path, w: usize, h: usize) -> Result<(Intrinsics, Option<Distortion>)> {
    let cam = io::read_camera(path).with_context(|| format!("reading intrinsics {}", path.display()))?;
    let k = cam.intrinsics(Some((w, h))).with_context(|| format!("intrinsics {}", path.display()))?;
    Ok((k, cam.has_distortion().then_some(cam.distortion)))
}

fn read_mask(path: &Path) -> Result<Mask> {
    io::read_mask(path).with_context(|| format!("reading mask {}", path.display()))
}

struct Inputs {
    depth: DepthMap,
    k: Intrinsics,
    roi: Mask,
    params: CpcParams,
    /// The lens distortion of `--intrinsics` and its undistortion map, when it has one: `depth`
    /// and `roi` are then already undistorted, the image must be too.
    undistort: Option<(Distortion, CoordMap)>,
}

/// `resize`: bring the depth map to (width, height) px first (a prediction at network resolution).
fn load_inputs(a: &InputArgs, resize: Option<(usize, usize, laparo_depth::eval::ResizeFilter)>) -> Result<Inputs> {
    let mut depth =
        io::read_depth(&a.depth, a.depth_unit).with_context(|| format!("reading depth {}", a.depth.display()))?;
    if let Some((w, h, f)) = resize {
        if (depth.width, depth.height) != (w, h) {
            depth = resize_depth(&depth, w, h, f)?;
        }
    }
    let (k, distortion) = read_intrinsics(&a.intrinsics, depth.width, depth.height)?;
    let mut roi = match &a.mask {
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
        max_rel_magnification: (a.max_magnification > 0.0).then_some(a.max_magnification),
        scale: a.scale.parse()?,
        ..CpcParams::default()
    };
    // Lens distortion is applied, never ignored: depth (bilinear; NaN where any neighbour is
    // invalid) and ROI (nearest) are resampled into the pinhole image with the same K.
    let undistort = match distortion {
        Some(d) => {
            let map = CoordMap::undistort(&k, &d, depth.width, depth.height);
            let dimg = depth.to_image().map(|v| if DepthMap::is_valid(v) { v } else { f64::NAN });
            let (ud, _) = remap(&dimg, &map, Interp::Bilinear, f64::NAN)?;
            depth = DepthMap::new(ud.width, ud.height, depth.unit, ud.data)?;
            let (ur, _) = remap(&roi.map(|b| b as u8), &map, Interp::Nearest, 0u8)?;
            roi = ur.map(|v| v != 0);
            Some((d, map))
        }
        None => None,
    };
    Ok(Inputs { depth, k, roi, params, undistort })
}

fn f32_map(m: &Image<f64>) -> Image<f32> {
    m.map(|v| v as f32)
}

/// Files `cpc warp` writes into its output folder.
const WARP_OUTPUTS: [&str; 8] = [
    "undistorted.png",
    "warped.png",
    "mask.png",
    "map_backward.npy",
    "map_forward.npy",
    "lambda_sweep.csv",
    "lambda_sweep.png",
    "stats.json",
];

/// Refuse an output folder where a written file would replace one of the inputs.
fn refuse_overwriting_inputs(out: &Path, inputs: &[&Path]) -> Result<()> {
    for name in WARP_OUTPUTS {
        laparo_core::atomic::refuse_overwrite(&out.join(name), inputs, false).context("--out")?;
    }
    Ok(())
}

/// Resize `depth` to `w`×`h` px with `filter` (invalid depth stays invalid: NaN propagates).
fn resize_depth(depth: &DepthMap, w: usize, h: usize, filter: laparo_depth::eval::ResizeFilter) -> Result<DepthMap> {
    let img = depth.to_image().map(|v| if DepthMap::is_valid(v) { v } else { f64::NAN });
    let r = laparo_depth::eval::resize_map(&img, w, h, filter)?;
    Ok(DepthMap::new(w, h, depth.unit, r.data)?)
}

fn warp(a: WarpArgs) -> Result<()> {
    if a.image.is_dir() {
        return warp_batch(a);
    }
    let mut inputs: Vec<&Path> = vec![&a.image, &a.input.depth, &a.input.intrinsics];
    if let Some(m) = &a.input.mask {
        inputs.push(m);
    }
    refuse_overwriting_inputs(&a.out, &inputs)?;
    let spinner = ProgressBar::new_spinner();
    spinner.set_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}").unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    spinner.set_message(format!("CPC warp of {}{}", a.image.display(), if a.auto_lambda { " (λ sweep)" } else { "" }));
    spinner.enable_steady_tick(std::time::Duration::from_millis(120));
    let r = warp_one(&mut CpcSolver::new(), &a, &a.image, &a.input, &a.out);
    spinner.finish_and_clear();
    let s = r?;
    println!(
        "λ = {:.4}: {} vertices, {} triangles, angle error {:.2}° -> {:.2}°, δ_area {:.3}, {} flipped; canvas {}x{}; written to {}",
        s.lambda, s.n_vertices, s.n_triangles, s.angle_error_deg_before, s.angle_error_deg_after, s.delta_area, s.n_flipped,
        s.canvas_width, s.canvas_height, a.out.display()
    );
    Ok(())
}

/// `cpc warp --image DIR --depth DIR`: every frame, one solver (topology reused when the mesh
/// is unchanged), a progress bar, outputs in `OUT/<stem>/`.
fn warp_batch(a: WarpArgs) -> Result<()> {
    if !a.input.depth.is_dir() {
        bail!("--image {} is a folder, so --depth {} must be one too", a.image.display(), a.input.depth.display());
    }
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&a.image)
        .with_context(|| format!("reading folder {}", a.image.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && matches!(io::extension(p).as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff"))
        .collect();
    frames.sort();
    if frames.is_empty() {
        bail!("--image {}: no PNG/JPEG/TIFF image in this folder", a.image.display());
    }
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let depths: Vec<PathBuf> = frames
        .iter()
        .map(|f| {
            ["npy", "npz", "pfm", "tif", "tiff", "png", "exr"]
                .iter()
                .map(|e| a.input.depth.join(format!("{}.{e}", stem(f))))
                .find(|p| p.is_file())
                .with_context(|| {
                    format!(
                        "--depth {}: no depth map named '{}.*' for {}",
                        a.input.depth.display(),
                        stem(f),
                        f.display()
                    )
                })
        })
        .collect::<Result<_>>()?;
    laparo_core::atomic::refuse_overwrite(&a.out, &[&a.image, &a.input.depth], true).context("--out")?;
    let pb = ProgressBar::new(frames.len() as u64);
    pb.set_style(
        ProgressStyle::with_template("cpc warp [{bar:40}] {pos}/{len} frames ({per_sec}, eta {eta}) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.enable_steady_tick(std::time::Duration::from_millis(250));
    let mut solver = CpcSolver::new();
    let mut failures = Vec::new();
    for (f, d) in frames.iter().zip(&depths) {
        let out = a.out.join(stem(f));
        pb.set_message(stem(f));
        let input = InputArgs { depth: d.clone(), ..a.input.clone() };
        match warp_one(&mut solver, &a, f, &input, &out) {
            Ok(_) => {}
            Err(e) => failures.push(format!("{}: {e:#}", f.display())),
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    println!("cpc warp: {} of {} frames warped -> {}", frames.len() - failures.len(), frames.len(), a.out.display());
    if !failures.is_empty() {
        bail!("{} frame(s) failed:\n  {}", failures.len(), failures.join("\n  "));
    }
    Ok(())
}

/// Warp one frame into `out` (the files of [`WARP_OUTPUTS`]), returning its statistics.
fn warp_one(
    solver: &mut CpcSolver,
    a: &WarpArgs,
    image_path: &Path,
    input: &InputArgs,
    out: &Path,
) -> Result<laparo_cpc::CpcStats> {
    let t0 = Instant::now();
    let image = io::read_image(image_path).with_context(|| format!("reading image {}", image_path.display()))?;
    let mut inp = match load_inputs(input, a.resize_depth.map(|f| (image.width, image.height, f))) {
        Ok(i) => i,
        Err(e) => {
            // A depth map at another resolution (a network's): say how to use it.
            if let (None, Ok(d)) = (a.resize_depth, io::read_depth(&input.depth, input.depth_unit)) {
                if (d.width, d.height) != (image.width, image.height) {
                    return Err(e.context(format!(
                        "depth {} is {}x{} but image {} is {}x{} (use --resize-depth bilinear|nearest for a prediction at network resolution)",
                        input.depth.display(), d.width, d.height, image_path.display(), image.width, image.height
                    )));
                }
            }
            return Err(e);
        }
    };
    if (inp.depth.width, inp.depth.height) != (image.width, image.height) {
        bail!(
            "depth {} is {}x{} but image {} is {}x{} (use --resize-depth bilinear|nearest for a prediction at network resolution)",
            input.depth.display(),
            inp.depth.width,
            inp.depth.height,
            image_path.display(),
            image.width,
            image.height
        );
    }
    let t_read = t0.elapsed().as_secs_f64() * 1e3;
    inp.params.lambda = if a.auto_lambda {
        CpcParams::auto_lambda()
    } else {
        LambdaChoice::Fixed(a.lambda.unwrap_or(laparo_cpc::pipeline::DEFAULT_LAMBDA))
    };
    if a.equiareal {
        inp.params.equiareal = Some(Default::default());
    }
    let image = match &inp.undistort {
        Some((_, map)) => remap(&image, map, Interp::Bilinear, 0u8)?.0,
        None => image,
    };
    let mut r = laparo_cpc::cpc_warp_with(solver, &image, &inp.depth, &inp.k, &inp.roi, &inp.params)?;
    let t = Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    if inp.undistort.is_some() {
        io::write_png(out.join("undistorted.png"), &image)?;
    }
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
    stats["inputs"] = json!({"image": image_path, "depth": input.depth, "depth_unit": input.depth_unit.to_string(),
        "intrinsics": input.intrinsics, "mask": input.mask, "resize_depth": a.resize_depth});
    if let Some((d, _)) = &inp.undistort {
        stats["undistorted"] = json!({
            "distortion_opencv": d.to_opencv(),
            "note": "the camera has lens distortion: image, depth and mask were undistorted to the pinhole camera with the same K (undistorted.png); every output is in that frame"
        });
    }
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
    for w in &s.warnings {
        eprintln!("warning: {w} (sweep written to {})", out.join("lambda_sweep.csv").display());
    }
    Ok(r.stats)
}

fn lambda(a: LambdaArgs) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![&a.input.depth, &a.input.intrinsics];
    inputs.extend(a.input.mask.as_deref());
    laparo_core::atomic::refuse_overwrite_in(&a.out, &["lambda_sweep.csv", "lambda_sweep.png", "lambda.json"], &inputs)
        .context("--out")?;
    let inp = load_inputs(&a.input, None)?;
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
    match (&s.fit, &s.warning) {
        (Some(f), _) => println!("ℓ = {:.4} (fit RMSE {:.4}); written to {}", s.ell, f.rmse, a.out.display()),
        (None, w) => {
            eprintln!("warning: {}", w.as_deref().unwrap_or("fit failed"));
            println!("λ = {:.4} (fallback); sweep written to {}", s.ell, a.out.display());
        }
    }
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
