use super::kernel::{homography_px, nearest_row, safe_span};
use super::*;

/// xorshift in [0, 1).
fn rng(seed: u64) -> impl FnMut() -> f64 {
    let mut st = seed | 1;
    move || {
        st ^= st << 13;
        st ^= st >> 7;
        st ^= st << 17;
        (st >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The contract written out per pixel in plain code (f32, x first then y, round half up).
fn reference_bilinear_u8(img: &Image<u8>, fx: f32, fy: f32) -> Option<Vec<u8>> {
    let (w, h, c) = (img.width, img.height, img.channels);
    if !(fx >= 0.0 && fy >= 0.0 && fx <= (w - 1) as f32 && fy <= (h - 1) as f32) {
        return None;
    }
    let x0 = (fx.floor() as usize).min(w.saturating_sub(2));
    let y0 = (fy.floor() as usize).min(h.saturating_sub(2));
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
    let l = |a: f32, b: f32, t: f32| a + t * (b - a);
    Some(
        (0..c)
            .map(|k| {
                let g = |x: usize, y: usize| img.get(x, y, k) as f32;
                let v = l(l(g(x0, y0), g(x1, y0), ax), l(g(x0, y1), g(x1, y1), ax), ay);
                (v + 0.5) as u8
            })
            .collect(),
    )
}

fn random_u8(w: usize, h: usize, c: usize, seed: u64) -> Image<u8> {
    let mut r = rng(seed);
    Image::from_vec(w, h, c, (0..w * h * c).map(|_| (r() * 256.0) as u8).collect()).unwrap()
}

#[test]
fn hand_values_every_type() {
    // 2x2: 0 10 / 20 30. At (0.5, 0.5): lerp(lerp(0,10,.5), lerp(20,30,.5), .5) = 15.
    let u8img = Image::from_vec(2, 2, 1, vec![0u8, 10, 20, 30]).unwrap();
    let map = CoordMap { width: 4, height: 1, xy: vec![[0.5, 0.5], [0.25, 0.0], [0.05, 0.0], [1.01, 0.0]] };
    let (o, m) = remap(&u8img, &map, Interp::Bilinear, 7).unwrap();
    // 0.25·10 = 2.5 → 3 (half up); 0.05·10 = 0.5 → 1; outside → fill 7.
    assert_eq!(o.data, vec![15, 3, 1, 7]);
    assert_eq!(m.data, vec![true, true, true, false]);
    let u16img = u8img.map(|v| v as u16 * 1000);
    let (o, _) = remap(&u16img, &map, Interp::Bilinear, 0).unwrap();
    assert_eq!(o.data, vec![15000, 2500, 500, 0]);
    let f32img = u8img.map(|v| v as f32);
    let (o, m) = remap(&f32img, &map, Interp::Bilinear, f32::NAN).unwrap();
    assert_eq!(&o.data[..3], &[15.0, 2.5, 0.5]);
    assert!(o.data[3].is_nan() && !m.data[3]);
    let f64img = u8img.map(|v| v as f64);
    assert_eq!(f64img.sample_bilinear(0.5, 0.5, 0), Some(15.0));
    assert_eq!(f64img.sample_bilinear(0.25, 0.0, 0), Some(2.5));
    assert_eq!(f64img.sample_bilinear(1.0, 1.0, 0), Some(30.0));
    assert_eq!(f64img.sample_bilinear(1.01, 0.0, 0), None);
    // Nearest: round half up, domain [-0.5, w-0.5).
    let map = CoordMap { width: 4, height: 1, xy: vec![[0.5, 0.0], [0.49, 0.6], [-0.5, 0.0], [1.5, 0.0]] };
    let (o, m) = remap(&u8img, &map, Interp::Nearest, 99).unwrap();
    assert_eq!(o.data, vec![10, 20, 0, 99]);
    assert_eq!(m.data, vec![true, true, true, false]);
}

#[test]
fn float_texels_are_exact_at_integer_positions_next_to_non_finite_values() {
    let img = Image::from_vec(3, 1, 1, vec![1.5f32, f32::INFINITY, 2.0]).unwrap();
    // x = 0 and x = 2 take their pixel untouched although a neighbour is inf; x = 0.5 is invalid.
    let map = CoordMap { width: 3, height: 1, xy: vec![[0.0, 0.0], [2.0, 0.0], [0.5, 0.0]] };
    let (o, m) = remap(&img, &map, Interp::Bilinear, -1.0).unwrap();
    assert_eq!(o.data, vec![1.5, 2.0, -1.0]);
    assert_eq!(m.data, vec![true, true, false]);
    let (o, m) = remap(&img, &CoordMap::identity(3, 1), Interp::Nearest, -1.0).unwrap();
    assert_eq!((o.data, m.data), (vec![1.5, -1.0, 2.0], vec![true, false, true]));
}

#[test]
fn identity_reproduces_every_type_bit_for_bit() {
    for c in [1, 2, 3, 4, 5] {
        let img = random_u8(13, 7, c, 3 + c as u64);
        for interp in [Interp::Bilinear, Interp::Nearest] {
            let (o, m) = remap(&img, &CoordMap::identity(13, 7), interp, 0).unwrap();
            assert_eq!(o, img, "{c} channels {interp:?}");
            assert!(m.data.iter().all(|&v| v));
            let h = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            assert_eq!(warp_homography(&img, &h, 13, 7, interp, 0).unwrap().0, img);
        }
    }
    let f = random_u8(9, 5, 1, 1).map(|v| v as f32 * 0.37 - 3.0);
    assert_eq!(remap(&f, &CoordMap::identity(9, 5), Interp::Bilinear, 0.0).unwrap().0, f);
    let g = random_u8(9, 5, 1, 2).map(|v| v as u16 * 257);
    assert_eq!(remap(&g, &CoordMap::identity(9, 5), Interp::Bilinear, 0).unwrap().0, g);
}

#[test]
fn bilinear_rows_match_the_written_out_contract() {
    // SSE2 RGB(A) pixels, scalar 1/2/5 channels, border pixels (scalar tail of the SIMD path).
    let mut r = rng(11);
    for c in [1, 2, 3, 4, 5] {
        let img = random_u8(17, 11, c, c as u64);
        let xy: Vec<[f32; 2]> = (0..2000)
            .map(|i| match i {
                0 => [16.0, 10.0],
                1 => [15.5, 10.0],
                2 => [16.0, 9.999],
                _ => [(r() * 18.0 - 0.5) as f32, (r() * 12.0 - 0.5) as f32],
            })
            .collect();
        let map = CoordMap { width: xy.len(), height: 1, xy: xy.clone() };
        let (o, m) = remap(&img, &map, Interp::Bilinear, 0).unwrap();
        for (k, p) in xy.iter().enumerate() {
            match reference_bilinear_u8(&img, p[0], p[1]) {
                Some(v) => {
                    assert!(m.data[k]);
                    assert_eq!(&o.data[k * c..k * c + c], &v[..], "{c} ch at {p:?}");
                }
                None => assert!(!m.data[k] && o.data[k * c..k * c + c].iter().all(|&v| v == 0)),
            }
        }
    }
}

#[test]
fn bilinear_is_within_half_a_grey_level_of_the_exact_value() {
    // f64 closed form of the same interpolation; the f32 contract + rounding stays within 0.5 + 1e-3.
    let img = random_u8(31, 23, 3, 5);
    let mut r = rng(5);
    for _ in 0..5000 {
        let (x, y) = (r() * 30.0, r() * 22.0);
        let (xf, yf) = (x as f32, y as f32);
        let v = reference_bilinear_u8(&img, xf, yf).unwrap();
        for (k, &vk) in v.iter().enumerate() {
            let exact = img.sample_bilinear(xf as f64, yf as f64, k).unwrap();
            assert!((vk as f64 - exact).abs() <= 0.5 + 1e-3, "{vk} vs {exact}");
        }
    }
}

#[test]
fn fused_homography_rows_equal_the_two_pass_path() {
    // CATS-like and strong homographies; RGB u8 bilinear (fused AVX2) and f32 nearest (fused
    // AVX2 with the safe span) against remap_rows with the same f32 row coordinates (scalar).
    let mut r = rng(9);
    for t in 0..60 {
        let (w, h) = if t % 5 == 0 { (160, 90) } else { (2 + (r() * 70.0) as usize, 2 + (r() * 50.0) as usize) };
        let img = random_u8(w, h, 3, t);
        let fmap = Image::from_vec(
            w,
            h,
            1,
            (0..w * h)
                .map(|i| match (r() * 30.0) as u32 {
                    0 => f32::INFINITY,
                    1 => f32::NAN,
                    _ => i as f32 * 0.37 - 11.0,
                })
                .collect(),
        )
        .unwrap();
        let deg: f64 = [0.3, 5.0, 45.0, 170.0][t as usize % 4] * (2.0 * r() - 1.0);
        let (sn, cs) = deg.to_radians().sin_cos();
        let s = 1.0 + 0.2 * (2.0 * r() - 1.0);
        let p = [0.0, 1e-4, 2e-3][t as usize % 3] * (2.0 * r() - 1.0);
        let (tx, ty) = ((2.0 * r() - 1.0) * w as f64 * 0.3, (2.0 * r() - 1.0) * h as f64 * 0.3);
        let h_inv = [[s * cs, -s * sn, tx], [s * sn, s * cs, ty], [p, p * 0.5, 1.0]];
        let (ow, oh) = (w + 3, h + 1);
        let rows = |y: usize, sx: &mut [f32], sy: &mut [f32]| {
            let (a, c) = homography_row_coeffs(&h_inv, y);
            homography_row(a, c, sx, sy)
        };
        let fused = warp_homography(&img, &h_inv, ow, oh, Interp::Bilinear, 4).unwrap();
        let two_pass = remap_rows(&img, ow, oh, Interp::Bilinear, 4, rows).unwrap();
        assert_eq!(fused, two_pass, "case {t}: RGB bilinear");
        let fused = warp_homography(&fmap, &h_inv, ow, oh, Interp::Nearest, -7.0).unwrap();
        let two_pass = remap_rows(&fmap, ow, oh, Interp::Nearest, -7.0, rows).unwrap();
        let bits = |i: &Image<f32>| i.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!((bits(&fused.0), &fused.1), (bits(&two_pass.0), &two_pass.1), "case {t}: f32 nearest");
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let img = random_u8(257, 131, 3, 77);
    let h_inv = [[0.98, 0.05, 3.2], [-0.04, 1.01, -2.5], [1e-4, -2e-5, 1.0]];
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| warp_homography(&img, &h_inv, 257, 131, Interp::Bilinear, 0).unwrap())
    };
    assert_eq!(run(1), run(2));
    assert_eq!(run(1), run(5));
}

#[test]
fn bad_inputs_are_errors() {
    let img = random_u8(4, 4, 1, 1);
    let map = CoordMap { width: 3, height: 3, xy: vec![[0.0; 2]; 8] };
    assert!(remap(&img, &map, Interp::Bilinear, 0).is_err());
    let nan = [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert!(warp_homography(&img, &nan, 4, 4, Interp::Bilinear, 0).is_err());
    let empty: Image<u8> = Image { width: 0, height: 0, channels: 1, data: vec![] };
    assert!(remap(&empty, &CoordMap::identity(2, 2), Interp::Nearest, 0).is_err());
    assert!(warp_homography(
        &img,
        &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        usize::MAX,
        2,
        Interp::Nearest,
        0
    )
    .is_err());
}

/// Plain per-pixel reference of the nearest f32 row.
fn nearest_reference(
    a: [f32; 3],
    c: [f32; 3],
    data: &[f32],
    w: usize,
    h: usize,
    fill: f32,
    n: usize,
) -> (Vec<u32>, Vec<bool>) {
    let (mut o, mut m) = (vec![fill.to_bits(); n], vec![false; n]);
    for x in 0..n {
        let (fx, fy) = homography_px(a, c, x as i32 as f32);
        if fx >= -0.5 && fy >= -0.5 && fx < w as f32 - 0.5 && fy < h as f32 - 0.5 {
            let ix = ((fx + 0.5).floor() as usize).min(w - 1);
            let iy = ((fy + 0.5).floor() as usize).min(h - 1);
            let v = data[iy * w + ix];
            if v.is_finite() {
                o[x] = v.to_bits();
                m[x] = true;
            }
        }
    }
    (o, m)
}

#[test]
fn nearest_rows_equal_the_per_pixel_reference_and_the_safe_span_is_safe() {
    let mut rnd = rng(0x9E37_79B9_7F4A_7C15);
    let mut fast_rows = 0;
    for t in 0..300 {
        let (w, h) = if t % 5 == 0 { (640, 360) } else { (1 + (rnd() * 90.0) as usize, 1 + (rnd() * 60.0) as usize) };
        let n = if t % 7 == 0 { 1 + (rnd() * 100.0) as usize } else { w };
        let data: Vec<f32> = (0..w * h)
            .map(|i| match (rnd() * 40.0) as u32 {
                0 => f32::INFINITY,
                1 => f32::NAN,
                2 => f32::NEG_INFINITY,
                _ => i as f32 * 0.37 - 11.0,
            })
            .collect();
        let img = Image::from_vec(w, h, 1, data.clone()).unwrap();
        let deg = [0.3, 5.0, 45.0, 170.0][t % 4] * (2.0 * rnd() - 1.0);
        let (sn, cs) = f64::to_radians(deg).sin_cos();
        let s = 1.0 + [0.0, 0.001, 0.2, -0.5][(t / 4) % 4] * rnd();
        let p = [0.0, 1e-5, 1e-3, 2e-2][(t / 16) % 4] * (2.0 * rnd() - 1.0);
        let (tx, ty) = ((2.0 * rnd() - 1.0) * w as f64 * 0.3, (2.0 * rnd() - 1.0) * h as f64 * 0.3);
        let q = p * (2.0 * rnd() - 1.0);
        for y in 0..h {
            let yf = y as f64;
            let a = [(s * cs) as f32, (s * sn) as f32, p as f32];
            let c = [(-s * sn * yf + tx) as f32, (s * cs * yf + ty) as f32, (q * yf + 1.0) as f32];
            let fill = -7.0;
            let (ro, rm) = nearest_reference(a, c, &data, w, h, fill, n);
            // Fused path (when the CPU has AVX2).
            let (mut o, mut m) = (vec![MaybeUninit::new(1.5f32); n], vec![MaybeUninit::new(true); n]);
            if f32::homography_row_simd(a, c, &img, Interp::Nearest, fill, &mut o, &mut m) {
                // SAFETY: initialised above.
                let o: Vec<u32> = o.iter().map(|v| unsafe { v.assume_init() }.to_bits()).collect();
                let m: Vec<bool> = m.iter().map(|v| unsafe { v.assume_init() }).collect();
                assert_eq!((&o, &m), (&ro, &rm), "case {t} row {y} ({w}x{h}, n {n}, {deg} deg)");
            }
            // Portable path.
            let (mut sx, mut sy) = (vec![0f32; n], vec![0f32; n]);
            homography_row(a, c, &mut sx, &mut sy);
            let (mut o, mut m) = (vec![1.5f32; n], vec![true; n]);
            nearest_row::<f32, 1>(&data, w, h, 1, fill, &sx, &sy, &mut o, &mut m);
            let o: Vec<u32> = o.iter().map(|v| v.to_bits()).collect();
            assert_eq!((&o, &m), (&ro, &rm), "portable: case {t} row {y}");
            let (xs, xe) = safe_span(a, c, w, h, n);
            assert!(xs <= xe && xe <= n);
            if xe > xs + 8 {
                fast_rows += 1;
            }
            for x in xs..xe {
                let (fx, fy) = (sx[x], sy[x]);
                assert!(fx > -0.5 && fy > -0.5 && fx < w as f32 - 0.5 && fy < h as f32 - 0.5, "span {t} {y} {x}");
            }
        }
    }
    assert!(fast_rows > 1000, "the safe span was exercised ({fast_rows} rows)");
}

#[test]
fn safe_span_rejects_degenerate_rows() {
    let nan = f32::NAN;
    assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0, 10, 10), (0, 0));
    assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 10, 10, 0), (0, 0));
    assert_eq!(safe_span([nan, 0.0, 0.0], [0.0, 0.0, 1.0], 10, 10, 10), (0, 0));
    assert_eq!(safe_span([1.0, 0.0, f32::INFINITY], [0.0, 0.0, 1.0], 10, 10, 10), (0, 0));
    assert_eq!(safe_span([1.0, 0.0, -0.01], [0.0, 5.0, 0.05], 100, 10, 100), (0, 0));
    assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 5.0, -1.0], 100, 10, 100), (0, 0));
    // Identity row 5 of a 100x10 image: all but the end pixels (one-pixel shrink).
    assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 5.0, 1.0], 100, 10, 100), (1, 99));
    assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 10.0, 1.0], 100, 10, 100), (0, 0));
}

#[test]
fn homography_row_identity_is_exact() {
    let mut sx = vec![0.0; 1000];
    let mut sy = vec![0.0; 1000];
    homography_row([1.0, 0.0, 0.0], [-7.0, 3.0, 1.0], &mut sx, &mut sy);
    for (i, (&a, &b)) in sx.iter().zip(&sy).enumerate() {
        assert_eq!((a, b), (i as f32 - 7.0, 3.0));
    }
}

/// The undistortion map inverts the distortion: a point drawn in the distorted image at
/// `distort_pixel(p)` lands back at `p` (closed form of the map, checked against the camera
/// model's own iterative undistortion).
#[test]
fn undistort_map_inverts_the_camera_distortion() {
    let k = Intrinsics::new(500.0, 505.0, 321.5, 238.0, 640, 480).unwrap();
    let d = Distortion::brown_conrady(-0.23, 0.34, 0.001, -0.0005, -0.24);
    let map = CoordMap::undistort(&k, &d, 640, 480);
    for &(u, v) in &[(10usize, 12usize), (320, 240), (600, 400), (100, 450)] {
        let [sx, sy] = map.xy[v * 640 + u];
        let (bu, bv) = d.undistort_pixel(&k, sx as f64, sy as f64).unwrap();
        assert!(
            (bu - u as f64).abs() < 1e-3 && (bv - v as f64).abs() < 1e-3,
            "({u},{v}) -> ({sx},{sy}) -> ({bu},{bv})"
        );
    }
    // With zero distortion the map is the identity.
    assert_eq!(CoordMap::undistort(&k, &Distortion::default(), 64, 48), CoordMap::identity(64, 48));
}

#[test]
fn bicubic_weights_by_hand() {
    use super::kernel::cubic_weights;
    assert_eq!(cubic_weights(0.0), [0.0, 1.0, 0.0, 0.0]);
    assert_eq!(cubic_weights(1.0), [0.0, 0.0, 1.0, 0.0]);
    // t = ½: (−1/16, 9/16, 9/16, −1/16), all exact in binary
    assert_eq!(cubic_weights(0.5), [-0.0625, 0.5625, 0.5625, -0.0625]);
    let mut r = rng(5);
    for _ in 0..100 {
        let t = r();
        let w = cubic_weights(t);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        // first moment: Σ w_i (i − 1) = t (linear reproduction)
        assert!((-w[0] + w[2] + 2.0 * w[3] - t).abs() < 1e-15);
    }
}

#[test]
fn bicubic_reproduces_quadratics_and_integer_positions() {
    // Keys' kernel with a = −½ is exact for polynomials of degree ≤ 2 (tensor product in 2D).
    let (w, h) = (12, 9);
    let p = |x: f64, y: f64| 3.0 - 0.5 * x + 0.25 * y + 0.125 * x * x - 0.0625 * x * y + 0.03125 * y * y;
    let img = Image::from_vec(w, h, 1, (0..w * h).map(|i| p((i % w) as f64, (i / w) as f64)).collect()).unwrap();
    let mut r = rng(11);
    let pts: Vec<[f32; 2]> = (0..200).map(|_| [(1.0 + r() * 7.9) as f32, (1.0 + r() * 4.9) as f32]).collect();
    let map = CoordMap { width: pts.len(), height: 1, xy: pts.clone() };
    let (out, valid) = remap(&img, &map, Interp::Bicubic, f64::NAN).unwrap();
    for (i, q) in pts.iter().enumerate() {
        assert!(valid.data[i]);
        let exact = p(q[0] as f64, q[1] as f64);
        assert!((out.data[i] - exact).abs() < 1e-12, "{q:?}: {} vs {exact}", out.data[i]);
    }
    // integer positions reproduce the source bit for bit, even next to NaN
    let mut f = Image::from_vec(5, 4, 1, (0..20).map(|i| i as f32 * 0.37).collect()).unwrap();
    f.data[7] = f32::NAN;
    let (o, v) = remap(&f, &CoordMap::identity(5, 4), Interp::Bicubic, -1.0).unwrap();
    for i in 0..20 {
        if i == 7 {
            assert!(!v.data[i] && o.data[i] == -1.0);
        } else {
            assert!(v.data[i] && o.data[i].to_bits() == f.data[i].to_bits(), "pixel {i}");
        }
    }
    let u = random_u8(7, 6, 3, 3);
    let (o, v) = remap(&u, &CoordMap::identity(7, 6), Interp::Bicubic, 0).unwrap();
    assert_eq!(o, u);
    assert!(v.data.iter().all(|&b| b));
}

#[test]
fn bicubic_u8_rounds_and_saturates_by_hand() {
    let img = Image::from_vec(4, 1, 1, vec![0u8, 0, 255, 255]).unwrap();
    let map = CoordMap { width: 4, height: 1, xy: vec![[1.5, 0.0], [0.5, 0.0], [2.5, 0.0], [3.5, 0.0]] };
    let (o, v) = remap(&img, &map, Interp::Bicubic, 7).unwrap();
    // x = 1.5: 9/16·0 + 9/16·255 − 1/16·255 − 1/16·0 = 127.5 → 128 (half up)
    // x = 0.5: taps 0,0,1,2 → −1/16·255 = −15.9 → 0 (saturated)
    // x = 2.5: taps 1,2,3,3 → −1/16·0 + 9/16·255 + 9/16·255 − 1/16·255 = 271 → 255 (saturated)
    // x = 3.5: outside [0, w − 1] → fill
    assert_eq!(o.data, vec![128, 0, 255, 7]);
    assert_eq!(v.data, vec![true, true, true, false]);
}

/// The unclamped integer-texel bicubic path equals the clamped, zero-skipping per-pixel rule
/// (`bicubic_px_generic`) bit for bit: u8 and u16, 1 and 3 channels, homographies with fractional
/// and integer source positions, pixels at the borders and outside.
#[test]
fn bicubic_interior_path_equals_the_generic_rule() {
    use super::kernel::bicubic_px_generic;
    use rand::{Rng, SeedableRng};
    fn check<T: Texel + Default>(img: &Image<T>, h_inv: &[[f64; 3]; 3]) -> usize {
        let (w, h) = (img.width + 7, img.height + 5);
        let (out, valid) = warp_homography(img, h_inv, w, h, Interp::Bicubic, T::default()).unwrap();
        let c = img.channels;
        let (mut sx, mut sy) = (vec![0f32; w], vec![0f32; w]);
        let mut px = vec![T::default(); c];
        let mut n_valid = 0;
        for y in 0..h {
            let (a, cc) = homography_row_coeffs(h_inv, y);
            homography_row(a, cc, &mut sx, &mut sy);
            for x in 0..w {
                let (fx, fy) = (sx[x], sy[x]);
                let inside = fx >= 0.0 && fy >= 0.0 && fx <= (img.width - 1) as f32 && fy <= (img.height - 1) as f32;
                let ok =
                    inside && bicubic_px_generic(&img.data, img.width, img.height, c, T::default(), fx, fy, &mut px);
                assert_eq!(valid.get(x, y, 0), ok, "({x}, {y})");
                if ok {
                    n_valid += 1;
                    for (ch, &v) in px.iter().enumerate() {
                        assert_eq!(out.get(x, y, ch), v, "({x}, {y}) channel {ch}");
                    }
                }
            }
        }
        n_valid
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for (c, (iw, ih)) in [(1usize, (37usize, 29usize)), (3, (23, 19))] {
        let a: Vec<u8> = (0..iw * ih * c).map(|_| rng.gen()).collect();
        let b: Vec<u16> = (0..iw * ih * c).map(|_| rng.gen()).collect();
        let (a, b) = (Image::from_vec(iw, ih, c, a).unwrap(), Image::from_vec(iw, ih, c, b).unwrap());
        let shift = [[1.0, 0.0, -3.0], [0.0, 1.0, -2.0], [0.0, 0.0, 1.0]];
        for k in 0..6 {
            let h_inv = if k == 0 {
                shift
            } else {
                let mut r = |s: f64| rng.gen_range(-s..s);
                [[1.0 + r(0.2), r(0.2), r(4.0) - 3.0], [r(0.2), 1.0 + r(0.2), r(4.0) - 2.0], [r(2e-3), r(2e-3), 1.0]]
            };
            assert!(check(&a, &h_inv) > iw * ih / 3);
            assert!(check(&b, &h_inv) > iw * ih / 3);
        }
        // source positions beyond the image and beyond i32 (the SIMD path must leave them to the
        // scalar rule, which rejects them): x_s = 4e8 x, and a row whose x_s passes 2^31 only at its end
        for h_inv in
            [[[4e8, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [[1.0, 0.0, 3.0], [0.0, 1.0, 2.0], [-0.02, 0.0, 1.0]]]
        {
            check(&a, &h_inv);
            check(&b, &h_inv);
        }
    }
}

/// The coordinate map of a pixel-centre-aligned resize, written out from its definition.
fn resize_map(sw: usize, sh: usize, w: usize, h: usize) -> CoordMap {
    let pos = |i: usize, n: usize, m: usize| ((i as f64 + 0.5) * n as f64 / m as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let mut xy = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            xy.push([pos(x, sw, w) as f32, pos(y, sh, h) as f32]);
        }
    }
    CoordMap { width: w, height: h, xy }
}

#[test]
fn resize_equals_remap_with_the_resize_map() {
    let mut r = rng(7);
    for &(sw, sh, w, h, c) in &[(37, 23, 29, 17, 1), (37, 23, 80, 51, 3), (5, 4, 13, 9, 4), (64, 48, 32, 24, 1)] {
        let img = Image::from_vec(sw, sh, c, (0..sw * sh * c).map(|_| (r() * 256.0) as u8).collect()).unwrap();
        let imf = Image::from_vec(sw, sh, c, img.data.iter().map(|&v| v as f32 * 0.37).collect()).unwrap();
        let imd = Image::from_vec(sw, sh, c, img.data.iter().map(|&v| v as f64 * 0.37).collect()).unwrap();
        let map = resize_map(sw, sh, w, h);
        for interp in [Interp::Bilinear, Interp::Nearest, Interp::Bicubic] {
            assert_eq!(resize(&img, w, h, interp, 0).unwrap(), remap(&img, &map, interp, 0).unwrap());
            assert_eq!(resize(&imf, w, h, interp, 0.0).unwrap(), remap(&imf, &map, interp, 0.0).unwrap());
            assert_eq!(resize(&imd, w, h, interp, 0.0).unwrap(), remap(&imd, &map, interp, 0.0).unwrap());
        }
    }
}

#[test]
fn resize_hand_values_and_errors() {
    // 6 → 5 columns: positions (i + ½)·1.2 − ½ = 0.1, 1.3, 2.5, 3.7, 4.9 on the ramp 10·x.
    let img = Image::from_vec(6, 1, 1, vec![0u8, 10, 20, 30, 40, 50]).unwrap();
    assert_eq!(resize(&img, 5, 1, Interp::Bilinear, 0).unwrap().0.data, vec![1, 13, 25, 37, 49]);
    // 2× upsampling of [0, 4, 8]: positions −¼ (clamped to 0), ¼, ¾, 1¼, 1¾, 2¼ (clamped to 2).
    let f = Image::from_vec(3, 1, 1, vec![0f32, 4.0, 8.0]).unwrap();
    assert_eq!(resize(&f, 6, 1, Interp::Bilinear, 0.0).unwrap().0.data, vec![0.0, 1.0, 3.0, 5.0, 7.0, 8.0]);
    // NaN propagates where its weight is non-zero and marks the sample invalid.
    let n = Image::from_vec(3, 1, 1, vec![0f64, f64::NAN, 8.0]).unwrap();
    let (o, m) = resize(&n, 6, 1, Interp::Bilinear, -1.0).unwrap();
    assert_eq!(o.data, vec![0.0, -1.0, -1.0, -1.0, -1.0, 8.0]);
    assert_eq!(m.data, vec![true, false, false, false, false, true]);
    assert!(resize(&img, 0, 3, Interp::Bilinear, 0).is_err());
    assert!(resize(&Image::<u8>::filled(0, 0, 1, 0), 3, 3, Interp::Bilinear, 0).is_err());
}

#[test]
fn sample_smooth_interpolates_smooth_patches_and_keeps_edges() {
    // 3×2 map: a smooth left part (1, 1.5 / 2, 2.5) and a 10 px jump to the right column.
    let d = [1.0f32, 1.5, 11.0, 2.0, 2.5, 12.0];
    let v = |i: usize, j: usize| Some(d[j * 3 + i]);
    // Smooth 2×2 (span 1.5 ≤ 2): bilinear, 1 + 0.5·0.5 + 1·0.25 = 1.5 at (0.5, 0.25).
    assert_eq!(sample_smooth(3, 2, 0.5, 0.25, 2.0f32, v), Some(1.5));
    // Same patch with span limit 1: nearest of (0.5, 0.25) is (1, 0) → 1.5.
    assert_eq!(sample_smooth(3, 2, 0.5, 0.25, 1.0f32, v), Some(1.5));
    assert_eq!(sample_smooth(3, 2, 0.4, 0.6, 1.0f32, v), Some(2.0));
    // Across the jump: nearest.
    assert_eq!(sample_smooth(3, 2, 1.6, 0.0, 2.0f32, v), Some(11.0));
    // Outside [−½, w − ½): none; at the border band: nearest.
    assert_eq!(sample_smooth(3, 2, -0.6, 0.0, 2.0f32, v), None);
    assert_eq!(sample_smooth(3, 2, 2.3, 1.4, 2.0f32, v), Some(12.0));
    // An invalid neighbour: nearest; an invalid nearest: none.
    let hole = |i: usize, j: usize| (i != 1 || j != 1).then_some(d[j * 3 + i] as f64);
    assert_eq!(sample_smooth(3, 2, 0.3, 0.3, 2.0, hole), Some(1.0));
    assert_eq!(sample_smooth(3, 2, 0.8, 0.8, 2.0, hole), None);
}

#[test]
fn exact_u8_resize_of_a_falling_ramp_wraps_instead_of_overflowing() {
    // b < a in the horizontal blend: the difference wraps, so the sum must wrap too (issue 49: every
    // `cpc eval` panicked with "attempt to add with overflow" in a debug build).
    let img = Image::from_vec(6, 2, 1, (0..12).map(|i| (250 - i % 6 * 10) as u8).collect()).unwrap();
    let r = resize_exact_u8(&img, 5, 2).unwrap();
    assert_eq!(&r.data[..5], &[249, 237, 225, 213, 201]);
}

#[test]
fn exact_u8_resize_hand_values_and_one_grey_level_from_the_float_contract() {
    // 6 → 5: positions 0.1, 1.3, 2.5, 3.7, 4.9 → weights round(256·frac) = 26, 77, 128, 179, 230;
    // 10·x0 + (10·w + 128) >> 8 on the ramp 10·x.
    let img = Image::from_vec(6, 2, 1, (0..12).map(|i| (i % 6 * 10) as u8).collect()).unwrap();
    let r = resize_exact_u8(&img, 5, 2).unwrap();
    assert_eq!(&r.data[..5], &[1, 13, 25, 37, 49]);
    let mut rnd = rng(11);
    for &(sw, sh, w, h) in &[(640, 480, 533, 400), (97, 61, 40, 25), (31, 17, 62, 34)] {
        let img = Image::from_vec(sw, sh, 1, (0..sw * sh).map(|_| (rnd() * 256.0) as u8).collect()).unwrap();
        let a = resize_exact_u8(&img, w, h).unwrap();
        let (b, _) = resize(&img, w, h, Interp::Bilinear, 0).unwrap();
        let worst = a.data.iter().zip(&b.data).map(|(&p, &q)| (p as i32 - q as i32).abs()).max().unwrap();
        assert!(worst <= 1, "{sw}x{sh} -> {w}x{h}: {worst} grey levels apart");
    }
    assert!(resize_exact_u8(&Image::filled(4, 4, 3, 0u8), 2, 2).is_err());
}
