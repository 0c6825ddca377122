//! Scene description files (TOML) for `laparo mpm simulate`; see the crate README for the format.
use crate::error::MpmError;
use crate::linalg::Vector;
use crate::sampling;
use crate::scene::{box_lattice, ellipsoid_lattice, Boundary, GridSpec, Material, Scene, WallKind};
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
    /// box | ellipsoid | mesh (closed surface, voxelised) | tet_mesh (one particle per tetrahedron)
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

fn bad(path: &Path, msg: impl Into<String>) -> MpmError {
    MpmError::InvalidScene(format!("{}: {}", path.display(), msg.into()))
}

fn vec_of<const D: usize>(path: &Path, name: &str, v: &Option<Vec<f64>>) -> Result<Option<Vector<D>>, MpmError> {
    match v {
        None => Ok(None),
        Some(v) if v.len() == D => Ok(Some(Vector::<D>::from_fn(|i, _| v[i]))),
        Some(v) => Err(bad(path, format!("{name} has {} components, the scene is {D}D", v.len()))),
    }
}

/// Read a scene TOML file (mesh paths are relative to the file's folder).
pub fn load_scene_file(path: &Path) -> Result<LoadedScene, MpmError> {
    let text = std::fs::read_to_string(path).map_err(|e| bad(path, e.to_string()))?;
    let f: SceneFile = toml::from_str(&text).map_err(|e| bad(path, e.to_string()))?;
    f.material.validate()?;
    match f.dim {
        2 => Ok(LoadedScene::D2(build::<2>(path, &f)?)),
        3 => Ok(LoadedScene::D3(build::<3>(path, &f)?)),
        d => Err(bad(path, format!("dim must be 2 or 3 (got {d})"))),
    }
}

fn build<const D: usize>(path: &Path, f: &SceneFile) -> Result<Scene<D>, MpmError> {
    let dx = f.grid.dx;
    let dt = match f.time.dt {
        Some(dt) => dt,
        None => crate::cfl::cfl_dt(&f.material, dx, f.time.cfl_safety.unwrap_or(0.3)),
    };
    let mut scene = Scene::<D>::new(Vec::new(), 1.0, f.material, f.grid, dt, f.time.steps);
    scene.volumes.clear();
    scene.masses.clear();
    scene.velocities.clear();
    let mut fixed = Vec::new();
    let mut forces = Vec::new();
    let folder = path.parent().unwrap_or(Path::new("."));
    if f.bodies.is_empty() {
        return Err(bad(path, "no [[body]]"));
    }
    for (bi, b) in f.bodies.iter().enumerate() {
        let spacing = b.spacing.unwrap_or(dx / 2.0);
        if !(spacing > 0.0) {
            return Err(bad(path, format!("body {bi}: spacing must be > 0")));
        }
        let need = |v: Option<Vector<D>>, name: &str| {
            v.ok_or_else(|| bad(path, format!("body {bi} ({}) needs {name}", b.shape)))
        };
        let (pos, vols): (Vec<Vector<D>>, Vec<f64>) = match b.shape.as_str() {
            "box" => {
                let p = box_lattice(
                    need(vec_of::<D>(path, "lo", &b.lo)?, "lo")?,
                    need(vec_of::<D>(path, "hi", &b.hi)?, "hi")?,
                    spacing,
                );
                let n = p.len();
                (p, vec![spacing.powi(D as i32); n])
            }
            "ellipsoid" => {
                let p = ellipsoid_lattice(
                    need(vec_of::<D>(path, "center", &b.center)?, "center")?,
                    need(vec_of::<D>(path, "radii", &b.radii)?, "radii")?,
                    spacing,
                );
                let n = p.len();
                (p, vec![spacing.powi(D as i32); n])
            }
            "mesh" | "tet_mesh" => {
                if D != 3 {
                    return Err(bad(path, format!("body {bi}: meshes need dim = 3")));
                }
                let mp = folder.join(b.path.as_deref().ok_or_else(|| bad(path, format!("body {bi} needs path")))?);
                let scale = b.scale.unwrap_or(1.0);
                let offset = vec_of::<D>(path, "offset", &b.offset)?.unwrap_or_else(Vector::<D>::zeros);
                let to_d = |v: &Vector<3>| Vector::<D>::from_fn(|i, _| v[i] * scale + offset[i]);
                if b.shape == "mesh" {
                    let m = sampling::read_surface_mesh(&mp)?;
                    sampling::check_closed(&m, &mp)?;
                    // voxelise in mesh units at spacing/scale, then transform
                    let pts = sampling::voxelize(&m, spacing / scale);
                    let n = pts.len();
                    (pts.iter().map(to_d).collect(), vec![spacing.powi(3); n])
                } else {
                    let (p, v) = sampling::tet_particles(&sampling::read_tet_mesh(&mp)?);
                    (p.iter().map(to_d).collect(), v.iter().map(|v| v * scale.powi(3)).collect())
                }
            }
            s => return Err(bad(path, format!("body {bi}: unknown shape '{s}' (box, ellipsoid, mesh, tet_mesh)"))),
        };
        if pos.is_empty() {
            return Err(bad(path, format!("body {bi} produced no particles")));
        }
        let centre = pos.iter().fold(Vector::<D>::zeros(), |a, p| a + p) / pos.len() as f64;
        let v0 = vec_of::<D>(path, "velocity", &b.velocity)?.unwrap_or_else(Vector::<D>::zeros);
        let rate = vec_of::<D>(path, "stretch_rate", &b.stretch_rate)?.unwrap_or_else(Vector::<D>::zeros);
        let fd = vec_of::<D>(path, "force_density", &b.force_density)?;
        for (p, v) in pos.iter().zip(&vols) {
            scene.positions.push(*p);
            scene.velocities.push(v0 + rate.component_mul(&(p - centre)));
            scene.volumes.push(*v);
            scene.masses.push(v * f.material.density);
            fixed.push(b.fixed);
            forces.push(fd.map(|f| f * *v).unwrap_or_else(Vector::<D>::zeros));
        }
    }
    if fixed.iter().any(|&x| x) {
        scene.fixed = fixed;
    }
    if forces.iter().any(|f| f.norm() > 0.0) {
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
    scene.validate()?;
    Ok(scene)
}
