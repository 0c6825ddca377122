//! SGM on a warped pair with canvas outside the images (`sgm::masked`): a random-texture pair with a
//! constant disparity, black wedges outside each image's mask (what a rectification with α > 0
//! leaves), matched as is and through `match_masked`.
use laparo_core::image::{Image, Mask};
use laparo_stereo::{extend_rows, match_masked};
use laparo_stereo::{match_pair, SgmParams};
use rand::{Rng, SeedableRng};

const K: i32 = 12;

/// Left and right (right[x] = left[x + K], so d = K everywhere), masks with a wedge cut off the
/// left image's left side and the right image's right side, pixels outside the masks black.
fn wedged_pair() -> (Image<u8>, Image<u8>, Mask, Mask) {
    let (w, h) = (240usize, 160usize);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let wide: Vec<u8> = (0..(w + K as usize) * h).map(|_| rng.gen()).collect();
    let ww = w + K as usize;
    let mut l = Image::filled(w, h, 1, 0u8);
    let mut r = Image::filled(w, h, 1, 0u8);
    let mut ml = Image::filled(w, h, 1, false);
    let mut mr = Image::filled(w, h, 1, false);
    for y in 0..h {
        let (a, b) = (10 + y / 4, w - 10 - y / 5);
        for x in 0..w {
            if x >= a {
                l.set(x, y, 0, wide[y * ww + x]);
                ml.set(x, y, 0, true);
            }
            if x < b {
                r.set(x, y, 0, wide[y * ww + x + K as usize]);
                mr.set(x, y, 0, true);
            }
        }
    }
    (l, r, ml, mr)
}

#[test]
fn extend_rows_copies_the_nearest_in_mask_pixel() {
    let img = Image::from_vec(5, 2, 1, vec![0u8, 7, 8, 9, 0, 1, 2, 3, 4, 5]).unwrap();
    let m = Image::from_vec(5, 2, 1, vec![false, true, true, true, false, false, false, false, false, false]).unwrap();
    let e = extend_rows(&img, &m);
    assert_eq!(e.data, vec![7, 7, 8, 9, 9, 1, 2, 3, 4, 5]); // a row without a mask pixel is unchanged
}

#[test]
fn masked_matching_is_valid_only_inside_and_more_accurate_near_the_wedges() {
    let (l, r, ml, mr) = wedged_pair();
    let (w, h) = l.size();
    let p = SgmParams::new(0, 32);
    let plain = match_pair(&l, &r, &p).unwrap();
    let masked = match_masked(&l, &r, &ml, &mr, &p).unwrap();
    // pixels that have a true match in view: left in mask, x − K in the right mask
    let seen = |i: usize| {
        let (x, y) = (i % w, i / w);
        ml.data[i] && x >= K as usize && mr.data[y * w + x - K as usize]
    };
    let (mut ok_plain, mut ok_masked, mut bad_plain, mut bad_masked, mut n_seen) = (0, 0, 0, 0, 0);
    for i in 0..w * h {
        let (dp, dm) = (plain.disparity.data[i], masked.disparity.data[i]);
        if dm.is_finite() {
            // valid only where the left pixel is inside and its match lands inside the right mask
            let (x, y) = (i % w, i / w);
            let xr = (x as f32 - dm + 0.5).floor();
            assert!(ml.data[i], "valid outside the left mask at ({x}, {y})");
            assert!(xr >= 0.0 && mr.data[y * w + xr as usize], "match outside the right mask at ({x}, {y}): d {dm}");
            bad_masked += ((dm - K as f32).abs() > 1.0) as usize;
        }
        if dp.is_finite() {
            bad_plain += ((dp - K as f32).abs() > 1.0) as usize;
        }
        if seen(i) {
            n_seen += 1;
            ok_plain += (dp.is_finite() && (dp - K as f32).abs() <= 1.0) as usize;
            ok_masked += (dm.is_finite() && (dm - K as f32).abs() <= 1.0) as usize;
        }
    }
    eprintln!(
        "{n_seen} pixels with a match in view: correct plain {ok_plain}, masked {ok_masked}; wrong valid plain {bad_plain}, masked {bad_masked}; n_valid {}",
        masked.stats.n_valid
    );
    assert_eq!(masked.stats.n_valid, masked.disparity.data.iter().filter(|v| v.is_finite()).count());
    assert!(ok_masked as f64 >= 0.97 * n_seen as f64, "{ok_masked} of {n_seen}");
    assert!(ok_masked >= ok_plain, "masked {ok_masked} < plain {ok_plain}");
    assert!(bad_masked < bad_plain, "wrong valid pixels: masked {bad_masked}, plain {bad_plain}");
    // mask sizes are checked
    let small = Image::filled(w - 1, h, 1, true);
    let e = match_masked(&l, &r, &small, &mr, &p).unwrap_err().to_string();
    assert!(e.contains("left mask"), "{e}");
}
