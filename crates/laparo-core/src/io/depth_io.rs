//! Float maps (depth, disparity) and depth maps, dispatching on the file extension.
//!
//! | extension | stored as | read | written by [`write_depth`] |
//! |---|---|---|---|
//! | `.npy` | any numeric dtype | exact | float64, exact |
//! | `.npz` | first array (see [`read_npz`](super::read_npz) for a named one) | exact | float64 `depth` array |
//! | `.pfm` | float32, rows bottom-to-top | exact | float32 |
//! | `.tif` / `.tiff` | float32 (or integer) gray | exact | float32 gray |
//! | `.exr` | OpenEXR, one channel (half/float/uint) | exact | float32 |
//! | `.png` | 16-bit integer, **no scaling**: the value is the depth in the caller's unit; 0 = invalid | exact | uint16 **millimetres**, rounded, 0 = invalid |
use crate::depth::{DepthMap, DepthUnit};
use crate::error::{CoreError, Result};
use crate::image::{Image, Mask};
use std::path::Path;

/// Read a single- or multi-channel float map (depth, disparity, ...) by extension:
/// `npy` (any numeric dtype incl. float16), `npz` (first array), `pfm`, `tif`/`tiff`, `exr`,
/// `png` (16-bit integer values as stored).
pub fn read_float_map(path: impl AsRef<Path>) -> Result<Image<f64>> {
    let path = path.as_ref();
    match super::extension(path).as_str() {
        "npy" => super::read_npy(path),
        "npz" => super::read_npz(path, None),
        "pfm" => Ok(super::read_pfm(path)?.map(f64::from)),
        "tif" | "tiff" => Ok(super::read_tiff_f32(path)?.map(f64::from)),
        "exr" => super::read_exr(path),
        "png" => Ok(super::read_png16(path)?.map(f64::from)),
        other => Err(CoreError::format(
            path,
            format!("unsupported float-map extension '{other}' (expected npy, npz, pfm, tif, tiff, exr or png)"),
        )),
    }
}

/// Write a float map by extension: `npy` (f64, exact), `npz` (f64 array `arr_0`), `pfm` or
/// `tif`/`tiff` (f32). PNG is refused (it would round; use [`write_depth`] or `write_png16`).
pub fn write_float_map(path: impl AsRef<Path>, img: &Image<f64>) -> Result<()> {
    let path = path.as_ref();
    let f32img = || img.map(|v| v as f32);
    match super::extension(path).as_str() {
        "npy" => super::write_npy_f64(path, img),
        "npz" => super::write_npz_f64(path, &[("arr_0", img)]),
        "pfm" => super::write_pfm(path, &f32img()),
        "tif" | "tiff" => super::write_tiff_f32(path, &f32img()),
        "exr" => super::write_exr(path, img),
        other => Err(CoreError::format(
            path,
            format!("cannot write a float map as '{other}' (expected npy, npz, pfm, tif, tiff or exr)"),
        )),
    }
}

/// Read a validity / region-of-interest mask — the one mask reader of every command. Image files
/// (png, jpg, jpeg, 8/16-bit tif, ...) are true where channel 0 is non-zero; `npy` (incl. bool),
/// `npz`, `pfm`, `exr` and float TIFF where the value is finite and non-zero. Multi-channel float
/// maps are rejected.
pub fn read_mask(path: impl AsRef<Path>) -> Result<Mask> {
    let path = path.as_ref();
    let (w, h, data) = match super::extension(path).as_str() {
        "npy" | "npz" | "pfm" | "exr" => {
            let m = read_float_map(path)?;
            if m.channels != 1 {
                return Err(CoreError::format(path, format!("mask has {} channels, expected 1", m.channels)));
            }
            (m.width, m.height, m.data.iter().map(|v| v.is_finite() && *v != 0.0).collect())
        }
        ext => match super::read_png16(path) {
            Ok(m) => (m.width, m.height, m.data.chunks_exact(m.channels).map(|p| p[0] != 0).collect()),
            // A float TIFF mask (0.0 / 1.0).
            Err(e) if matches!(ext, "tif" | "tiff") => {
                let m = super::read_tiff_f32(path).map_err(|_| e)?;
                (m.width, m.height, m.data.chunks_exact(m.channels).map(|p| p[0].is_finite() && p[0] != 0.0).collect())
            }
            Err(e) => return Err(e),
        },
    };
    Ok(Image { width: w, height: h, channels: 1, data })
}

/// Write a mask as an 8-bit gray PNG (true = 255, false = 0), atomically.
pub fn write_mask_png(path: impl AsRef<Path>, mask: &Mask) -> Result<()> {
    super::write_png(path, &mask.map(|b| if b { 255u8 } else { 0 }))
}

/// Read a depth map stored in `unit` (see the module table). Zero, negative and non-finite
/// values become NaN (invalid). The file must have one channel.
pub fn read_depth(path: impl AsRef<Path>, unit: DepthUnit) -> Result<DepthMap> {
    let path = path.as_ref();
    let img = read_float_map(path)?;
    if img.channels != 1 {
        return Err(CoreError::format(path, format!("depth map has {} channels, expected 1", img.channels)));
    }
    let data = img.data.into_iter().map(|v| if DepthMap::is_valid(v) { v } else { f64::NAN }).collect();
    DepthMap::new(img.width, img.height, unit, data)
}

/// Write a depth map by extension. `npy`/`npz`/`pfm`/`tif` keep the map's own unit (the caller
/// must remember it); `png` stores uint16 millimetres (rounded; invalid → 0) and fails on depths
/// beyond 65.535 m.
pub fn write_depth(path: impl AsRef<Path>, depth: &DepthMap) -> Result<()> {
    let path = path.as_ref();
    let n = depth.width * depth.height;
    if depth.data.len() != n {
        return Err(CoreError::SizeMismatch(format!(
            "{}: depth data has {} values for {}x{}",
            path.display(),
            depth.data.len(),
            depth.width,
            depth.height
        )));
    }
    match super::extension(path).as_str() {
        "png" => {
            let mm = depth.to_unit(DepthUnit::Mm);
            let mut out = Vec::with_capacity(n);
            for &v in &mm.data {
                if !DepthMap::is_valid(v) {
                    out.push(0u16);
                } else {
                    let r = v.round();
                    if r > 65535.0 {
                        return Err(CoreError::format(path, format!("depth {v} mm does not fit a 16-bit PNG")));
                    }
                    out.push(r as u16);
                }
            }
            super::write_png16(path, &Image { width: depth.width, height: depth.height, channels: 1, data: out })
        }
        "npz" => super::write_npz_f64(path, &[("depth", &depth.to_image())]),
        _ => write_float_map(path, &depth.to_image()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_round_trips_every_extension() {
        let dir = tempfile::tempdir().unwrap();
        let d = DepthMap::new(3, 2, DepthUnit::Mm, vec![10.0, 250.5, f64::NAN, 0.0, 99.0, 1234.0]).unwrap();
        for ext in ["npy", "npz", "pfm", "tif", "tiff"] {
            let p = dir.path().join(format!("d.{ext}"));
            write_depth(&p, &d).unwrap();
            let back = read_depth(&p, DepthUnit::Mm).unwrap();
            assert_eq!(back.unit, DepthUnit::Mm);
            for (i, (a, b)) in back.data.iter().zip(&d.data).enumerate() {
                if DepthMap::is_valid(*b) {
                    assert_eq!(a, b, "{ext} pixel {i}");
                } else {
                    assert!(a.is_nan(), "{ext} pixel {i}: 0/NaN must read back as NaN");
                }
            }
        }
        // PNG: millimetres, rounded; a map in metres is converted.
        let p = dir.path().join("d.png");
        let m = d.to_unit(DepthUnit::M);
        write_depth(&p, &m).unwrap();
        let back = read_depth(&p, DepthUnit::Mm).unwrap();
        assert_eq!(back.data[0], 10.0);
        assert_eq!(back.data[1], 251.0); // 250.5 rounds away from zero
        assert!(back.data[2].is_nan() && back.data[3].is_nan());
        assert_eq!(back.data[5], 1234.0);
        let raw = super::super::read_png16(&p).unwrap();
        assert_eq!(raw.data, vec![10, 251, 0, 0, 99, 1234]);
        let far = DepthMap::new(1, 1, DepthUnit::M, vec![70.0]).unwrap();
        assert!(write_depth(dir.path().join("far.png"), &far).unwrap_err().to_string().contains("far.png"));
        assert!(!dir.path().join("far.png").exists());
    }

    #[test]
    fn mask_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let m = Image::from_vec(3, 2, 1, vec![true, false, true, false, false, true]).unwrap();
        let p = dir.path().join("m.png");
        write_mask_png(&p, &m).unwrap();
        assert_eq!(read_mask(&p).unwrap(), m);
        assert_eq!(super::super::read_image(&p).unwrap().data, vec![255, 0, 255, 0, 0, 255]);
        let q = dir.path().join("m.npy");
        let f = Image::from_vec(3, 2, 1, vec![1.0, 0.0, 0.5, f64::NAN, 0.0, -2.0]).unwrap();
        super::super::write_npy_f64(&q, &f).unwrap();
        assert_eq!(read_mask(&q).unwrap().data, vec![true, false, true, false, false, true]);
    }

    #[test]
    fn unknown_extension_and_multichannel_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.xyz");
        std::fs::write(&p, b"x").unwrap();
        assert!(read_float_map(&p).unwrap_err().to_string().contains("d.xyz"));
        let q = dir.path().join("rgb.pfm");
        super::super::write_pfm(&q, &Image::filled(2, 2, 3, 1.0f32)).unwrap();
        assert!(read_depth(&q, DepthUnit::M).unwrap_err().to_string().contains("rgb.pfm"));
        assert!(write_float_map(dir.path().join("x.png"), &Image::filled(1, 1, 1, 1.0)).is_err());
    }
}
