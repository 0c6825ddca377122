//! Portable Float Map (PFM), the SceneFlow / Middlebury disparity format.
//!
//! Layout: ASCII header `PF` (3 channels) or `Pf` (1 channel), whitespace, `width height`,
//! whitespace, `scale` (its sign gives the byte order: negative = little-endian, positive =
//! big-endian; its magnitude is ignored), exactly one whitespace byte, then `width*height*channels`
//! float32 values with rows stored **bottom-to-top**. In memory, as everywhere in laparo, the
//! first row is the top row. We always write little-endian with scale `-1.0`.
//!
//! Hand-written: the format is 20 lines and no maintained crate reads it with the row flip and
//! both byte orders.
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use crate::image::Image;
use std::path::Path;

/// Next whitespace-separated header token starting at `*pos`; leaves `*pos` on the byte after it.
fn token<'a>(bytes: &'a [u8], pos: &mut usize) -> Option<&'a str> {
    while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    let start = *pos;
    while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() && *pos - start < 64 {
        *pos += 1;
    }
    if start == *pos {
        return None;
    }
    std::str::from_utf8(&bytes[start..*pos]).ok()
}

/// Read a PFM file; the first row in memory is the top row of the picture.
pub fn read_pfm(path: impl AsRef<Path>) -> Result<Image<f32>> {
    let path = path.as_ref();
    let bytes = super::read_bytes(path)?;
    let bad = |msg: &str| CoreError::format(path, format!("not a valid PFM file: {msg}"));
    let mut pos = 0;
    let channels = match token(&bytes, &mut pos) {
        Some("Pf") => 1,
        Some("PF") => 3,
        _ => return Err(bad("header must start with 'Pf' or 'PF'")),
    };
    let mut num =
        |what: &str| -> Result<&str> { token(&bytes, &mut pos).ok_or_else(|| bad(&format!("missing {what}"))) };
    let w: usize = num("width")?.parse().map_err(|_| bad("width is not a positive integer"))?;
    let h: usize = num("height")?.parse().map_err(|_| bad("height is not a positive integer"))?;
    let scale: f64 = num("scale")?.parse().map_err(|_| bad("scale is not a number"))?;
    if w == 0 || h == 0 {
        return Err(bad(&format!("empty size {w}x{h}")));
    }
    if !(scale.is_finite() && scale != 0.0) {
        return Err(bad("scale must be a non-zero number"));
    }
    let little = scale < 0.0;
    // Exactly one whitespace byte ends the header (tolerate a Windows "\r\n").
    if pos >= bytes.len() || !bytes[pos].is_ascii_whitespace() {
        return Err(bad("header not terminated (file truncated?)"));
    }
    pos += 1;
    let n = w
        .checked_mul(h)
        .and_then(|v| v.checked_mul(channels))
        .ok_or_else(|| bad(&format!("size {w}x{h} overflows")))?;
    let need = n * 4;
    let mut rest = &bytes[pos..];
    if rest.len() == need + 1 && bytes[pos - 1] == b'\r' && rest[0] == b'\n' {
        rest = &rest[1..];
    }
    if rest.len() < need {
        return Err(CoreError::format(
            path,
            format!(
                "truncated PFM: header says {w}x{h}x{channels} floats ({need} bytes), file has {} data bytes",
                rest.len()
            ),
        ));
    }
    if rest.len() > need {
        return Err(CoreError::format(
            path,
            format!("PFM has {} unexpected bytes after the {w}x{h}x{channels} floats", rest.len() - need),
        ));
    }
    let row = w * channels;
    let mut data = vec![0f32; n];
    for (i, chunk) in rest.chunks_exact(4).enumerate() {
        let b = [chunk[0], chunk[1], chunk[2], chunk[3]];
        let v = if little { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) };
        let (file_row, col) = (i / row, i % row);
        data[(h - 1 - file_row) * row + col] = v;
    }
    Ok(Image { width: w, height: h, channels, data })
}

/// Write a 1- or 3-channel float image as PFM (little-endian, rows bottom-to-top), atomically.
pub fn write_pfm(path: impl AsRef<Path>, img: &Image<f32>) -> Result<()> {
    let path = path.as_ref();
    super::check_writable(path, img, &[1, 3])?;
    let header = format!("{}\n{} {}\n-1.0\n", if img.channels == 1 { "Pf" } else { "PF" }, img.width, img.height);
    let row = img.width * img.channels;
    let mut buf = Vec::with_capacity(header.len() + img.data.len() * 4);
    buf.extend_from_slice(header.as_bytes());
    for r in img.data.chunks_exact(row).rev() {
        for v in r {
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }
    write_atomic(path, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_layout_by_hand() {
        // 2x2 gray, top row [1, 2], bottom row [3, 4]: the file stores the bottom row first.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.pfm");
        let img = Image::from_vec(2, 2, 1, vec![1.0f32, 2.0, 3.0, 4.0]).unwrap();
        write_pfm(&p, &img).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.starts_with(b"Pf\n2 2\n-1.0\n"));
        let body = &bytes[12..];
        let vals: Vec<f32> = body.chunks(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        assert_eq!(vals, vec![3.0, 4.0, 1.0, 2.0]);
        assert_eq!(read_pfm(&p).unwrap(), img);
        // Big-endian file written by hand, header tokens on one line.
        let mut be = b"Pf 2 1 1.0\n".to_vec();
        for v in [0.5f32, -7.25] {
            be.extend_from_slice(&v.to_be_bytes());
        }
        std::fs::write(&p, &be).unwrap();
        assert_eq!(read_pfm(&p).unwrap().data, vec![0.5, -7.25]);
    }

    #[test]
    fn pfm_rgb_round_trip_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.pfm");
        let data: Vec<f32> = (0..3 * 4 * 3).map(|i| (i as f32).sin() * 1e3).chain([f32::INFINITY]).collect();
        let mut data = data;
        data.truncate(36);
        data[5] = f32::INFINITY;
        let img = Image::from_vec(3, 4, 3, data).unwrap();
        write_pfm(&p, &img).unwrap();
        let back = read_pfm(&p).unwrap();
        assert!(back.data.iter().zip(&img.data).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(back.size(), (3, 4));
    }

    #[test]
    fn pfm_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.pfm");
        for content in [&b"P6\n2 2\n255\n"[..], b"Pf\n2 x\n-1\n", b"Pf\n2 2\n-1.0\n\0\0\0\0", b"", b"Pf\n2 2\n-1.0"] {
            std::fs::write(&p, content).unwrap();
            let e = read_pfm(&p).unwrap_err().to_string();
            assert!(e.contains("bad.pfm"), "{e}");
        }
        std::fs::write(&p, b"Pf\n1 1\n-1.0\n\0\0\0\0\0\0").unwrap();
        assert!(read_pfm(&p).unwrap_err().to_string().contains("unexpected bytes"));
        let e = write_pfm(&p, &Image::filled(2, 2, 2, 0f32)).unwrap_err().to_string();
        assert!(e.contains("bad.pfm"), "{e}");
    }

    #[test]
    fn real_middlebury_pfm_matches_npy() {
        let d = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/middlebury-motorcycle"));
        if !d.join("motorcycle_disp.pfm").exists() {
            eprintln!("SKIP real_middlebury_pfm_matches_npy: {} absent", d.display());
            return;
        }
        let pfm = read_pfm(d.join("motorcycle_disp.pfm")).unwrap();
        let npy = super::super::read_npy(d.join("motorcycle_disp.npy")).unwrap();
        assert_eq!((pfm.width, pfm.height, pfm.channels), (741, 500, 1));
        assert_eq!(pfm.size(), npy.size());
        let mut n_inf = 0;
        for (a, b) in pfm.data.iter().zip(&npy.data) {
            assert_eq!(*a as f64, *b);
            n_inf += a.is_infinite() as usize;
        }
        assert_eq!(n_inf, 27226); // README: 27,226 invalid (+inf) pixels
    }
}
