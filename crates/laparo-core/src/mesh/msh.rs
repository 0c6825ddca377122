//! Gmsh `.msh` ASCII, versions 1 (`$NOD`/`$ELM`) and 2 (`$MeshFormat 2.x`/`$Nodes`/`$Elements`).
use super::{check_read, fmt_f64, MixedMesh, TetMesh};
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::Vector3;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// Read the tetrahedra of a Gmsh mesh (an error if it has none).
pub fn read_msh(path: impl AsRef<Path>) -> Result<TetMesh> {
    let path = path.as_ref();
    let m = read_msh_mixed(path)?;
    if m.tets.is_empty() {
        return Err(CoreError::format(
            path,
            format!("no tetrahedra ({} triangles): use read_msh_mixed or read_mesh for surfaces", m.triangles.len()),
        ));
    }
    Ok(m.tet_mesh())
}

/// Read nodes, triangles (type 2; corners of 6-node type 9) and tetrahedra (type 4; corners of
/// 10-node type 11) of an ASCII Gmsh v1 or v2 file with their physical tags. Other element types
/// (points, lines, quads, hexahedra, ...) are skipped. Node ids may be arbitrary.
pub fn read_msh_mixed(path: impl AsRef<Path>) -> Result<MixedMesh> {
    let path = path.as_ref();
    let bytes = crate::io::read_bytes(path)?;
    let text = String::from_utf8_lossy(&bytes);
    let lines: Vec<(usize, &str)> =
        text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())).filter(|(_, l)| !l.is_empty()).collect();
    let err = |no: usize, m: String| CoreError::format(path, format!("line {no}: {m}"));
    let mut i = 0;
    let mut version: Option<u32> = None;
    let mut ids: HashMap<i64, usize> = HashMap::new();
    let mut m = MixedMesh::default();
    let mut saw_nodes = false;
    let mut saw_elements = false;
    let num =
        |no: usize, s: &str| -> Result<f64> { s.parse::<f64>().map_err(|_| err(no, format!("'{s}' is not a number"))) };
    let int = |no: usize, s: &str| -> Result<i64> {
        s.parse::<i64>().map_err(|_| err(no, format!("'{s}' is not an integer")))
    };
    while i < lines.len() {
        let (no, l) = lines[i];
        match l {
            "$MeshFormat" => {
                let (no2, f) = *lines.get(i + 1).ok_or_else(|| err(no, "truncated $MeshFormat".into()))?;
                let t: Vec<&str> = f.split_whitespace().collect();
                let v: f64 = num(no2, t.first().copied().unwrap_or(""))?;
                if !(2.0..3.0).contains(&v) {
                    return Err(err(
                        no2,
                        format!(
                            "Gmsh format {v} is not supported (ASCII v1 or v2; convert with `gmsh -save -format msh2`)"
                        ),
                    ));
                }
                if t.get(1) != Some(&"0") {
                    return Err(err(no2, "binary .msh is not supported; save as ASCII".into()));
                }
                version = Some(2);
                i += 2;
                while i < lines.len() && lines[i].1 != "$EndMeshFormat" {
                    i += 1;
                }
                i += 1;
            }
            "$NOD" | "$Nodes" => {
                let end = if l == "$NOD" { "$ENDNOD" } else { "$EndNodes" };
                if version.is_none() {
                    version = Some(if l == "$NOD" { 1 } else { 2 });
                }
                let (no2, c) = *lines.get(i + 1).ok_or_else(|| err(no, "truncated node block".into()))?;
                let n = int(no2, c)? as usize;
                m.vertices.reserve(n.min(lines.len()));
                for k in 0..n {
                    let (nl, row) = *lines
                        .get(i + 2 + k)
                        .ok_or_else(|| err(no, format!("node block ends after {k} of {n} nodes")))?;
                    let t: Vec<&str> = row.split_whitespace().collect();
                    if t.len() < 4 {
                        return Err(err(nl, format!("node line has {} fields, needs 4", t.len())));
                    }
                    let id = int(nl, t[0])?;
                    if ids.insert(id, m.vertices.len()).is_some() {
                        return Err(err(nl, format!("duplicate node id {id}")));
                    }
                    m.vertices.push(Vector3::new(num(nl, t[1])?, num(nl, t[2])?, num(nl, t[3])?));
                }
                i += 2 + n;
                match lines.get(i) {
                    Some((_, e)) if *e == end => i += 1,
                    Some((nl, e)) => return Err(err(*nl, format!("expected {end}, found '{e}'"))),
                    None => return Err(err(no, format!("truncated: no {end}"))),
                }
                saw_nodes = true;
            }
            "$ELM" | "$Elements" => {
                let end = if l == "$ELM" { "$ENDELM" } else { "$EndElements" };
                let v1 = l == "$ELM";
                let (no2, c) = *lines.get(i + 1).ok_or_else(|| err(no, "truncated element block".into()))?;
                let n = int(no2, c)? as usize;
                for k in 0..n {
                    let (nl, row) = *lines
                        .get(i + 2 + k)
                        .ok_or_else(|| err(no, format!("element block ends after {k} of {n} elements")))?;
                    let t: Vec<i64> = row.split_whitespace().map(|s| int(nl, s)).collect::<Result<_>>()?;
                    if t.len() < 3 {
                        return Err(err(nl, "element line too short".into()));
                    }
                    let ty = t[1];
                    // v1: id type phys elem nnodes nodes... ; v2: id type ntags tags... nodes...
                    let (tag, nodes) = if v1 {
                        // a negative or huge count is refused before any index arithmetic
                        let nn = usize::try_from(t.get(4).copied().unwrap_or(-1)).ok();
                        if t.len() < 5 || nn.and_then(|n| n.checked_add(5)) != Some(t.len()) {
                            return Err(err(nl, "v1 element line: node count does not match".into()));
                        }
                        (t[2], &t[5..])
                    } else {
                        let nt = usize::try_from(t[2])
                            .map_err(|_| err(nl, format!("v2 element line: negative tag count {}", t[2])))?;
                        if nt > t.len() - 3 {
                            return Err(err(nl, "v2 element line: fewer tags than announced".into()));
                        }
                        (if nt > 0 { t[3] } else { 0 }, &t[3 + nt..])
                    };
                    let (want, corners) = match ty {
                        2 => (3, 3),
                        9 => (6, 3),
                        4 => (4, 4),
                        11 => (10, 4),
                        _ => (0, 0),
                    };
                    if corners == 0 {
                        continue;
                    }
                    if nodes.len() != want {
                        return Err(err(nl, format!("element type {ty} needs {want} nodes, line has {}", nodes.len())));
                    }
                    let mut idx = [0usize; 4];
                    for c in 0..corners {
                        idx[c] = *ids.get(&nodes[c]).ok_or_else(|| err(nl, format!("unknown node id {}", nodes[c])))?;
                    }
                    if corners == 3 {
                        m.triangles.push([idx[0], idx[1], idx[2]]);
                        m.triangle_tags.push(tag);
                    } else {
                        m.tets.push(idx);
                        m.tet_tags.push(tag);
                    }
                }
                i += 2 + n;
                match lines.get(i) {
                    Some((_, e)) if *e == end => i += 1,
                    Some((nl, e)) => return Err(err(*nl, format!("expected {end}, found '{e}'"))),
                    None => return Err(err(no, format!("truncated: no {end}"))),
                }
                saw_elements = true;
            }
            _ if l.starts_with('$') && !l.starts_with("$End") && !l.starts_with("$END") => {
                // Unknown section ($PhysicalNames, $NodeData, ...): skip to its end marker.
                let name = &l[1..];
                i += 1;
                while i < lines.len() && !lines[i].1.eq_ignore_ascii_case(&format!("$End{name}")) {
                    i += 1;
                }
                i += 1;
            }
            _ => return Err(err(no, format!("unexpected '{l}' (not a Gmsh ASCII v1/v2 file?)"))),
        }
    }
    if !saw_nodes || !saw_elements {
        return Err(CoreError::format(path, "not a Gmsh mesh: missing node or element section"));
    }
    check_read(path, &m.vertices, &m.tets)?;
    check_read(path, &m.vertices, &m.triangles)?;
    Ok(m)
}

/// Write tetrahedra as Gmsh ASCII v2.2 (node ids 1..n, element type 4, physical tag 1), atomically.
pub fn write_msh(path: impl AsRef<Path>, mesh: &TetMesh) -> Result<()> {
    let path = path.as_ref();
    check_read(path, &mesh.vertices, &mesh.tets)?;
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    let _ = writeln!(s, "{}", mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        let _ = writeln!(s, "{} {} {} {}", i + 1, fmt_f64(v.x), fmt_f64(v.y), fmt_f64(v.z));
    }
    let _ = writeln!(s, "$EndNodes\n$Elements\n{}", mesh.tets.len());
    for (i, t) in mesh.tets.iter().enumerate() {
        let _ = writeln!(s, "{} 4 2 1 1 {} {} {} {}", i + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
    }
    s.push_str("$EndElements\n");
    write_atomic(path, s.as_bytes())
}
