//! `laparo guide ...`: the guidance pipeline end to end in silico (thesis §5.4.3, Fig. 5.10).
//!
//! - `laparo guide scenario --out DIR [--quick]`: render the scenario (P2ILF liver + tumour, before
//!   and after an incision, uncalibrated stereo pair, ground truth).
//! - `laparo guide --scenario DIR --out DIR [--route calibrated|self-rectified] [--quick]`: run every
//!   stage, write the intermediates, `report.json` and `report.html`.
//! - `laparo guide stereo | rigid | landmarks`: one stage on its own.
//! - `laparo guide end-to-end --out DIR [--quick]`: everything in one command — the FEM ground truth
//!   of the non-anatomical incision, the scenario, the pipeline on both stereo routes, `DIR/index.html`.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use laparo_guide::pipeline::{self, GuideConfig, Route};
use laparo_guide::render::View;
use laparo_guide::scenario::{self, json_read, Polyline2, Pose, ScenarioConfig};
use std::path::PathBuf;

/// `laparo guide`: the whole pipeline, or a subcommand.
#[derive(Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct GuideArgs {
    #[command(subcommand)]
    pub sub: Option<GuideSub>,
    #[command(flatten)]
    pub run: RunArgs,
}

/// Arguments of the whole pipeline.
#[derive(Args)]
pub struct RunArgs {
    /// Scenario folder (from `laparo guide scenario`).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Stereo route: calibrated, or self-rectified (extrinsics from the images: essential matrix of SIFT matches; intrinsics and baseline length from the calibration).
    #[arg(long, default_value = "calibrated")]
    pub route: String,
    /// Settings for the quick (960×540) scenario.
    #[arg(long)]
    pub quick: bool,
    /// Optimiser iterations of the registration.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Particle spacing of the registration (mm).
    #[arg(long)]
    pub spacing_mm: Option<f64>,
    /// Register with the thesis' RODS-MPM (one field, v₀ the unknown, landmarks at their nearest particles)
    /// instead of the crack-aware rung L3 (the cut assumed from the drawn incision, two fields, loads).
    #[arg(long)]
    pub thesis_registration: bool,
}

/// Subcommands.
#[derive(Subcommand)]
pub enum GuideSub {
    /// Render a scenario folder with ground truth.
    Scenario(ScenarioArgs),
    /// The whole chain in one command: FEM ground truth of the incision → scenario → pipeline on both
    /// stereo routes → DIR/index.html (resumes: the ground truth is cached in DIR/ground-truth).
    EndToEnd(EndToEndArgs),
    /// Stage 1 alone: depth (mm) of a scenario pair.
    Stereo {
        /// Scenario folder.
        #[arg(long)]
        scenario: PathBuf,
        /// past or present.
        #[arg(long, default_value = "past")]
        pair: String,
        /// calibrated or self-rectified.
        #[arg(long, default_value = "calibrated")]
        route: String,
        /// Output folder (depth_mm.npy, depth.png, cloud.ply, errors.json).
        #[arg(long)]
        out: PathBuf,
    },
    /// Stage 2 alone: ICP of a point cloud (camera frame) onto a model from a rough pose.
    Rigid {
        /// Point cloud (PLY, mm, camera frame).
        #[arg(long)]
        cloud: PathBuf,
        /// Preoperative model (mm, model frame).
        #[arg(long)]
        model: PathBuf,
        /// Initial pose JSON, model → camera: {"model_to_camera": {"R": 3 rows, "t_mm": [x, y, z]}} or
        /// {"T": 4x4 rows} (the form every laparo transform is written in; see laparo-core `se3`).
        #[arg(long)]
        initial_pose: PathBuf,
        /// Output JSON: the estimated pose under "model_to_camera" (the same form), ICP RMSE and iterations.
        #[arg(long)]
        out: PathBuf,
    },
    /// Stage 3 alone: back-project a 2D polyline (JSON points_px) onto an aligned model (camera frame).
    Landmarks {
        /// Polyline JSON (`points_px`).
        #[arg(long)]
        polyline: PathBuf,
        /// Aligned model (camera frame, mm).
        #[arg(long)]
        model: PathBuf,
        /// Scenario folder (for the camera).
        #[arg(long)]
        scenario: PathBuf,
        /// Output PLY of the 3D points.
        #[arg(long)]
        out: PathBuf,
    },
}

/// `laparo guide scenario`.
#[derive(Args)]
pub struct ScenarioArgs {
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// 960×540, 6 mm tetrahedra (the demo size).
    #[arg(long)]
    pub quick: bool,
    /// The scenario's organ, texture frame and camera.
    #[command(flatten)]
    pub inputs: SceneInputs,
    /// Ground-truth deformation folder from laparo-fem (rest.vtk + deformation.json); default: the
    /// stand-in analytic incision.
    #[arg(long)]
    pub deformation: Option<PathBuf>,
    /// Render width (px); the height follows 16:9.
    #[arg(long)]
    pub width: Option<usize>,
}

/// `laparo guide end-to-end`.
#[derive(Args)]
pub struct EndToEndArgs {
    /// Output folder (ground-truth/, scenario/, calibrated/, self-rectified/, index.html, summary.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Demo size: 960×540 images, 10 mm tetrahedra, short registration (default: 1920×1080, 8 mm).
    #[arg(long)]
    pub quick: bool,
    /// Incision scenario of the benchmark (non-anatomical: wedge cut around a virtual tumour).
    #[arg(long, default_value = "non-anatomical")]
    pub incision: String,
    /// Tetrahedron edge of the FEM ground truth (mm).
    #[arg(long)]
    pub edge_mm: Option<f64>,
    /// FEM load increments per solve.
    #[arg(long)]
    pub fem_steps: Option<usize>,
    /// FEM region (mm): nodes farther than this from the cut are held fixed; 0 = the whole organ.
    #[arg(long)]
    pub fem_region_mm: Option<f64>,
    /// Stereo routes: both, calibrated or self-rectified.
    #[arg(long, default_value = "both")]
    pub route: String,
    /// Register with the thesis' RODS-MPM (one field, v₀ the unknown, landmarks at their nearest particles)
    /// instead of the crack-aware rung L3 (the cut assumed from the drawn incision, two fields, loads).
    #[arg(long)]
    pub thesis_registration: bool,
    /// The scenario's organ, texture frame and camera.
    #[command(flatten)]
    pub inputs: SceneInputs,
}

/// The inputs of a rendered scenario; each defaults to the P2ILF data under ../shared/data.
#[derive(Args)]
pub struct SceneInputs {
    /// Organ surface (closed, mm); default ../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj.
    #[arg(long)]
    pub organ: Option<PathBuf>,
    /// Texture frame; default ../shared/data/surgical/p2ilf_frame/P2ILF22_patient1_12.jpg.
    #[arg(long)]
    pub frame: Option<PathBuf>,
    /// Camera file; default ../shared/data/meshes/p2ilf/acquisition-camera-metadata.json.
    #[arg(long)]
    pub camera: Option<PathBuf>,
}

impl SceneInputs {
    /// (organ, frame, camera) paths, the defaults filled in.
    fn resolve(self) -> Result<(PathBuf, PathBuf, PathBuf)> {
        Ok((
            data("meshes/p2ilf/patient2_1_3d-liver-model.obj", self.organ, "organ")?,
            data("surgical/p2ilf_frame/P2ILF22_patient1_12.jpg", self.frame, "frame")?,
            data("meshes/p2ilf/acquisition-camera-metadata.json", self.camera, "camera")?,
        ))
    }
}

fn end_to_end(e: EndToEndArgs) -> Result<()> {
    use laparo_guide::end_to_end::{self as e2e, EndToEndConfig};
    let (organ, frame, camera) = e.inputs.resolve()?;
    laparo_core::atomic::refuse_overwrite(&e.out, &[&organ, &frame, &camera], true).context("--out")?;
    let mut cfg = if e.quick { EndToEndConfig::quick() } else { EndToEndConfig::full() };
    cfg.incision = e.incision;
    if let Some(v) = e.edge_mm {
        cfg.edge_mm = v;
    }
    if let Some(v) = e.fem_steps {
        cfg.fem_steps = v;
    }
    if let Some(v) = e.fem_region_mm {
        cfg.fem_region_mm = (v > 0.0).then_some(v);
    }
    let keep: Vec<Route> = match e.route.as_str() {
        "both" => vec![Route::Calibrated, Route::SelfRectified],
        r => vec![r.parse().with_context(|| format!("--route {r}: expected both, calibrated or self-rectified"))?],
    };
    cfg.routes.retain(|c| keep.contains(&c.route));
    for r in &mut cfg.routes {
        r.crack_aware = !e.thesis_registration;
    }
    let pb = indicatif::ProgressBar::new_spinner();
    pb.enable_steady_tick(std::time::Duration::from_millis(250));
    pb.set_message("FEM ground truth of the incision (TET10 Neo-Hookean, calibrated pressure)");
    let rep = e2e::run(&organ, &frame, &camera, &cfg, &e.out, &mut |s: &str| {
        pb.suspend(|| eprintln!("{s}"));
        pb.set_message(s.chars().take(100).collect::<String>());
    });
    pb.finish_and_clear();
    let rep = rep?;
    for r in &rep.routes {
        println!("{}: {}", r["route"], serde_json::to_string(&r["summary"])?);
    }
    if let Some(d) = rep.tre_difference_mm {
        println!("final TRE, self-rectified − calibrated: {d:+.2} mm");
    }
    println!(
        "total {:.1} s, peak {:.0} MiB; report: {}",
        rep.total_seconds,
        rep.peak_memory_mib.unwrap_or(f64::NAN),
        e2e::index_path(&e.out).display()
    );
    Ok(())
}

fn data(rel: &str, given: Option<PathBuf>, flag: &str) -> Result<PathBuf> {
    match given {
        Some(p) => Ok(p),
        None => crate::demo::shared_data(rel)
            .with_context(|| format!("--{flag} not given and ../shared/data/{rel} not found (set LAPARO_SHARED_DATA)")),
    }
}

pub fn run(a: GuideArgs) -> Result<()> {
    match a.sub {
        Some(GuideSub::EndToEnd(e)) => end_to_end(e),
        Some(GuideSub::Scenario(s)) => {
            let (organ, frame, camera) = s.inputs.resolve()?;
            let mut inputs: Vec<&std::path::Path> = vec![&organ, &frame, &camera];
            inputs.extend(s.deformation.as_deref());
            laparo_core::atomic::refuse_overwrite(&s.out, &inputs, true).context("--out")?;
            let mut cfg = if s.quick { ScenarioConfig::quick() } else { ScenarioConfig::full() };
            if let Some(w) = s.width {
                cfg.width = w;
                cfg.height = w * 9 / 16;
            }
            let r = scenario::generate(&organ, &frame, &camera, s.deformation.as_deref(), &cfg, &s.out)?;
            println!(
                "scenario {}: {}x{} px, {} tets / {} nodes, displacement mean {:.2} / max {:.2} mm, liver pixels {:?}, {:.1} s ({})",
                s.out.display(),
                cfg.width,
                cfg.height,
                r.manifest.tet_mesh[0],
                r.manifest.tet_mesh[1],
                r.manifest.displacement_mm[0],
                r.manifest.displacement_mm[1],
                r.liver_pixels,
                r.seconds,
                r.manifest.deformation_source
            );
            Ok(())
        }
        Some(GuideSub::Stereo { scenario, pair, route, out }) => {
            if pair != "past" && pair != "present" {
                bail!("--pair {pair}: expected past or present");
            }
            laparo_core::atomic::refuse_overwrite_in(&out, &["depth_mm.npy", "cloud.ply", "errors.json"], &[&scenario])
                .context("--out")?;
            let route: Route = route.parse()?;
            let man: scenario::Manifest = json_read(&scenario.join("scenario.json"), "stereo")?;
            let calib = laparo_core::StereoCalibration::read(scenario.join("calibration.json"))?;
            let l = laparo_core::io::read_rgb8(scenario.join(format!("{pair}_left.png")))?;
            let r = laparo_core::io::read_rgb8(scenario.join(format!("{pair}_right.png")))?;
            let mask = laparo_core::io::read_mask(scenario.join(format!("{pair}_liver_mask.png")))?;
            std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
            let t0 = std::time::Instant::now();
            let sd = pipeline::stereo_depth(&l, &r, &calib, route, man.depth_prior_mm, &format!("{pair} pair"))?;
            let secs = t0.elapsed().as_secs_f64();
            let gt = laparo_core::io::read_float_map(scenario.join(format!("gt/{pair}_depth_gt_mm.npy")))?;
            let err = pipeline::depth_errors(&sd.depth_mm, &gt, &mask);
            laparo_core::io::write_float_map(out.join("depth_mm.npy"), &sd.depth_mm)?;
            let view = View { k: calib.left, r: nalgebra::Matrix3::identity(), t: nalgebra::Vector3::zeros() };
            let cloud = pipeline::point_cloud(&sd.depth_mm, &mask, &view, 2);
            laparo_core::mesh::write_ply(
                out.join("cloud.ply"),
                &laparo_core::mesh::TriMesh { vertices: cloud, faces: vec![] },
            )?;
            let body =
                serde_json::json!({"depth_error": err, "seconds": secs, "range_px": sd.range_px, "info": sd.info});
            laparo_core::atomic::write_atomic(
                &out.join("errors.json"),
                serde_json::to_string_pretty(&body)?.as_bytes(),
            )?;
            println!("{pair} depth ({route:?}): {err} in {secs:.1} s");
            Ok(())
        }
        Some(GuideSub::Rigid { cloud, model, initial_pose, out }) => {
            laparo_core::atomic::refuse_overwrite_files(&[&out], &[&cloud, &model, &initial_pose]).context("--out")?;
            let c = laparo_core::mesh::read_mesh(&cloud)?;
            let m = laparo_core::mesh::read_mesh(&model)?;
            let init: Pose = json_read(&initial_pose, "rigid")?;
            let r = pipeline::rigid_alignment(
                &m,
                &c.vertices,
                &init,
                &GuideConfig::full(Route::Calibrated),
                &initial_pose.display().to_string(),
            )?;
            laparo_core::atomic::write_atomic(&out, serde_json::to_string_pretty(&r)?.as_bytes())?;
            println!("rigid: ICP RMSE {:.3} mm in {} iterations; wrote {}", r.rmse_mm, r.iterations, out.display());
            Ok(())
        }
        Some(GuideSub::Landmarks { polyline, model, scenario, out }) => {
            laparo_core::atomic::refuse_overwrite_files(
                &[&out],
                &[&polyline, &model, &scenario.join("calibration.json")],
            )
            .context("--out")?;
            let p: Polyline2 = json_read(&polyline, "landmarks")?;
            let calib = laparo_core::StereoCalibration::read(scenario.join("calibration.json"))?;
            let input = polyline.display().to_string();
            pipeline::check_polyline(&p.points_px, calib.width, calib.height, "landmarks", &input)?;
            let m = laparo_core::mesh::read_mesh(&model)?;
            let view = View { k: calib.left, r: nalgebra::Matrix3::identity(), t: nalgebra::Vector3::zeros() };
            let pts = pipeline::back_project_polyline(&p.points_px, &view, &m, "landmarks", &input)?;
            laparo_core::mesh::write_ply(&out, &laparo_core::mesh::TriMesh { vertices: pts.clone(), faces: vec![] })?;
            println!("{} landmarks written to {}", pts.len(), out.display());
            Ok(())
        }
        None => {
            let r = a.run;
            let scenario = r.scenario.context("--scenario is required (make one with `laparo guide scenario`)")?;
            let out = r.out.context("--out is required")?;
            laparo_core::atomic::refuse_overwrite(&out, &[&scenario], true).context("--out")?;
            let route: Route = r.route.parse()?;
            let mut cfg = if r.quick { GuideConfig::quick(route) } else { GuideConfig::full(route) };
            if let Some(i) = r.iterations {
                cfg.iterations = i;
            }
            if let Some(s) = r.spacing_mm {
                cfg.spacing_mm = s;
            }
            cfg.crack_aware = !r.thesis_registration;
            let rep = pipeline::run(&scenario, &out, &cfg, &mut |s| {
                eprintln!("[guide] {} ({:.1} s): {}", s.name, s.seconds, s.metrics);
            })?;
            println!("{}", serde_json::to_string_pretty(&rep.summary)?);
            println!(
                "total {:.1} s, peak {:.0} MiB; report: {}",
                rep.total_seconds,
                rep.peak_memory_mib.unwrap_or(f64::NAN),
                pipeline::report_path(&out).display()
            );
            Ok(())
        }
    }
}
