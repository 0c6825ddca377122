//! NumPy `.npy` and `.npz` arrays as images: shape (H, W) → 1 channel, (H, W, C) → C channels
//! (leading singleton axes of 4-D+ arrays are dropped; a 3-D (1, H, W) with W > 4 is read as (H, W)). Any of f16, f32, f64, u8, u16, u32, u64, i8, i16, i32, i64
//! and bool, little- or big-endian, C or Fortran order; values are converted to f64 on reading.
use super::npy_header;
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use crate::image::Image;
use ndarray::{ArrayD, IxDyn};
use ndarray_npy::{WritableElement, WriteNpyExt};
use std::io::{Cursor, Read};
use std::path::Path;

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

/// Decode `.npy` bytes into an image; `what` prefixes messages (e.g. the array name in a .npz).
/// The header is parsed by the bounded reader of [`super::npy_header`] and the data length is
/// checked against the shape before any allocation.
fn npy_bytes_to_image(bytes: &[u8], path: &Path, what: &str) -> Result<Image<f64>> {
    let err = |m: String| CoreError::format(path, format!("{what}{m}"));
    let h = npy_header::parse_header(bytes).map_err(err)?;
    let data = &bytes[h.data_offset.min(bytes.len())..];
    let values = npy_header::decode(&h, data).map_err(err)?;
    shape_to_image(path, what, &h.shape, values)
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
    let decompress = |e: std::io::Error| CoreError::format(path, format!("{what}cannot decompress: {e}"));
    // Read the header first (bounded), then exactly the announced data: a forged size in the
    // archive or the header cannot make the reader allocate more than the data can hold.
    let mut head = Vec::new();
    (&mut entry).take(12).read_to_end(&mut head).map_err(decompress)?;
    let hlen = match head.get(6) {
        Some(1) if head.len() >= 10 => u16::from_le_bytes([head[8], head[9]]) as usize,
        Some(2 | 3) if head.len() >= 12 => u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize,
        _ => 0,
    };
    if hlen > npy_header::MAX_HEADER_BYTES {
        return Err(CoreError::format(path, format!("{what}.npy header of {hlen} bytes is too large")));
    }
    let want_head = if head.get(6) == Some(&1) { 10 + hlen } else { 12 + hlen };
    (&mut entry).take((want_head.saturating_sub(head.len())) as u64).read_to_end(&mut head).map_err(decompress)?;
    let h = npy_header::parse_header(&head).map_err(|m| CoreError::format(path, format!("{what}{m}")))?;
    let need = h.data_bytes().map_err(|m| CoreError::format(path, format!("{what}{m}")))?;
    // Deflate cannot expand by more than ~1032:1; a stored entry not at all.
    let max_plain = entry.compressed_size().saturating_mul(1100).saturating_add(4096);
    if need as u64 > max_plain || need as u64 > entry.size() {
        return Err(CoreError::format(
            path,
            format!(
                "{what}truncated: the header announces {need} bytes of data, the archive entry holds {}",
                entry.size().saturating_sub(head.len() as u64).min(max_plain)
            ),
        ));
    }
    let mut bytes = head;
    bytes.reserve_exact(need);
    (&mut entry).take(need as u64 + 1).read_to_end(&mut bytes).map_err(decompress)?;
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

    fn raw_npy(header: &str, data: &[u8]) -> Vec<u8> {
        let mut h = header.to_string();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        let mut f = b"\x93NUMPY\x01\x00".to_vec();
        f.extend_from_slice(&(h.len() as u16).to_le_bytes());
        f.extend_from_slice(h.as_bytes());
        f.extend_from_slice(data);
        f
    }

    /// Regression (issue 10): a 160-byte file with hexadecimal / underscore / double-quoted
    /// dimensions aborted with "memory allocation of 80000000000 bytes failed", and ~22 nested
    /// lists in the header took a minute.
    #[test]
    fn hostile_npy_headers_fail_fast_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("evil.npy");
        for hdr in [
            "{\"descr\": \"<f8\", \"fortran_order\": False, \"shape\": (100000, 100000), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (0x186a0, 0x186a0), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (100_000, 100_000), }",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 1), 'x': [[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]}",
        ] {
            let f = raw_npy(hdr, &[0u8; 16]);
            assert!(f.len() <= 160, "{}", f.len());
            std::fs::write(&p, &f).unwrap();
            let e = read_npy(&p).unwrap_err().to_string();
            assert!(e.contains("evil.npy"), "{hdr}: {e}");
        }
    }

    #[test]
    fn npz_with_forged_shape_is_refused_before_allocating() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("evil.npz");
        let f = raw_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }", &[0u8; 16]);
        let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        zip.start_file("arr_0.npy", zip::write::SimpleFileOptions::default()).unwrap();
        std::io::Write::write_all(&mut zip, &f).unwrap();
        std::fs::write(&p, zip.finish().unwrap().into_inner()).unwrap();
        let e = read_npz(&p, None).unwrap_err().to_string();
        assert!(e.contains("evil.npz") && e.contains("truncated"), "{e}");
    }

    #[test]
    fn float16_npy_by_hand() {
        // '<f2' shape (1, 3): 1.0, -2.0, 0.5 (0x3c00, 0xc000, 0x3800)
        let data = [0x00, 0x3c, 0x00, 0xc0, 0x00, 0x38];
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.npy");
        std::fs::write(&p, raw_npy("{'descr': '<f2', 'fortran_order': False, 'shape': (1, 3), }", &data)).unwrap();
        assert_eq!(read_npy(&p).unwrap().data, vec![1.0, -2.0, 0.5]);
    }
}
