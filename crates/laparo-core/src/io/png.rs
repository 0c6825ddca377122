//! 8-bit and 16-bit raster images (PNG, JPEG, TIFF, anything the `image` crate decodes).
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use crate::image::Image;
use image::{DynamicImage, ExtendedColorType, ImageEncoder};
use std::io::Cursor;
use std::path::Path;

fn decode(path: &Path) -> Result<DynamicImage> {
    let bytes = super::read_bytes(path)?;
    if bytes.is_empty() {
        return Err(CoreError::format(path, "file is empty"));
    }
    let complete = match image::guess_format(&bytes) {
        Ok(image::ImageFormat::Jpeg) => check_jpeg_complete(&bytes),
        Ok(image::ImageFormat::Png) => check_png_complete(&bytes),
        _ => Ok(()),
    };
    complete.map_err(|m| CoreError::format(path, m))?;
    let reader =
        image::ImageReader::new(Cursor::new(bytes)).with_guessed_format().map_err(|e| CoreError::io(path, e))?;
    if reader.format().is_none() {
        return Err(CoreError::format(path, "not a recognised image format (expected PNG, JPEG or TIFF)"));
    }
    reader.decode().map_err(|e| CoreError::format(path, format!("cannot decode image: {e}")))
}

/// A JPEG must end its last scan with the EOI marker (FF D9): decoders fill a truncated scan
/// with grey and report success, which silently corrupts masks and images. Inside the
/// entropy-coded data every FF is stuffed (FF 00), so an FF D9 after the last SOS (FF DA) is the EOI.
fn check_jpeg_complete(b: &[u8]) -> std::result::Result<(), String> {
    let sos = b.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    match sos {
        None => Err("truncated JPEG: no image scan (SOS marker)".into()),
        Some(i) if b[i..].windows(2).any(|w| w == [0xFF, 0xD9]) => Ok(()),
        Some(_) => Err("truncated JPEG: the end-of-image marker (FF D9) is missing".into()),
    }
}

/// A PNG must hold its IEND chunk; a file cut inside or after the image data is refused.
fn check_png_complete(b: &[u8]) -> std::result::Result<(), String> {
    let idat = b.windows(4).position(|w| w == b"IDAT");
    match idat {
        None => Err("truncated PNG: no image data (IDAT chunk)".into()),
        Some(i) if b[i..].windows(4).any(|w| w == b"IEND") => Ok(()),
        Some(_) => Err("truncated PNG: the IEND chunk is missing".into()),
    }
}

fn wrap<T: Copy>(path: &Path, w: u32, h: u32, c: usize, data: Vec<T>) -> Result<Image<T>> {
    Image::from_vec(w as usize, h as usize, c, data).map_err(|e| CoreError::format(path, e.to_string()))
}

/// Width and height (px) of the image at `path` from its header, without decoding the pixels: a
/// command checks its memory budget with it before a large image is decoded.
pub fn image_size(path: impl AsRef<Path>) -> Result<(usize, usize)> {
    let path = path.as_ref();
    let reader = image::ImageReader::open(path)
        .map_err(|e| CoreError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| CoreError::io(path, e))?;
    if reader.format().is_none() {
        return Err(CoreError::format(path, "not a recognised image format (expected PNG, JPEG or TIFF)"));
    }
    let (w, h) = reader.into_dimensions().map_err(|e| CoreError::format(path, format!("cannot read the size: {e}")))?;
    Ok((w as usize, h as usize))
}

/// Read an 8-bit image (PNG, JPEG, TIFF, ...) with its channels as stored: 1 (gray), 3 (RGB)
/// or 4 (RGBA; gray+alpha is expanded to RGBA). Deeper images are rounded to 8 bits.
pub fn read_image(path: impl AsRef<Path>) -> Result<Image<u8>> {
    let path = path.as_ref();
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    match img {
        DynamicImage::ImageLuma8(b) => wrap(path, w, h, 1, b.into_raw()),
        DynamicImage::ImageRgb8(b) => wrap(path, w, h, 3, b.into_raw()),
        DynamicImage::ImageRgba8(b) => wrap(path, w, h, 4, b.into_raw()),
        DynamicImage::ImageLuma16(_) => wrap(path, w, h, 1, img.to_luma8().into_raw()),
        DynamicImage::ImageRgb16(_) | DynamicImage::ImageRgb32F(_) => wrap(path, w, h, 3, img.to_rgb8().into_raw()),
        _ => wrap(path, w, h, 4, img.to_rgba8().into_raw()),
    }
}

/// Read an image as 8-bit RGB (gray is replicated, alpha dropped).
pub fn read_rgb8(path: impl AsRef<Path>) -> Result<Image<u8>> {
    let path = path.as_ref();
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    wrap(path, w, h, 3, img.to_rgb8().into_raw())
}

/// Read a 16-bit image (typically a depth or disparity PNG) keeping the stored integer values
/// exactly. 8-bit files are widened without rescaling (value 200 stays 200). Channels as stored
/// (1, 3 or 4; gray+alpha is expanded to RGBA).
pub fn read_png16(path: impl AsRef<Path>) -> Result<Image<u16>> {
    let path = path.as_ref();
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    let widen = |v: Vec<u8>| v.into_iter().map(u16::from).collect::<Vec<u16>>();
    match img {
        DynamicImage::ImageLuma16(b) => wrap(path, w, h, 1, b.into_raw()),
        DynamicImage::ImageRgb16(b) => wrap(path, w, h, 3, b.into_raw()),
        DynamicImage::ImageRgba16(b) => wrap(path, w, h, 4, b.into_raw()),
        DynamicImage::ImageLumaA16(_) => wrap(path, w, h, 4, img.to_rgba16().into_raw()),
        DynamicImage::ImageLuma8(b) => wrap(path, w, h, 1, widen(b.into_raw())),
        DynamicImage::ImageRgb8(b) => wrap(path, w, h, 3, widen(b.into_raw())),
        DynamicImage::ImageRgba8(b) => wrap(path, w, h, 4, widen(b.into_raw())),
        DynamicImage::ImageLumaA8(_) => wrap(path, w, h, 4, widen(img.to_rgba8().into_raw())),
        _ => Err(CoreError::format(path, "floating-point image: read it with read_tiff_f32 or read_float_map")),
    }
}

fn color_type(path: &Path, channels: usize, sixteen: bool) -> Result<ExtendedColorType> {
    Ok(match (channels, sixteen) {
        (1, false) => ExtendedColorType::L8,
        (2, false) => ExtendedColorType::La8,
        (3, false) => ExtendedColorType::Rgb8,
        (4, false) => ExtendedColorType::Rgba8,
        (1, true) => ExtendedColorType::L16,
        (2, true) => ExtendedColorType::La16,
        (3, true) => ExtendedColorType::Rgb16,
        (4, true) => ExtendedColorType::Rgba16,
        _ => return Err(CoreError::format(path, format!("cannot write {channels} channels to PNG (1-4)"))),
    })
}

fn dims(path: &Path, w: usize, h: usize) -> Result<(u32, u32)> {
    match (u32::try_from(w), u32::try_from(h)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(CoreError::format(path, format!("image {w}x{h} too large"))),
    }
}

/// Write an 8-bit image (1, 2, 3 or 4 channels) as PNG, atomically.
pub fn write_png(path: impl AsRef<Path>, img: &Image<u8>) -> Result<()> {
    let path = path.as_ref();
    super::check_writable(path, img, &[1, 2, 3, 4])?;
    let (w, h) = dims(path, img.width, img.height)?;
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf)
        .write_image(&img.data, w, h, color_type(path, img.channels, false)?)
        .map_err(|e| CoreError::format(path, format!("PNG encoding failed: {e}")))?;
    write_atomic(path, &buf)
}

/// Write a 16-bit image (1, 2, 3 or 4 channels) as PNG, atomically; values are stored exactly.
pub fn write_png16(path: impl AsRef<Path>, img: &Image<u16>) -> Result<()> {
    let path = path.as_ref();
    super::check_writable(path, img, &[1, 2, 3, 4])?;
    let (w, h) = dims(path, img.width, img.height)?;
    // The encoder expects native-endian samples and swaps them to PNG's big-endian itself.
    let bytes: Vec<u8> = img.data.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf)
        .write_image(&bytes, w, h, color_type(path, img.channels, true)?)
        .map_err(|e| CoreError::format(path, format!("PNG encoding failed: {e}")))?;
    write_atomic(path, &buf)
}

/// Write an 8-bit gray or RGB image as JPEG with `quality` in 1..=100, atomically
/// (RGBA loses its alpha).
pub fn write_jpeg(path: impl AsRef<Path>, img: &Image<u8>, quality: u8) -> Result<()> {
    let path = path.as_ref();
    super::check_writable(path, img, &[1, 3, 4])?;
    let (w, h) = dims(path, img.width, img.height)?;
    let rgb;
    let (data, ct) = match img.channels {
        1 => (&img.data, ExtendedColorType::L8),
        3 => (&img.data, ExtendedColorType::Rgb8),
        _ => {
            rgb = img.to_rgb();
            (&rgb.data, ExtendedColorType::Rgb8)
        }
    };
    let mut buf = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality.clamp(1, 100))
        .write_image(data, w, h, ct)
        .map_err(|e| CoreError::format(path, format!("JPEG encoding failed: {e}")))?;
    write_atomic(path, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png8_round_trip_all_channel_counts() {
        let dir = tempfile::tempdir().unwrap();
        for c in [1usize, 3, 4] {
            let data: Vec<u8> = (0..5 * 3 * c).map(|i| (i * 37 % 256) as u8).collect();
            let img = Image::from_vec(5, 3, c, data).unwrap();
            let p = dir.path().join(format!("a{c}.png"));
            write_png(&p, &img).unwrap();
            assert_eq!(read_image(&p).unwrap(), img);
            let rgb = read_rgb8(&p).unwrap();
            assert_eq!(rgb.channels, 3);
            assert_eq!(rgb.pixel(4, 2)[0], img.pixel(4, 2)[0]);
            assert_eq!(image_size(&p).unwrap(), (5, 3), "size from the header");
        }
        let bad = dir.path().join("x.png");
        std::fs::write(&bad, b"not an image").unwrap();
        assert!(image_size(&bad).unwrap_err().to_string().contains("x.png"));
    }

    #[test]
    fn png16_preserves_values_above_255() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u16> = vec![0, 1, 255, 256, 1000, 40000, 65535, 12345];
        let img = Image::from_vec(4, 2, 1, data.clone()).unwrap();
        let p = dir.path().join("d.png");
        write_png16(&p, &img).unwrap();
        let back = read_png16(&p).unwrap();
        assert_eq!(back, img);
        // Independent decoder: the `png` crate must see big-endian 16-bit samples with our values.
        let dec = ::png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&p).unwrap()));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!(info.bit_depth, ::png::BitDepth::Sixteen);
        let vals: Vec<u16> = buf[..info.buffer_size()].chunks(2).map(|b| u16::from_be_bytes([b[0], b[1]])).collect();
        assert_eq!(vals, data);
        // RGB 16-bit too
        let rgb = Image::from_vec(2, 1, 3, vec![1u16, 300, 65535, 7, 8, 9]).unwrap();
        write_png16(&p, &rgb).unwrap();
        assert_eq!(read_png16(&p).unwrap(), rgb);
    }

    #[test]
    fn jpeg_is_close() {
        let dir = tempfile::tempdir().unwrap();
        let img = Image::filled(16, 16, 3, 120u8);
        let p = dir.path().join("a.jpg");
        write_jpeg(&p, &img, 95).unwrap();
        let back = read_image(&p).unwrap();
        assert_eq!(back.channels, 3);
        assert!(back.data.iter().all(|&v| (v as i32 - 120).abs() <= 2));
    }

    #[test]
    fn garbage_and_missing_files_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("garbage.png");
        std::fs::write(&p, b"this is not an image at all").unwrap();
        let e = read_image(&p).unwrap_err().to_string();
        assert!(e.contains("garbage.png"), "{e}");
        // truncated PNG
        let good = dir.path().join("good.png");
        write_png(&good, &Image::filled(64, 64, 3, 7u8)).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        let t = dir.path().join("trunc.png");
        std::fs::write(&t, &bytes[..bytes.len() / 2]).unwrap();
        let e = read_png16(&t).unwrap_err().to_string();
        assert!(e.contains("trunc.png"), "{e}");
        let e = read_image(dir.path().join("missing.png")).unwrap_err().to_string();
        assert!(e.contains("missing.png"), "{e}");
        let e = write_png(dir.path().join("five.png"), &Image::filled(2, 2, 5, 0u8)).unwrap_err().to_string();
        assert!(e.contains("five.png"), "{e}");
    }

    /// Regression (issue 10): a truncated JPEG decoded "successfully" (the missing scan filled
    /// with grey); a PNG cut before IEND likewise. Both must be errors naming the file.
    #[test]
    fn truncated_jpeg_and_png_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..64 * 48 * 3).map(|i| ((i * 7) % 251) as u8).collect();
        let img = Image::from_vec(64, 48, 3, data).unwrap();
        let j = dir.path().join("full.jpg");
        write_jpeg(&j, &img, 90).unwrap();
        assert!(read_image(&j).is_ok());
        let bytes = std::fs::read(&j).unwrap();
        for cut in [bytes.len() - 2, bytes.len() * 2 / 3, bytes.len() / 2] {
            let t = dir.path().join("cut.jpg");
            std::fs::write(&t, &bytes[..cut]).unwrap();
            let e = read_image(&t).unwrap_err().to_string();
            assert!(e.contains("cut.jpg") && e.contains("truncated"), "cut at {cut}: {e}");
        }
        let p = dir.path().join("full.png");
        write_png(&p, &img).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        for cut in [bytes.len() - 12, bytes.len() - 20, bytes.len() / 2] {
            let t = dir.path().join("cut.png");
            std::fs::write(&t, &bytes[..cut]).unwrap();
            let e = read_image(&t).unwrap_err().to_string();
            assert!(e.contains("cut.png"), "cut at {cut}: {e}");
        }
    }
}
