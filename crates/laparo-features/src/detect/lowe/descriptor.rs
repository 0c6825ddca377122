//! The SIFT descriptor (Lowe 2004 §6; OpenCV `calcSIFTDescriptor`): gradients in a window
//! rotated to the keypoint angle, weighted by a Gaussian of σ = d/2 histogram widths,
//! trilinearly spread over 4×4 spatial cells × 8 direction bins (histogram width 3·scale),
//! normalised, clipped at 0.2, renormalised and scaled by 512 to integers in 0 … 255.
use super::blur::Plane;
use super::fastmath::mag_ang;

/// Spatial cells per side.
const D: usize = 4;
/// Direction bins.
const N: usize = 8;
/// Descriptor length d·d·n.
pub const DIM: usize = D * D * N;
/// Histogram width in units of the keypoint scale (OpenCV `SIFT_DESCR_SCL_FCTR`).
const SCL_FCTR: f32 = 3.0;
/// Clip after the first normalisation (OpenCV `SIFT_DESCR_MAG_THR`).
const MAG_THR: f32 = 0.2;
/// Scale to byte range (OpenCV `SIFT_INT_DESCR_FCTR`).
const INT_FCTR: f32 = 512.0;

/// Descriptor of a keypoint at `pt` (octave px) of `img`, direction `ori` (degrees, the
/// image-space direction = 360 − keypoint angle) and scale `scl` (octave px).
pub fn describe(img: &Plane, pt: (f32, f32), ori: f32, scl: f32) -> [f32; DIM] {
    let (px, py) = (pt.0.round() as i64, pt.1.round() as i64);
    let (s, c) = (ori.to_radians()).sin_cos();
    let bins_per_deg = N as f32 / 360.0;
    let exp_scale = -1.0 / (D as f32 * D as f32 * 0.5);
    let hist_width = SCL_FCTR * scl;
    let mut radius = (hist_width * std::f32::consts::SQRT_2 * (D as f32 + 1.0) * 0.5).round() as i64;
    let diag = ((img.w * img.w + img.h * img.h) as f64).sqrt() as i64;
    radius = radius.min(diag);
    let (cos_t, sin_t) = (c / hist_width, s / hist_width);
    let (w, h) = (img.w as i64, img.h as i64);
    // (c_rot² + r_rot²) = (i² + j²)/hist_width²: the weight factorises into e(i)·e(j).
    let e: Vec<f32> =
        (-radius..=radius).map(|i| ((i * i) as f32 / (hist_width * hist_width) * exp_scale).exp()).collect();
    let cap = ((2 * radius + 1) * (2 * radius + 1)) as usize;
    let (mut dx, mut dy, mut wt, mut rb, mut cb) = (
        Vec::with_capacity(cap),
        Vec::with_capacity(cap),
        Vec::with_capacity(cap),
        Vec::with_capacity(cap),
        Vec::with_capacity(cap),
    );
    let half = D as f32 / 2.0 - 0.5;
    for i in -radius..=radius {
        let r = py + i;
        if r <= 0 || r >= h - 1 {
            continue;
        }
        let (up, row, dn) = (img.row(r as usize - 1), img.row(r as usize), img.row(r as usize + 1));
        let ei = e[(i + radius) as usize];
        let (fi_s, fi_c) = (i as f32 * sin_t, i as f32 * cos_t);
        // Both bins are linear in j: only the j with −1 < bin < D for both can count (one px
        // of margin each side; the exact test below decides).
        let (mut jlo, mut jhi) = ((-radius).max(1 - px), radius.min(w - 2 - px));
        for (slope, icpt) in [(cos_t, half - fi_s), (sin_t, half + fi_c)] {
            if slope.abs() > 1e-12 {
                let (a, b) = ((-1.0 - icpt) / slope, (D as f32 - icpt) / slope);
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                jlo = jlo.max(lo.floor() as i64 - 1);
                jhi = jhi.min(hi.ceil() as i64 + 1);
            }
        }
        for j in jlo..=jhi {
            let c_rot = j as f32 * cos_t - fi_s;
            let r_rot = j as f32 * sin_t + fi_c;
            let rbin = r_rot + half;
            let cbin = c_rot + half;
            if rbin > -1.0 && rbin < D as f32 && cbin > -1.0 && cbin < D as f32 {
                let x = (px + j) as usize;
                dx.push(row[x + 1] - row[x - 1]);
                dy.push(up[x] - dn[x]);
                wt.push(ei * e[(j + radius) as usize]);
                rb.push(rbin);
                cb.push(cbin);
            }
        }
    }
    let mut mag = vec![0f32; dx.len()];
    let mut ang = vec![0f32; dx.len()];
    mag_ang(&dx, &dy, &mut mag, &mut ang);
    let mut hist = [0f32; (D + 2) * (D + 2) * (N + 2)];
    for k in 0..dx.len() {
        let (mut rbin, mut cbin) = (rb[k], cb[k]);
        let mut obin = (ang[k] - ori) * bins_per_deg;
        let m = mag[k] * wt[k];
        let (r0, c0, o0) = (floor_i(rbin), floor_i(cbin), floor_i(obin));
        rbin -= r0 as f32;
        cbin -= c0 as f32;
        obin -= o0 as f32;
        let mut o0 = o0 as i64;
        if o0 < 0 {
            o0 += N as i64;
        }
        if o0 >= N as i64 {
            o0 -= N as i64;
        }
        let v_r1 = m * rbin;
        let v_r0 = m - v_r1;
        let v_rc11 = v_r1 * cbin;
        let v_rc10 = v_r1 - v_rc11;
        let v_rc01 = v_r0 * cbin;
        let v_rc00 = v_r0 - v_rc01;
        let v_rco111 = v_rc11 * obin;
        let v_rco110 = v_rc11 - v_rco111;
        let v_rco101 = v_rc10 * obin;
        let v_rco100 = v_rc10 - v_rco101;
        let v_rco011 = v_rc01 * obin;
        let v_rco010 = v_rc01 - v_rco011;
        let v_rco001 = v_rc00 * obin;
        let v_rco000 = v_rc00 - v_rco001;
        let idx = (((r0 as i64 + 1) * (D as i64 + 2) + c0 as i64 + 1) * (N as i64 + 2) + o0) as usize;
        hist[idx] += v_rco000;
        hist[idx + 1] += v_rco001;
        hist[idx + N + 2] += v_rco010;
        hist[idx + N + 3] += v_rco011;
        hist[idx + (D + 2) * (N + 2)] += v_rco100;
        hist[idx + (D + 2) * (N + 2) + 1] += v_rco101;
        hist[idx + (D + 3) * (N + 2)] += v_rco110;
        hist[idx + (D + 3) * (N + 2) + 1] += v_rco111;
    }
    let mut dst = [0f32; DIM];
    for i in 0..D {
        for j in 0..D {
            let idx = ((i + 1) * (D + 2) + (j + 1)) * (N + 2);
            hist[idx] += hist[idx + N];
            hist[idx + 1] += hist[idx + N + 1];
            for k in 0..N {
                dst[(i * D + j) * N + k] = hist[idx + k];
            }
        }
    }
    let nrm2: f32 = dst.iter().map(|v| v * v).sum();
    let thr = nrm2.sqrt() * MAG_THR;
    let mut nrm2 = 0f32;
    for v in dst.iter_mut() {
        *v = v.min(thr);
        nrm2 += *v * *v;
    }
    let f = INT_FCTR / nrm2.sqrt().max(f32::EPSILON);
    for v in dst.iter_mut() {
        *v = (round_even(*v * f) as f32).min(255.0);
    }
    dst
}

/// ⌊v⌋ for |v| < 2³¹ without a libm call (SSE2 has no floor instruction).
#[inline(always)]
fn floor_i(v: f32) -> i32 {
    let t = v as i32;
    t - (v < t as f32) as i32
}

/// Round half to even (OpenCV `cvRound`) for 0 ≤ v < 2²²: the bits of v + 1.5·2²³.
#[inline(always)]
pub(super) fn round_even(v: f32) -> i32 {
    (v + 12_582_912.0).to_bits() as i32 - 0x4B40_0000
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_fills_one_direction_bin_per_cell() {
        // I = 2x: every gradient points along +x (0°); with ori = 0 all mass is in bin 0 of each
        // cell, the 16 values are symmetric about the centre and the vector has norm ≈ 512.
        let img = Plane { w: 81, h: 81, data: (0..81 * 81).map(|i| 2.0 * (i % 81) as f32).collect() };
        let d = describe(&img, (40.0, 40.0), 0.0, 2.0);
        for cell in 0..16 {
            for b in 1..8 {
                assert_eq!(d[cell * 8 + b], 0.0, "cell {cell} bin {b}");
            }
        }
        let n: f32 = d.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((n - 512.0).abs() < 8.0, "{n}");
        assert_eq!(d[0], d[15 * 8]);
        assert_eq!(d[5 * 8], d[10 * 8]);
    }
}
