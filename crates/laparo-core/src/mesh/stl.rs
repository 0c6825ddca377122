//! STL, ascii and binary. STL stores each triangle's corners separately; the reader merges
//! corners with bit-identical coordinates into shared vertices so that topology (closedness,
//! normals) can be computed.
use super::{check_read, fmt_f64, TriMesh};
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::Vector3;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

struct Welder {
    map: HashMap<[u64; 3], usize>,
    vertices: Vec<Vector3<f64>>,
}

impl Welder {
    fn add(&mut self, p: Vector3<f64>) -> usize {
        // +0.0 and -0.0 are the same point.
        let key = [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits);
        let n = self.vertices.len();
        *self.map.entry(key).or_insert_with(|| {
            self.vertices.push(p);
            n
        })
    }
}

/// Read an ascii or binary STL (binary when the size matches the triangle count at byte 80).
pub fn read_stl(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let bytes = crate::io::read_bytes(path)?;
    let mut w = Welder { map: HashMap::new(), vertices: Vec::new() };
    let mut faces = Vec::new();
    let binary_len =
        |b: &[u8]| (b.len() >= 84).then(|| 84 + 50 * u32::from_le_bytes([b[80], b[81], b[82], b[83]]) as usize);
    let is_ascii = bytes.trim_ascii_start().starts_with(b"solid") && binary_len(&bytes) != Some(bytes.len());
    if !is_ascii {
        let Some(expect) = binary_len(&bytes) else {
            return Err(CoreError::format(path, "not an STL file (too short for binary, no 'solid' keyword)"));
        };
        if expect != bytes.len() {
            return Err(CoreError::format(
                path,
                format!("binary STL size mismatch: header announces {} bytes, file has {}", expect, bytes.len()),
            ));
        }
        let n = (expect - 84) / 50;
        faces.reserve(n);
        for t in 0..n {
            let rec = &bytes[84 + 50 * t..84 + 50 * (t + 1)];
            let f = |o: usize| f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as f64;
            let mut tri = [0usize; 3];
            for (k, slot) in tri.iter_mut().enumerate() {
                let o = 12 + 12 * k;
                *slot = w.add(Vector3::new(f(o), f(o + 4), f(o + 8)));
            }
            faces.push(tri);
        }
    } else {
        let text = String::from_utf8_lossy(&bytes);
        let mut corners: Vec<usize> = Vec::new();
        let mut in_loop = false;
        for (i, line) in text.lines().enumerate() {
            let no = i + 1;
            let t: Vec<&str> = line.split_whitespace().collect();
            match t.first().copied() {
                Some("outer") => {
                    in_loop = true;
                    corners.clear();
                }
                Some("vertex") => {
                    if t.len() < 4 || !in_loop {
                        return Err(CoreError::format(path, format!("line {no}: malformed vertex line")));
                    }
                    let mut c = [0f64; 3];
                    for k in 0..3 {
                        c[k] = t[k + 1].parse().map_err(|_| {
                            CoreError::format(path, format!("line {no}: '{}' is not a number", t[k + 1]))
                        })?;
                    }
                    corners.push(w.add(Vector3::new(c[0], c[1], c[2])));
                }
                Some("endloop") => {
                    if corners.len() < 3 {
                        return Err(CoreError::format(
                            path,
                            format!("line {no}: facet with {} vertices", corners.len()),
                        ));
                    }
                    for k in 1..corners.len() - 1 {
                        faces.push([corners[0], corners[k], corners[k + 1]]);
                    }
                    in_loop = false;
                }
                _ => {}
            }
        }
        if in_loop {
            return Err(CoreError::format(path, "truncated ascii STL: facet without 'endloop'"));
        }
        if !text.lines().any(|l| l.trim_start().starts_with("endsolid")) {
            return Err(CoreError::format(path, "truncated ascii STL: no 'endsolid'"));
        }
    }
    if faces.is_empty() {
        return Err(CoreError::format(path, "STL without triangles"));
    }
    check_read(path, &w.vertices, &faces)?;
    Ok(TriMesh { vertices: w.vertices, faces })
}

/// Write an STL (binary float32 unless `ascii`), atomically. Facet normals are the unit face
/// normals (zero for degenerate faces).
pub fn write_stl(path: impl AsRef<Path>, mesh: &TriMesh, ascii: bool) -> Result<()> {
    let path = path.as_ref();
    check_read(path, &mesh.vertices, &mesh.faces)?;
    if ascii {
        let mut s = String::from("solid laparo\n");
        for (i, f) in mesh.faces.iter().enumerate() {
            let n = mesh.face_normal(i);
            let _ = writeln!(s, "  facet normal {} {} {}\n    outer loop", fmt_f64(n.x), fmt_f64(n.y), fmt_f64(n.z));
            for &k in f {
                let v = mesh.vertices[k];
                let _ = writeln!(s, "      vertex {} {} {}", fmt_f64(v.x), fmt_f64(v.y), fmt_f64(v.z));
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        s.push_str("endsolid laparo\n");
        return write_atomic(path, s.as_bytes());
    }
    let n = u32::try_from(mesh.faces.len()).map_err(|_| CoreError::format(path, "too many faces for binary STL"))?;
    let mut out = Vec::with_capacity(84 + 50 * mesh.faces.len());
    let mut header = [b' '; 80];
    header[..17].copy_from_slice(b"binary STL laparo");
    out.extend_from_slice(&header);
    out.extend_from_slice(&n.to_le_bytes());
    for (i, f) in mesh.faces.iter().enumerate() {
        let nrm = mesh.face_normal(i);
        for c in [nrm.x, nrm.y, nrm.z] {
            out.extend_from_slice(&(c as f32).to_le_bytes());
        }
        for &k in f {
            for c in mesh.vertices[k].iter() {
                out.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
        out.extend_from_slice(&[0, 0]);
    }
    write_atomic(path, &out)
}
