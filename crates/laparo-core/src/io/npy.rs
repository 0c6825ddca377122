//! NumPy `.npy` and `.npz` arrays as images: shape (H, W) → 1 channel, (H, W, C) → C channels
//! (leading singleton axes of 4-D+ arrays are dropped; a 3-D (1, H, W) with W > 4 is read as (H, W)). Any of f32, f64, u8, u16, u32, u64, i8, i16, i32, i64
//! and bool, little- or big-endian, C or Fortran order; values are converted to f64 on reading.
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use crate::image::Image;
use ndarray::{ArrayD, IxDyn};
use ndarray_npy::{ReadNpyError, ReadNpyExt, WritableElement, WriteNpyExt};
use std::io::{Cursor, Read};
use std::path::Path;

fn npy_error(what: &str, e: ReadNpyError) -> String {
    match e {
        ReadNpyError::MissingData => format!("{what}truncated: less data than the header announces"),
        ReadNpyError::Io(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("{what}truncated: unexpected end of file")
        }
        ReadNpyError::ExtraBytes(n) => format!("{what}{n} unexpected bytes after the array data"),
        ReadNpyError::ParseHeader(e) => format!("{what}not a valid .npy file: {e}"),
        ReadNpyError::WrongDescriptor(d) => format!("{what}unsupported dtype {d}"),
        e => format!("{what}{e}"),
    }
}

fn shape_to_image(path: &Path, what: &str, shape: &[usize], data: Vec<f64>) -> Result<Image<f64>> {
    let mut dims: Vec<usize> = shape.to_vec();
    if dims.len() > 3 {
        while dims.len() > 2 && dims[0] == 1 {
            dims.remove(0);
        }
    }
    // (1, H, W) as written by PyTorch-style code: a channel axis first, wider than 4.
    if dims.len() == 3 && dims[0] == 1 && dims[2] > 4 {
        dims.remove(0);
    }
    let (h, w, c) = match dims.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, c] if *c >= 1 => (*h, *w, *c),
        _ => {
            return Err(CoreError::format(
                path,
                format!("{what}array of shape {shape:?} is not an image (expected (H, W) or (H, W, C))"),
            ))
        }
    };
    Image::from_vec(w, h, c, data).map_err(|e| CoreError::format(path, format!("{what}{e}")))
}

/// Check, before ndarray-npy allocates, that the data announced by the header (shape × item
/// size) is present, so a corrupt header cannot request a huge allocation.
fn check_npy_length(bytes: &[u8]) -> std::result::Result<(), String> {
    if bytes.len() < 10 || !bytes.starts_with(b"\x93NUMPY") {
        return Ok(()); // ndarray-npy reports the bad magic
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        _ if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        _ => return Ok(()),
    };
    let Some(header) = bytes.get(start..start + hlen) else {
        return Err("truncated: header is cut short".into());
    };
    let header = String::from_utf8_lossy(header);
    let field = |key: &str| header.find(key).map(|i| &header[i + key.len()..]);
    let Some(shape) = field("'shape'") else { return Ok(()) };
    let Some(open) = shape.find('(') else { return Ok(()) };
    let Some(close) = shape.find(')') else { return Ok(()) };
    let mut count: u128 = 1;
    for d in shape[open + 1..close].split(',').map(str::trim).filter(|d| !d.is_empty()) {
        let Ok(d) = d.trim_end_matches('L').parse::<u128>() else { return Ok(()) };
        count = count.saturating_mul(d);
    }
    let item: u128 = field("'descr'")
        .and_then(|d| d.split('\'').nth(1))
        .map(|d| d.chars().rev().take_while(|c| c.is_ascii_digit()).collect::<String>())
        .and_then(|digits| digits.chars().rev().collect::<String>().parse().ok())
        .unwrap_or(1);
    let need = count.saturating_mul(item);
    let have = (bytes.len() - (start + hlen)) as u128;
    if need > have {
        return Err(format!("truncated: the header announces {need} bytes of data, the file has {have}"));
    }
    Ok(())
}

/// Decode `.npy` bytes into an image; `what` prefixes messages (e.g. the array name in a .npz).
fn npy_bytes_to_image(bytes: &[u8], path: &Path, what: &str) -> Result<Image<f64>> {
    check_npy_length(bytes).map_err(|m| CoreError::format(path, format!("{what}{m}")))?;
    macro_rules! attempt {
        ($t:ty, $conv:expr) => {
            match ArrayD::<$t>::read_npy(bytes) {
                Ok(a) => {
                    let shape = a.shape().to_vec();
                    // `iter` walks in logical (row-major) order whatever the memory order.
                    let data: Vec<f64> = a.iter().map(|&v| $conv(v)).collect();
                    return shape_to_image(path, what, &shape, data);
                }
                Err(ReadNpyError::WrongDescriptor(_)) => {}
                Err(e) => return Err(CoreError::format(path, npy_error(what, e))),
            }
        };
    }
    attempt!(f64, |v: f64| v);
    attempt!(f32, |v: f32| v as f64);
    attempt!(u8, |v: u8| v as f64);
    attempt!(u16, |v: u16| v as f64);
    attempt!(i32, |v: i32| v as f64);
    attempt!(i64, |v: i64| v as f64);
    attempt!(u32, |v: u32| v as f64);
    attempt!(u64, |v: u64| v as f64);
    attempt!(i16, |v: i16| v as f64);
    attempt!(i8, |v: i8| v as f64);
    match ArrayD::<bool>::read_npy(bytes) {
        Ok(a) => {
            let shape = a.shape().to_vec();
            let data = a.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
            shape_to_image(path, what, &shape, data)
        }
        Err(e) => Err(CoreError::format(path, npy_error(what, e))),
    }
}

/// Read a `.npy` array as an `Image<f64>` (see the module doc for the accepted shapes and dtypes).
pub fn read_npy(path: impl AsRef<Path>) -> Result<Image<f64>> {
    let path = path.as_ref();
    let bytes = super::read_bytes(path)?;
    npy_bytes_to_image(&bytes, path, "")
}

fn open_npz(path: &Path) -> Result<zip::ZipArchive<Cursor<Vec<u8>>>> {
    let bytes = super::read_bytes(path)?;
    zip::ZipArchive::new(Cursor::new(bytes))
        .map_err(|e| CoreError::format(path, format!("not a valid .npz (zip) archive: {e}")))
}

/// Names of the arrays stored in a `.npz` archive (without the `.npy` suffix), in archive order.
pub fn read_npz_names(path: impl AsRef<Path>) -> Result<Vec<String>> {
    let path = path.as_ref();
    let zip = open_npz(path)?;
    Ok((0..zip.len())
        .filter_map(|i| zip.name_for_index(i))
        .map(|n| n.strip_suffix(".npy").unwrap_or(n).to_string())
        .collect())
}

/// Read one array of a `.npz` archive as an `Image<f64>`: the array called `name`, or the first
/// array of the archive when `name` is `None`.
pub fn read_npz(path: impl AsRef<Path>, name: Option<&str>) -> Result<Image<f64>> {
    let path = path.as_ref();
    let mut zip = open_npz(path)?;
    if zip.is_empty() {
        return Err(CoreError::format(path, "the .npz archive holds no array"));
    }
    let index = match name {
        None => 0,
        Some(n) => {
            let with = format!("{n}.npy");
            match zip.index_for_name(n).or_else(|| zip.index_for_name(&with)) {
                Some(i) => i,
                None => {
                    let names: Vec<&str> = (0..zip.len()).filter_map(|i| zip.name_for_index(i)).collect();
                    return Err(CoreError::format(path, format!("no array '{n}' in the archive (it holds {names:?})")));
                }
            }
        }
    };
    let mut entry = zip.by_index(index).map_err(|e| CoreError::format(path, format!("cannot open array: {e}")))?;
    let what = format!("array '{}': ", entry.name().strip_suffix(".npy").unwrap_or(entry.name()));
    let mut bytes = Vec::with_capacity((entry.size() as usize).min(1 << 26));
    entry.read_to_end(&mut bytes).map_err(|e| CoreError::format(path, format!("{what}cannot decompress: {e}")))?;
    npy_bytes_to_image(&bytes, path, &what)
}

fn to_array<T: Copy>(img: &Image<T>) -> ArrayD<T> {
    let shape =
        if img.channels == 1 { IxDyn(&[img.height, img.width]) } else { IxDyn(&[img.height, img.width, img.channels]) };
    ArrayD::from_shape_vec(shape, img.data.clone()).expect("image data length checked")
}

fn write_npy_generic<T: Copy + WritableElement>(path: &Path, img: &Image<T>) -> Result<()> {
    super::check_writable(path, img, &[1, 2, 3, 4, 5, 6, 7, 8])?;
    let mut buf = Vec::new();
    to_array(img).write_npy(&mut buf).map_err(|e| CoreError::format(path, format!("cannot encode .npy: {e}")))?;
    write_atomic(path, &buf)
}

/// Write a float32 image as `.npy` (shape (H, W) for one channel, else (H, W, C)), atomically.
pub fn write_npy_f32(path: impl AsRef<Path>, img: &Image<f32>) -> Result<()> {
    write_npy_generic(path.as_ref(), img)
}

/// Write a float64 image as `.npy` (shape (H, W) for one channel, else (H, W, C)), atomically.
pub fn write_npy_f64(path: impl AsRef<Path>, img: &Image<f64>) -> Result<()> {
    write_npy_generic(path.as_ref(), img)
}

/// Write named float64 images into one uncompressed `.npz` archive, atomically.
pub fn write_npz_f64(path: impl AsRef<Path>, arrays: &[(&str, &Image<f64>)]) -> Result<()> {
    let path = path.as_ref();
    let mut npz = ndarray_npy::NpzWriter::new(Cursor::new(Vec::new()));
    for (name, img) in arrays {
        super::check_writable(path, img, &[1, 2, 3, 4, 5, 6, 7, 8])?;
        npz.add_array(*name, &to_array(img))
            .map_err(|e| CoreError::format(path, format!("cannot add array '{name}': {e}")))?;
    }
    let cur = npz.finish().map_err(|e| CoreError::format(path, format!("cannot finish .npz: {e}")))?;
    write_atomic(path, &cur.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Array2, Array3, ShapeBuilder};

    fn write_raw<T: WritableElement>(p: &Path, a: &ArrayD<T>) {
        let mut buf = Vec::new();
        a.write_npy(&mut buf).unwrap();
        std::fs::write(p, buf).unwrap();
    }

    #[test]
    fn npy_round_trip_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let img64 = Image::from_vec(3, 2, 1, vec![1.5, -2.25, f64::NAN, 1e-300, 7.0, f64::INFINITY]).unwrap();
        let p = dir.path().join("a.npy");
        write_npy_f64(&p, &img64).unwrap();
        let back = read_npy(&p).unwrap();
        assert_eq!(back.size(), (3, 2));
        for (a, b) in back.data.iter().zip(&img64.data) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        let img32 = Image::from_vec(2, 2, 3, (0..12).map(|i| i as f32 * 0.1 - 0.3).collect()).unwrap();
        write_npy_f32(&p, &img32).unwrap();
        let back = read_npy(&p).unwrap();
        assert_eq!(back.channels, 3);
        for (a, b) in back.data.iter().zip(&img32.data) {
            assert_eq!(*a, *b as f64);
        }
    }

    #[test]
    fn npy_integer_dtypes_and_fortran_order() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("i.npy");
        // (2, 3) array [[0,1,2],[3,4,5]] stored in Fortran order.
        let f = Array2::from_shape_vec((2, 3).f(), vec![0u16, 3, 1, 4, 2, 5]).unwrap();
        assert_eq!(f[[0, 1]], 1);
        write_raw(&p, &f.into_dyn());
        let img = read_npy(&p).unwrap();
        assert_eq!(img.size(), (3, 2));
        assert_eq!(img.data, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        let a = Array2::from_shape_vec((1, 2), vec![-5i32, 70000]).unwrap().into_dyn();
        write_raw(&p, &a);
        assert_eq!(read_npy(&p).unwrap().data, vec![-5.0, 70000.0]);
        let a = Array2::from_shape_vec((1, 2), vec![-5i64, 1 << 40]).unwrap().into_dyn();
        write_raw(&p, &a);
        assert_eq!(read_npy(&p).unwrap().data, vec![-5.0, (1u64 << 40) as f64]);
        let a = Array3::from_shape_vec((1, 1, 2), vec![255u8, 3]).unwrap().into_dyn();
        write_raw(&p, &a);
        let img = read_npy(&p).unwrap();
        assert_eq!((img.channels, img.data.clone()), (2, vec![255.0, 3.0]));
        let a = Array2::from_shape_vec((1, 2), vec![true, false]).unwrap().into_dyn();
        write_raw(&p, &a);
        assert_eq!(read_npy(&p).unwrap().data, vec![1.0, 0.0]);
        // leading singleton axis (1, H, W)
        let a = Array3::from_shape_vec((1, 2, 5), vec![1.0f32; 10]).unwrap().into_dyn();
        write_raw(&p, &a);
        let img = read_npy(&p).unwrap();
        assert_eq!((img.width, img.height, img.channels), (5, 2, 1));
        let a = ndarray::Array4::from_shape_vec((1, 1, 2, 3), vec![1.0f32; 6]).unwrap().into_dyn();
        write_raw(&p, &a);
        let img = read_npy(&p).unwrap();
        assert_eq!((img.width, img.height, img.channels), (3, 2, 1));
    }

    #[test]
    fn npy_bad_files_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.npy");
        write_npy_f64(&p, &Image::filled(10, 10, 1, 1.0)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 8]).unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("t.npy") && e.contains("truncated"), "{e}");
        std::fs::write(&p, &bytes[..20]).unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("t.npy"), "{e}");
        std::fs::write(&p, b"garbage garbage garbage").unwrap();
        assert!(read_npy(&p).unwrap_err().to_string().contains("t.npy"));
        // unsupported dtype: complex128
        let hdr = "{'descr': '<c16', 'fortran_order': False, 'shape': (1, 1), }";
        let mut h = hdr.to_string();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        let mut f = b"\x93NUMPY\x01\x00".to_vec();
        f.extend_from_slice(&(h.len() as u16).to_le_bytes());
        f.extend_from_slice(h.as_bytes());
        f.extend_from_slice(&[0u8; 16]);
        std::fs::write(&p, &f).unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("t.npy") && e.contains("dtype"), "{e}");
        // 1-D array is not an image
        write_raw(&p, &ndarray::Array1::from_vec(vec![1.0f64, 2.0]).into_dyn());
        assert!(read_npy(&p).unwrap_err().to_string().contains("shape"));
    }

    #[test]
    fn npy_big_endian_by_hand() {
        // '>f8' shape (1, 2): values 1.5 and -3.0 stored big-endian.
        let hdr = "{'descr': '>f8', 'fortran_order': False, 'shape': (1, 2), }";
        let mut h = hdr.to_string();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        let mut f = b"\x93NUMPY\x01\x00".to_vec();
        f.extend_from_slice(&(h.len() as u16).to_le_bytes());
        f.extend_from_slice(h.as_bytes());
        f.extend_from_slice(&1.5f64.to_be_bytes());
        f.extend_from_slice(&(-3.0f64).to_be_bytes());
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("be.npy");
        std::fs::write(&p, &f).unwrap();
        assert_eq!(read_npy(&p).unwrap().data, vec![1.5, -3.0]);
    }

    #[test]
    fn npz_round_trip_and_names() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npz");
        let a = Image::from_vec(2, 1, 1, vec![1.0, 2.0]).unwrap();
        let b = Image::from_vec(1, 2, 1, vec![3.0, f64::NAN]).unwrap();
        write_npz_f64(&p, &[("disp", &a), ("mask", &b)]).unwrap();
        assert_eq!(read_npz_names(&p).unwrap(), vec!["disp", "mask"]);
        assert_eq!(read_npz(&p, None).unwrap(), a);
        assert_eq!(read_npz(&p, Some("disp")).unwrap(), a);
        let bb = read_npz(&p, Some("mask")).unwrap();
        assert_eq!(bb.data[0], 3.0);
        assert!(bb.data[1].is_nan());
        let e = read_npz(&p, Some("nope")).unwrap_err().to_string();
        assert!(e.contains("a.npz") && e.contains("nope"), "{e}");
        std::fs::write(&p, b"PK garbage").unwrap();
        assert!(read_npz(&p, None).unwrap_err().to_string().contains("a.npz"));
    }

    #[test]
    fn real_middlebury_npz_matches_npy() {
        let d = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/middlebury-motorcycle"));
        if !d.join("motorcycle_disp.npz").exists() {
            eprintln!("SKIP real_middlebury_npz_matches_npy: {} absent", d.display());
            return;
        }
        let a = read_npy(d.join("motorcycle_disp.npy")).unwrap();
        let names = read_npz_names(d.join("motorcycle_disp.npz")).unwrap();
        let b = read_npz(d.join("motorcycle_disp.npz"), Some(&names[0])).unwrap();
        assert_eq!(a.size(), b.size());
        assert!(a.data.iter().zip(&b.data).all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan())));
    }
}
