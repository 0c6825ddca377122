//! OpenEXR float maps (depth, disparity): the first layer, one channel (`Y`, `Z`, `R`, or the
//! only one), half / float / uint samples converted to f64. The header is read first and the
//! size bounded before any pixel is decoded.
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use crate::image::Image;
use exr::prelude::{AnyChannel, AnyChannels, FlatSamples, ReadChannels, ReadLayers, WritableImage};
use std::io::Cursor;
use std::path::Path;

/// Read a single-channel OpenEXR image as an `Image<f64>`. Multi-channel files give their `Y`,
/// `Z`, `R` or `depth` channel (in that preference); otherwise they are refused.
pub fn read_exr(path: impl AsRef<Path>) -> Result<Image<f64>> {
    let path = path.as_ref();
    let bytes = super::read_bytes(path)?;
    let err = |m: String| CoreError::format(path, m);
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(&bytes), false)
        .map_err(|e| err(format!("not a valid OpenEXR file: {e}")))?;
    let header = meta.headers.first().ok_or_else(|| err("OpenEXR file without a layer".into()))?;
    let (w, h) = (header.layer_size.0, header.layer_size.1);
    super::camera_io::check_image_size(w as u64, h as u64, &path.display().to_string())?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(&bytes))
        .map_err(|e| err(format!("cannot decode OpenEXR: {e}")))?;
    let layer = image.layer_data;
    let list = &layer.channel_data.list;
    let ch = if list.len() == 1 {
        &list[0]
    } else {
        let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
        ["Y", "Z", "R", "depth", "disparity"]
            .iter()
            .find_map(|want| list.iter().find(|c| c.name.to_string() == *want))
            .ok_or_else(|| err(format!("OpenEXR with channels {names:?}: expected one channel (or Y, Z, R)")))?
    };
    let (w, h) = (layer.size.0, layer.size.1);
    let data: Vec<f64> = match &ch.sample_data {
        FlatSamples::F16(v) => v.iter().map(|x| x.to_f64()).collect(),
        FlatSamples::F32(v) => v.iter().map(|&x| x as f64).collect(),
        FlatSamples::U32(v) => v.iter().map(|&x| x as f64).collect(),
    };
    Image::from_vec(w, h, 1, data).map_err(|e| err(e.to_string()))
}

/// Write a one-channel image as a float32 OpenEXR (channel `Y`, lossless compression), atomically.
pub fn write_exr(path: impl AsRef<Path>, img: &Image<f64>) -> Result<()> {
    let path = path.as_ref();
    super::check_writable(path, img, &[1])?;
    let samples = FlatSamples::F32(img.data.iter().map(|&v| v as f32).collect());
    let channels = AnyChannels::sort(smallvec_one(AnyChannel::new("Y", samples)));
    let image = exr::prelude::Image::from_channels((img.width, img.height), channels);
    let mut buf = Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut buf)
        .map_err(|e| CoreError::format(path, format!("cannot encode OpenEXR: {e}")))?;
    write_atomic(path, &buf.into_inner())
}

fn smallvec_one<T>(x: T) -> exr::prelude::SmallVec<[T; 4]> {
    let mut v = exr::prelude::SmallVec::new();
    v.push(x);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.exr");
        let img = Image::from_vec(3, 2, 1, vec![0.25, 1.5, -2.0, 1e-3f32 as f64, 1234.5, f64::INFINITY]).unwrap();
        write_exr(&p, &img).unwrap();
        let back = read_exr(&p).unwrap();
        assert_eq!(back.size(), (3, 2));
        assert_eq!(back.data, img.data);
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        assert!(read_exr(&p).unwrap_err().to_string().contains("d.exr"));
        std::fs::write(&p, b"v/1\x01garbage").unwrap();
        assert!(read_exr(&p).unwrap_err().to_string().contains("d.exr"));
    }
}
