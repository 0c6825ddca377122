//! Legacy VTK, ASCII: `UNSTRUCTURED_GRID` (classic `CELLS` and 5.1 `OFFSETS`/`CONNECTIVITY`)
//! and `POLYDATA` (`POLYGONS`).
use super::{check_read, fmt_f64, MixedMesh, TetMesh};
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::Path;

/// Read the tetrahedra of a legacy VTK file (an error if it has none).
pub fn read_vtk(path: impl AsRef<Path>) -> Result<TetMesh> {
    let path = path.as_ref();
    let m = read_vtk_mixed(path)?;
    if m.tets.is_empty() {
        return Err(CoreError::format(
            path,
            format!("no tetrahedra ({} triangles): use read_vtk_mixed or read_mesh for surfaces", m.triangles.len()),
        ));
    }
    Ok(m.tet_mesh())
}

struct Tokens<'a> {
    it: std::iter::Peekable<std::str::SplitAsciiWhitespace<'a>>,
}

impl<'a> Tokens<'a> {
    fn next(&mut self, what: &str) -> std::result::Result<&'a str, String> {
        self.it.next().ok_or_else(|| format!("truncated: expected {what}"))
    }
    fn usize(&mut self, what: &str) -> std::result::Result<usize, String> {
        let t = self.next(what)?;
        t.parse().map_err(|_| format!("'{t}' is not a count/index ({what})"))
    }
    fn f64(&mut self, what: &str) -> std::result::Result<f64, String> {
        let t = self.next(what)?;
        match t.to_ascii_lowercase().as_str() {
            "nan" => Ok(f64::NAN),
            "inf" | "infinity" => Ok(f64::INFINITY),
            "-inf" | "-infinity" => Ok(f64::NEG_INFINITY),
            _ => t.parse().map_err(|_| format!("'{t}' is not a number ({what})")),
        }
    }
}

/// Read points, triangles (cell type 5, corners of 22; polygons/quads fan-triangulated) and
/// tetrahedra (type 10, corners of 24) of an ASCII legacy VTK file. Tags are all 0 (cell data
/// arrays are not read).
pub fn read_vtk_mixed(path: impl AsRef<Path>) -> Result<MixedMesh> {
    let path = path.as_ref();
    let bytes = crate::io::read_bytes(path)?;
    let text = String::from_utf8_lossy(&bytes);
    let bad = |m: String| CoreError::format(path, m);
    let mut lines = text.splitn(4, '\n');
    let l0 = lines.next().unwrap_or("");
    if !l0.trim_start().starts_with("# vtk DataFile") {
        return Err(bad("not a legacy VTK file (first line must be '# vtk DataFile Version ...')".into()));
    }
    let _title = lines.next();
    let fmt = lines.next().unwrap_or("").trim();
    if fmt.eq_ignore_ascii_case("BINARY") {
        return Err(bad("binary legacy VTK is not supported; save as ASCII".into()));
    }
    if !fmt.eq_ignore_ascii_case("ASCII") {
        return Err(bad(format!("third line must be ASCII, found '{fmt}'")));
    }
    let rest = lines.next().unwrap_or("");
    let mut t = Tokens { it: rest.split_ascii_whitespace().peekable() };
    let mut m = MixedMesh::default();
    let mut cells: Vec<Vec<usize>> = Vec::new();
    let mut types: Vec<u32> = Vec::new();
    let mut polydata = false;
    let res: std::result::Result<(), String> = (|| {
        while let Some(kw) = t.it.next() {
            match kw.to_ascii_uppercase().as_str() {
                "DATASET" => {
                    let d = t.next("dataset type")?;
                    match d.to_ascii_uppercase().as_str() {
                        "UNSTRUCTURED_GRID" => {}
                        "POLYDATA" => polydata = true,
                        other => {
                            return Err(format!("DATASET {other} is not supported (UNSTRUCTURED_GRID or POLYDATA)"))
                        }
                    }
                }
                "POINTS" => {
                    let n = t.usize("point count")?;
                    t.next("point data type")?;
                    m.vertices.reserve(n.min(rest.len()));
                    for k in 0..n {
                        let w = format!("coordinates of point {k}");
                        m.vertices.push(Vector3::new(t.f64(&w)?, t.f64(&w)?, t.f64(&w)?));
                    }
                }
                "CELLS" | "POLYGONS" | "TRIANGLE_STRIPS" => {
                    let is_poly = !kw.eq_ignore_ascii_case("CELLS");
                    let strips = kw.eq_ignore_ascii_case("TRIANGLE_STRIPS");
                    let a = t.usize("cell count")?;
                    let b = t.usize("cell list size")?;
                    let mut block: Vec<Vec<usize>> = Vec::new();
                    if t.it.peek().is_some_and(|s| s.eq_ignore_ascii_case("OFFSETS")) {
                        // VTK 5.1: a = number of offsets (cells + 1), b = connectivity length.
                        t.next("OFFSETS")?;
                        t.next("offset type")?;
                        let offsets: Vec<usize> =
                            (0..a).map(|_| t.usize("offset")).collect::<std::result::Result<_, _>>()?;
                        let c = t.next("CONNECTIVITY")?;
                        if !c.eq_ignore_ascii_case("CONNECTIVITY") {
                            return Err(format!("expected CONNECTIVITY, found '{c}'"));
                        }
                        t.next("connectivity type")?;
                        let conn: Vec<usize> =
                            (0..b).map(|_| t.usize("connectivity")).collect::<std::result::Result<_, _>>()?;
                        for w in offsets.windows(2) {
                            if w[0] > w[1] || w[1] > conn.len() {
                                return Err("OFFSETS are not increasing or exceed CONNECTIVITY".into());
                            }
                            block.push(conn[w[0]..w[1]].to_vec());
                        }
                    } else {
                        let mut used = 0;
                        for k in 0..a {
                            let n = t.usize(&format!("size of cell {k}"))?;
                            let c: Vec<usize> =
                                (0..n).map(|_| t.usize("cell index")).collect::<std::result::Result<_, _>>()?;
                            used += n + 1;
                            block.push(c);
                        }
                        if used != b {
                            return Err(format!("cell list size {b} does not match its content ({used})"));
                        }
                    }
                    if is_poly {
                        for c in block {
                            if strips {
                                for k in 0..c.len().saturating_sub(2) {
                                    let tri = if k % 2 == 0 {
                                        [c[k], c[k + 1], c[k + 2]]
                                    } else {
                                        [c[k + 1], c[k], c[k + 2]]
                                    };
                                    m.triangles.push(tri);
                                }
                            } else {
                                if c.len() < 3 {
                                    return Err(format!("polygon with {} corners", c.len()));
                                }
                                for k in 1..c.len() - 1 {
                                    m.triangles.push([c[0], c[k], c[k + 1]]);
                                }
                            }
                        }
                    } else {
                        cells = block;
                    }
                }
                "CELL_TYPES" => {
                    let n = t.usize("cell type count")?;
                    types = (0..n)
                        .map(|_| t.usize("cell type").map(|v| v as u32))
                        .collect::<std::result::Result<_, _>>()?;
                }
                "VERTICES" | "LINES" => {
                    let a = t.usize("count")?;
                    let b = t.usize("size")?;
                    let _ = a;
                    for _ in 0..b {
                        t.next("index")?;
                    }
                }
                "METADATA" => {
                    // VTK 9 writes "METADATA INFORMATION 0" after POINTS.
                    let k = t.next("INFORMATION")?;
                    let n = t.usize("information count")?;
                    if !k.eq_ignore_ascii_case("INFORMATION") || n != 0 {
                        return Err("METADATA with content is not supported".into());
                    }
                }
                // Attribute data follows: nothing more about geometry.
                "POINT_DATA" | "CELL_DATA" | "FIELD" => break,
                other => return Err(format!("unexpected keyword '{other}'")),
            }
        }
        Ok(())
    })();
    res.map_err(bad)?;
    if !polydata || !cells.is_empty() {
        if cells.len() != types.len() {
            return Err(bad(format!("{} cells but {} CELL_TYPES", cells.len(), types.len())));
        }
        for (c, &ty) in cells.iter().zip(&types) {
            let need = |n: usize| -> Result<()> {
                if c.len() != n {
                    return Err(bad(format!("cell of type {ty} has {} points, needs {n}", c.len())));
                }
                Ok(())
            };
            match ty {
                5 => {
                    need(3)?;
                    m.triangles.push([c[0], c[1], c[2]]);
                }
                22 => {
                    need(6)?;
                    m.triangles.push([c[0], c[1], c[2]]);
                }
                7 | 9 => {
                    for k in 1..c.len().saturating_sub(1) {
                        m.triangles.push([c[0], c[k], c[k + 1]]);
                    }
                }
                10 => {
                    need(4)?;
                    m.tets.push([c[0], c[1], c[2], c[3]]);
                }
                24 => {
                    need(10)?;
                    m.tets.push([c[0], c[1], c[2], c[3]]);
                }
                _ => {}
            }
        }
    }
    if m.vertices.is_empty() {
        return Err(bad("no POINTS".into()));
    }
    m.triangle_tags = vec![0; m.triangles.len()];
    m.tet_tags = vec![0; m.tets.len()];
    check_read(path, &m.vertices, &m.tets)?;
    check_read(path, &m.vertices, &m.triangles)?;
    Ok(m)
}

/// Write tetrahedra as an ASCII legacy VTK unstructured grid (double points), atomically.
pub fn write_vtk(path: impl AsRef<Path>, mesh: &TetMesh) -> Result<()> {
    write_vtk_fields(path, "laparo tetrahedral mesh", &mesh.vertices, &mesh.tets, &[], &[])
}

/// Values of one named VTK data array: one per node (`POINT_DATA`) or one per tetrahedron
/// (`CELL_DATA`).
#[derive(Debug, Clone, Copy)]
pub enum VtkValues<'a> {
    /// `SCALARS name int 1` (labels, indices).
    Int(&'a [i64]),
    /// `SCALARS name double 1` (distances in mm, errors, …).
    Double(&'a [f64]),
    /// `VECTORS name double` (displacements in mm, …).
    Vector(&'a [Vector3<f64>]),
}

impl VtkValues<'_> {
    fn len(&self) -> usize {
        match self {
            VtkValues::Int(v) => v.len(),
            VtkValues::Double(v) => v.len(),
            VtkValues::Vector(v) => v.len(),
        }
    }
}

/// A named data array for [`write_vtk_fields`].
#[derive(Debug, Clone, Copy)]
pub struct VtkField<'a> {
    /// Array name as ParaView shows it (no whitespace).
    pub name: &'a str,
    /// The values.
    pub values: VtkValues<'a>,
}

impl<'a> VtkField<'a> {
    /// A named array.
    pub fn new(name: &'a str, values: VtkValues<'a>) -> Self {
        VtkField { name, values }
    }
}

/// Write tetrahedra as an ASCII legacy VTK unstructured grid with per-node (`point_fields`) and
/// per-tetrahedron (`cell_fields`) data arrays, atomically; `title` is the header's comment line.
/// An array of the wrong length, a name with whitespace, a non-finite vertex or an out-of-range
/// index is an error naming `path`; nothing is written then.
pub fn write_vtk_fields(
    path: impl AsRef<Path>,
    title: &str,
    vertices: &[Vector3<f64>],
    tets: &[[usize; 4]],
    point_fields: &[VtkField<'_>],
    cell_fields: &[VtkField<'_>],
) -> Result<()> {
    let path = path.as_ref();
    check_read(path, vertices, tets)?;
    for (kind, fields, n) in [("node", point_fields, vertices.len()), ("cell", cell_fields, tets.len())] {
        for f in fields {
            if f.name.is_empty() || f.name.chars().any(char::is_whitespace) {
                return Err(CoreError::format(path, format!("VTK array name '{}' is empty or has whitespace", f.name)));
            }
            if f.values.len() != n {
                return Err(CoreError::format(
                    path,
                    format!("{kind} field `{}` has {} values for {n} {kind}s", f.name, f.values.len()),
                ));
            }
        }
    }
    let title: String = title.chars().map(|c| if c == '\n' || c == '\r' { ' ' } else { c }).collect();
    let mut s = format!("# vtk DataFile Version 3.0\n{title}\nASCII\nDATASET UNSTRUCTURED_GRID\n");
    let _ = writeln!(s, "POINTS {} double", vertices.len());
    for v in vertices {
        let _ = writeln!(s, "{} {} {}", fmt_f64(v.x), fmt_f64(v.y), fmt_f64(v.z));
    }
    let _ = writeln!(s, "CELLS {} {}", tets.len(), tets.len() * 5);
    for c in tets {
        let _ = writeln!(s, "4 {} {} {} {}", c[0], c[1], c[2], c[3]);
    }
    let _ = writeln!(s, "CELL_TYPES {}", tets.len());
    for _ in tets {
        s.push_str("10\n");
    }
    for (section, fields, n) in [("CELL_DATA", cell_fields, tets.len()), ("POINT_DATA", point_fields, vertices.len())] {
        if fields.is_empty() {
            continue;
        }
        let _ = writeln!(s, "{section} {n}");
        for f in fields {
            match f.values {
                VtkValues::Int(v) => {
                    let _ = writeln!(s, "SCALARS {} int 1\nLOOKUP_TABLE default", f.name);
                    for x in v {
                        let _ = writeln!(s, "{x}");
                    }
                }
                VtkValues::Double(v) => {
                    let _ = writeln!(s, "SCALARS {} double 1\nLOOKUP_TABLE default", f.name);
                    for &x in v {
                        let _ = writeln!(s, "{}", fmt_f64(x));
                    }
                }
                VtkValues::Vector(v) => {
                    let _ = writeln!(s, "VECTORS {} double", f.name);
                    for x in v {
                        let _ = writeln!(s, "{} {} {}", fmt_f64(x.x), fmt_f64(x.y), fmt_f64(x.z));
                    }
                }
            }
        }
    }
    write_atomic(path, s.as_bytes())
}
