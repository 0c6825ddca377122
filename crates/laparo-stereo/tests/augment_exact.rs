//! Exactness of camera augmentation: identity, integer shifts, map round trips, Euler
//! conventions, and the two disparity rules on cases with a closed-form answer.
use laparo_core::se3::rotation_zyx;
use laparo_core::{Distortion, Image, Intrinsics};
use laparo_stereo::{augment_image, augment_stereo, CameraAugmentation, GtRule, StereoAugmentation, StereoSample};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};

fn k(w: usize, h: usize) -> Intrinsics {
    Intrinsics::new(0.9 * w as f64 + 0.37, 0.9 * w as f64 + 0.37, w as f64 / 2.0 + 0.13, h as f64 / 2.0 - 0.21, w, h)
        .unwrap()
}

fn random_image(w: usize, h: usize, c: usize, seed: u64) -> Image<u8> {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    Image::from_vec(w, h, c, (0..w * h * c).map(|_| r.gen()).collect()).unwrap()
}

fn random_disp(w: usize, h: usize, seed: u64) -> Image<f32> {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    Image::from_vec(
        w,
        h,
        1,
        (0..w * h).map(|i| if i % 17 == 0 { f32::INFINITY } else { r.gen_range(0.0..80.0) }).collect(),
    )
    .unwrap()
}

#[test]
fn identity_gives_back_input_bit_for_bit() {
    let (w, h) = (97, 61);
    let kk = k(w, h);
    for c in [1, 3, 4] {
        let img = random_image(w, h, c, c as u64);
        let out = augment_image(&img, &CameraAugmentation::identity(kk)).unwrap();
        assert_eq!(out.image, img, "{c} channels");
        assert!(out.valid.data.iter().all(|&v| v));
    }
    // Euler angles of exactly 0 degrees give the identity too, and so does a stereo sample.
    let a = CameraAugmentation::from_euler_deg(
        kk,
        Distortion::default(),
        [0.0; 3],
        Matrix3::identity(),
        Distortion::default(),
    );
    let s = StereoSample {
        left: random_image(w, h, 3, 10),
        right: random_image(w, h, 3, 11),
        disp_left: Some(random_disp(w, h, 12)),
        disp_right: Some(random_disp(w, h, 13)),
        occ_left: None,
        occ_right: None,
    };
    let p = StereoAugmentation { left: a.clone(), right: a, dx_right_px: 0.0 };
    for rule in [GtRule::Thesis, GtRule::Exact] {
        let o = augment_stereo(&s, &p, rule).unwrap();
        assert_eq!(o.left.image, s.left);
        assert_eq!(o.right.image, s.right);
        let d = o.disp_left.unwrap();
        let src = s.disp_left.as_ref().unwrap();
        for i in 0..src.data.len() {
            if src.data[i].is_finite() {
                assert!(d.valid.data[i]);
                assert_eq!(d.disparity.data[i].to_bits(), src.data[i].to_bits(), "{rule:?} pixel {i}");
            } else {
                assert!(!d.valid.data[i] && d.disparity.data[i] == f32::INFINITY);
            }
        }
    }
}

#[test]
fn integer_translation_reproduces_shifted_pixels() {
    let (w, h) = (80, 50);
    let img = random_image(w, h, 3, 5);
    for (tx, ty) in [(7.0, 0.0), (-13.0, 4.0), (0.0, -9.0)] {
        let kr = Matrix3::new(1.0, 0.0, tx, 0.0, 1.0, ty, 0.0, 0.0, 1.0);
        let a = CameraAugmentation::from_euler_deg(k(w, h), Distortion::default(), [0.0; 3], kr, Distortion::default());
        let out = augment_image(&img, &a).unwrap();
        for y in 0..h {
            for x in 0..w {
                let (sx, sy) = (x as f64 - tx, y as f64 - ty);
                let inside = sx >= 0.0 && sy >= 0.0 && sx < w as f64 && sy < h as f64;
                assert_eq!(out.valid.get(x, y, 0), inside, "({x},{y}) shift ({tx},{ty})");
                if inside {
                    assert_eq!(out.image.pixel(x, y), img.pixel(sx as usize, sy as usize));
                } else {
                    assert_eq!(out.image.pixel(x, y), &[0, 0, 0]);
                }
            }
        }
    }
}

#[test]
fn maps_of_eq_3_5_and_inverse_compose_to_identity() {
    let (w, h) = (640, 480);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for case in 0..6 {
        let e = [rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0)];
        let kr = Matrix3::new(
            rng.gen_range(0.9..1.1),
            0.0,
            rng.gen_range(-50.0..50.0),
            0.0,
            rng.gen_range(0.9..1.1),
            rng.gen_range(-5.0..5.0),
            0.0,
            0.0,
            1.0,
        );
        let (din, dout) = if case % 2 == 0 {
            (Distortion::default(), Distortion::default())
        } else {
            (
                Distortion::brown_conrady(-0.12, 0.04, 0.001, -0.0007, -0.005),
                Distortion::brown_conrady(rng.gen_range(-0.1..0.1), 0.01, 0.0005, 0.0002, 0.0),
            )
        };
        let m = CameraAugmentation::from_euler_deg(k(w, h), din, e, kr, dout).map().unwrap();
        let mut worst = 0.0f64;
        for y in (0..h).step_by(12) {
            for x in (0..w).step_by(12) {
                let (xf, yf) = (x as f64, y as f64);
                let (u, v) = m.forward(xf, yf).unwrap();
                let (a, b) = m.inverse(u, v).unwrap();
                worst = worst.max((a - xf).hypot(b - yf));
                let (u, v) = m.inverse(xf, yf).unwrap();
                let (a, b) = m.forward(u, v).unwrap();
                worst = worst.max((a - xf).hypot(b - yf));
            }
        }
        assert!(worst < 1e-9, "case {case}: worst round trip {worst} px");
    }
}

#[test]
fn euler_convention_matches_nalgebra_and_axis_products() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for _ in 0..20 {
        let (x, y, z): (f64, f64, f64) = (rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
        let a = CameraAugmentation::from_euler_deg(
            k(100, 100),
            Distortion::default(),
            [x, y, z],
            Matrix3::identity(),
            Distortion::default(),
        );
        let r = a.r();
        // nalgebra: from_euler_angles(roll, pitch, yaw) = Rz(yaw) Ry(pitch) Rx(roll).
        let n = Rotation3::from_euler_angles(x.to_radians(), y.to_radians(), z.to_radians());
        assert!((r - n.matrix()).norm() < 1e-14);
        let prod = Rotation3::from_axis_angle(&Vector3::z_axis(), z.to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), y.to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), x.to_radians());
        assert!((r - prod.matrix()).norm() < 1e-14);
        assert!((r - rotation_zyx(x.to_radians(), y.to_radians(), z.to_radians())).norm() == 0.0);
        // A rotation about +z by ψ moves the point right of the principal point downwards (y down).
        let az = CameraAugmentation::from_euler_deg(
            k(100, 100),
            Distortion::default(),
            [0.0, 0.0, 1.0],
            Matrix3::identity(),
            Distortion::default(),
        );
        let m = az.map().unwrap();
        let (_, v) = m.forward(90.0, az.k.cy).unwrap();
        assert!(v > az.k.cy);
        // Round trip of the derived Euler angles.
        let b = CameraAugmentation::from_rotation(
            a.k,
            Distortion::default(),
            r,
            Matrix3::identity(),
            Distortion::default(),
        );
        for i in 0..3 {
            assert!((b.euler_deg[i] - [x, y, z][i]).abs() < 1e-12);
        }
    }
}

#[test]
fn rules_agree_for_pure_principal_point_shift() {
    // R = I: both rules must give d + Δx_right exactly where the source pixel is inside.
    let (w, h) = (120, 40);
    let kk = k(w, h);
    let s = StereoSample {
        left: random_image(w, h, 3, 1),
        right: random_image(w, h, 3, 2),
        disp_left: Some(random_disp(w, h, 3)),
        disp_right: None,
        occ_left: None,
        occ_right: None,
    };
    let dx = -37.0;
    let p = StereoAugmentation {
        left: CameraAugmentation::identity(kk),
        right: CameraAugmentation::from_euler_deg(
            kk,
            Distortion::default(),
            [0.0; 3],
            Matrix3::new(1.0, 0.0, -dx, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            Distortion::default(),
        ),
        dx_right_px: dx,
    };
    let a = augment_stereo(&s, &p, GtRule::Thesis).unwrap().disp_left.unwrap();
    let b = augment_stereo(&s, &p, GtRule::Exact).unwrap().disp_left.unwrap();
    let src = s.disp_left.as_ref().unwrap();
    for i in 0..src.data.len() {
        if src.data[i].is_finite() {
            let want = src.data[i] as f64 + dx;
            assert!((a.disparity.data[i] as f64 - want).abs() < 1e-5);
            assert!((b.disparity.data[i] as f64 - want).abs() < 1e-5);
            assert_eq!(b.vertical_residual.as_ref().unwrap().data[i], 0.0);
        }
    }
    // And the right image moved by −Δx: augmented right pixel x shows source x + Δx.
    let o = augment_stereo(&s, &p, GtRule::Exact).unwrap();
    assert_eq!(o.right.image.pixel(50, 7), s.right.pixel(13, 7));
}

#[test]
fn bad_parameters_are_rejected_with_names() {
    let kk = k(50, 40);
    let mut a = CameraAugmentation::identity(kk);
    a.rotation = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let e = a.map().unwrap_err().to_string();
    assert!(e.contains("rotation"), "{e}");
    let b = CameraAugmentation::identity(kk);
    let small = Image::filled(49, 40, 3, 0u8);
    let e = augment_image(&small, &b).unwrap_err().to_string();
    assert!(e.contains("49x40"), "{e}");
}

#[test]
fn occlusion_masks_follow_their_camera() {
    // Masks are warped by nearest neighbour with their own camera's map: for a pure shift of the
    // right camera, the right mask moves with the right image and the left one stays.
    let (w, h) = (40, 30);
    let kk = k(w, h);
    let mask = Image::from_vec(w, h, 1, (0..w * h).map(|i| (i % w) < 10).collect()).unwrap();
    let s = StereoSample {
        left: random_image(w, h, 3, 1),
        right: random_image(w, h, 3, 2),
        disp_left: None,
        disp_right: None,
        occ_left: Some(mask.clone()),
        occ_right: Some(mask.clone()),
    };
    let p = StereoAugmentation {
        left: CameraAugmentation::identity(kk),
        right: CameraAugmentation::from_euler_deg(
            kk,
            Distortion::default(),
            [0.0; 3],
            Matrix3::new(1.0, 0.0, 5.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            Distortion::default(),
        ),
        dx_right_px: -5.0,
    };
    let o = augment_stereo(&s, &p, GtRule::Thesis).unwrap();
    assert_eq!(o.occ_left.unwrap(), mask);
    let r = o.occ_right.unwrap();
    for x in 0..w {
        assert_eq!(r.get(x, 7, 0), (5..15).contains(&x), "x = {x}");
    }
}
