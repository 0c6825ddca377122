//! Disparity ↔ depth with a non-zero principal-point offset on the real Middlebury 2014
//! Motorcycle pair (../shared/data/middlebury-motorcycle; calibration from its README:
//! f = 994.97775 px, b = 193.001 mm, doffs = c_x^R − c_x^L = 31.08575 px at 741x500).
//! Skips when the data is absent.
use laparo_core::image::Image;
use laparo_stereo::DisparityGeometry;
use laparo_stereo::{evaluate, EvalOptions};
use std::path::PathBuf;

fn load() -> Option<Image<f64>> {
    let p = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/middlebury-motorcycle/motorcycle_disp.npy"
    ));
    if !p.exists() {
        eprintln!("SKIP: {} not found", p.display());
        return None;
    }
    Some(laparo_core::io::read_npy(&p).unwrap())
}

fn geo() -> DisparityGeometry {
    DisparityGeometry::middlebury(994.97775, 193.001, 31.08575, 311.193, 254.87675)
}

#[test]
fn depth_range_matches_readme_and_round_trips() {
    let Some(d) = load() else { return };
    assert_eq!((d.width, d.height), (741, 500));
    let g = geo();
    assert!((g.offset_px() + 31.08575).abs() < 1e-12);
    let z = g.depth_map(&d);
    let valid: Vec<f64> = z.data.iter().copied().filter(|v| v.is_finite()).collect();
    // README: 343,274 valid pixels, Z from 2110 mm to 5017 mm.
    assert_eq!(valid.len(), 343_274);
    let (lo, hi) = valid.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    assert!((lo - 2110.0).abs() < 1.0 && (hi - 5017.0).abs() < 1.0, "Z range {lo}..{hi} mm");
    // Z = b f / (d + doffs) at one pixel, by hand.
    let (x, y) = (400, 300); // d = 47.6979 px (finite)
    let dv = d.get(x, y, 0);
    assert!((dv - 47.697853).abs() < 1e-5);
    assert!((z.get(x, y) - 193.001 * 994.97775 / (dv + 31.08575)).abs() < 1e-9);
    // Depth → disparity gives the GT back (including the offset term).
    let back = g.disparity_map(&z);
    let worst =
        d.data.iter().zip(&back.data).filter(|(a, _)| a.is_finite()).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max);
    assert!(worst < 1e-9, "round trip {worst} px");
    // Without the offset term the depths would be wrong by tens of percent.
    let no_off = DisparityGeometry::middlebury(994.97775, 193.001, 0.0, 311.193, 254.87675);
    assert!((no_off.depth_mm(dv) / z.get(x, y) - 1.0).abs() > 0.3);
    // Point cloud: one point per valid pixel, X = (x − c_x0) Z / f.
    let cloud = g.point_cloud(&d);
    assert_eq!(cloud.len(), 343_274);
    let (px, py, p) = cloud.iter().find(|(a, b, _)| (*a, *b) == (x, y)).copied().unwrap();
    assert!((p.x - (px as f64 - 311.193) * p.z / 994.97775).abs() < 1e-9);
    assert!((p.y - (py as f64 - 254.87675) * p.z / 994.97775).abs() < 1e-9);
}

#[test]
fn eval_of_shifted_gt_on_real_map() {
    let Some(d) = load() else { return };
    let g = geo();
    let shifted = d.map(|v| v + 1.5);
    let o = EvalOptions { depth_range_mm: None, ..EvalOptions::default() };
    let m = evaluate(&shifted, &d, None, Some(&g), &o).unwrap();
    assert_eq!(m.n_valid, 343_274);
    assert!((m.epe_px - 1.5).abs() < 1e-9);
    assert_eq!(m.bad_percent(1.0), Some(100.0));
    assert_eq!(m.bad_percent(2.0), Some(0.0));
    // A +1.5 px disparity error brings every point closer: z/z* = (d*+doffs)/(d*+doffs+1.5).
    let dep = m.depth.unwrap();
    let rel: f64 = d.data.iter().filter(|v| v.is_finite()).map(|v| 1.5 / (v + 31.08575 + 1.5)).sum::<f64>() / 343_274.0;
    assert!((dep.abs_rel - rel).abs() < 1e-12, "{} vs {rel}", dep.abs_rel);
}
