//! Stereo evaluation metrics hand-derived on tiny arrays (Tables 3.7–3.8 definitions).
use laparo_core::image::Image;
use laparo_stereo::DisparityGeometry;
use laparo_stereo::{evaluate, evaluate_maps, EvalOptions};

fn img(w: usize, h: usize, v: &[f64]) -> Image<f64> {
    Image::from_vec(w, h, 1, v.to_vec()).unwrap()
}

const NAN: f64 = f64::NAN;

fn gt() -> Image<f64> {
    img(4, 2, &[10.0, 20.0, NAN, 5.0, -3.0, 8.0, -12.0, 0.0])
}
fn pred() -> Image<f64> {
    img(4, 2, &[11.0, 17.0, 4.0, 5.5, NAN, 8.0, -12.0, 0.2])
}
/// f = 100 px, b = 2 mm (f b = 200), c_x^L − c_x^R = 50 − 60 = −10 px: z = 200 / (d + 10).
fn geo() -> DisparityGeometry {
    DisparityGeometry { f_px: 100.0, fy_px: 100.0, baseline_mm: 2.0, cx_left: 50.0, cx_right: 60.0, cy: 1.0 }
}

#[test]
fn disparity_metrics_by_hand() {
    let m = evaluate(&pred(), &gt(), None, None, &EvalOptions::default()).unwrap();
    // Valid GT: 7 pixels (one NaN); one of them has no prediction.
    assert_eq!((m.n_valid, m.n_pred_missing), (7, 1));
    // |errors| = 1, 3, 0.5, 0, 0, 0.2 → EPE = 4.7 / 6.
    assert!((m.epe_px - 4.7 / 6.0).abs() < 1e-15, "{}", m.epe_px);
    // > 1 px: {3} + missing = 2 of 7; > 2 px: same; > 3 px: only the missing one.
    assert!((m.bad_percent(1.0).unwrap() - 200.0 / 7.0).abs() < 1e-12);
    assert!((m.bad_percent(2.0).unwrap() - 200.0 / 7.0).abs() < 1e-12);
    assert!((m.bad_percent(3.0).unwrap() - 100.0 / 7.0).abs() < 1e-12);
    assert!(m.depth.is_none());
}

#[test]
fn zero_invalid_and_mask() {
    let o = EvalOptions { zero_is_invalid: true, ..EvalOptions::default() };
    let m = evaluate(&pred(), &gt(), None, None, &o).unwrap();
    assert_eq!(m.n_valid, 6);
    assert!((m.epe_px - 4.5 / 5.0).abs() < 1e-15);
    let mut mask = Image::filled(4, 2, 1, true);
    mask.set(1, 0, 0, false);
    let m = evaluate(&pred(), &gt(), Some(&mask), None, &EvalOptions::default()).unwrap();
    assert_eq!(m.n_valid, 6);
    assert!((m.epe_px - 1.7 / 5.0).abs() < 1e-15);
    assert!((m.bad_percent(1.0).unwrap() - 100.0 / 6.0).abs() < 1e-12);
}

#[test]
fn depth_metrics_by_hand() {
    let o = EvalOptions { depth_range_mm: Some((1.0, 100.0)), ..EvalOptions::default() };
    let (m, maps) = evaluate_maps(&pred(), &gt(), None, Some(&geo()), &o).unwrap();
    let d = m.depth.unwrap();
    // Valid GT depth: d* > −10 → pixels with d* = 10, 20, 5, −3, 8, 0 (not −12).
    let zg: [f64; 6] = [200.0 / 20.0, 200.0 / 30.0, 200.0 / 15.0, 200.0 / 7.0, 200.0 / 18.0, 200.0 / 10.0];
    // Predictions 11, 17, 5.5, missing (→ far clamp 100 mm), 8, 0.2.
    let zp: [f64; 6] = [200.0 / 21.0, 200.0 / 27.0, 200.0 / 15.5, 100.0, 200.0 / 18.0, 200.0 / 10.2];
    let n = 6.0;
    let mae: f64 = zg.iter().zip(&zp).map(|(g, p)| (g - p).abs()).sum::<f64>() / n;
    let rmse = (zg.iter().zip(&zp).map(|(g, p)| (g - p).powi(2)).sum::<f64>() / n).sqrt();
    let rel: f64 = zg.iter().zip(&zp).map(|(g, p)| (g - p).abs() / g).sum::<f64>() / n;
    assert_eq!(d.n_valid, 6);
    assert!((d.mae_mm - mae).abs() < 1e-12 && (d.rmse_mm - rmse).abs() < 1e-12 && (d.abs_rel - rel).abs() < 1e-12);
    // Ratios 1.05, 1.111, 1.0333, 3.5, 1, 1.02 against 1.25^0.25 = 1.0574: 4 of 6.
    assert!((d.delta_0_25 - 4.0 / 6.0).abs() < 1e-15);
    // Maps: error at the first pixel, NaN where GT depth is invalid (d* = −12).
    let ze = maps.depth_error_mm.unwrap();
    assert!((ze.get(0, 0, 0) - (10.0 - 200.0 / 21.0)).abs() < 1e-12);
    assert!(ze.get(2, 1, 0).is_nan() && maps.disparity_error_px.get(2, 0, 0).is_nan());
    // Default clamp [10, 500] mm moves the near predictions: the 6.67 mm GT pixel is predicted 10 mm.
    let m2 = evaluate(&pred(), &gt(), None, Some(&geo()), &EvalOptions::default()).unwrap();
    assert!(m2.depth.unwrap().mae_mm != d.mae_mm);
}

#[test]
fn perfect_prediction_and_errors() {
    let g = img(3, 1, &[1.0, 2.0, 3.0]);
    let m = evaluate(&g, &g, None, Some(&geo()), &EvalOptions::default()).unwrap();
    assert_eq!(m.epe_px, 0.0);
    let d = m.depth.unwrap();
    assert_eq!((d.mae_mm, d.rmse_mm, d.abs_rel, d.delta_0_25), (0.0, 0.0, 0.0, 1.0));
    let e = evaluate(&img(2, 1, &[1.0, 2.0]), &g, None, None, &EvalOptions::default()).unwrap_err();
    assert!(e.to_string().contains("size mismatch"), "{e}");
    let e = evaluate(&g, &img(3, 1, &[NAN; 3]), None, None, &EvalOptions::default()).unwrap_err();
    assert!(e.to_string().contains("no valid"), "{e}");
}
