//! Stereo dataset layouts (SceneFlow, Middlebury, generic), per-sample CATS augmentation with
//! atomic outputs and a JSON sidecar, and parsing of hand-written augmentation parameters.
//!
//! Outputs mirror the input tree: every input file `ROOT/rel` becomes `OUT/rel` (augmented);
//! the sidecar `OUT/<id>.cats.json` (id = left image path without extension) is written last,
//! so a sample is finished iff its sidecar exists. Validity masks (PNG, 255 = valid) and, for
//! the exact rule, the vertical residual (PFM, px) go to `OUT/cats_aux/<id>_*.{png,pfm}`.
//! Unknown disparities are written as +inf (Middlebury's convention; CATS disparities can be
//! negative, so 0 cannot mark them).
//!
//! Submodules along the three seams: `layout` (discovery and loading), `output` (augmentation,
//! outputs and sidecar), `params` (hand-written parameters); everything is re-exported here.
use std::path::Path;

mod layout;
mod output;
mod params;

pub use layout::{discover, load_sample, read_disparity, source_cameras, Layout, SampleFiles};
pub use output::{augment_sample, resume_state, run_params_hash, ResumeState, SampleStats, Sidecar};
pub use params::{check_homographies, parse_params};
#[cfg(test)]
use {layout::read_middlebury_calib, output::output_paths};

use crate::error::StereoError;

fn ferr(path: &Path, msg: impl Into<String>) -> StereoError {
    StereoError::File { path: path.to_path_buf(), msg: msg.into() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_hand_written_params() {
        let t = r#"{"k": [[500, 0, 320], [0, 500, 240], [0, 0, 1]],
                    "left": {"euler_deg": [0.0, 0.1, 0.2]},
                    "right": {"rotation": [[1,0,0],[0,1,0],[0,0,1]]},
                    "dx_right_px": -40}"#;
        let p = parse_params(t, 640, 480).unwrap();
        assert_eq!(p.right.k_rel[0][2], 40.0);
        assert_eq!(p.dx_right_px, -40.0);
        assert!((p.left.euler_deg[2] - 0.2).abs() < 1e-12);
        let bad = t.replace("[[1,0,0],[0,1,0],[0,0,1]]", "[[1,0,0],[0,2,0],[0,0,1]]");
        let e = parse_params(&bad, 640, 480).unwrap_err().to_string();
        assert!(e.contains("right.rotation"), "{e}");
        let nok = parse_params(r#"{"left": {}}"#, 640, 480).unwrap_err().to_string();
        assert!(nok.contains("no intrinsics"), "{nok}");
        let inc = r#"{"k": {"fx": 500, "fy": 500, "cx": 320, "cy": 240},
                     "right": {"k_rel": [[1,0,-40],[0,1,0],[0,0,1]]}, "dx_right_px": -40}"#;
        assert!(parse_params(inc, 640, 480).unwrap_err().to_string().contains("disagrees"));
    }

    #[test]
    fn middlebury_calib_parsing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("calib.txt");
        std::fs::write(&p, "cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\ncam1=[3979.911 0 1369.115; 0 3979.911 1019.507; 0 0 1]\ndoffs=124.343\n").unwrap();
        let (l, r) = read_middlebury_calib(&p, 2964, 2000).unwrap();
        assert_eq!(l.cx, 1244.772);
        assert!((r.cx - l.cx - 124.343).abs() < 1e-9);
        std::fs::write(&p, "cam0=[1 0 0; 0 1 0]\n").unwrap();
        let e = read_middlebury_calib(&p, 10, 10).unwrap_err().to_string();
        assert!(e.contains("calib.txt") && e.contains("cam0"), "{e}");
    }

    #[test]
    fn discover_layouts() {
        let dir = tempfile::tempdir().unwrap();
        let r = dir.path();
        let touch = |p: &str| {
            let p = r.join(p);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        };
        for f in [
            "frames_cleanpass/TRAIN/A/0000/left/0006.png",
            "frames_cleanpass/TRAIN/A/0000/right/0006.png",
            "disparity/TRAIN/A/0000/left/0006.pfm",
            "frames_cleanpass/TRAIN/A/0000/left/0007.png",
            "frames_cleanpass/TRAIN/A/0000/right/0007.png",
        ] {
            touch(f);
        }
        let s = discover(r, Layout::SceneFlow).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].id, "frames_cleanpass/TRAIN/A/0000/left/0006");
        assert_eq!(s[0].disp_left.as_deref(), Some(r.join("disparity/TRAIN/A/0000/left/0006.pfm").as_path()));
        assert!(s[0].disp_right.is_none() && s[1].disp_left.is_none());
        let o = output_paths(&s[0], r, Path::new("/out"));
        assert_eq!(o.disp_left.unwrap(), Path::new("/out/disparity/TRAIN/A/0000/left/0006.pfm"));
        assert_eq!(o.sidecar, Path::new("/out/frames_cleanpass/TRAIN/A/0000/left/0006.cats.json"));
        // A left image without its right partner is an error naming the file.
        touch("frames_cleanpass/TRAIN/A/0000/left/0008.png");
        let e = discover(r, Layout::SceneFlow).unwrap_err().to_string();
        assert!(e.contains("0008.png") && e.contains("right"), "{e}");

        let m = tempfile::tempdir().unwrap();
        for f in ["Piano/im0.png", "Piano/im1.png", "Piano/disp0GT.pfm", "Piano/calib.txt"] {
            let p = m.path().join(f);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        }
        let s = discover(m.path(), Layout::Middlebury).unwrap();
        assert_eq!((s.len(), s[0].id.as_str()), (1, "Piano/im0"));
        assert!(s[0].disp_left.as_ref().unwrap().ends_with("disp0GT.pfm") && s[0].calib.is_some());
        assert!(discover(m.path(), Layout::Generic).unwrap_err().to_string().contains("left"));
    }
}
