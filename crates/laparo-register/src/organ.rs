//! Organ → particles in physical units, region of interest, horizon reach, source landmarks.
//!
//! **Units.** Inputs are explicit: lengths in mm, E in kPa, density in kg/m³, time in s. The engine
//! runs in the consistent system (mm, s, kg): stress kg/(mm·s²) = 1 kPa (so E in kPa is used as is),
//! density kg/mm³ = 10⁻⁹ × kg/m³, velocities mm/s, wave speeds mm/s. Grid cell Δx = 2 × spacing by
//! default (two particles per cell per axis, as DiffTaichi's RODS set-up).
use crate::distance::{build_tree, ClosestPoint, PointCloud};
use crate::error::{RegisterError, Result};
use kiddo::SquaredEuclidean;
use laparo_mpm::sampling::{check_closed, read_surface_mesh, read_tet_mesh, sample_tet_mesh, voxelize};
use laparo_mpm::{cfl_dt, GridSpec, Material, Model, Scene, Vector};
use std::path::Path;

/// Checkpoint memory of the adjoint per particle and step (bytes): the particle state x, v, C, F in
/// f64 (3 + 3 + 9 + 9 doubles) plus its share of the grid checkpoint (laparo-mpm README: ≈ 46 KB per
/// particle at T = 200).
pub const CHECKPOINT_BYTES_PER_PARTICLE_STEP: f64 = 230.0;

/// Region of interest (model coordinates, mm).
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Roi {
    /// Ball.
    Ball {
        /// Centre (mm).
        center: [f64; 3],
        /// Radius (mm).
        radius_mm: f64,
    },
    /// Axis-aligned box.
    Box {
        /// Low corner (mm).
        lo: [f64; 3],
        /// High corner (mm).
        hi: [f64; 3],
    },
}

impl Roi {
    /// Whether `p` (mm) lies in the region (on its boundary included).
    pub fn inside(&self, p: &Vector<3>) -> bool {
        self.depth(p) >= 0.0
    }
    /// Distance inside the ROI boundary (negative outside).
    pub(crate) fn depth(&self, p: &Vector<3>) -> f64 {
        match self {
            Roi::Ball { center, radius_mm } => radius_mm - (p - Vector::<3>::from(*center)).norm(),
            Roi::Box { lo, hi } => (0..3).map(|d| (p[d] - lo[d]).min(hi[d] - p[d])).fold(f64::INFINITY, f64::min),
        }
    }
}

/// Physical set-up of an organ simulation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OrganConfig {
    /// Particle spacing (mm).
    pub spacing_mm: f64,
    /// Grid cell Δx (mm); None = 2 × spacing.
    pub dx_mm: Option<f64>,
    /// Young's modulus (kPa); thesis 4.1.
    pub youngs_modulus_kpa: f64,
    /// Poisson's ratio; thesis 0.49.
    pub poisson_ratio: f64,
    /// Density (kg/m³).
    pub density_kg_m3: f64,
    /// Horizon T (steps); thesis 200.
    pub steps: usize,
    /// Time step (s); None = CFL with `cfl_safety`.
    pub dt_s: Option<f64>,
    /// CFL safety factor c Δt / Δx of the default Δt.
    pub cfl_safety: f64,
    /// Largest accepted CFL number c Δt / Δx (an explicit Δt above it is refused).
    pub cfl_limit: f64,
    /// Region of interest (boundary particles fixed).
    pub roi: Option<Roi>,
    /// Memory available for the adjoint checkpoints (bytes); None = MemAvailable of /proc/meminfo.
    pub memory_limit_bytes: Option<f64>,
}

impl Default for OrganConfig {
    fn default() -> Self {
        OrganConfig {
            spacing_mm: 3.0,
            dx_mm: None,
            youngs_modulus_kpa: 4.1,
            poisson_ratio: 0.49,
            density_kg_m3: 1000.0,
            steps: 200,
            dt_s: None,
            cfl_safety: 0.3,
            cfl_limit: 0.5,
            roi: None,
            memory_limit_bytes: None,
        }
    }
}

/// Horizon reach (register.md pitfall 3): how far information travels in T·Δt.
#[derive(Clone, Debug, serde::Serialize)]
pub struct HorizonReport {
    /// P-wave speed (mm/s).
    pub p_wave_speed_mm_s: f64,
    /// Shear-wave speed (mm/s).
    pub shear_wave_speed_mm_s: f64,
    /// T·Δt (s).
    pub duration_s: f64,
    /// Distance a P wave travels in T·Δt (mm).
    pub p_reach_mm: f64,
    /// Distance a shear wave travels in T·Δt (mm).
    pub shear_reach_mm: f64,
    /// Largest distance of a particle from its nearest landmark (mm).
    pub farthest_from_landmarks_mm: f64,
    /// Fraction of particles farther than the P-wave reach from every landmark (they cannot move).
    pub unreachable_fraction: f64,
    /// Fraction farther than the shear reach.
    pub beyond_shear_fraction: f64,
}

/// An organ sampled into particles, ready to register.
#[derive(Clone, Debug)]
pub struct Organ {
    /// The simulation scene (engine units: mm, s, kg; grid coordinates).
    pub scene: Scene<3>,
    /// Grid coordinates = model coordinates (mm) + offset.
    pub offset: Vector<3>,
    /// Particle spacing (mm).
    pub spacing_mm: f64,
    /// Particles fixed on the ROI boundary.
    pub fixed_count: usize,
    /// Non-fatal findings.
    pub warnings: Vec<String>,
    /// Side of a crack Σ for the side-aware preconditioner, unbounded (±1 wherever the particle's closest
    /// point on Σ is interior, 0 beyond the crack front; the grid's `scene.crack_side` is only the band near
    /// Σ); empty without a crack. Set by [`crate::crack::label_organ`].
    pub smoothing_sides: Vec<i8>,
}

impl Organ {
    /// Rest particle positions in model coordinates (mm).
    pub fn rest_model(&self) -> Vec<Vector<3>> {
        self.scene.positions.iter().map(|p| p - self.offset).collect()
    }
    /// Source landmark particles: the nearest particle to each annotated point (model mm). A point
    /// farther than one grid cell from every particle is outside the body: an error naming it.
    pub fn landmark_particles(&self, points_mm: &[Vector<3>], input: &str) -> Result<Vec<usize>> {
        let cloud = PointCloud::new(self.scene.positions.clone());
        points_mm
            .iter()
            .enumerate()
            .map(|(k, q)| {
                let g = q + self.offset;
                let (c, i) = cloud.closest(&g);
                let d = (c - g).norm();
                if d > self.scene.grid.dx {
                    Err(RegisterError::bad(
                        input,
                        format!(
                            "landmark {k} at ({:.2}, {:.2}, {:.2}) mm is {d:.2} mm from the nearest particle (> Δx = {:.2} mm): \
                             outside the body or the region of interest",
                            q[0], q[1], q[2], self.scene.grid.dx
                        ),
                    ))
                } else {
                    Ok(i)
                }
            })
            .collect()
    }
    /// Horizon reach given the landmark particles.
    pub fn horizon(&self, landmarks: &[usize]) -> HorizonReport {
        let m = &self.scene.material;
        let (mu, _) = m.lame();
        let cp = m.p_wave_speed();
        let cs = (mu / m.density).sqrt();
        let t = self.scene.steps as f64 * self.scene.dt;
        let (lp, ls) = (cp * t, cs * t);
        let lm: Vec<Vector<3>> = landmarks.iter().map(|&p| self.scene.positions[p]).collect();
        let (mut far, mut unreach, mut beyond) = (0.0f64, 0usize, 0usize);
        if !lm.is_empty() {
            let tree = build_tree(&lm);
            for p in &self.scene.positions {
                let d = tree.nearest_one::<SquaredEuclidean>(&[p[0], p[1], p[2]]).distance.sqrt();
                far = far.max(d);
                unreach += (d > lp) as usize;
                beyond += (d > ls) as usize;
            }
        }
        let n = self.scene.n_particles().max(1) as f64;
        HorizonReport {
            p_wave_speed_mm_s: cp,
            shear_wave_speed_mm_s: cs,
            duration_s: t,
            p_reach_mm: lp,
            shear_reach_mm: ls,
            farthest_from_landmarks_mm: far,
            unreachable_fraction: unreach as f64 / n,
            beyond_shear_fraction: beyond as f64 / n,
        }
    }
}

impl OrganConfig {
    /// The Neo-Hookean material of this set-up (density in kg/mm³, E in kPa: the solver's units).
    fn material(&self) -> Material {
        Material {
            model: Model::NeoHookean,
            youngs_modulus: self.youngs_modulus_kpa,
            poisson_ratio: self.poisson_ratio,
            density: self.density_kg_m3 * 1e-9,
        }
    }

    /// The time step Δt (s) the simulation uses: `dt_s` when given (refused above `cfl_limit`), else
    /// `cfl_safety` Δx / c with c the P-wave speed.
    pub fn time_step_s(&self) -> Result<f64> {
        let dx = check_config(self)?;
        let material = self.material();
        material.validate()?;
        match self.dt_s {
            Some(dt) => {
                let c = material.p_wave_speed() * dt / dx;
                if !(dt > 0.0) || c > self.cfl_limit {
                    return Err(RegisterError::param(
                        "dt_s",
                        dt,
                        format!(
                            "CFL violated: c Δt / Δx = {c:.3} > {} (c = {:.0} mm/s, Δx = {dx} mm)",
                            self.cfl_limit,
                            material.p_wave_speed()
                        ),
                    ));
                }
                Ok(dt)
            }
            None => Ok(cfl_dt(&material, dx, self.cfl_safety)),
        }
    }
}

fn available_memory() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

fn check_config(cfg: &OrganConfig) -> Result<f64> {
    let pos = |name: &str, v: f64| {
        if v > 0.0 && v.is_finite() {
            Ok(())
        } else {
            Err(RegisterError::param(name, v, "must be finite and > 0"))
        }
    };
    pos("spacing_mm", cfg.spacing_mm)?;
    pos("youngs_modulus_kpa", cfg.youngs_modulus_kpa)?;
    pos("density_kg_m3", cfg.density_kg_m3)?;
    pos("cfl_safety", cfg.cfl_safety)?;
    if !(cfg.poisson_ratio > -1.0 && cfg.poisson_ratio < 0.5) {
        return Err(RegisterError::param("poisson_ratio", cfg.poisson_ratio, "must be in (-1, 0.5)"));
    }
    if cfg.steps == 0 {
        return Err(RegisterError::param("steps", 0.0, "must be >= 1"));
    }
    let dx = cfg.dx_mm.unwrap_or(2.0 * cfg.spacing_mm);
    pos("dx_mm", dx)?;
    if dx < cfg.spacing_mm {
        return Err(RegisterError::param("dx_mm", dx, "grid cell smaller than the particle spacing"));
    }
    Ok(dx)
}

/// The organ's closed surface (mm): the file itself for a surface mesh, the boundary of a tetrahedral one
/// (`.msh`/`.vtk`).
pub fn organ_surface(path: &Path) -> Result<laparo_core::mesh::TriMesh> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext == "msh" || ext == "vtk" {
        Ok(read_tet_mesh(path)?.boundary())
    } else {
        Ok(read_surface_mesh(path)?)
    }
}

/// Sample a mesh file into an organ: a closed OBJ/PLY/STL surface (voxelised) or a Gmsh/VTK tetrahedral
/// mesh (filled at the spacing). Errors name the file (non-closed surface, empty mesh) or the parameter
/// (memory above the limit, CFL).
pub fn organ_from_mesh(path: &Path, cfg: &OrganConfig) -> Result<Organ> {
    let dx = check_config(cfg)?;
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let limit = cfg.memory_limit_bytes.or_else(available_memory).unwrap_or(f64::INFINITY);
    // a first check from the volume, before sampling (the exact one is in `organ_from_points`)
    let budget = |volume: f64| -> Result<()> {
        let n = volume / cfg.spacing_mm.powi(3);
        checkpoint_segment(n as usize, cfg, limit, &path.display().to_string()).map(|_| ())
    };
    let points = if ext == "msh" || ext == "vtk" {
        let mesh = read_tet_mesh(path)?;
        if cfg.roi.is_none() {
            budget(mesh.volume())?;
        }
        sample_tet_mesh(&mesh, cfg.spacing_mm)?
    } else {
        let mesh = read_surface_mesh(path)?;
        check_closed(&mesh, path)?;
        if cfg.roi.is_none() {
            budget(mesh.signed_volume().abs())?;
        }
        voxelize(&mesh, cfg.spacing_mm)
    };
    if points.is_empty() {
        return Err(RegisterError::bad(
            path.display().to_string(),
            format!("no particle at spacing {} mm", cfg.spacing_mm),
        ));
    }
    let _ = dx;
    organ_from_points(points, cfg, &path.display().to_string())
}

/// The adjoint checkpoint segment (`Scene::checkpoint_segment`) for `n` particles within `limit` bytes: 0 when
/// every step fits; an error naming `--spacing-mm` when even segments of ≈ √T steps do not.
fn checkpoint_segment(n: usize, cfg: &OrganConfig, limit: f64, input: &str) -> Result<usize> {
    laparo_mpm::checkpoint_segment_for(n, cfg.steps, CHECKPOINT_BYTES_PER_PARTICLE_STEP, limit).ok_or_else(|| {
        let full = n as f64 * cfg.steps as f64 * CHECKPOINT_BYTES_PER_PARTICLE_STEP;
        RegisterError::param(
            "spacing_mm",
            cfg.spacing_mm,
            format!(
                "{input}: ≈{n} particles need ≈{:.1} GB of adjoint checkpoints at T = {} (≈{:.1} GB with segments of √T steps; available {:.1} GB): coarser spacing, fewer steps or a region of interest",
                full / 1e9,
                cfg.steps,
                full * 2.0 / (cfg.steps as f64).sqrt() / 1e9,
                limit / 1e9
            ),
        )
    })
}

/// An organ from particle positions already sampled at `cfg.spacing_mm` (model mm).
pub fn organ_from_points(mut points: Vec<Vector<3>>, cfg: &OrganConfig, input: &str) -> Result<Organ> {
    let dx = check_config(cfg)?;
    let mut warnings = Vec::new();
    if let Some(roi) = &cfg.roi {
        points.retain(|p| roi.inside(p));
        if points.is_empty() {
            return Err(RegisterError::bad(input, "the region of interest contains no particle of the organ"));
        }
    }
    let limit = cfg.memory_limit_bytes.or_else(available_memory).unwrap_or(f64::INFINITY);
    let segment = checkpoint_segment(points.len(), cfg, limit, input)?;
    if segment > 0 {
        warnings.push(format!(
            "{} particles × T {} exceed the adjoint memory ({:.1} GB): checkpoints every {segment} steps, each segment recomputed in the reverse pass (same gradient, one more forward pass)",
            points.len(),
            cfg.steps,
            limit / 1e9
        ));
    }
    let mut lo = points[0];
    let mut hi = points[0];
    for p in &points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    // margin: 3 wall cells + 6 free cells around the body
    let margin = 9.0 * dx;
    let extent = (hi - lo).max() + 2.0 * margin;
    let n_grid = (extent / dx).ceil() as usize + 1;
    let offset = Vector::<3>::repeat(margin) - lo;
    let positions: Vec<Vector<3>> = points.iter().map(|p| p + offset).collect();
    let dt = cfg.time_step_s()?; // validates the material
    let material = cfg.material();
    let grid = GridSpec { n_grid, dx };
    let vol = cfg.spacing_mm.powi(3);
    let mut scene = Scene::new(positions, vol, material, grid, dt, cfg.steps);
    scene.cfl_limit = cfg.cfl_limit;
    scene.checkpoint_segment = segment;
    let mut fixed_count = 0;
    if let Some(roi) = &cfg.roi {
        scene.fixed = points.iter().map(|p| roi.depth(p) < dx).collect();
        fixed_count = scene.fixed.iter().filter(|&&f| f).count();
        if fixed_count == points.len() {
            return Err(RegisterError::bad(
                input,
                "every particle of the region of interest is on its boundary (ROI too small)",
            ));
        }
    }
    if (dx / cfg.spacing_mm).powi(3) < 2.0 {
        warnings.push(format!("fewer than 2 particles per cell (Δx {dx} mm, spacing {} mm)", cfg.spacing_mm));
    }
    scene.validate()?;
    Ok(Organ { scene, offset, spacing_mm: cfg.spacing_mm, fixed_count, warnings, smoothing_sides: Vec::new() })
}
