//! Rectification acceptance: synthetic 3D points seen by a distorted, rotated, calibrated stereo
//! pair land on the same row after rectification (< 1e-6 px), with the disparity of §3.3.8.
use laparo_core::calib::StereoCalibration;
use laparo_core::camera::{Distortion, Intrinsics};
use laparo_core::se3::rotation_zyx;
use laparo_stereo::{Rectification, RectifyOptions, Side};
use nalgebra::Vector3;

fn pair() -> StereoCalibration {
    let left = Intrinsics::new(1035.3, 1035.1, 596.9, 520.4, 1280, 1024).unwrap();
    let right = Intrinsics::new(1030.2, 1031.0, 688.4, 515.1, 1280, 1024).unwrap();
    StereoCalibration {
        width: 1280,
        height: 1024,
        left,
        // Much stronger than SCARED's, to exercise undistortion.
        left_dist: Distortion::brown_conrady(-0.12, 0.05, 0.001, -0.0008, 0.01),
        right,
        right_dist: Distortion::brown_conrady(-0.10, 0.03, -0.0005, 0.0012, 0.0),
        r: rotation_zyx(0.8f64.to_radians(), -1.1f64.to_radians(), 0.6f64.to_radians()),
        t_mm: Vector3::new(-4.3, 0.12, -0.07),
    }
}

/// Project a left-frame point (mm) into the distorted image of one camera.
fn project(k: &Intrinsics, d: &Distortion, p: &Vector3<f64>) -> (f64, f64) {
    let (xd, yd) = d.distort_normalized(p.x / p.z, p.y / p.z);
    k.normalized_to_pixel(xd, yd)
}

fn points() -> Vec<Vector3<f64>> {
    let mut v = Vec::new();
    for i in 0..9 {
        for j in 0..7 {
            let z = 30.0 + 11.0 * ((i * 7 + j) % 10) as f64;
            v.push(Vector3::new((i as f64 - 4.0) * 0.1 * z, (j as f64 - 3.0) * 0.1 * z, z));
        }
    }
    v
}

fn check(opts: RectifyOptions) {
    let c = pair();
    let rect = Rectification::new(&c, opts).unwrap();
    let g = rect.geometry();
    let mut worst_y = 0.0f64;
    let mut worst_d = 0.0f64;
    let mut n = 0;
    for p in points() {
        let pr = c.r * p + c.t_mm;
        let (ul, vl) = project(&c.left, &c.left_dist, &p);
        let (ur, vr) = project(&c.right, &c.right_dist, &pr);
        let inside = |u: f64, v: f64| u >= 0.0 && v >= 0.0 && u <= 1279.0 && v <= 1023.0;
        if !(inside(ul, vl) && inside(ur, vr)) {
            continue;
        }
        n += 1;
        let (xl, yl) = rect.rectify_point(Side::Left, ul, vl).unwrap();
        let (xr, yr) = rect.rectify_point(Side::Right, ur, vr).unwrap();
        worst_y = worst_y.max((yl - yr).abs());
        // Depth along the rectified optical axis.
        let z = (rect.r1 * p).z;
        worst_d = worst_d.max(((xl - xr) - g.disparity_px(z)).abs());
        // The inverse map goes back to the source pixel.
        let (a, b) = rect.source_point(Side::Left, xl, yl).unwrap();
        assert!((a - ul).abs() < 1e-6 && (b - vl).abs() < 1e-6, "inverse map ({a}, {b}) vs ({ul}, {vl})");
    }
    assert!(n > 30, "only {n} points inside both images");
    assert!(worst_y < 1e-6, "rectified rows differ by {worst_y} px");
    assert!(worst_d < 1e-6, "disparity differs from f b / z + offset by {worst_d} px");
}

#[test]
fn rectified_rows_equal_aligned_principal_points() {
    check(RectifyOptions::default());
    let rect = Rectification::new(&pair(), RectifyOptions::default()).unwrap();
    assert_eq!(rect.doffs_px(), 0.0);
    assert!((rect.k1.cy - rect.k2.cy).abs() == 0.0);
}

#[test]
fn rectified_rows_equal_with_principal_point_offset() {
    check(RectifyOptions { alpha: -1.0, align_principal_points: false });
    let rect = Rectification::new(&pair(), RectifyOptions { alpha: -1.0, align_principal_points: false }).unwrap();
    // Not aligned: the raw pair's c_x difference (~ −91 px) survives, shifted by the rotations.
    assert!(rect.disparity_offset_px() < -50.0, "{}", rect.disparity_offset_px());
    // alpha < 0: f' = mean f_y.
    assert!((rect.focal_px() - 0.5 * (1035.1 + 1031.0)).abs() < 1e-12);
}

#[test]
fn alpha_zero_every_rectified_pixel_has_a_source_alpha_one_keeps_every_source_pixel() {
    let c = pair();
    let r0 = Rectification::new(&c, RectifyOptions { alpha: 0.0, align_principal_points: true }).unwrap();
    for side in [Side::Left, Side::Right] {
        let t = r0.remap_table(side);
        let (w, h) = (1279.0 + 0.5, 1023.0 + 0.5);
        let bad =
            t.xy.iter()
                .filter(|p| !(p[0] as f64 >= -0.5 && p[1] as f64 >= -0.5 && p[0] as f64 <= w && p[1] as f64 <= h))
                .count();
        // The inner rectangle is found from border samples every 8 px: allow a sub-pixel sliver.
        assert!(bad as f64 / t.xy.len() as f64 <= 1e-3, "{side:?}: {bad} rectified pixels without source");
    }
    let r1 = Rectification::new(&c, RectifyOptions { alpha: 1.0, align_principal_points: true }).unwrap();
    assert!(r1.focal_px() < r0.focal_px());
    for side in [Side::Left, Side::Right] {
        for (u, v) in [(0.0, 0.0), (1279.0, 0.0), (0.0, 1023.0), (1279.0, 1023.0), (640.0, 0.0), (0.0, 512.0)] {
            let (x, y) = r1.rectify_point(side, u, v).unwrap();
            assert!(
                x >= -1e-6 && y >= -1e-6 && x <= 1279.0 + 1e-6 && y <= 1023.0 + 1e-6,
                "{side:?} ({u},{v}) -> ({x},{y})"
            );
        }
    }
}

#[test]
fn rectified_image_of_a_plane_matches_along_rows() {
    // A fronto-parallel textured plane at z = 60 mm (in the rectified frame) is rendered by both
    // distorted cameras (inverse mapping, exact texture function); after rectification the left
    // image at x equals the right image at x − d with d = f' b / z + (c_x^L − c_x^R).
    use laparo_core::image::Image;
    let c = pair();
    let rect = Rectification::new(&c, RectifyOptions::default()).unwrap();
    let z0 = 60.0;
    let n_plane = rect.r1.transpose() * Vector3::z(); // plane normal in the left frame
    let tex = |p: &Vector3<f64>| {
        let q = rect.r1 * p; // rectified-left coordinates
        (127.5 + 60.0 * (q.x * 0.9).sin() + 60.0 * (q.y * 0.7).cos()).round() as u8
    };
    let render = |side: Side| {
        let (k, d) = match side {
            Side::Left => (&c.left, &c.left_dist),
            Side::Right => (&c.right, &c.right_dist),
        };
        let mut img = Image::filled(1280, 1024, 1, 0u8);
        for y in 0..1024 {
            for x in 0..1280 {
                let (xn, yn) = k.pixel_to_normalized(x as f64, y as f64);
                let (u, v) = d.undistort_normalized(xn, yn).unwrap();
                // Ray in the left frame: for the right camera, X_left = Rᵀ (X_right − T).
                let (o, dir) = match side {
                    Side::Left => (Vector3::zeros(), Vector3::new(u, v, 1.0)),
                    Side::Right => (-(c.r.transpose() * c.t_mm), c.r.transpose() * Vector3::new(u, v, 1.0)),
                };
                let s = (z0 - n_plane.dot(&o)) / n_plane.dot(&dir);
                img.set(x, y, 0, tex(&(o + dir * s)));
            }
        }
        img
    };
    let (l, ml) = rect.rectify_image(Side::Left, &render(Side::Left)).unwrap();
    let (r, mr) = rect.rectify_image(Side::Right, &render(Side::Right)).unwrap();
    let d = rect.geometry().disparity_px(z0);
    let mut err = 0.0;
    let mut n = 0usize;
    for y in 100..900 {
        for x in 200..1100 {
            let xr = x as f64 - d;
            let x0 = xr.floor() as usize;
            if !(ml.get(x, y, 0) && mr.get(x0, y, 0) && mr.get(x0 + 1, y, 0)) {
                continue;
            }
            // d is not an integer in general: interpolate the right image along the row.
            let a = xr - x0 as f64;
            let v = (1.0 - a) * r.get(x0, y, 0) as f64 + a * r.get(x0 + 1, y, 0) as f64;
            err += (l.get(x, y, 0) as f64 - v).abs();
            n += 1;
        }
    }
    let mae = err / n as f64;
    // Texture period ~ 7 mm ≈ 120 px: bilinear resampling twice + 8-bit rounding stays well below 1 grey level (a 1-px row error costs ~1.5).
    eprintln!("plane test: mean |L(x) - R(x - d)| = {mae:.3} grey levels over {n} px (d = {d:.3} px)");
    assert!(n > 500_000 && mae < 0.6, "mean |L(x) − R(x − d)| = {mae} grey levels over {n} px");
}

#[test]
fn remap_table_matches_the_exact_inverse_map() {
    // Brown–Conrady (fast path) and rational (general path) distortion.
    let mut c = pair();
    for rational in [false, true] {
        if rational {
            c.left_dist.k4 = 0.05;
            c.left_dist.k6 = -0.01;
        }
        let rect = Rectification::new(&c, RectifyOptions { alpha: -1.0, align_principal_points: true }).unwrap();
        let t = rect.remap_table(Side::Left);
        let mut worst = 0.0f64;
        for y in (0..1024).step_by(7) {
            for x in (0..1280).step_by(5) {
                let (a, b) = rect.source_point(Side::Left, x as f64, y as f64).unwrap();
                let p = t.xy[y * 1280 + x];
                worst = worst.max((p[0] as f64 - a).abs().max((p[1] as f64 - b).abs()));
            }
        }
        // f32 storage: ~1e-4 px at 1280 px.
        assert!(worst < 5e-4, "rational = {rational}: table differs from source_point by {worst} px");
    }
}
