//! Stanford PLY: ascii, binary_little_endian and binary_big_endian.
use super::{check_read, fmt_f64, TriMesh};
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
enum Prop {
    Scalar(String, Ty),
    List(String, Ty, Ty),
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

#[derive(Clone, Copy, PartialEq)]
enum Enc {
    Ascii,
    Le,
    Be,
}

/// Value source over the body: whitespace tokens (ascii) or raw bytes (binary).
struct Body<'a> {
    bytes: &'a [u8],
    pos: usize,
    enc: Enc,
}

impl Body<'_> {
    fn next(&mut self, ty: Ty) -> std::result::Result<f64, String> {
        if self.enc == Enc::Ascii {
            while self.pos < self.bytes.len() && self.bytes[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            let start = self.pos;
            while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if start == self.pos {
                return Err("truncated: fewer values than the header announces".into());
            }
            let tok = std::str::from_utf8(&self.bytes[start..self.pos]).map_err(|_| "non-text value".to_string())?;
            return tok.parse::<f64>().map_err(|_| format!("'{tok}' is not a number"));
        }
        let n = ty.size();
        if self.pos + n > self.bytes.len() {
            return Err("truncated: fewer bytes than the header announces".into());
        }
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
        self.pos += n;
        if self.enc == Enc::Be {
            b[..n].reverse();
        }
        Ok(match ty {
            Ty::I8 => b[0] as i8 as f64,
            Ty::U8 => b[0] as f64,
            Ty::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F64 => f64::from_le_bytes(b),
        })
    }
}

/// Read a PLY mesh (vertex x, y, z; face `vertex_indices`/`vertex_index` lists, fan-triangulated).
/// A PLY without faces (a point cloud) gives a mesh without faces.
pub fn read_ply(path: impl AsRef<Path>) -> Result<TriMesh> {
    Ok(read_ply_with_colors(path)?.0)
}

/// Like [`read_ply`], also returning the per-vertex `red`/`green`/`blue` if present (as stored,
/// 0–255; float colours in [0, 1] are scaled).
pub fn read_ply_with_colors(path: impl AsRef<Path>) -> Result<(TriMesh, Option<Vec<[u8; 3]>>)> {
    let path = path.as_ref();
    let bytes = crate::io::read_bytes(path)?;
    let bad = |msg: String| CoreError::format(path, msg);
    if !bytes.starts_with(b"ply") {
        return Err(bad("not a PLY file (no 'ply' magic)".into()));
    }
    let end = find(&bytes, b"end_header").ok_or_else(|| bad("no 'end_header' (truncated header?)".into()))?;
    let mut body_start = end + b"end_header".len();
    if bytes.get(body_start) == Some(&b'\r') {
        body_start += 1;
    }
    if bytes.get(body_start) == Some(&b'\n') {
        body_start += 1;
    }
    let header = String::from_utf8_lossy(&bytes[..end]);
    let mut enc = None;
    let mut elements: Vec<Element> = Vec::new();
    for (i, line) in header.lines().enumerate() {
        let no = i + 1;
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["ply"] | [] => {}
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _ver] => {
                enc = Some(match *f {
                    "ascii" => Enc::Ascii,
                    "binary_little_endian" => Enc::Le,
                    "binary_big_endian" => Enc::Be,
                    _ => return Err(bad(format!("header line {no}: unknown format '{f}'"))),
                })
            }
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().map_err(|_| bad(format!("header line {no}: bad element count '{count}'")))?,
                props: Vec::new(),
            }),
            ["property", "list", ct, it, name] => {
                let (ct, it) = match (Ty::parse(ct), Ty::parse(it)) {
                    (Some(a), Some(b)) => (a, b),
                    _ => return Err(bad(format!("header line {no}: unknown list types '{ct} {it}'"))),
                };
                let e = elements.last_mut().ok_or_else(|| bad(format!("header line {no}: property before element")))?;
                e.props.push(Prop::List(name.to_string(), ct, it));
            }
            ["property", ty, name] => {
                let ty = Ty::parse(ty).ok_or_else(|| bad(format!("header line {no}: unknown type '{ty}'")))?;
                let e = elements.last_mut().ok_or_else(|| bad(format!("header line {no}: property before element")))?;
                e.props.push(Prop::Scalar(name.to_string(), ty));
            }
            _ => return Err(bad(format!("header line {no}: cannot parse '{line}'"))),
        }
    }
    let enc = enc.ok_or_else(|| bad("no 'format' line in the header".into()))?;
    let mut body = Body { bytes: &bytes[body_start..], pos: 0, enc };
    let mut vertices: Vec<Vector3<f64>> = Vec::new();
    let mut colors: Option<Vec<[u8; 3]>> = None;
    let mut faces: Vec<[usize; 3]> = Vec::new();
    for e in &elements {
        let is_vertex = e.name == "vertex";
        let is_face = e.name == "face";
        let pos_of = |n: &str| e.props.iter().position(|p| matches!(p, Prop::Scalar(m, _) if m == n));
        let (xi, yi, zi) = (pos_of("x"), pos_of("y"), pos_of("z"));
        let (ri, gi, bi) =
            (pos_of("red").or(pos_of("r")), pos_of("green").or(pos_of("g")), pos_of("blue").or(pos_of("b")));
        let float_color = ri.is_some_and(|i| matches!(e.props[i], Prop::Scalar(_, Ty::F32 | Ty::F64)));
        if is_vertex {
            if xi.is_none() || yi.is_none() || zi.is_none() {
                return Err(bad("vertex element without x, y, z".into()));
            }
            vertices.reserve(e.count.min(bytes.len()));
            if ri.is_some() && gi.is_some() && bi.is_some() {
                colors = Some(Vec::with_capacity(e.count.min(bytes.len())));
            }
        }
        let mut vals = vec![0f64; e.props.len()];
        let mut list: Vec<usize> = Vec::new();
        for k in 0..e.count {
            let ctx = |m: String| bad(format!("{} {}: {m}", e.name, k));
            for (pi, p) in e.props.iter().enumerate() {
                match p {
                    Prop::Scalar(_, ty) => vals[pi] = body.next(*ty).map_err(ctx)?,
                    Prop::List(name, ct, it) => {
                        let n = body.next(*ct).map_err(ctx)?;
                        if !(n >= 0.0 && n.fract() == 0.0 && n < 1e6) {
                            return Err(ctx(format!("bad list length {n}")));
                        }
                        let take = is_face && (name == "vertex_indices" || name == "vertex_index");
                        if take {
                            list.clear();
                        }
                        for _ in 0..n as usize {
                            let v = body.next(*it).map_err(ctx)?;
                            if take {
                                if !(v >= 0.0 && v.fract() == 0.0) {
                                    return Err(ctx(format!("bad vertex index {v}")));
                                }
                                list.push(v as usize);
                            }
                        }
                        if take {
                            if list.len() < 3 {
                                return Err(ctx(format!("face with {} corners", list.len())));
                            }
                            for j in 1..list.len() - 1 {
                                faces.push([list[0], list[j], list[j + 1]]);
                            }
                        }
                    }
                }
            }
            if is_vertex {
                vertices.push(Vector3::new(vals[xi.unwrap()], vals[yi.unwrap()], vals[zi.unwrap()]));
                if let Some(c) = colors.as_mut() {
                    let conv = |v: f64| {
                        if float_color {
                            (v * 255.0).round().clamp(0.0, 255.0) as u8
                        } else {
                            v.clamp(0.0, 255.0) as u8
                        }
                    };
                    c.push([conv(vals[ri.unwrap()]), conv(vals[gi.unwrap()]), conv(vals[bi.unwrap()])]);
                }
            }
        }
    }
    if !elements.iter().any(|e| e.name == "vertex") {
        return Err(bad("no 'vertex' element".into()));
    }
    check_read(path, &vertices, &faces)?;
    Ok((TriMesh { vertices, faces }, colors))
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// PLY body encoding for [`write_ply_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    /// ASCII PLY.
    Ascii,
    /// Binary little-endian PLY.
    BinaryLittleEndian,
}

/// Write a binary little-endian PLY (double x, y, z; int vertex indices), atomically.
pub fn write_ply(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    write_ply_with(path, mesh, PlyEncoding::BinaryLittleEndian, None)
}

/// Write a PLY with the chosen encoding and optional per-vertex RGB colours, atomically.
/// Coordinates are stored as double, so reading back is bit-exact.
pub fn write_ply_with(
    path: impl AsRef<Path>,
    mesh: &TriMesh,
    encoding: PlyEncoding,
    colors: Option<&[[u8; 3]]>,
) -> Result<()> {
    let path = path.as_ref();
    check_read(path, &mesh.vertices, &mesh.faces)?;
    if let Some(c) = colors {
        if c.len() != mesh.vertices.len() {
            return Err(CoreError::SizeMismatch(format!(
                "{}: {} colours for {} vertices",
                path.display(),
                c.len(),
                mesh.vertices.len()
            )));
        }
    }
    if mesh.vertices.len() > i32::MAX as usize {
        return Err(CoreError::format(path, "too many vertices for 32-bit PLY indices"));
    }
    let mut h = String::from("ply\n");
    h.push_str(match encoding {
        PlyEncoding::Ascii => "format ascii 1.0\n",
        PlyEncoding::BinaryLittleEndian => "format binary_little_endian 1.0\n",
    });
    h.push_str("comment written by laparo\n");
    let _ = writeln!(h, "element vertex {}", mesh.vertices.len());
    h.push_str("property double x\nproperty double y\nproperty double z\n");
    if colors.is_some() {
        h.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    let _ = writeln!(h, "element face {}", mesh.faces.len());
    h.push_str("property list uchar int vertex_indices\nend_header\n");
    let mut out = h.into_bytes();
    match encoding {
        PlyEncoding::Ascii => {
            let mut s = String::new();
            for (i, v) in mesh.vertices.iter().enumerate() {
                let _ = write!(s, "{} {} {}", fmt_f64(v.x), fmt_f64(v.y), fmt_f64(v.z));
                if let Some(c) = colors {
                    let _ = write!(s, " {} {} {}", c[i][0], c[i][1], c[i][2]);
                }
                s.push('\n');
            }
            for f in &mesh.faces {
                let _ = writeln!(s, "3 {} {} {}", f[0], f[1], f[2]);
            }
            out.extend_from_slice(s.as_bytes());
        }
        PlyEncoding::BinaryLittleEndian => {
            for (i, v) in mesh.vertices.iter().enumerate() {
                for c in [v.x, v.y, v.z] {
                    out.extend_from_slice(&c.to_le_bytes());
                }
                if let Some(c) = colors {
                    out.extend_from_slice(&c[i]);
                }
            }
            for f in &mesh.faces {
                out.push(3);
                for &k in f {
                    out.extend_from_slice(&(k as i32).to_le_bytes());
                }
            }
        }
    }
    write_atomic(path, &out)
}
