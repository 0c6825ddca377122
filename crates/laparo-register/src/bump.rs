//! "Beyond incisions" (issue 47): a smooth analytic deformation of an organ — a Gaussian bump pushed into its
//! broadest face — seen only through landmarks along one surface curve. Does RODS-MPM recover the bump, and
//! does it move the tissue no landmark sees? `laparo register bump` runs it for each unknown (v₀, the thesis;
//! loads, rung L3) and scores the whole surface against the analytic field.
use crate::benchmark::Stats;
use crate::distance::{ClosestPoint, Polyline};
use crate::error::{RegisterError, Result};
use crate::io::{SourceGroup, TargetSpec};
use crate::optimize::{register_sided, EnergyAudit, OptimizerConfig};
use crate::organ::{organ_from_mesh, OrganConfig};
use crate::pipeline::{build_loss, landmark_offsets};
use crate::transfer::Transfer;
use laparo_core::mesh::TriMesh;
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

type V3 = Vector3<f64>;

/// The bump and its landmark curve.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct BumpConfig {
    /// Peak displacement (mm), into the organ along the surface normal at the centre.
    pub amplitude_mm: f64,
    /// Gaussian width σ (mm).
    pub sigma_mm: f64,
    /// Landmarks along the curve.
    pub landmarks: usize,
}

impl Default for BumpConfig {
    fn default() -> Self {
        BumpConfig { amplitude_mm: 9.0, sigma_mm: 45.0, landmarks: 30 }
    }
}

/// A bump case on one organ surface (mm, model frame).
#[derive(Clone, Debug, serde::Serialize)]
pub struct BumpCase {
    /// Centre c of the bump: the surface vertex farthest along the organ's thinnest principal axis (its
    /// broadest face; the axis signed so that its largest component is positive).
    pub centre: V3,
    /// Unit direction of the displacement: the inward surface normal at c.
    pub direction: V3,
    /// Peak displacement (mm).
    pub amplitude_mm: f64,
    /// σ (mm).
    pub sigma_mm: f64,
    /// Source landmarks: the curve where the plane through c normal to the organ's longest axis meets the
    /// broad face within 2σ of c (the polyline through the crossings of the surface's triangle edges), sampled
    /// evenly by arc length.
    pub landmarks: Vec<V3>,
    /// Their displaced positions, the target polyline (the curve after the bump).
    pub target: Vec<V3>,
}

impl BumpCase {
    /// u(x) = A exp(−|x − c|² / (2σ²)) d: the analytic displacement (mm).
    pub fn displacement(&self, x: &V3) -> V3 {
        let r2 = (x - self.centre).norm_squared();
        self.direction * self.amplitude_mm * (-r2 / (2.0 * self.sigma_mm * self.sigma_mm)).exp()
    }

    /// The case on `surface` (a closed organ surface, mm). Errors name the parameter or the surface.
    pub fn new(surface: &TriMesh, cfg: &BumpConfig) -> Result<Self> {
        for (name, v) in [("amplitude_mm", cfg.amplitude_mm), ("sigma_mm", cfg.sigma_mm)] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(RegisterError::param(name, v, "must be finite and > 0"));
            }
        }
        if cfg.landmarks < 2 {
            return Err(RegisterError::param("landmarks", cfg.landmarks as f64, "at least 2"));
        }
        let n = surface.vertices.len();
        if n < 4 || surface.faces.is_empty() {
            return Err(RegisterError::bad("organ surface", "fewer than 4 vertices or no triangle"));
        }
        let mean = surface.vertices.iter().sum::<V3>() / n as f64;
        let cov =
            surface.vertices.iter().fold(Matrix3::zeros(), |a, v| a + (v - mean) * (v - mean).transpose()) / n as f64;
        let eig = nalgebra::SymmetricEigen::new(cov);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        // eigenvectors have no sign: take the one whose largest component is positive (deterministic)
        let signed = |v: V3| if v[v.iamax()] < 0.0 { -v } else { v };
        let thin: V3 = signed(eig.eigenvectors.column(order[0]).into());
        let long: V3 = eig.eigenvectors.column(order[2]).into();
        let centre = *surface
            .vertices
            .iter()
            .max_by(|a, b| (*a - mean).dot(&thin).total_cmp(&(*b - mean).dot(&thin)))
            .ok_or_else(|| RegisterError::bad("organ surface", "no vertex"))?;
        let outward = crate::crack::outward_normals(surface, &[centre], 10.0)[0];
        let direction = -outward;
        // the curve: vertices in the slab about the plane through c normal to the long axis, on the broad face
        let along = outward.cross(&long).try_normalize(1e-9).ok_or_else(|| {
            RegisterError::bad("organ surface", "the surface normal at the bump centre is parallel to its long axis")
        })?;
        let sigma = cfg.sigma_mm;
        // points of the surface on the plane: where triangle edges cross it (exactly on the surface, whatever
        // the triangulation's density), on the broad face and within 2σ of c
        let mut cand: Vec<(f64, V3)> = Vec::new();
        for f in &surface.faces {
            for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                let (a, b) = (surface.vertices[f[i]], surface.vertices[f[j]]);
                let (sa, sb) = ((a - centre).dot(&long), (b - centre).dot(&long));
                let x = if sa == 0.0 {
                    Some(a) // a vertex on the plane
                } else if sa * sb < 0.0 {
                    Some(a + (b - a) * (sa / (sa - sb)))
                } else {
                    None
                };
                if let Some(x) = x {
                    let d = x - centre;
                    if d.norm() <= 2.0 * sigma && d.dot(&outward) > -sigma / 3.0 {
                        cand.push((d.dot(&along), x));
                    }
                }
            }
        }
        // the crossings in order along the curve, then `landmarks` points evenly spaced by arc length on the
        // polyline through them (chords of the surface's triangles)
        cand.sort_by(|a, b| a.0.total_cmp(&b.0));
        cand.dedup_by(|a, b| (a.1 - b.1).norm() < 1e-9);
        let mut arc = vec![0.0];
        for w in cand.windows(2) {
            arc.push(arc.last().copied().unwrap_or(0.0) + (w[1].1 - w[0].1).norm());
        }
        let length = arc.last().copied().unwrap_or(0.0);
        let mut landmarks: Vec<V3> = Vec::with_capacity(cfg.landmarks);
        if cand.len() >= 2 && length > 0.0 {
            let mut j = 0;
            for k in 0..cfg.landmarks {
                let s = length * (k as f64 + 0.5) / cfg.landmarks as f64;
                while j + 2 < arc.len() && arc[j + 1] < s {
                    j += 1;
                }
                let f = ((s - arc[j]) / (arc[j + 1] - arc[j]).max(1e-300)).clamp(0.0, 1.0);
                landmarks.push(cand[j].1 + (cand[j + 1].1 - cand[j].1) * f);
            }
        }
        if landmarks.len() < (cfg.landmarks / 2).max(2) {
            return Err(RegisterError::bad(
                "organ surface",
                format!(
                    "{} surface crossings along the bump's curve: the plane through its centre barely meets the surface",
                    cand.len()
                ),
            ));
        }
        let mut case = BumpCase {
            centre,
            direction,
            amplitude_mm: cfg.amplitude_mm,
            sigma_mm: sigma,
            landmarks,
            target: Vec::new(),
        };
        case.target = case.landmarks.iter().map(|x| x + case.displacement(x)).collect();
        Ok(case)
    }
}

/// One registration of a bump case, scored against the analytic field at the surface vertices.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BumpRun {
    /// The unknown (`velocity` or `loads`).
    pub unknown: String,
    /// |x_registered − (x + u(x))| over every surface vertex (mm).
    pub surface_error_mm: Stats,
    /// The same for no registration, |u(x)| (mm).
    pub surface_error_none_mm: Stats,
    /// Surface vertices farther than 2σ from the bump's centre: how far the registration moved them (mm).
    pub far_motion_mm: Stats,
    /// … and their error against the analytic field (which moves them by at most A e⁻² there).
    pub far_error_mm: Stats,
    /// Landmarks' distance to the target curve, each carried by the deformed *mesh* (the surface transfer).
    pub landmark_to_curve_mesh_mm: Stats,
    /// … carried by their nearest particles instead (what the loss sees with the thesis' scoring).
    pub landmark_to_curve_particles_mm: Stats,
    /// Eq. 5.10 before and after (landmarks at their material points).
    pub loss_mm: [f64; 2],
    /// Iterations, particles, seconds.
    pub iterations: usize,
    /// Particles simulated.
    pub particles: usize,
    /// Wall time of the optimisation (s).
    pub seconds: f64,
    /// Energy audit of the registered run.
    pub energy: EnergyAudit,
}

fn stats(v: impl Iterator<Item = f64>) -> Stats {
    Stats::of(&v.collect::<Vec<_>>())
}

/// Register the bump `case` on the organ `organ_path` (closed surface `surface`, mm) with `organ_cfg` and
/// `opt` (its `unknown` chooses the rung); returns the scores and the registered surface (model frame).
pub fn run_bump(
    organ_path: &Path,
    surface: &TriMesh,
    case: &BumpCase,
    organ_cfg: &OrganConfig,
    opt: &OptimizerConfig,
) -> Result<(BumpRun, TriMesh)> {
    let organ = organ_from_mesh(organ_path, organ_cfg)?;
    let groups = vec![SourceGroup { name: "curve".into(), points: case.landmarks.clone(), weight: 1.0 }];
    let targets = vec![TargetSpec::Polyline(case.target.clone())];
    let mut loss = build_loss(&organ, &groups, &targets, 0.0, "bump landmarks")?;
    loss.offsets = landmark_offsets(&organ, &groups, &loss);
    let before = loss.mean_distance(&organ.scene.positions);
    let t0 = std::time::Instant::now();
    let reg = register_sided(&organ.scene, &loss, opt, None, &[], &mut |_, _| true)?;
    let seconds = t0.elapsed().as_secs_f64();
    let after = loss.mean_distance(&reg.final_state.x);
    let off = organ.offset;
    let rest = organ.rest_model();
    let def: Vec<V3> = reg.final_state.x.iter().map(|p| p - off).collect();
    let transfer = Transfer::new(&rest, organ.spacing_mm)?;
    let moved = |x: &V3| -> Result<V3> { Ok(transfer.apply(x, &def)?.position) };
    let registered: Vec<V3> = surface.vertices.iter().map(moved).collect::<Result<_>>()?;
    let truth: Vec<V3> = surface.vertices.iter().map(|x| x + case.displacement(x)).collect();
    let far: Vec<usize> = (0..surface.vertices.len())
        .filter(|&k| (surface.vertices[k] - case.centre).norm() > 2.0 * case.sigma_mm)
        .collect();
    let curve = Polyline::open(case.target.clone());
    let lm_mesh: Vec<f64> =
        case.landmarks.iter().map(|x| moved(x).map(|p| curve.distance(&p))).collect::<Result<_>>()?;
    let lm_part: Vec<f64> = loss.groups[0].particles.iter().map(|&p| curve.distance(&def[p])).collect();
    let run = BumpRun {
        unknown: opt.unknown.name().into(),
        surface_error_mm: stats(registered.iter().zip(&truth).map(|(a, b)| (a - b).norm())),
        surface_error_none_mm: stats(surface.vertices.iter().zip(&truth).map(|(a, b)| (a - b).norm())),
        far_motion_mm: stats(far.iter().map(|&k| (registered[k] - surface.vertices[k]).norm())),
        far_error_mm: stats(far.iter().map(|&k| (registered[k] - truth[k]).norm())),
        landmark_to_curve_mesh_mm: stats(lm_mesh.into_iter()),
        landmark_to_curve_particles_mm: stats(lm_part.into_iter()),
        loss_mm: [before, after],
        iterations: reg.history.last().map(|r| r.iteration).unwrap_or(0),
        particles: organ.scene.n_particles(),
        seconds,
        energy: reg.energy,
    };
    Ok((run, TriMesh { vertices: registered, faces: surface.faces.clone() }))
}
