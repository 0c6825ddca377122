//! Real SCARED ds1-3 stereo pair (../shared/data/surgical/scared_pair_ds1-3 with its calibration):
//! after rectification, patch correspondences found by NCC search (15×15, NCC > 0.95, parabolic
//! sub-pixel row) lie on the same row to a fraction of a pixel. The calibration does not fit this
//! frame perfectly: the same measurement on OpenCV 5.0's rectification of the same pair
//! (`stereoRectify` + `initUndistortRectifyMap` + `remap`, `cv2.matchTemplate` TM_CCOEFF_NORMED)
//! gives a median y_R − y_L of −0.229 px (raw pair: −0.243 px), and laparo must agree with it.
//! Skips when the data is absent.
use laparo_core::calib::StereoCalibration;
use laparo_core::image::Image;
use laparo_stereo::{Rectification, RectifyOptions, Side};
use std::path::PathBuf;

const R: isize = 7; // 15×15 patches

fn gray(img: &Image<u8>) -> Image<f64> {
    let c = img.channels;
    let data = img
        .data
        .chunks_exact(c)
        .map(|p| if c >= 3 { 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64 } else { p[0] as f64 })
        .collect();
    Image { width: img.width, height: img.height, channels: 1, data }
}

fn ncc(a: &Image<f64>, ax: isize, ay: isize, b: &Image<f64>, bx: isize, by: isize) -> f64 {
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for j in -R..=R {
        for i in -R..=R {
            let va = a.get((ax + i) as usize, (ay + j) as usize, 0);
            let vb = b.get((bx + i) as usize, (by + j) as usize, 0);
            sa += va;
            sb += vb;
            saa += va * va;
            sbb += vb * vb;
            sab += va * vb;
        }
    }
    let n = ((2 * R + 1) * (2 * R + 1)) as f64;
    let cov = sab - sa * sb / n;
    let den = ((saa - sa * sa / n) * (sbb - sb * sb / n)).sqrt();
    if den > 1e-9 {
        cov / den
    } else {
        0.0
    }
}

/// Sub-pixel vertical offsets y_R − y_L of confident patch matches (dx searched in `dx_range`).
fn vertical_offsets(
    l: &Image<f64>,
    r: &Image<f64>,
    valid: &dyn Fn(isize, isize) -> bool,
    dx_range: (isize, isize),
) -> Vec<f64> {
    let (w, h) = (l.width as isize, l.height as isize);
    let mut out = Vec::new();
    for y in (120..h - 120).step_by(60) {
        for x in (200..w - 200).step_by(60) {
            if !valid(x, y) {
                continue;
            }
            let mut best = (-2.0, 0, 0);
            for dy in -4..=4 {
                for dx in dx_range.0..=dx_range.1 {
                    let (xr, yr) = (x + dx, y + dy);
                    if xr - R < 1 || xr + R >= w - 1 || !valid(xr, yr) {
                        continue;
                    }
                    let c = ncc(l, x, y, r, xr, yr);
                    if c > best.0 {
                        best = (c, dx, dy);
                    }
                }
            }
            let (c, dx, dy) = best;
            if c < 0.95 || dy.abs() == 4 {
                continue;
            }
            let (cm, cp) = (ncc(l, x, y, r, x + dx, y + dy - 1), ncc(l, x, y, r, x + dx, y + dy + 1));
            let den = cm - 2.0 * c + cp;
            let sub = if den < 0.0 { 0.5 * (cm - cp) / den } else { 0.0 };
            out.push(dy as f64 + sub.clamp(-0.5, 0.5));
        }
    }
    out
}

#[test]
fn rectified_scared_pair_rows_agree_with_opencv_rectification() {
    let d = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data"));
    let (lp, rp, cp) = (
        d.join("surgical/scared_pair_ds1-3/Left_Image.png"),
        d.join("surgical/scared_pair_ds1-3/Right_Image.png"),
        d.join("calib/scared_ds1-3_endoscope_calibration.yaml"),
    );
    if !(lp.exists() && rp.exists() && cp.exists()) {
        eprintln!("SKIP: SCARED pair or calibration not found under {}", d.display());
        return;
    }
    let calib = StereoCalibration::read_with_size(&cp, 1280, 1024).unwrap();
    let (l8, r8) = (laparo_core::io::read_image(&lp).unwrap(), laparo_core::io::read_image(&rp).unwrap());
    // Raw pair: c_x^L − c_x^R = −91 px, so disparities are mostly negative.
    let raw = vertical_offsets(&gray(&l8), &gray(&r8), &|_, _| true, (-40, 110));
    let rect = Rectification::new(&calib, RectifyOptions::default()).unwrap();
    let (lr, ml) = rect.rectify_image(Side::Left, &l8).unwrap();
    let (rr, mr) = rect.rectify_image(Side::Right, &r8).unwrap();
    let ok = |m: &laparo_core::image::Mask, x: isize, y: isize| {
        (-R..=R).all(|j| (-R..=R).all(|i| m.get((x + i) as usize, (y + j) as usize, 0)))
    };
    let fixed = vertical_offsets(&gray(&lr), &gray(&rr), &|x, y| ok(&ml, x, y) && ok(&mr, x, y), (-130, 30));
    let median = |mut v: Vec<f64>| laparo_core::stats::median(&mut v);
    let (m_raw, m_fix) = (median(raw.clone()), median(fixed.clone()));
    let abs_fix = median(fixed.iter().map(|v| v.abs()).collect());
    eprintln!(
        "SCARED ds1-3: {} raw matches, median y_R − y_L = {m_raw:.3} px; {} rectified matches, median {m_fix:.3} px, median |.| {abs_fix:.3} px",
        raw.len(),
        fixed.len()
    );
    assert!(raw.len() >= 30 && fixed.len() >= 50);
    assert!((m_raw - -0.243).abs() < 0.05, "raw median {m_raw} px (OpenCV-side measurement −0.243)");
    assert!((m_fix - -0.229).abs() < 0.05, "rectified median {m_fix} px (OpenCV rectification: −0.229)");
    assert!(abs_fix < 0.3, "rectified |vertical disparity| {abs_fix} px");
}
