//! Landmark and target files (model coordinates, mm).
//!
//! * Landmarks: JSON `{"groups": [{"name": "left lip", "points": [[x, y, z], …], "weight": 1.0}]}` or CSV
//!   lines `group,x,y,z` (a header line is skipped).
//! * Targets: JSON `{"groups": [{"name": "left lip", "type": "points" | "polyline", "points": [[x, y, z], …]}]}`
//!   matched to the landmark groups by name (`points`: one target per landmark, in order), or a PLY/OBJ
//!   file: a triangle surface (with faces) or a point cloud (without), shared by every group.
//! * P2ILF 3D contours (`patient*_3D-contours.json`: contours of mesh vertex ids) → landmark groups.
use crate::distance::{PointCloud, Polyline, TriangleSurface};
use crate::error::{RegisterError, Result};
use crate::loss::GroupTarget;
use laparo_mpm::Vector;
use serde_json::Value;
use std::path::Path;
use std::sync::Arc;

/// Source landmarks of one group.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SourceGroup {
    /// Name.
    pub name: String,
    /// Annotated points (mm).
    pub points: Vec<Vector<3>>,
    /// Weight.
    pub weight: f64,
}

/// Target of one group.
#[derive(Clone, Debug)]
pub enum TargetSpec {
    /// One point per landmark.
    Points(Vec<Vector<3>>),
    /// A polyline.
    Polyline(Vec<Vector<3>>),
    /// A triangle surface.
    Surface(Vec<Vector<3>>, Vec<[usize; 3]>),
    /// A point cloud.
    Cloud(Vec<Vector<3>>),
}

impl TargetSpec {
    /// The loss target (eq. 5.10) of this spec, its points shifted by `offset` (mm) into the frame the
    /// landmarks are scored in.
    pub fn group_target(&self, offset: Vector<3>) -> GroupTarget<3> {
        let sh = |v: &[Vector<3>]| v.iter().map(|p| p + offset).collect::<Vec<_>>();
        match self {
            TargetSpec::Points(p) => GroupTarget::Paired(sh(p)),
            TargetSpec::Polyline(p) => GroupTarget::Shared(Arc::new(Polyline::open(sh(p)))),
            TargetSpec::Surface(v, f) => GroupTarget::Shared(Arc::new(TriangleSurface::new(sh(v), f.clone()))),
            TargetSpec::Cloud(p) => GroupTarget::Shared(Arc::new(PointCloud::new(sh(p)))),
        }
    }
}

fn bad(path: &Path, reason: impl Into<String>) -> RegisterError {
    RegisterError::bad(path.display().to_string(), reason)
}

/// Largest |coordinate| (mm) of a landmark or target point: 1 km. A point further out is a unit or
/// format error; accepted, it would dominate every fit (a target 1e15 mm away "converges").
pub const MAX_COORD_MM: f64 = 1e6;

/// A landmark or target point: three finite coordinates within ±[`MAX_COORD_MM`]; `what` names it.
fn checked_point(c: &[f64], path: &Path, what: &str) -> Result<Vector<3>> {
    if let Some(x) = c.iter().find(|x| !x.is_finite()) {
        return Err(bad(path, format!("{what}: non-finite coordinate {x}")));
    }
    if let Some(x) = c.iter().find(|x| x.abs() > MAX_COORD_MM) {
        return Err(bad(path, format!("{what}: coordinate {x:e} mm is beyond ±{MAX_COORD_MM:e} mm (wrong units?)")));
    }
    Ok(Vector::<3>::new(c[0], c[1], c[2]))
}

fn points_of(v: &Value, path: &Path, what: &str) -> Result<Vec<Vector<3>>> {
    let arr = v.as_array().ok_or_else(|| bad(path, format!("{what}: expected a list of [x, y, z]")))?;
    arr.iter()
        .enumerate()
        .map(|(i, p)| {
            let c = p
                .as_array()
                .filter(|c| c.len() == 3)
                .ok_or_else(|| bad(path, format!("{what}[{i}]: expected [x, y, z]")))?;
            let f: Vec<f64> = c.iter().filter_map(|x| x.as_f64()).filter(|x| x.is_finite()).collect();
            if f.len() != 3 {
                return Err(bad(path, format!("{what}[{i}]: non-numeric or non-finite coordinate")));
            }
            checked_point(&f, path, &format!("{what}[{i}]"))
        })
        .collect()
}

fn read_json(path: &Path) -> Result<Value> {
    let text = std::fs::read_to_string(path).map_err(|e| bad(path, format!("cannot read: {e}")))?;
    serde_json::from_str(&text).map_err(|e| bad(path, format!("invalid JSON: {e}")))
}

/// Read landmark groups (JSON or CSV).
pub fn read_landmarks(path: &Path) -> Result<Vec<SourceGroup>> {
    let ext = crate::io_ext(path);
    let groups = if ext == "csv" {
        let text = std::fs::read_to_string(path).map_err(|e| bad(path, format!("cannot read: {e}")))?;
        let mut groups: Vec<SourceGroup> = Vec::new();
        for (ln, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let cells: Vec<&str> = line.split(',').map(|c| c.trim()).collect();
            if cells.len() != 4 {
                return Err(bad(path, format!("line {}: expected group,x,y,z", ln + 1)));
            }
            let nums: Vec<f64> = cells[1..].iter().filter_map(|c| c.parse().ok()).collect();
            if nums.len() != 3 {
                if ln == 0 {
                    continue; // header
                }
                return Err(bad(path, format!("line {}: non-numeric coordinate", ln + 1)));
            }
            // "nan" and "inf" parse as numbers: refused here as the JSON reader refuses them.
            let p = checked_point(&nums, path, &format!("line {}", ln + 1))?;
            match groups.iter_mut().find(|g| g.name == cells[0]) {
                Some(g) => g.points.push(p),
                None => groups.push(SourceGroup { name: cells[0].into(), points: vec![p], weight: 1.0 }),
            }
        }
        groups
    } else {
        let v = read_json(path)?;
        let gs = v.get("groups").and_then(|g| g.as_array()).ok_or_else(|| bad(path, "expected {\"groups\": [...]}"))?;
        gs.iter()
            .enumerate()
            .map(|(i, g)| {
                let name =
                    g.get("name").and_then(|n| n.as_str()).map(String::from).unwrap_or_else(|| format!("group{i}"));
                let points = points_of(g.get("points").unwrap_or(&Value::Null), path, &format!("groups[{i}].points"))?;
                let weight = g.get("weight").and_then(|w| w.as_f64()).unwrap_or(1.0);
                if !(weight > 0.0 && weight.is_finite()) {
                    return Err(bad(path, format!("groups[{i}].weight must be > 0")));
                }
                Ok(SourceGroup { name, points, weight })
            })
            .collect::<Result<Vec<_>>>()?
    };
    if groups.iter().all(|g| g.points.is_empty()) {
        return Err(bad(path, "no landmark"));
    }
    Ok(groups)
}

/// Read targets for `groups`: JSON (per group, by name) or a PLY/OBJ surface / point cloud (shared).
pub fn read_targets(path: &Path, groups: &[SourceGroup]) -> Result<Vec<TargetSpec>> {
    let ext = crate::io_ext(path);
    if ext == "json" {
        let v = read_json(path)?;
        let gs = v.get("groups").and_then(|g| g.as_array()).ok_or_else(|| bad(path, "expected {\"groups\": [...]}"))?;
        return groups
            .iter()
            .map(|src| {
                let (i, g) = gs
                    .iter()
                    .enumerate()
                    .find(|(_, g)| g.get("name").and_then(|n| n.as_str()) == Some(src.name.as_str()))
                    .ok_or_else(|| bad(path, format!("no target group named `{}`", src.name)))?;
                let pts = points_of(g.get("points").unwrap_or(&Value::Null), path, &format!("groups[{i}].points"))?;
                if pts.is_empty() {
                    return Err(bad(path, format!("target group `{}` is empty", src.name)));
                }
                match g.get("type").and_then(|t| t.as_str()).unwrap_or("points") {
                    "points" => {
                        if pts.len() != src.points.len() {
                            return Err(bad(
                                path,
                                format!(
                                    "group `{}`: {} target points for {} landmarks",
                                    src.name,
                                    pts.len(),
                                    src.points.len()
                                ),
                            ));
                        }
                        Ok(TargetSpec::Points(pts))
                    }
                    "polyline" => Ok(TargetSpec::Polyline(pts)),
                    "cloud" => Ok(TargetSpec::Cloud(pts)),
                    t => Err(bad(
                        path,
                        format!("group `{}`: unknown target type `{t}` (points, polyline, cloud)", src.name),
                    )),
                }
            })
            .collect();
    }
    let mesh = laparo_core::mesh::read_mesh(path)?;
    if mesh.vertices.is_empty() {
        return Err(bad(path, "empty target (no vertex)"));
    }
    for (i, v) in mesh.vertices.iter().enumerate() {
        checked_point(&[v[0], v[1], v[2]], path, &format!("vertex {i}"))?;
    }
    let spec = if mesh.faces.is_empty() {
        TargetSpec::Cloud(mesh.vertices.clone())
    } else {
        TargetSpec::Surface(mesh.vertices.clone(), mesh.faces.clone())
    };
    Ok(vec![spec; groups.len()])
}

/// P2ILF 3D contours (mesh vertex ids per contour) → one landmark group per contour.
pub fn read_p2ilf_contours(path: &Path, vertices: &[Vector<3>]) -> Result<Vec<SourceGroup>> {
    let v = read_json(path)?;
    let cs = v.get("contour").and_then(|c| c.as_array()).ok_or_else(|| bad(path, "expected a `contour` list"))?;
    cs.iter()
        .enumerate()
        .map(|(i, c)| {
            let kind = c.get("contourType").and_then(|t| t.as_str()).unwrap_or("contour");
            let ids = c
                .pointer("/modelPoints/vertices")
                .and_then(|v| v.as_array())
                .ok_or_else(|| bad(path, format!("contour {i}: no modelPoints.vertices")))?;
            let points = ids
                .iter()
                .map(|id| {
                    let k =
                        id.as_u64().ok_or_else(|| bad(path, format!("contour {i}: non-integer vertex id")))? as usize;
                    vertices
                        .get(k)
                        .copied()
                        .ok_or_else(|| bad(path, format!("contour {i}: vertex {k} >= {}", vertices.len())))
                })
                .collect::<Result<Vec<_>>>()?;
            Ok(SourceGroup { name: format!("{kind} {i}"), points, weight: 1.0 })
        })
        .collect()
}
