//! Middlebury stereo `calib.txt` (2014/2021 datasets): the parser lives in
//! [`laparo_core::io::calib_formats`] (one reader per kind of input); re-exported here.
use crate::error::Result;
use laparo_core::calib::StereoCalibration;
use laparo_core::io::calib_formats::parse_middlebury_calib;
use laparo_core::CoreError;
use std::path::Path;

/// Read a Middlebury `calib.txt`.
pub fn read_middlebury_calib(path: impl AsRef<Path>) -> Result<StereoCalibration> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| CoreError::io(path, e))?;
    Ok(parse_middlebury_calib(&text, path)?)
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
        // Regression (issue 10): doffs = nan passed the check (a NaN comparison is false).
        let e = parse_middlebury_calib(&t.replace("doffs=124.343", "doffs=nan"), Path::new("calib.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("calib.txt") && e.contains("doffs = NaN"), "{e}");
        // K's last row must be [0 0 1].
        let e = parse_middlebury_calib(
            &t.replace("0 3979.911 1019.507; 0 0 1]\ncam1", "0 3979.911 1019.507; 0 0 2]\ncam1"),
            Path::new("calib.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("cam0") && e.contains("[0, 0, 1]"), "{e}");
        // Absurd sizes are bounded, not allocated.
        let e = parse_middlebury_calib(&t.replace("width=2964", "width=9223372036854775807"), Path::new("calib.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("calib.txt") && e.contains("out of range"), "{e}");
    }
}
