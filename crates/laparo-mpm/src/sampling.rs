//! Particles from geometry: voxelised closed surface meshes (OBJ / PLY / STL) and tetrahedral meshes
//! (Gmsh .msh v2 ASCII, legacy VTK ASCII).
//!
//! laparo_core::mesh had not landed when this crate was written, so minimal readers live here.
use crate::error::MpmError;
use crate::linalg::Vector;
use std::collections::HashMap;
use std::path::Path;

/// A triangle surface mesh.
#[derive(Clone, Debug, Default)]
pub struct SurfaceMesh {
    /// Vertex positions.
    pub vertices: Vec<Vector<3>>,
    /// Triangles (vertex indices).
    pub faces: Vec<[usize; 3]>,
}

/// A tetrahedral mesh.
#[derive(Clone, Debug, Default)]
pub struct TetMesh {
    /// Vertex positions.
    pub vertices: Vec<Vector<3>>,
    /// Tetrahedra (vertex indices).
    pub tets: Vec<[usize; 4]>,
}

fn err(path: &Path, reason: impl Into<String>) -> MpmError {
    MpmError::Mesh { path: path.display().to_string(), reason: reason.into() }
}

fn ext(path: &Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default()
}

/// Read an OBJ, PLY (ASCII or binary little-endian) or STL (ASCII or binary) triangle mesh.
pub fn read_surface_mesh(path: &Path) -> Result<SurfaceMesh, MpmError> {
    let bytes = std::fs::read(path).map_err(|e| err(path, e.to_string()))?;
    let mesh = match ext(path).as_str() {
        "obj" => read_obj(path, &bytes)?,
        "ply" => read_ply(path, &bytes)?,
        "stl" => read_stl(path, &bytes)?,
        e => return Err(err(path, format!("unsupported surface mesh extension '{e}' (obj, ply, stl)"))),
    };
    if mesh.faces.is_empty() {
        return Err(err(path, "no triangles"));
    }
    for f in &mesh.faces {
        if f.iter().any(|&i| i >= mesh.vertices.len()) {
            return Err(err(path, "face index out of range"));
        }
    }
    if !mesh.vertices.iter().all(|v| v.iter().all(|c| c.is_finite())) {
        return Err(err(path, "non-finite vertex"));
    }
    Ok(mesh)
}

fn parse_f(path: &Path, s: Option<&str>) -> Result<f64, MpmError> {
    s.and_then(|t| t.parse::<f64>().ok()).ok_or_else(|| err(path, "malformed number"))
}

fn read_obj(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MpmError> {
    let text = String::from_utf8_lossy(bytes);
    let mut m = SurfaceMesh::default();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let x = parse_f(path, it.next())?;
                let y = parse_f(path, it.next())?;
                let z = parse_f(path, it.next())?;
                m.vertices.push(Vector::<3>::new(x, y, z));
            }
            Some("f") => {
                let n = m.vertices.len() as i64;
                let idx: Result<Vec<usize>, MpmError> = it
                    .map(|t| {
                        let i: i64 = t.split('/').next().unwrap_or("").parse().map_err(|_| err(path, "bad face"))?;
                        let i = if i < 0 { n + i } else { i - 1 };
                        if i < 0 {
                            return Err(err(path, "bad face index"));
                        }
                        Ok(i as usize)
                    })
                    .collect();
                let idx = idx?;
                for k in 1..idx.len().saturating_sub(1) {
                    m.faces.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(m)
}

fn read_stl(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MpmError> {
    let mut raw: Vec<Vector<3>> = Vec::new();
    let is_binary = bytes.len() >= 84 && {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        84 + 50 * n == bytes.len()
    };
    if is_binary {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        for t in 0..n {
            let o = 84 + 50 * t + 12;
            for v in 0..3 {
                let f = |k: usize| {
                    let b = o + 12 * v + 4 * k;
                    f32::from_le_bytes([bytes[b], bytes[b + 1], bytes[b + 2], bytes[b + 3]]) as f64
                };
                raw.push(Vector::<3>::new(f(0), f(1), f(2)));
            }
        }
    } else {
        let text = String::from_utf8_lossy(bytes);
        for line in text.lines() {
            let mut it = line.split_whitespace();
            if it.next() == Some("vertex") {
                raw.push(Vector::<3>::new(
                    parse_f(path, it.next())?,
                    parse_f(path, it.next())?,
                    parse_f(path, it.next())?,
                ));
            }
        }
        if !raw.len().is_multiple_of(3) {
            return Err(err(path, "vertex count not a multiple of 3"));
        }
    }
    // Weld identical vertices so that closedness can be checked.
    let mut map: HashMap<[u64; 3], usize> = HashMap::new();
    let mut m = SurfaceMesh::default();
    let mut ids = Vec::with_capacity(raw.len());
    for v in raw {
        let key = [v[0].to_bits(), v[1].to_bits(), v[2].to_bits()];
        let id = *map.entry(key).or_insert_with(|| {
            m.vertices.push(v);
            m.vertices.len() - 1
        });
        ids.push(id);
    }
    for t in ids.chunks(3) {
        m.faces.push([t[0], t[1], t[2]]);
    }
    Ok(m)
}

fn read_ply(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MpmError> {
    let hdr_end = bytes.windows(10).position(|w| w == b"end_header").ok_or_else(|| err(path, "no end_header"))?;
    let header = String::from_utf8_lossy(&bytes[..hdr_end]).to_string();
    let mut body = hdr_end + 10;
    while body < bytes.len() && (bytes[body] == b'\n' || bytes[body] == b'\r') {
        body += 1;
        if bytes[body - 1] == b'\n' {
            break;
        }
    }
    let mut format = "";
    let mut nv = 0usize;
    let mut nf = 0usize;
    let mut vprops: Vec<(String, String)> = Vec::new();
    let mut flist: Option<(String, String)> = None;
    let mut cur = "";
    for line in header.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["format", f, ..] => {
                format = if f.starts_with("ascii") {
                    "ascii"
                } else if f.contains("little") {
                    "le"
                } else {
                    "be"
                }
            }
            ["element", "vertex", n] => {
                nv = n.parse().map_err(|_| err(path, "bad vertex count"))?;
                cur = "vertex";
            }
            ["element", "face", n] => {
                nf = n.parse().map_err(|_| err(path, "bad face count"))?;
                cur = "face";
            }
            ["element", ..] => cur = "other",
            ["property", "list", ct, it, _] if cur == "face" => flist = Some((ct.to_string(), it.to_string())),
            ["property", ty, name] if cur == "vertex" => vprops.push((ty.to_string(), name.to_string())),
            _ => {}
        }
    }
    let pos_of = |n: &str| vprops.iter().position(|(_, p)| p == n);
    let (ix, iy, iz) = match (pos_of("x"), pos_of("y"), pos_of("z")) {
        (Some(a), Some(b), Some(c)) => (a, b, c),
        _ => return Err(err(path, "vertex x/y/z properties missing")),
    };
    let mut m = SurfaceMesh::default();
    if format == "ascii" {
        let text = String::from_utf8_lossy(&bytes[body..]);
        let mut lines = text.lines().filter(|l| !l.trim().is_empty());
        for _ in 0..nv {
            let t: Vec<f64> = lines
                .next()
                .ok_or_else(|| err(path, "truncated vertices"))?
                .split_whitespace()
                .map(|s| s.parse::<f64>().map_err(|_| err(path, "bad vertex")))
                .collect::<Result<_, _>>()?;
            if t.len() < vprops.len() {
                return Err(err(path, "short vertex line"));
            }
            m.vertices.push(Vector::<3>::new(t[ix], t[iy], t[iz]));
        }
        for _ in 0..nf {
            let t: Vec<usize> = lines
                .next()
                .ok_or_else(|| err(path, "truncated faces"))?
                .split_whitespace()
                .map(|s| s.parse::<usize>().map_err(|_| err(path, "bad face")))
                .collect::<Result<_, _>>()?;
            let k = *t.first().ok_or_else(|| err(path, "empty face"))?;
            if t.len() < k + 1 {
                return Err(err(path, "short face line"));
            }
            for j in 1..k.saturating_sub(1) {
                m.faces.push([t[1], t[1 + j], t[2 + j]]);
            }
        }
        return Ok(m);
    }
    if format != "le" {
        return Err(err(path, "big-endian binary PLY is not supported"));
    }
    let size = |ty: &str| match ty {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        _ => 0,
    };
    let read = |b: &[u8], ty: &str| -> f64 {
        match ty {
            "char" | "int8" => b[0] as i8 as f64,
            "uchar" | "uint8" => b[0] as f64,
            "short" | "int16" => i16::from_le_bytes([b[0], b[1]]) as f64,
            "ushort" | "uint16" => u16::from_le_bytes([b[0], b[1]]) as f64,
            "int" | "int32" => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            "uint" | "uint32" => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            "float" | "float32" => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            _ => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    };
    if vprops.iter().any(|(t, _)| size(t) == 0) {
        return Err(err(path, "unsupported vertex property type"));
    }
    let stride: usize = vprops.iter().map(|(t, _)| size(t)).sum();
    let offs: Vec<usize> = vprops
        .iter()
        .scan(0, |a, (t, _)| {
            let o = *a;
            *a += size(t);
            Some(o)
        })
        .collect();
    let mut o = body;
    for _ in 0..nv {
        if o + stride > bytes.len() {
            return Err(err(path, "truncated binary vertices"));
        }
        let v = &bytes[o..o + stride];
        m.vertices.push(Vector::<3>::new(
            read(&v[offs[ix]..], &vprops[ix].0),
            read(&v[offs[iy]..], &vprops[iy].0),
            read(&v[offs[iz]..], &vprops[iz].0),
        ));
        o += stride;
    }
    let (ct, it) = flist.ok_or_else(|| err(path, "no face list property"))?;
    let (cs, is) = (size(&ct), size(&it));
    for _ in 0..nf {
        if o + cs > bytes.len() {
            return Err(err(path, "truncated binary faces"));
        }
        let k = read(&bytes[o..], &ct) as usize;
        o += cs;
        if o + k * is > bytes.len() {
            return Err(err(path, "truncated binary faces"));
        }
        let idx: Vec<usize> = (0..k).map(|j| read(&bytes[o + j * is..], &it) as usize).collect();
        o += k * is;
        for j in 1..k.saturating_sub(1) {
            m.faces.push([idx[0], idx[j], idx[j + 1]]);
        }
    }
    Ok(m)
}

/// Error unless every edge is shared by exactly two triangles (a closed, manifold surface).
pub fn check_closed(mesh: &SurfaceMesh, path: &Path) -> Result<(), MpmError> {
    let mut edges: HashMap<(usize, usize), u32> = HashMap::new();
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let open = edges.values().filter(|&&c| c != 2).count();
    if open > 0 {
        return Err(err(path, format!("surface is not closed: {open} edges are not shared by exactly two triangles")));
    }
    Ok(())
}

/// Lattice points (spacing `spacing`, cell-centred on the mesh bounding box) inside a closed surface,
/// by ray parity along +x per lattice row.
pub fn voxelize(mesh: &SurfaceMesh, spacing: f64) -> Vec<Vector<3>> {
    let mut lo = Vector::<3>::from_element(f64::INFINITY);
    let mut hi = Vector::<3>::from_element(f64::NEG_INFINITY);
    for v in &mesh.vertices {
        lo = lo.inf(v);
        hi = hi.sup(v);
    }
    let counts: [usize; 3] = std::array::from_fn(|d| ((hi[d] - lo[d]) / spacing).ceil().max(1.0) as usize);
    let mut out = Vec::new();
    for i in 0..counts[1] {
        for j in 0..counts[2] {
            // tiny irrational offsets keep rays off vertices and edges
            let y = lo[1] + (i as f64 + 0.5) * spacing + spacing * 1.234e-7;
            let z = lo[2] + (j as f64 + 0.5) * spacing + spacing * 2.718e-7;
            let mut xs: Vec<f64> = Vec::new();
            for f in &mesh.faces {
                let (a, b, c) = (mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]);
                // barycentric test in the (y, z) plane
                let d = (b[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (b[2] - a[2]);
                if d == 0.0 {
                    continue;
                }
                let u = ((y - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (z - a[2])) / d;
                let v = ((b[1] - a[1]) * (z - a[2]) - (y - a[1]) * (b[2] - a[2])) / d;
                if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
                    xs.push(a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]));
                }
            }
            xs.sort_by(f64::total_cmp);
            for k in 0..counts[0] {
                let x = lo[0] + (k as f64 + 0.5) * spacing;
                let crossings = xs.iter().filter(|&&c| c > x).count();
                if crossings % 2 == 1 {
                    out.push(Vector::<3>::new(x, y, z));
                }
            }
        }
    }
    out
}

/// Read a tetrahedral mesh: Gmsh `.msh` (format 2 ASCII) or legacy `.vtk` ASCII unstructured grid.
pub fn read_tet_mesh(path: &Path) -> Result<TetMesh, MpmError> {
    let text = std::fs::read_to_string(path).map_err(|e| err(path, e.to_string()))?;
    let m = match ext(path).as_str() {
        "msh" => read_msh(path, &text)?,
        "vtk" => read_vtk(path, &text)?,
        e => return Err(err(path, format!("unsupported tetrahedral mesh extension '{e}' (msh, vtk)"))),
    };
    if m.tets.is_empty() {
        return Err(err(path, "no tetrahedra"));
    }
    if m.tets.iter().any(|t| t.iter().any(|&i| i >= m.vertices.len())) {
        return Err(err(path, "tetrahedron index out of range"));
    }
    Ok(m)
}

fn read_msh(path: &Path, text: &str) -> Result<TetMesh, MpmError> {
    let mut lines = text.lines();
    let mut m = TetMesh::default();
    let mut ids: HashMap<usize, usize> = HashMap::new();
    while let Some(l) = lines.next() {
        match l.trim() {
            "$MeshFormat" => {
                let v = lines.next().unwrap_or("");
                if !v.trim_start().starts_with('2') || v.split_whitespace().nth(1) != Some("0") {
                    return Err(err(path, format!("only Gmsh format 2 ASCII is supported (got '{v}')")));
                }
            }
            "$Nodes" => {
                let n: usize =
                    lines.next().and_then(|s| s.trim().parse().ok()).ok_or_else(|| err(path, "bad $Nodes"))?;
                for _ in 0..n {
                    let t: Vec<&str> =
                        lines.next().ok_or_else(|| err(path, "truncated $Nodes"))?.split_whitespace().collect();
                    if t.len() < 4 {
                        return Err(err(path, "bad node line"));
                    }
                    let id: usize = t[0].parse().map_err(|_| err(path, "bad node id"))?;
                    ids.insert(id, m.vertices.len());
                    m.vertices.push(Vector::<3>::new(
                        parse_f(path, Some(t[1]))?,
                        parse_f(path, Some(t[2]))?,
                        parse_f(path, Some(t[3]))?,
                    ));
                }
            }
            "$Elements" => {
                let n: usize =
                    lines.next().and_then(|s| s.trim().parse().ok()).ok_or_else(|| err(path, "bad $Elements"))?;
                for _ in 0..n {
                    let t: Vec<usize> = lines
                        .next()
                        .ok_or_else(|| err(path, "truncated $Elements"))?
                        .split_whitespace()
                        .map(|s| s.parse().map_err(|_| err(path, "bad element")))
                        .collect::<Result<_, _>>()?;
                    if t.len() >= 3 && t[1] == 4 {
                        let nt = t[2];
                        let nodes = &t[3 + nt..];
                        if nodes.len() < 4 {
                            return Err(err(path, "short tetrahedron"));
                        }
                        let map =
                            |id: usize| ids.get(&id).copied().ok_or_else(|| err(path, format!("unknown node {id}")));
                        m.tets.push([map(nodes[0])?, map(nodes[1])?, map(nodes[2])?, map(nodes[3])?]);
                    }
                }
            }
            _ => {}
        }
    }
    Ok(m)
}

fn read_vtk(path: &Path, text: &str) -> Result<TetMesh, MpmError> {
    if text.contains("BINARY") && !text.contains("ASCII") {
        return Err(err(path, "only ASCII legacy VTK is supported"));
    }
    let toks: Vec<&str> = text.split_whitespace().collect();
    let mut m = TetMesh::default();
    let find = |k: &str| toks.iter().position(|t| *t == k);
    let p = find("POINTS").ok_or_else(|| err(path, "no POINTS"))?;
    let n: usize = toks.get(p + 1).and_then(|s| s.parse().ok()).ok_or_else(|| err(path, "bad POINTS"))?;
    for i in 0..n {
        let g = |k: usize| parse_f(path, toks.get(p + 3 + 3 * i + k).copied());
        m.vertices.push(Vector::<3>::new(g(0)?, g(1)?, g(2)?));
    }
    let c = find("CELLS").ok_or_else(|| err(path, "no CELLS"))?;
    let nc: usize = toks.get(c + 1).and_then(|s| s.parse().ok()).ok_or_else(|| err(path, "bad CELLS"))?;
    let ct = find("CELL_TYPES").ok_or_else(|| err(path, "no CELL_TYPES"))?;
    let mut o = c + 3;
    for i in 0..nc {
        let k: usize = toks.get(o).and_then(|s| s.parse().ok()).ok_or_else(|| err(path, "bad cell"))?;
        let ty: usize = toks.get(ct + 2 + i).and_then(|s| s.parse().ok()).ok_or_else(|| err(path, "bad cell type"))?;
        if ty == 10 && k == 4 {
            let g = |j: usize| {
                toks.get(o + 1 + j).and_then(|s| s.parse::<usize>().ok()).ok_or_else(|| err(path, "bad cell index"))
            };
            m.tets.push([g(0)?, g(1)?, g(2)?, g(3)?]);
        }
        o += k + 1;
    }
    Ok(m)
}

/// One particle per tetrahedron at its centroid, with the tetrahedron's volume.
pub fn tet_particles(mesh: &TetMesh) -> (Vec<Vector<3>>, Vec<f64>) {
    let mut pos = Vec::with_capacity(mesh.tets.len());
    let mut vol = Vec::with_capacity(mesh.tets.len());
    for t in &mesh.tets {
        let [a, b, c, d] = t.map(|i| mesh.vertices[i]);
        let v = ((b - a).cross(&(c - a))).dot(&(d - a)).abs() / 6.0;
        if v > 0.0 {
            pos.push((a + b + c + d) / 4.0);
            vol.push(v);
        }
    }
    (pos, vol)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_obj() -> String {
        let mut s = String::new();
        for z in [0.0, 1.0] {
            for y in [0.0, 1.0] {
                for x in [0.0, 1.0] {
                    s += &format!("v {x} {y} {z}\n");
                }
            }
        }
        // 12 outward triangles of the unit cube (vertices 1..8, index = 1 + x + 2y + 4z)
        for f in [
            [1, 3, 4],
            [1, 4, 2],
            [5, 6, 8],
            [5, 8, 7],
            [1, 2, 6],
            [1, 6, 5],
            [3, 7, 8],
            [3, 8, 4],
            [1, 5, 7],
            [1, 7, 3],
            [2, 4, 8],
            [2, 8, 6],
        ] {
            s += &format!("f {} {} {}\n", f[0], f[1], f[2]);
        }
        s
    }

    #[test]
    fn voxelised_cube_has_the_right_volume_and_open_mesh_is_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cube.obj");
        std::fs::write(&p, cube_obj()).unwrap();
        let m = read_surface_mesh(&p).unwrap();
        check_closed(&m, &p).unwrap();
        let pts = voxelize(&m, 0.1);
        assert_eq!(pts.len(), 1000);
        let mut open = m.clone();
        open.faces.pop();
        let e = check_closed(&open, &p).unwrap_err().to_string();
        assert!(e.contains("not closed") && e.contains("cube.obj"), "{e}");
    }

    #[test]
    fn gmsh_and_vtk_tetrahedra() {
        let dir = tempfile::tempdir().unwrap();
        let msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n2\n1 15 2 0 1 1\n2 4 2 0 1 1 2 3 4\n$EndElements\n";
        let p = dir.path().join("t.msh");
        std::fs::write(&p, msh).unwrap();
        let (pos, vol) = tet_particles(&read_tet_mesh(&p).unwrap());
        assert_eq!(pos.len(), 1);
        assert!((vol[0] - 1.0 / 6.0).abs() < 1e-15 && (pos[0][0] - 0.25).abs() < 1e-15);
        let vtk = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0 2 0 0 0 2 0 0 0 2\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
        let p = dir.path().join("t.vtk");
        std::fs::write(&p, vtk).unwrap();
        let (_, vol) = tet_particles(&read_tet_mesh(&p).unwrap());
        assert!((vol[0] - 8.0 / 6.0).abs() < 1e-12);
    }
}
