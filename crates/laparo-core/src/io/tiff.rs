//! 32-bit float TIFF (gray, or RGB) through the `tiff` crate.
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use crate::image::Image;
use std::io::Cursor;
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::{colortype, TiffEncoder};
use tiff::ColorType;

/// Read the first image of a TIFF file as `Image<f32>`. Float samples are kept exactly; integer
/// samples are converted to their numeric value (no rescaling). Gray, gray+alpha, RGB and RGBA.
pub fn read_tiff_f32(path: impl AsRef<Path>) -> Result<Image<f32>> {
    let path = path.as_ref();
    let bytes = super::read_bytes(path)?;
    let bad = |e: tiff::TiffError| CoreError::format(path, format!("cannot decode TIFF: {e}"));
    let mut dec = Decoder::new(Cursor::new(bytes)).map_err(bad)?;
    let (w, h) = dec.dimensions().map_err(bad)?;
    let channels = match dec.colortype().map_err(bad)? {
        ColorType::Gray(_) => 1,
        ColorType::GrayA(_) => 2,
        ColorType::RGB(_) => 3,
        ColorType::RGBA(_) => 4,
        ColorType::Multiband { num_samples, .. } => num_samples as usize,
        other => return Err(CoreError::format(path, format!("unsupported TIFF colour type {other:?}"))),
    };
    let data: Vec<f32> = match dec.read_image().map_err(bad)? {
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::U64(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::I64(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::F16(v) => v.into_iter().map(f32::from).collect(),
    };
    Image::from_vec(w as usize, h as usize, channels, data).map_err(|e| CoreError::format(path, e.to_string()))
}

/// Write a 1-channel (gray) or 3-channel (RGB) float32 TIFF, uncompressed, atomically.
pub fn write_tiff_f32(path: impl AsRef<Path>, img: &Image<f32>) -> Result<()> {
    let path = path.as_ref();
    super::check_writable(path, img, &[1, 3])?;
    let (w, h) = (img.width as u32, img.height as u32);
    let bad = |e: tiff::TiffError| CoreError::format(path, format!("cannot encode TIFF: {e}"));
    let mut cur = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut cur).map_err(bad)?;
        if img.channels == 1 {
            enc.write_image::<colortype::Gray32Float>(w, h, &img.data).map_err(bad)?;
        } else {
            enc.write_image::<colortype::RGB32Float>(w, h, &img.data).map_err(bad)?;
        }
    }
    write_atomic(path, &cur.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiff_round_trip_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.tiff");
        let data: Vec<f32> = vec![0.0, -1.5, 3.25e-7, f32::NAN, f32::INFINITY, 123456.78];
        let img = Image::from_vec(3, 2, 1, data).unwrap();
        write_tiff_f32(&p, &img).unwrap();
        let back = read_tiff_f32(&p).unwrap();
        assert_eq!(back.size(), (3, 2));
        assert!(back.data.iter().zip(&img.data).all(|(a, b)| a.to_bits() == b.to_bits()));
        let rgb = Image::from_vec(1, 2, 3, vec![1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        write_tiff_f32(&p, &rgb).unwrap();
        assert_eq!(read_tiff_f32(&p).unwrap(), rgb);
    }

    #[test]
    fn tiff_garbage_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.tif");
        std::fs::write(&p, b"II*\0garbage").unwrap();
        assert!(read_tiff_f32(&p).unwrap_err().to_string().contains("g.tif"));
        let good = dir.path().join("ok.tif");
        write_tiff_f32(&good, &Image::filled(50, 50, 1, 1.0f32)).unwrap();
        let b = std::fs::read(&good).unwrap();
        std::fs::write(&p, &b[..b.len() / 2]).unwrap();
        assert!(read_tiff_f32(&p).unwrap_err().to_string().contains("g.tif"));
    }
}
