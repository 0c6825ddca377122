//! Scene description files (TOML) for `laparo mpm simulate`; see the crate README for the format.
//!
//! Every number is checked (finite, positive where required, in range) and the memory of the
//! simulation is estimated before particles are sampled, so absurd files fail with an error naming
//! the parameter instead of exhausting memory or time.
use crate::budget::{estimate_memory_bytes, DEFAULT_MEMORY_LIMIT_BYTES};
use crate::error::{MpmError, Warning};
use crate::grid_spec::GridSpec;
use crate::linalg::Vector;
use crate::sampling;
use crate::scene::{box_lattice, ellipsoid_lattice, Boundary, Material, Scene, WallKind};
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    dim: usize,
    grid: GridSpec,
    material: Material,
    time: TimeFile,
    #[serde(default)]
    boundary: Option<BoundaryFile>,
    #[serde(default)]
    gravity: Option<Vec<f64>>,
    #[serde(default)]
    mass_epsilon: Option<f64>,
    #[serde(rename = "body")]
    bodies: Vec<BodyFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TimeFile {
    steps: usize,
    #[serde(default)]
    dt: Option<f64>,
    #[serde(default)]
    cfl_safety: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoundaryFile {
    walls: WallKind,
    #[serde(default = "three")]
    thickness: usize,
}
fn three() -> usize {
    3
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BodyFile {
    /// box | ellipsoid | mesh (closed surface, voxelised) | tet_mesh (tetrahedra filled at `spacing`)
    shape: String,
    #[serde(default)]
    lo: Option<Vec<f64>>,
    #[serde(default)]
    hi: Option<Vec<f64>>,
    #[serde(default)]
    center: Option<Vec<f64>>,
    #[serde(default)]
    radii: Option<Vec<f64>>,
    #[serde(default)]
    path: Option<String>,
    #[serde(default)]
    scale: Option<f64>,
    #[serde(default)]
    offset: Option<Vec<f64>>,
    #[serde(default)]
    spacing: Option<f64>,
    #[serde(default)]
    velocity: Option<Vec<f64>>,
    #[serde(default)]
    stretch_rate: Option<Vec<f64>>,
    #[serde(default)]
    fixed: bool,
    #[serde(default)]
    force_density: Option<Vec<f64>>,
}

/// A scene loaded from a file, 2D or 3D.
pub enum LoadedScene {
    /// 2D scene.
    D2(Scene<2>),
    /// 3D scene.
    D3(Scene<3>),
}

/// Limits of [`load_scene_file_with`].
#[derive(Clone, Copy, Debug)]
pub struct LoadOptions {
    /// Refuse scenes whose estimated simulation memory ([`crate::estimate_memory_bytes`]) exceeds
    /// this many bytes.
    pub max_memory_bytes: u64,
    /// Refuse mesh bodies whose sampling would examine more lattice points than this (time bound).
    pub max_scan_points: f64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions { max_memory_bytes: DEFAULT_MEMORY_LIMIT_BYTES, max_scan_points: 4e9 }
    }
}

/// Fewer particles per grid cell than this draw a [`Warning::SparseParticles`].
pub const MIN_PARTICLES_PER_CELL: f64 = 2.0;

fn bad(path: &Path, msg: impl Into<String>) -> MpmError {
    MpmError::InvalidScene(format!("{}: {}", path.display(), msg.into()))
}

/// `v` as a D-vector of finite numbers.
fn vec_of<const D: usize>(path: &Path, name: &str, v: &Option<Vec<f64>>) -> Result<Option<Vector<D>>, MpmError> {
    match v {
        None => Ok(None),
        Some(v) if v.len() != D => Err(bad(path, format!("{name} has {} components, the scene is {D}D", v.len()))),
        Some(v) if !v.iter().all(|x| x.is_finite()) => Err(bad(path, format!("{name} = {v:?} must be finite"))),
        Some(v) => Ok(Some(Vector::<D>::from_fn(|i, _| v[i]))),
    }
}

fn positive(path: &Path, name: &str, v: f64) -> Result<f64, MpmError> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(bad(path, format!("{name} = {v} must be finite and > 0")))
    }
}

fn gb(bytes: f64) -> String {
    format!("{:.1} GB", bytes / 1e9)
}

/// Read a scene TOML file (mesh paths are relative to the file's folder) with the default
/// [`LoadOptions`]; returns the scene and the warnings about it (e.g. too few particles per cell).
pub fn load_scene_file(path: &Path) -> Result<(LoadedScene, Vec<Warning>), MpmError> {
    load_scene_file_with(path, &LoadOptions::default())
}

/// [`load_scene_file`] with explicit limits.
pub fn load_scene_file_with(path: &Path, opts: &LoadOptions) -> Result<(LoadedScene, Vec<Warning>), MpmError> {
    let text = std::fs::read_to_string(path).map_err(|e| bad(path, e.to_string()))?;
    let f: SceneFile = toml::from_str(&text).map_err(|e| bad(path, e.to_string()))?;
    f.material.validate().map_err(|e| bad(path, format!("[material] {e}")))?;
    match f.dim {
        2 => build::<2>(path, &f, opts).map(|(s, w)| (LoadedScene::D2(s), w)),
        3 => build::<3>(path, &f, opts).map(|(s, w)| (LoadedScene::D3(s), w)),
        d => Err(bad(path, format!("dim must be 2 or 3 (got {d})"))),
    }
}

/// Check the grid and time parameters; returns Δt.
fn check_grid_time<const D: usize>(path: &Path, f: &SceneFile, opts: &LoadOptions) -> Result<f64, MpmError> {
    let (n, dx) = (f.grid.n_grid, f.grid.dx);
    if n < 4 {
        return Err(bad(path, format!("grid.n_grid = {n} must be >= 4")));
    }
    positive(path, "grid.dx", dx)?;
    if !(1.0 / dx).is_finite() || !f.grid.extent().is_finite() {
        return Err(bad(path, format!("grid.dx = {dx:e} is out of range (1/dx and n_grid*dx must be finite)")));
    }
    // Block keys are u32 and the block table is dense: bound it before anything else.
    let table = estimate_memory_bytes(D, n, 0.0, 0.0);
    if table > opts.max_memory_bytes as f64 || (n as f64 / 4.0).ceil().powi(D as i32) >= u32::MAX as f64 {
        return Err(bad(
            path,
            format!(
                "grid.n_grid = {n} is too large: its {D}D block table alone needs {} (limit {})",
                gb(table),
                gb(opts.max_memory_bytes as f64)
            ),
        ));
    }
    let dt = match f.time.dt {
        Some(dt) => positive(path, "time.dt", dt)?,
        None => {
            let safety = positive(path, "time.cfl_safety", f.time.cfl_safety.unwrap_or(0.3))?;
            crate::cfl::cfl_dt(&f.material, dx, safety)
        }
    };
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(bad(path, format!("the CFL time step is {dt:e}: set time.dt")));
    }
    if let Some(b) = &f.boundary {
        if b.thickness > n / 2 {
            return Err(bad(path, format!("boundary.thickness = {} must be <= n_grid/2 = {}", b.thickness, n / 2)));
        }
    }
    if let Some(e) = f.mass_epsilon {
        if !(e >= 0.0 && e.is_finite()) {
            return Err(bad(path, format!("mass_epsilon = {e} must be finite and >= 0")));
        }
    }
    vec_of::<D>(path, "gravity", &f.gravity)?;
    Ok(dt)
}

/// One body's geometry before sampling: what to sample, its bounding box, and estimates of its
/// particle count and of the lattice points its sampling examines.
enum Geometry {
    Box { lo: Vec<f64>, hi: Vec<f64> },
    Ellipsoid { center: Vec<f64>, radii: Vec<f64> },
    Surface { mesh: sampling::TriMesh, scale: f64, offset: [f64; 3] },
    Tets { mesh: sampling::TetMesh },
}

struct Planned {
    geometry: Geometry,
    spacing: f64,
    lo: Vec<f64>,
    hi: Vec<f64>,
    particles: f64,
    scan: f64,
}

fn plan<const D: usize>(path: &Path, bi: usize, b: &BodyFile, dx: f64, extent: f64) -> Result<Planned, MpmError> {
    let name = |p: &str| format!("body {bi} ({}): {p}", b.shape);
    let spacing = positive(path, &name("spacing"), b.spacing.unwrap_or(dx / 2.0))?;
    let need = |v: &Option<Vec<f64>>, p: &str| -> Result<Vec<f64>, MpmError> {
        Ok(vec_of::<D>(path, &name(p), v)?.ok_or_else(|| bad(path, name(&format!("needs {p}"))))?.as_slice().to_vec())
    };
    let lattice = |lo: &[f64], hi: &[f64]| -> f64 {
        lo.iter().zip(hi).map(|(a, b)| ((b - a) / spacing + 1e-9).floor().max(0.0)).product()
    };
    let folder = path.parent().unwrap_or(Path::new("."));
    let (geometry, lo, hi, particles, scan) = match b.shape.as_str() {
        "box" => {
            let (lo, hi) = (need(&b.lo, "lo")?, need(&b.hi, "hi")?);
            if lo.iter().zip(&hi).any(|(a, b)| !(a < b)) {
                return Err(bad(path, name(&format!("lo = {lo:?} must be below hi = {hi:?} on every axis"))));
            }
            let n = lattice(&lo, &hi);
            (Geometry::Box { lo: lo.clone(), hi: hi.clone() }, lo, hi, n, n)
        }
        "ellipsoid" => {
            let (center, radii) = (need(&b.center, "center")?, need(&b.radii, "radii")?);
            if !radii.iter().all(|&r| r > 0.0) {
                return Err(bad(path, name(&format!("radii = {radii:?} must be > 0"))));
            }
            let lo: Vec<f64> = center.iter().zip(&radii).map(|(c, r)| c - r).collect();
            let hi: Vec<f64> = center.iter().zip(&radii).map(|(c, r)| c + r).collect();
            let n = lattice(&lo, &hi);
            (Geometry::Ellipsoid { center, radii }, lo, hi, n, n)
        }
        "mesh" | "tet_mesh" => {
            if D != 3 {
                return Err(bad(path, name("meshes need dim = 3")));
            }
            let mp = folder.join(b.path.as_deref().ok_or_else(|| bad(path, name("needs path")))?);
            let scale = positive(path, &name("scale"), b.scale.unwrap_or(1.0))?;
            let offset = vec_of::<3>(path, &name("offset"), &b.offset)?.unwrap_or_else(Vector::<3>::zeros);
            let to_world = |v: &Vector<3>| v * scale + offset;
            let world_box = |verts: &[Vector<3>]| -> Result<(Vec<f64>, Vec<f64>), MpmError> {
                let mut lo = Vector::<3>::from_element(f64::INFINITY);
                let mut hi = Vector::<3>::from_element(f64::NEG_INFINITY);
                for v in verts {
                    let w = to_world(v);
                    if !w.iter().all(|c| c.is_finite()) {
                        return Err(bad(
                            path,
                            name(&format!("mesh {}: a vertex is not finite after scale and offset", mp.display())),
                        ));
                    }
                    lo = lo.inf(&w);
                    hi = hi.sup(&w);
                }
                Ok((lo.as_slice().to_vec(), hi.as_slice().to_vec()))
            };
            if b.shape == "mesh" {
                let m = sampling::read_surface_mesh(&mp)?;
                sampling::check_closed(&m, &mp)?;
                let (lo, hi) = world_box(&m.vertices)?;
                let cells: f64 = lo.iter().zip(&hi).map(|(a, b)| ((b - a) / spacing).ceil().max(1.0)).product();
                // ray parity: one pass over the faces per lattice row
                let rows = cells / ((hi[0] - lo[0]) / spacing).ceil().max(1.0);
                let scan = cells + rows * m.faces.len() as f64;
                let off = [offset[0], offset[1], offset[2]];
                (Geometry::Surface { mesh: m, scale, offset: off }, lo, hi, cells, scan)
            } else {
                let mut m = sampling::read_tet_mesh(&mp)?;
                for v in &mut m.vertices {
                    *v = to_world(v);
                }
                let (lo, hi) = world_box(&m.vertices)?;
                let n = m.volume() / spacing.powi(3);
                let scan = sampling::tet_scan_points(&m, spacing);
                (Geometry::Tets { mesh: m }, lo, hi, n, scan)
            }
        }
        s => return Err(bad(path, format!("body {bi}: unknown shape '{s}' (box, ellipsoid, mesh, tet_mesh)"))),
    };
    if lo.iter().zip(&hi).any(|(a, b)| !(*a >= 0.0 && *b <= extent)) {
        return Err(bad(
            path,
            name(&format!("its bounding box {lo:?}..{hi:?} is outside the grid domain [0, {extent}]^{D} (n_grid*dx)")),
        ));
    }
    Ok(Planned { geometry, spacing, lo, hi, particles, scan })
}

/// Particle positions of a planned body.
fn sample<const D: usize>(p: &Planned) -> Result<Vec<Vector<D>>, MpmError> {
    let v = |s: &[f64]| Vector::<D>::from_fn(|i, _| s[i]);
    Ok(match &p.geometry {
        Geometry::Box { lo, hi } => box_lattice(v(lo), v(hi), p.spacing),
        Geometry::Ellipsoid { center, radii } => ellipsoid_lattice(v(center), v(radii), p.spacing),
        Geometry::Surface { mesh, scale, offset, .. } => {
            // voxelise in mesh units at spacing/scale, then transform
            sampling::voxelize(mesh, p.spacing / scale)
                .iter()
                .map(|q| Vector::<D>::from_fn(|i, _| q[i] * scale + offset[i]))
                .collect()
        }
        Geometry::Tets { mesh } => {
            sampling::sample_tet_mesh(mesh, p.spacing)?.iter().map(|q| Vector::<D>::from_fn(|i, _| q[i])).collect()
        }
    })
}

fn build<const D: usize>(path: &Path, f: &SceneFile, opts: &LoadOptions) -> Result<(Scene<D>, Vec<Warning>), MpmError> {
    let dt = check_grid_time::<D>(path, f, opts)?;
    let (dx, extent) = (f.grid.dx, f.grid.extent());
    if f.bodies.is_empty() {
        return Err(bad(path, "no [[body]]"));
    }
    // Plan every body (read meshes, check numbers and domain), then bound memory and time before
    // sampling anything.
    let plans =
        f.bodies.iter().enumerate().map(|(bi, b)| plan::<D>(path, bi, b, dx, extent)).collect::<Result<Vec<_>, _>>()?;
    let block = 4.0 * dx;
    let blocks: f64 = plans
        .iter()
        .map(|p| p.lo.iter().zip(&p.hi).map(|(a, b)| ((b - a) / block).ceil() + 2.0).product::<f64>())
        .sum();
    let particles: f64 = plans.iter().map(|p| p.particles).sum();
    let need = estimate_memory_bytes(D, f.grid.n_grid, particles, blocks);
    let limit = opts.max_memory_bytes as f64;
    for (bi, p) in plans.iter().enumerate() {
        if p.scan > opts.max_scan_points || estimate_memory_bytes(D, f.grid.n_grid, p.particles, 0.0) > limit {
            return Err(bad(
                path,
                format!(
                    "body {bi} ({}): spacing = {:e} is too fine: about {:.3e} particles ({:.3e} lattice points to test), \
                     the simulation would need about {} (limit {})",
                    f.bodies[bi].shape,
                    p.spacing,
                    p.particles,
                    p.scan,
                    gb(estimate_memory_bytes(D, f.grid.n_grid, p.particles, 0.0)),
                    gb(limit)
                ),
            ));
        }
    }
    if need > limit {
        return Err(bad(
            path,
            format!(
                "the scene would need about {} (limit {}): {:.3e} particles on a grid of {} cells with grid.dx = {:e}; \
                 increase spacing or dx, or reduce n_grid",
                gb(need),
                gb(limit),
                particles,
                f.grid.n_grid,
                dx
            ),
        ));
    }
    let mut scene = Scene::<D>::new(Vec::new(), 1.0, f.material, f.grid, dt, f.time.steps);
    let mut fixed = Vec::new();
    let mut forces = Vec::new();
    let mut warnings = Vec::new();
    for (bi, (b, plan)) in f.bodies.iter().zip(&plans).enumerate() {
        let pos = sample::<D>(plan)?;
        if pos.is_empty() {
            return Err(bad(
                path,
                format!(
                    "body {bi} ({}) produced no particles (spacing {:e} is coarser than the body?)",
                    b.shape, plan.spacing
                ),
            ));
        }
        let ppc = (dx / plan.spacing).powi(D as i32);
        if ppc < MIN_PARTICLES_PER_CELL {
            warnings.push(Warning::SparseParticles { body: bi, particles_per_cell: ppc, spacing: plan.spacing, dx });
        }
        let vol = plan.spacing.powi(D as i32);
        let centre = pos.iter().fold(Vector::<D>::zeros(), |a, p| a + p) / pos.len() as f64;
        let name = |p: &str| format!("body {bi} ({}): {p}", b.shape);
        let v0 = vec_of::<D>(path, &name("velocity"), &b.velocity)?.unwrap_or_else(Vector::<D>::zeros);
        let rate = vec_of::<D>(path, &name("stretch_rate"), &b.stretch_rate)?.unwrap_or_else(Vector::<D>::zeros);
        let fd = vec_of::<D>(path, &name("force_density"), &b.force_density)?;
        for p in &pos {
            scene.positions.push(*p);
            scene.velocities.push(v0 + rate.component_mul(&(p - centre)));
            scene.volumes.push(vol);
            scene.masses.push(vol * f.material.density);
            fixed.push(b.fixed);
            forces.push(fd.map(|f| f * vol).unwrap_or_else(Vector::<D>::zeros));
        }
    }
    if fixed.iter().any(|&x| x) {
        scene.fixed = fixed;
    }
    if forces.iter().any(|f| f.iter().any(|&c| c != 0.0)) {
        scene.external_forces = forces;
    }
    if let Some(b) = &f.boundary {
        scene.boundary = Boundary { walls: b.walls, thickness: b.thickness };
    }
    if let Some(g) = vec_of::<D>(path, "gravity", &f.gravity)? {
        scene.gravity = g;
    }
    if let Some(e) = f.mass_epsilon {
        scene.mass_epsilon = e;
    }
    scene.validate().map_err(|e| bad(path, e.to_string()))?;
    Ok((scene, warnings))
}
