//! Wavefront OBJ (geometry only: `v` and `f`).
use super::{check_read, fmt_f64, TriMesh};
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::Path;

/// Read the vertices and faces of an OBJ file. Face corners may be `i`, `i/t`, `i//n` or `i/t/n`,
/// 1-based or negative (relative to the last vertex so far); polygons are fan-triangulated.
/// Normals, texture coordinates, groups and materials are ignored.
pub fn read_obj(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let bytes = crate::io::read_bytes(path)?;
    let text = String::from_utf8_lossy(&bytes);
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    let err = |no: usize, msg: String| CoreError::format(path, format!("line {no}: {msg}"));
    for (i, line) in text.lines().enumerate() {
        let no = i + 1;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0f64; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let tok = it.next().ok_or_else(|| err(no, format!("vertex has {k} coordinates, needs 3")))?;
                    *slot = tok.parse().map_err(|_| err(no, format!("'{tok}' is not a number")))?;
                }
                vertices.push(Vector3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let mut idx = Vec::with_capacity(4);
                for tok in it {
                    let first = tok.split('/').next().unwrap_or("");
                    let k: i64 = first.parse().map_err(|_| err(no, format!("bad face corner '{tok}'")))?;
                    let n = vertices.len() as i64;
                    let j = if k > 0 { k - 1 } else { n + k };
                    if k == 0 || j < 0 || j >= n {
                        return Err(err(no, format!("face index {k} out of range ({n} vertices so far)")));
                    }
                    idx.push(j as usize);
                }
                if idx.len() < 3 {
                    return Err(err(no, format!("face with {} corners", idx.len())));
                }
                for k in 1..idx.len() - 1 {
                    faces.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if vertices.is_empty() {
        return Err(CoreError::format(path, "no vertices ('v' lines): not an OBJ mesh"));
    }
    check_read(path, &vertices, &faces)?;
    Ok(TriMesh { vertices, faces })
}

/// Write an OBJ file (`v x y z` with round-trip precision, `f a b c` 1-based), atomically.
pub fn write_obj(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    let path = path.as_ref();
    check_read(path, &mesh.vertices, &mesh.faces)?;
    let mut s = String::with_capacity(mesh.vertices.len() * 40 + mesh.faces.len() * 20);
    s.push_str("# written by laparo\n");
    for v in &mesh.vertices {
        let _ = writeln!(s, "v {} {} {}", fmt_f64(v.x), fmt_f64(v.y), fmt_f64(v.z));
    }
    for f in &mesh.faces {
        let _ = writeln!(s, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    write_atomic(path, s.as_bytes())
}
