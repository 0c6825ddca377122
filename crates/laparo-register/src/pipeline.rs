//! The end-to-end registration a user runs (`laparo register`): organ mesh + landmarks + targets →
//! registered particles, deformed meshes, display surface, overlay, report, loss curve. Every output is
//! written atomically; v₀ is checkpointed every few iterations so that an interrupted run resumes.
use crate::error::{RegisterError, Result};
use crate::io::{SourceGroup, TargetSpec};
use crate::loss::{GroupResidual, LandmarkGroup, RegionTerm, RegistrationLoss};
use crate::optimize::{register_sided, IterationRecord, OptimizerConfig};
use crate::organ::{organ_from_mesh, HorizonReport, Organ, OrganConfig};
use crate::surface::{particle_surface, SurfaceConfig};
use crate::transfer::Transfer;
use laparo_core::atomic::write_atomic;
use laparo_core::mesh::TriMesh;
use laparo_mpm::{det, diagnostics, Diagnostics, Vector};
use std::path::{Path, PathBuf};

/// Everything `laparo register` needs.
#[derive(Clone, Debug)]
pub struct Job {
    /// Organ mesh (closed surface or tetrahedral mesh, mm).
    pub organ: PathBuf,
    /// Organ set-up.
    pub organ_config: OrganConfig,
    /// Source landmark groups (mm).
    pub landmarks: Vec<SourceGroup>,
    /// Target per group.
    pub targets: Vec<TargetSpec>,
    /// Weight of the one-sided target→source term for point-cloud / surface targets (0 = off).
    pub region_weight: f64,
    /// Optimiser.
    pub optimizer: OptimizerConfig,
    /// Tumour mesh (mm) to deform.
    pub tumour: Option<PathBuf>,
    /// Image and camera file for the overlay.
    pub overlay: Option<(PathBuf, PathBuf)>,
    /// Output folder.
    pub out: PathBuf,
    /// Resume from `out/checkpoint_v0.json`.
    pub resume: bool,
    /// Checkpoint v₀ every this many iterations.
    pub checkpoint_every: usize,
    /// A crack surface (mm, model frame) to simulate on laparo-mpm's two-field grid, so the lips on either
    /// side can separate (an incision); None: one field, the thesis' RODS-MPM.
    pub crack: Option<crate::crack::CrackSurface>,
    /// Score each landmark at its own material point (its nearest particle plus the rest offset between them,
    /// [`RegistrationLoss::offsets`]) rather than at the particle itself (the thesis). The particles nearest a
    /// surface landmark lie up to half a spacing under the surface, so the thesis' loss pulls them onto the
    /// surface target and is not zero at the true deformation (the benchmark measured 2.5–2.9 mm instead of
    /// 2.0 mm at rest).
    pub landmark_offsets: bool,
}

/// `report.json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    /// Organ file.
    pub organ: String,
    /// Particles.
    pub particles: usize,
    /// Fixed particles (ROI boundary).
    pub fixed_particles: usize,
    /// Spacing (mm).
    pub spacing_mm: f64,
    /// Grid cell (mm).
    pub dx_mm: f64,
    /// Grid nodes per axis.
    pub n_grid: usize,
    /// Δt (s).
    pub dt_s: f64,
    /// T.
    pub steps: usize,
    /// E at the end (kPa).
    pub youngs_modulus_kpa: f64,
    /// ν.
    pub poisson_ratio: f64,
    /// Horizon reach.
    pub horizon: HorizonReport,
    /// Residual per group before.
    pub residual_before: Vec<GroupResidual>,
    /// Residual per group after.
    pub residual_after: Vec<GroupResidual>,
    /// Mean landmark distance before / after (mm).
    pub mean_distance_mm: [f64; 2],
    /// Iterations run (this session).
    pub iterations: usize,
    /// Simulations (forward + backward).
    pub simulations: usize,
    /// Mean wall time per simulation (s).
    pub seconds_per_simulation: f64,
    /// Wall time of the optimisation (s).
    pub optimisation_seconds: f64,
    /// Peak resident memory of the process (MiB), if known.
    pub peak_memory_mib: Option<f64>,
    /// Why the optimiser stopped.
    pub stop_reason: String,
    /// Diagnostics of the final state (energies, momenta, min J).
    pub final_diagnostics: Diagnostics,
    /// Energy audit from v₀ to the final state: KE(0), KE(T), elastic energy at T, dissipated.
    pub energy: crate::optimize::EnergyAudit,
    /// Tumour points outside every complete lattice cell (extrapolated) / in cells straddling a separation.
    pub tumour_flags: Option<[usize; 2]>,
    /// Display-surface size (vertices, faces).
    pub surface: [usize; 2],
    /// Warnings (horizon, sampling).
    pub warnings: Vec<String>,
    /// Files written.
    pub outputs: Vec<String>,
    /// Optimiser settings.
    pub optimizer: OptimizerConfig,
    /// Organ settings.
    pub organ_config: OrganConfig,
    /// Resumed from a checkpoint at this iteration.
    pub resumed_from: Option<usize>,
    /// How the crack surface labelled the particles (two-field grid), if one was given.
    pub crack: Option<crate::crack::CrackLabels>,
}

/// Peak resident set size (VmHWM) in MiB (Linux).
pub fn peak_memory_mib() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let l = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(l.split_whitespace().nth(1)?.parse::<f64>().ok()? / 1024.0)
}

/// Build the registration loss of `groups`/`targets` on `organ` (grid coordinates).
pub fn build_loss(
    organ: &Organ,
    groups: &[SourceGroup],
    targets: &[TargetSpec],
    region_weight: f64,
    input: &str,
) -> Result<RegistrationLoss<3>> {
    if groups.len() != targets.len() {
        return Err(RegisterError::bad(input, format!("{} landmark groups, {} targets", groups.len(), targets.len())));
    }
    let off = organ.offset;
    let sh = |v: &[Vector<3>]| v.iter().map(|p| p + off).collect::<Vec<_>>();
    let mut out = Vec::new();
    let mut region: Option<RegionTerm<3>> = None;
    for (g, t) in groups.iter().zip(targets) {
        let particles = organ.landmark_particles(&g.points, &format!("{input}: group `{}`", g.name))?;
        let target = t.group_target(off);
        if region_weight > 0.0 && region.is_none() {
            if let TargetSpec::Cloud(p) | TargetSpec::Surface(p, _) = t {
                region =
                    Some(RegionTerm { targets: sh(p), particles: surface_particles(organ), weight: region_weight });
            }
        }
        out.push(LandmarkGroup { name: g.name.clone(), particles, target, weight: g.weight });
    }
    let mut loss = RegistrationLoss::new(out);
    loss.region = region;
    Ok(loss)
}

/// The rest offsets of every landmark from the particle `loss` scores it at (mm, per group and landmark, in
/// `groups`' order): the landmark's material point is x_p + o ([`RegistrationLoss::offsets`]).
pub fn landmark_offsets(organ: &Organ, groups: &[SourceGroup], loss: &RegistrationLoss<3>) -> Vec<Vec<Vector<3>>> {
    let x = &organ.scene.positions;
    groups
        .iter()
        .zip(&loss.groups)
        .map(|(g, lg)| g.points.iter().zip(&lg.particles).map(|(q, &p)| q + organ.offset - x[p]).collect())
        .collect()
}

/// Particles with a missing lattice neighbour (the body's surface layer).
pub fn surface_particles(organ: &Organ) -> Vec<usize> {
    let x = &organ.scene.positions;
    let s = organ.spacing_mm;
    let tree = crate::distance::build_tree(x);
    (0..x.len())
        .filter(|&p| {
            let q = [x[p][0], x[p][1], x[p][2]];
            tree.within_unsorted::<kiddo::SquaredEuclidean>(&q, 1.01 * s * s).len() < 7
        })
        .collect()
}

fn write_ply_particles(path: &Path, x: &[Vector<3>], v: &[Vector<3>], j: &[f64]) -> Result<()> {
    Ok(write_atomic(path, &laparo_mpm::render::ply_bytes(x, v, j))?)
}

/// Run a registration job, calling `progress` with every accepted iteration.
pub fn run_job(job: &Job, progress: &mut dyn FnMut(&IterationRecord)) -> Result<Report> {
    if job.resume && matches!(job.optimizer.unknown, crate::optimize::Unknown::Loads { .. }) {
        return Err(RegisterError::bad(
            "resume",
            "a run with loads as the unknown cannot resume (the checkpoint holds v₀): start it again",
        ));
    }
    std::fs::create_dir_all(&job.out)
        .map_err(|e| RegisterError::bad(job.out.display().to_string(), format!("cannot create: {e}")))?;
    let mut organ = organ_from_mesh(&job.organ, &job.organ_config)?;
    let crack = match &job.crack {
        Some(c) => {
            let rest = organ.rest_model();
            Some(crate::crack::label_organ(&mut organ, c, &rest, &rest)?)
        }
        None => None,
    };
    let input = "landmarks";
    let mut loss = build_loss(&organ, &job.landmarks, &job.targets, job.region_weight, input)?;
    if job.landmark_offsets {
        loss.offsets = landmark_offsets(&organ, &job.landmarks, &loss);
    }
    let horizon = organ.horizon(&loss.landmark_particles());
    let mut warnings = organ.warnings.clone();
    if horizon.unreachable_fraction > 0.0 {
        warnings.push(format!(
            "{:.1} % of the particles are farther than the P-wave reach ({:.1} mm in T·Δt = {:.4} s) from every landmark: \
             they cannot move (longer horizon T or a region of interest)",
            100.0 * horizon.unreachable_fraction,
            horizon.p_reach_mm,
            horizon.duration_s
        ));
    }
    let ckpt = job.out.join("checkpoint_v0.json");
    let n = organ.scene.n_particles();
    let mut warm: Option<Vec<Vector<3>>> = None;
    let mut resumed_from = None;
    let mut scene = organ.scene.clone();
    if job.resume && ckpt.exists() {
        let v: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&ckpt)
                .map_err(|e| RegisterError::bad(ckpt.display().to_string(), e.to_string()))?,
        )
        .map_err(|e| RegisterError::bad(ckpt.display().to_string(), e.to_string()))?;
        let flat: Vec<f64> =
            v["v0"].as_array().map(|a| a.iter().filter_map(|x| x.as_f64()).collect()).unwrap_or_default();
        if flat.len() != 3 * n {
            return Err(RegisterError::bad(
                ckpt.display().to_string(),
                format!("{} values for {n} particles (different set-up?)", flat.len()),
            ));
        }
        warm = Some((0..n).map(|p| Vector::<3>::new(flat[3 * p], flat[3 * p + 1], flat[3 * p + 2])).collect());
        if let Some(e) = v["youngs_modulus_kpa"].as_f64() {
            scene.material.youngs_modulus = e;
        }
        resumed_from = v["iteration"].as_u64().map(|i| i as usize);
    }
    let residual_before = loss.residuals(&organ.scene.positions);
    let every = job.checkpoint_every.max(1);
    let mut ck_err: Option<RegisterError> = None;
    let e_now = std::cell::Cell::new(scene.material.youngs_modulus);
    let mut obs = |r: &IterationRecord, v: &[Vector<3>]| {
        progress(r);
        e_now.set(r.youngs_modulus);
        if r.iteration > 0 && r.iteration.is_multiple_of(every) {
            let flat: Vec<f64> = v.iter().flat_map(|x| [x[0], x[1], x[2]]).collect();
            let body = serde_json::json!({"iteration": r.iteration + resumed_from.unwrap_or(0), "loss": r.loss, "youngs_modulus_kpa": r.youngs_modulus, "v0": flat});
            if let Err(e) = write_atomic(&ckpt, body.to_string().as_bytes()) {
                ck_err = Some(e.into());
                return false;
            }
        }
        true
    };
    let t0 = std::time::Instant::now();
    let reg = register_sided(&scene, &loss, &job.optimizer, warm.as_deref(), &organ.smoothing_sides, &mut obs)?;
    if let Some(e) = ck_err {
        return Err(e);
    }
    let secs = t0.elapsed().as_secs_f64();
    let last = reg.history.last().cloned().ok_or_else(|| RegisterError::bad("registration", "no iteration"))?;
    // final checkpoint
    let flat: Vec<f64> = reg.velocities.iter().flat_map(|x| [x[0], x[1], x[2]]).collect();
    let body = serde_json::json!({"iteration": last.iteration + resumed_from.unwrap_or(0), "loss": last.loss, "youngs_modulus_kpa": reg.youngs_modulus, "v0": flat});
    write_atomic(&ckpt, body.to_string().as_bytes())?;
    let mut final_scene = scene.clone();
    final_scene.velocities = reg.velocities.clone();
    final_scene.material.youngs_modulus = reg.youngs_modulus;
    let fin = &reg.final_state;
    let diag = diagnostics(&final_scene, fin);
    let off = organ.offset;
    let model = |v: &[Vector<3>]| v.iter().map(|p| p - off).collect::<Vec<_>>();
    let rest_model = organ.rest_model();
    let def_model = model(&fin.x);
    let mut outputs = Vec::new();
    let mut out = |name: &str| {
        outputs.push(name.to_string());
        job.out.join(name)
    };
    let j: Vec<f64> = fin.f.iter().map(det).collect();
    write_ply_particles(&out("particles_registered.ply"), &def_model, &fin.v, &j)?;
    write_ply_particles(&out("particles_rest.ply"), &rest_model, &reg.velocities, &vec![1.0; n])?;
    if let Some(c) = &job.crack {
        // the crack surface the two-field grid used (given, or assumed from a lip), to look at beside the result
        laparo_core::mesh::write_ply(
            out("crack_surface.ply"),
            &TriMesh { vertices: c.vertices.clone(), faces: c.faces.clone() },
        )?;
    }
    // display surface
    let (sv, sf) = particle_surface(&def_model, organ.spacing_mm, &SurfaceConfig::default())?;
    let surface_mesh = TriMesh { vertices: sv.clone(), faces: sf.clone() };
    laparo_core::mesh::write_ply(out("surface_registered.ply"), &surface_mesh)?;
    // deformation transfer: the source surface (when the organ is a surface mesh) and the tumour
    let transfer = Transfer::new(&rest_model, organ.spacing_mm)?;
    let deform = |m: &TriMesh| -> Result<(TriMesh, [usize; 2])> {
        let mut flags = [0usize; 2];
        let mut verts = Vec::with_capacity(m.vertices.len());
        for v in &m.vertices {
            let t = transfer.apply(v, &def_model)?;
            flags[0] += t.extrapolated as usize;
            flags[1] += t.straddles as usize;
            verts.push(t.position);
        }
        Ok((TriMesh { vertices: verts, faces: m.faces.clone() }, flags))
    };
    let ext = crate::io_ext(&job.organ);
    if ext != "msh" && ext != "vtk" {
        let src = laparo_core::mesh::read_mesh(&job.organ)?;
        let (d, _) = deform(&src)?;
        laparo_core::mesh::write_obj(out("organ_deformed.obj"), &d)?;
    }
    let mut tumour_flags = None;
    let mut tumour_def = None;
    if let Some(tp) = &job.tumour {
        let t = laparo_core::mesh::read_mesh(tp)?;
        let (d, flags) = deform(&t)?;
        laparo_core::mesh::write_obj(out("tumour_deformed.obj"), &d)?;
        tumour_flags = Some(flags);
        tumour_def = Some(d);
    }
    // overlay
    if let Some((img_path, cam_path)) = &job.overlay {
        let img = laparo_core::io::read_rgb8(img_path)?;
        let cam = laparo_core::io::read_camera(cam_path)?;
        let k = cam.intrinsics(Some((img.width, img.height)))?;
        let pose = crate::overlay::CameraPose::framing(&rest_model, &k, 0.6);
        let mut layers = vec![crate::overlay::Layer { vertices: &sv, faces: &sf, color: [90, 200, 255], alpha: 0.45 }];
        if let Some(t) = &tumour_def {
            layers.push(crate::overlay::Layer {
                vertices: &t.vertices,
                faces: &t.faces,
                color: [255, 220, 0],
                alpha: 0.8,
            });
        }
        let o = crate::overlay::render_overlay(&img, &layers, &pose, &k, &cam.distortion);
        laparo_core::io::write_png(out("overlay.png"), &o)?;
    }
    // loss curve
    let mut csv = String::from("iteration,loss,mean_distance_mm,youngs_modulus_kpa,step_mm,simulations,seconds\n");
    for r in &reg.history {
        csv.push_str(&format!(
            "{},{:.9e},{:.9e},{:.6},{:.6e},{},{:.3}\n",
            r.iteration, r.loss, r.mean_distance, r.youngs_modulus, r.step, r.evaluations, r.seconds
        ));
    }
    write_atomic(&out("loss.csv"), csv.as_bytes())?;
    let losses: Vec<f64> = reg.history.iter().map(|r| r.mean_distance.max(1e-12)).collect();
    let lp = out("loss.png");
    laparo_core::atomic::write_atomic_with(&lp, |tmp| {
        laparo_mpm::render::plot_loss_curve(&tmp.with_extension("png"), &losses, "mean landmark distance (mm)")?;
        std::fs::rename(tmp.with_extension("png"), tmp).map_err(|e| laparo_core::CoreError::io(tmp, e))
    })?;
    let report = Report {
        organ: job.organ.display().to_string(),
        particles: n,
        fixed_particles: organ.fixed_count,
        spacing_mm: organ.spacing_mm,
        dx_mm: organ.scene.grid.dx,
        n_grid: organ.scene.grid.n_grid,
        dt_s: organ.scene.dt,
        steps: organ.scene.steps,
        youngs_modulus_kpa: reg.youngs_modulus,
        poisson_ratio: organ.scene.material.poisson_ratio,
        horizon,
        residual_before,
        residual_after: loss.residuals(&fin.x),
        mean_distance_mm: [reg.history[0].mean_distance, last.mean_distance],
        iterations: last.iteration,
        simulations: last.evaluations,
        seconds_per_simulation: secs / last.evaluations.max(1) as f64,
        optimisation_seconds: secs,
        peak_memory_mib: peak_memory_mib(),
        stop_reason: reg.stop_reason.clone(),
        final_diagnostics: diag,
        energy: reg.energy,
        tumour_flags,
        surface: [sv.len(), sf.len()],
        warnings,
        outputs: outputs.clone(),
        optimizer: job.optimizer.clone(),
        organ_config: job.organ_config.clone(),
        resumed_from,
        crack,
    };
    let text = serde_json::to_string_pretty(&report).map_err(|e| RegisterError::bad("report.json", e.to_string()))?;
    write_atomic(&job.out.join("report.json"), text.as_bytes())?;
    Ok(report)
}
