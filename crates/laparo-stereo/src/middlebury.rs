//! Middlebury stereo `calib.txt` (2014/2021 datasets): `cam0=[f 0 cx0; 0 f cy; 0 0 1]`,
//! `cam1=[...]`, `doffs`, `baseline` (mm), `width`, `height` (other keys ignored). The pair is
//! rectified, so it becomes a [`StereoCalibration`] with no distortion, R = I and
//! T = (−baseline, 0, 0); `doffs = c_x1 − c_x0` is checked against the camera matrices.
use laparo_core::calib::StereoCalibration;
use laparo_core::camera::{Distortion, Intrinsics};
use laparo_core::error::{CoreError, Result};
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

fn matrix(v: &str, path: &Path, key: &str) -> Result<Matrix3<f64>> {
    let inner = v.trim().trim_start_matches('[').trim_end_matches(']');
    let nums: Vec<f64> = inner
        .split(|c: char| c == ';' || c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| CoreError::format(path, format!("{key}: not a 3x3 matrix of numbers: '{v}'")))?;
    if nums.len() != 9 {
        return Err(CoreError::format(path, format!("{key}: {} numbers, expected 9", nums.len())));
    }
    Ok(Matrix3::from_row_slice(&nums))
}

/// Parse the text of a Middlebury `calib.txt` (`path` is used in error messages).
pub fn parse_middlebury_calib(text: &str, path: &Path) -> Result<StereoCalibration> {
    let mut get = std::collections::HashMap::new();
    for line in text.lines() {
        if let Some((k, v)) = line.split_once('=') {
            get.insert(k.trim().to_string(), v.trim().to_string());
        }
    }
    let need = |k: &str| get.get(k).ok_or_else(|| CoreError::format(path, format!("missing key '{k}'")));
    let num = |k: &str| -> Result<f64> {
        need(k)?.parse::<f64>().map_err(|_| CoreError::format(path, format!("{k}: not a number")))
    };
    let k0 = matrix(need("cam0")?, path, "cam0")?;
    let k1 = matrix(need("cam1")?, path, "cam1")?;
    let (w, h) = (num("width")?, num("height")?);
    if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0) {
        return Err(CoreError::format(path, format!("width/height {w}x{h} are not positive integers")));
    }
    let (w, h) = (w as usize, h as usize);
    let b = num("baseline")?;
    if !(b.is_finite() && b > 0.0) {
        return Err(CoreError::format(path, format!("baseline = {b} (must be > 0 mm)")));
    }
    let fmt = |e: CoreError| CoreError::format(path, e.to_string());
    let left = Intrinsics::from_matrix(&k0, w, h).map_err(fmt)?;
    let right = Intrinsics::from_matrix(&k1, w, h).map_err(fmt)?;
    if let Ok(doffs) = num("doffs") {
        let d = right.cx - left.cx;
        if (doffs - d).abs() > 1e-3 * doffs.abs().max(1.0) {
            return Err(CoreError::format(path, format!("doffs = {doffs} but cam1 cx − cam0 cx = {d}")));
        }
    }
    Ok(StereoCalibration {
        width: w,
        height: h,
        left,
        left_dist: Distortion::default(),
        right,
        right_dist: Distortion::default(),
        r: Matrix3::identity(),
        t_mm: Vector3::new(-b, 0.0, 0.0),
    })
}

/// Read a Middlebury `calib.txt`.
pub fn read_middlebury_calib(path: impl AsRef<Path>) -> Result<StereoCalibration> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| CoreError::io(path, e))?;
    parse_middlebury_calib(&text, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motorcycle_calib_txt() {
        let t = "cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\ncam1=[3979.911 0 1369.115; 0 3979.911 1019.507; 0 0 1]\ndoffs=124.343\nbaseline=193.001\nwidth=2964\nheight=2000\nndisp=270\n";
        let c = parse_middlebury_calib(t, Path::new("calib.txt")).unwrap();
        assert_eq!((c.width, c.height), (2964, 2000));
        assert!((c.right.cx - c.left.cx - 124.343).abs() < 1e-9 && (c.t_mm.x + 193.001).abs() < 1e-12);
        let bad = t.replace("doffs=124.343", "doffs=100");
        let e = parse_middlebury_calib(&bad, Path::new("calib.txt")).unwrap_err().to_string();
        assert!(e.contains("calib.txt") && e.contains("doffs"), "{e}");
        let e = parse_middlebury_calib("cam0=[1 0 0; 0 1 0; 0 0 1]", Path::new("x.txt")).unwrap_err().to_string();
        assert!(e.contains("missing key 'cam1'"), "{e}");
    }
}
