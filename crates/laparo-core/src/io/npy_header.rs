//! A bounded reader for NumPy `.npy` data: the header is a Python dict literal
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (H, W), }` parsed by a small grammar that
//! accepts only what NumPy writes (quoted keys, one quoted string, `True`/`False`, one flat tuple
//! of decimal integers). Nested collections, hexadecimal, underscores and other Python syntax are
//! rejected, the header is at most [`MAX_HEADER_BYTES`], and the data length implied by the shape
//! is compared with the bytes present **before** anything is allocated, so a small hostile file
//! can neither run for long nor request a huge allocation.

/// Largest header accepted (NumPy itself refuses headers above 10,000 bytes by default).
pub const MAX_HEADER_BYTES: usize = 65_536;
/// Largest dimension value accepted (each axis).
const MAX_DIM: u64 = 1 << 40;
/// Most axes accepted.
const MAX_AXES: usize = 8;

/// Element type of a `.npy` array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    Bool,
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F16,
    F32,
    F64,
}

impl Dtype {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Dtype::Bool | Dtype::U8 | Dtype::I8 => 1,
            Dtype::U16 | Dtype::I16 | Dtype::F16 => 2,
            Dtype::U32 | Dtype::I32 | Dtype::F32 => 4,
            Dtype::U64 | Dtype::I64 | Dtype::F64 => 8,
        }
    }
}

/// A parsed `.npy` header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NpyHeader {
    pub dtype: Dtype,
    pub big_endian: bool,
    pub fortran_order: bool,
    pub shape: Vec<usize>,
    /// Offset of the first data byte in the file.
    pub data_offset: usize,
}

impl NpyHeader {
    /// Number of elements (checked: the product of the axes fits in u64 and below 2^48).
    pub fn count(&self) -> Result<usize, String> {
        let mut n: u64 = 1;
        for &d in &self.shape {
            n = n
                .checked_mul(d as u64)
                .filter(|&n| n < (1 << 48))
                .ok_or("truncated: the shape announces more elements (over 2^48) than the file holds")?;
        }
        Ok(n as usize)
    }
    /// Bytes of data the header announces.
    pub fn data_bytes(&self) -> Result<usize, String> {
        Ok(self.count()? * self.dtype.size())
    }
}

/// Parse the magic, version and header dict at the start of `bytes` (which may hold only the
/// beginning of the file).
pub fn parse_header(bytes: &[u8]) -> Result<NpyHeader, String> {
    if bytes.len() < 10 || !bytes.starts_with(b"\x93NUMPY") {
        return Err("not a .npy file (missing the \\x93NUMPY magic)".into());
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("truncated: header is cut short".into());
            }
            (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12)
        }
        v => return Err(format!("unsupported .npy format version {v}")),
    };
    if hlen > MAX_HEADER_BYTES {
        return Err(format!("header of {hlen} bytes is larger than {MAX_HEADER_BYTES}"));
    }
    let header = bytes.get(start..start + hlen).ok_or("truncated: header is cut short")?;
    let text = std::str::from_utf8(header).map_err(|_| "header is not ASCII text")?;
    let mut p = DictParser { s: text.as_bytes(), pos: 0 };
    let (descr, fortran, shape) = p.dict()?;
    let (dtype, big_endian) = parse_descr(&descr)?;
    Ok(NpyHeader { dtype, big_endian, fortran_order: fortran, shape, data_offset: start + hlen })
}

fn parse_descr(d: &str) -> Result<(Dtype, bool), String> {
    let (order, code) = match d.as_bytes().first() {
        Some(b'<') | Some(b'|') | Some(b'=') => (false, &d[1..]),
        Some(b'>') => (true, &d[1..]),
        _ => (false, d),
    };
    let t = match code {
        "b1" | "?" => Dtype::Bool,
        "u1" | "B" => Dtype::U8,
        "i1" | "b" => Dtype::I8,
        "u2" => Dtype::U16,
        "i2" => Dtype::I16,
        "u4" => Dtype::U32,
        "i4" => Dtype::I32,
        "u8" => Dtype::U64,
        "i8" => Dtype::I64,
        "f2" | "e" => Dtype::F16,
        "f4" | "f" => Dtype::F32,
        "f8" | "d" => Dtype::F64,
        _ => return Err(format!("unsupported dtype {d:?} (expected bool, integers, float16, float32 or float64)")),
    };
    Ok((t, order && t.size() > 1))
}

struct DictParser<'a> {
    s: &'a [u8],
    pos: usize,
}

impl DictParser<'_> {
    fn ws(&mut self) {
        while self.pos < self.s.len() && matches!(self.s[self.pos], b' ' | b'\t' | b'\n' | b'\r') {
            self.pos += 1;
        }
    }
    fn expect(&mut self, c: u8) -> Result<(), String> {
        self.ws();
        if self.s.get(self.pos) == Some(&c) {
            self.pos += 1;
            Ok(())
        } else {
            Err(format!("header: expected '{}' at byte {}", c as char, self.pos))
        }
    }
    fn peek(&mut self) -> Option<u8> {
        self.ws();
        self.s.get(self.pos).copied()
    }
    fn string(&mut self) -> Result<String, String> {
        self.ws();
        let q = match self.s.get(self.pos) {
            Some(&q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("header: expected a quoted string at byte {}", self.pos)),
        };
        self.pos += 1;
        let start = self.pos;
        while self.pos < self.s.len() && self.s[self.pos] != q {
            if self.s[self.pos] == b'\\' || self.pos - start > 64 {
                return Err("header: unsupported string (escapes or longer than 64 characters)".into());
            }
            self.pos += 1;
        }
        if self.pos >= self.s.len() {
            return Err("header: unterminated string".into());
        }
        let v = String::from_utf8_lossy(&self.s[start..self.pos]).into_owned();
        self.pos += 1;
        Ok(v)
    }
    fn word(&mut self) -> &str {
        self.ws();
        let start = self.pos;
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_alphanumeric() {
            self.pos += 1;
        }
        std::str::from_utf8(&self.s[start..self.pos]).unwrap_or("")
    }
    fn int(&mut self) -> Result<usize, String> {
        self.ws();
        let start = self.pos;
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_digit() {
            self.pos += 1;
        }
        let digits = std::str::from_utf8(&self.s[start..self.pos]).unwrap_or("");
        // Python 2 long suffix.
        if self.s.get(self.pos) == Some(&b'L') {
            self.pos += 1;
        }
        if digits.is_empty() || digits.len() > 13 {
            return Err(format!("header: shape entry at byte {start} is not a plain decimal integer"));
        }
        if matches!(self.s.get(self.pos), Some(c) if c.is_ascii_alphanumeric() || *c == b'_' || *c == b'.') {
            return Err(format!("header: shape entry at byte {start} is not a plain decimal integer"));
        }
        let v: u64 = digits.parse().map_err(|_| "header: bad shape entry".to_string())?;
        if v > MAX_DIM {
            return Err(format!("header: dimension {v} is larger than {MAX_DIM}"));
        }
        Ok(v as usize)
    }
    fn shape(&mut self) -> Result<Vec<usize>, String> {
        self.expect(b'(')?;
        let mut v = Vec::new();
        loop {
            if self.peek() == Some(b')') {
                self.pos += 1;
                return Ok(v);
            }
            if v.len() == MAX_AXES {
                return Err(format!("header: more than {MAX_AXES} axes"));
            }
            v.push(self.int()?);
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b')') => {}
                _ => return Err(format!("header: expected ',' or ')' in the shape at byte {}", self.pos)),
            }
        }
    }
    fn dict(&mut self) -> Result<(String, bool, Vec<usize>), String> {
        self.expect(b'{')?;
        let (mut descr, mut fortran, mut shape) = (None, None, None);
        loop {
            if self.peek() == Some(b'}') {
                self.pos += 1;
                break;
            }
            let key = self.string()?;
            self.expect(b':')?;
            match key.as_str() {
                "descr" if descr.is_none() => {
                    if self.peek() != Some(b'\'') && self.peek() != Some(b'"') {
                        return Err("header: structured dtypes are not supported ('descr' must be a string)".into());
                    }
                    descr = Some(self.string()?)
                }
                "fortran_order" if fortran.is_none() => {
                    fortran = Some(match self.word() {
                        "True" => true,
                        "False" => false,
                        w => return Err(format!("header: fortran_order is '{w}', expected True or False")),
                    })
                }
                "shape" if shape.is_none() => shape = Some(self.shape()?),
                k => return Err(format!("header: unexpected or repeated key '{k}'")),
            }
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b'}') => {}
                _ => return Err(format!("header: expected ',' or '}}' at byte {}", self.pos)),
            }
        }
        self.ws();
        if self.pos != self.s.len() {
            return Err("header: text after the closing '}'".into());
        }
        match (descr, fortran, shape) {
            (Some(d), Some(f), Some(s)) => Ok((d, f, s)),
            _ => Err("header: 'descr', 'fortran_order' and 'shape' are all required".into()),
        }
    }
}

/// IEEE 754 binary16 → f64 (exact).
pub fn f16_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let man = (h & 0x3ff) as f64;
    match exp {
        0 => sign * man * 2f64.powi(-24),
        31 if man == 0.0 => sign * f64::INFINITY,
        31 => f64::NAN,
        e => sign * (1.0 + man / 1024.0) * 2f64.powi(e - 15),
    }
}

/// Decode the data of `h` from `data` (exactly `h.data_bytes()` bytes) to f64 values in logical
/// row-major order (Fortran-ordered arrays are transposed).
pub fn decode(h: &NpyHeader, data: &[u8]) -> Result<Vec<f64>, String> {
    let need = h.data_bytes()?;
    if data.len() < need {
        return Err(format!("truncated: the header announces {need} bytes of data, the file has {}", data.len()));
    }
    if data.len() > need {
        return Err(format!("{} unexpected bytes after the array data", data.len() - need));
    }
    let sz = h.dtype.size();
    let be = h.big_endian;
    macro_rules! conv {
        ($t:ty, $n:expr, $f:expr) => {{
            data.chunks_exact($n)
                .map(|c| {
                    let a: [u8; $n] = c.try_into().unwrap_or([0; $n]);
                    let v = if be { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) };
                    $f(v)
                })
                .collect::<Vec<f64>>()
        }};
    }
    let flat: Vec<f64> = match h.dtype {
        Dtype::Bool => data.iter().map(|&b| if b != 0 { 1.0 } else { 0.0 }).collect(),
        Dtype::U8 => data.iter().map(|&b| b as f64).collect(),
        Dtype::I8 => data.iter().map(|&b| b as i8 as f64).collect(),
        Dtype::U16 => conv!(u16, 2, |v: u16| v as f64),
        Dtype::I16 => conv!(i16, 2, |v: i16| v as f64),
        Dtype::F16 => conv!(u16, 2, f16_to_f64),
        Dtype::U32 => conv!(u32, 4, |v: u32| v as f64),
        Dtype::I32 => conv!(i32, 4, |v: i32| v as f64),
        Dtype::F32 => conv!(f32, 4, |v: f32| v as f64),
        Dtype::U64 => conv!(u64, 8, |v: u64| v as f64),
        Dtype::I64 => conv!(i64, 8, |v: i64| v as f64),
        Dtype::F64 => conv!(f64, 8, |v: f64| v),
    };
    debug_assert_eq!(flat.len() * sz, need);
    if !h.fortran_order || h.shape.len() < 2 {
        return Ok(flat);
    }
    // Fortran order: the first axis varies fastest. Walk the C-order index and map it.
    let n = flat.len();
    let dims = &h.shape;
    let mut strides = vec![1usize; dims.len()];
    for i in 1..dims.len() {
        strides[i] = strides[i - 1] * dims[i - 1];
    }
    let mut out = Vec::with_capacity(n);
    let mut idx = vec![0usize; dims.len()];
    for _ in 0..n {
        let off: usize = idx.iter().zip(&strides).map(|(i, s)| i * s).sum();
        out.push(flat[off]);
        for ax in (0..dims.len()).rev() {
            idx[ax] += 1;
            if idx[ax] < dims[ax] {
                break;
            }
            idx[ax] = 0;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(header: &str, data: &[u8]) -> Vec<u8> {
        let mut f = b"\x93NUMPY\x01\x00".to_vec();
        f.extend_from_slice(&(header.len() as u16).to_le_bytes());
        f.extend_from_slice(header.as_bytes());
        f.extend_from_slice(data);
        f
    }

    #[test]
    fn numpy_headers_parse() {
        let h = parse_header(&file("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }   \n", &[])).unwrap();
        assert_eq!((h.dtype, h.big_endian, h.fortran_order, h.shape.clone()), (Dtype::F64, false, false, vec![2, 3]));
        assert_eq!(h.data_bytes().unwrap(), 48);
        let h = parse_header(&file("{\"descr\": \">f2\", \"fortran_order\": True, \"shape\": (5,)}", &[])).unwrap();
        assert_eq!((h.dtype, h.big_endian, h.fortran_order, h.shape), (Dtype::F16, true, true, vec![5]));
        let h = parse_header(&file("{'descr': '|b1', 'fortran_order': False, 'shape': (), }", &[])).unwrap();
        assert_eq!(h.count().unwrap(), 1);
    }

    /// Regression (issue 10): hexadecimal, underscores, nested lists and huge dimensions went
    /// through ndarray-npy's literal parser (exponential time, 80 GB allocations).
    #[test]
    fn hostile_headers_are_rejected() {
        for hdr in [
            "{'descr': '<f8', 'fortran_order': False, 'shape': (0x100000, 100000), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (100_000, 100_000), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': ((((((((((((((((((((((1,),),),),),),),),),),),),),),),),),),),),),), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999999, 1), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1.5, 1), }",
            "{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (1,), }",
            "{'descr': '<c16', 'fortran_order': False, 'shape': (1,), }",
            "{'descr': '<f8', 'fortran_order': 0, 'shape': (1,), }",
            "{'descr': '<f8', 'descr': '<f8', 'fortran_order': False, 'shape': (1,), }",
            "{'descr': '<f8', 'shape': (1,), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1,), } x",
            "[1, 2]",
        ] {
            assert!(parse_header(&file(hdr, &[0; 8])).is_err(), "{hdr}");
        }
        // 100000 x 100000 f64 in a tiny file: parsed, then refused before allocating.
        let h =
            parse_header(&file("{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }", &[])).unwrap();
        assert!(decode(&h, &[0; 64]).unwrap_err().contains("truncated"));
    }

    #[test]
    fn f16_values_by_hand() {
        assert_eq!(f16_to_f64(0x3c00), 1.0);
        assert_eq!(f16_to_f64(0xc000), -2.0);
        assert_eq!(f16_to_f64(0x3555), 0.333251953125);
        assert_eq!(f16_to_f64(0x7bff), 65504.0);
        assert_eq!(f16_to_f64(0x0001), 2f64.powi(-24));
        assert_eq!(f16_to_f64(0x7c00), f64::INFINITY);
        assert!(f16_to_f64(0x7e00).is_nan());
    }

    #[test]
    fn fortran_order_3d_is_transposed() {
        // shape (2, 2, 2), value at (i, j, k) = 100i + 10j + k, stored with i fastest.
        let mut data = Vec::new();
        for k in 0..2u8 {
            for j in 0..2u8 {
                for i in 0..2u8 {
                    data.push(100 * i + 10 * j + k);
                }
            }
        }
        let h = parse_header(&file("{'descr': '|u1', 'fortran_order': True, 'shape': (2, 2, 2), }", &[])).unwrap();
        let v = decode(&h, &data).unwrap();
        assert_eq!(v, vec![0.0, 1.0, 10.0, 11.0, 100.0, 101.0, 110.0, 111.0]);
    }
}
