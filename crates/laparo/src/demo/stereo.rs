//! Demo section "stereo" (CATS, thesis §3.3): a built-in, analytically rendered rectified stereo
//! pair (slanted textured plane + box, exact GT disparity) is camera-augmented with parameters
//! drawn from the thesis' Table 3.6 statistics and Δx_right ~ U(−100, 0) px; before/after images,
//! disparity maps with colour bars for both GT rules, their difference, photometric checks, and a
//! Table 3.6-shaped statistics table computed by `calib_stats` on synthesised calibrations.
use super::DemoSection;
use anyhow::{Context, Result};
use laparo_core::calib::StereoCalibration;
use laparo_core::colormap::{colorize, Colormap};
use laparo_core::plot::with_colorbar;
use laparo_core::se3::rotation_zyx;
use laparo_core::table::Table;
use laparo_core::{io, Distortion, Image, Intrinsics};
use laparo_stereo::{
    augment_stereo, disparity_difference, AugmentedDisparity, AugmentedStereo, GtRule, StereoAugmentation, StereoSample,
};
use laparo_stereo::{calib_stats, stereo_extrinsics_from_rotations, summarize, table_3_6, MeanStd};
use laparo_stereo::{default_camera, Scene};
use laparo_stereo::{sample_rng, CatsConfig, Dist, TABLE_3_6};
use std::fmt::Write as _;
use std::path::Path;

const W: usize = 480;
const H: usize = 270;
const BASELINE_MM: f64 = 60.0;
const SEED: u64 = 2025;

fn hcat(imgs: &[&Image<u8>], gap: usize) -> Image<u8> {
    let h = imgs.iter().map(|i| i.height).max().unwrap_or(0);
    let w = imgs.iter().map(|i| i.width).sum::<usize>() + gap * imgs.len().saturating_sub(1);
    let mut out = Image::filled(w, h, 3, 255u8);
    let mut x0 = 0;
    for img in imgs {
        let rgb = img.to_rgb();
        for y in 0..rgb.height {
            for x in 0..rgb.width {
                out.pixel_mut(x0 + x, y).copy_from_slice(rgb.pixel(x, y));
            }
        }
        x0 += img.width + gap;
    }
    out
}

fn vcat(imgs: &[&Image<u8>], gap: usize) -> Image<u8> {
    let w = imgs.iter().map(|i| i.width).max().unwrap_or(0);
    let h = imgs.iter().map(|i| i.height).sum::<usize>() + gap * imgs.len().saturating_sub(1);
    let mut out = Image::filled(w, h, 3, 255u8);
    let mut y0 = 0;
    for img in imgs {
        let rgb = img.to_rgb();
        for y in 0..rgb.height {
            for x in 0..rgb.width {
                out.pixel_mut(x, y0 + y).copy_from_slice(rgb.pixel(x, y));
            }
        }
        y0 += img.height + gap;
    }
    out
}

/// Horizontal guide lines every `step` px (rows shared by both views show the misalignment).
fn with_guides(img: &Image<u8>, step: usize) -> Image<u8> {
    let mut o = img.to_rgb();
    for y in (step / 2..o.height).step_by(step) {
        for x in 0..o.width {
            if (x / 4) % 2 == 0 {
                o.pixel_mut(x, y).copy_from_slice(&[255, 40, 40]);
            }
        }
    }
    o
}

fn disp_f64(d: &Image<f32>) -> Image<f64> {
    d.map(|v| if v.is_finite() { v as f64 } else { f64::NAN })
}

/// Mean |L(x, y) − R(x − d, y + v)| in grey levels over pixels where everything is defined.
fn photometric(
    l: &Image<u8>,
    r: &Image<u8>,
    d: &Image<f32>,
    v: Option<&Image<f32>>,
    lv: Option<&Image<bool>>,
    rv: Option<&Image<bool>>,
) -> f64 {
    let (lg, rg) = (l.to_gray_f32(), r.to_gray_f32());
    let (mut s, mut n) = (0.0, 0usize);
    for y in 0..l.height {
        for x in 0..l.width {
            let dv = d.get(x, y, 0);
            if !dv.is_finite() || lv.is_some_and(|m| !m.get(x, y, 0)) {
                continue;
            }
            let sx = x as f64 - dv as f64;
            let sy = y as f64 + v.map_or(0.0, |v| v.get(x, y, 0) as f64);
            let Some(val) = rg.sample_bilinear(sx, sy, 0) else { continue };
            if let Some(m) = rv {
                let (x0, y0) = (sx.floor() as usize, sy.floor() as usize);
                let (x1, y1) = ((x0 + 1).min(l.width - 1), (y0 + 1).min(l.height - 1));
                if !(m.get(x0, y0, 0) && m.get(x1, y0, 0) && m.get(x0, y1, 0) && m.get(x1, y1, 0)) {
                    continue;
                }
            }
            s += (lg.get(x, y, 0) as f64 - val).abs();
            n += 1;
        }
    }
    s / n.max(1) as f64
}

/// Synthesise `n` calibrations with camera rotations drawn from a Table 3.6 row (SCARED-like
/// 1280×1024 intrinsics, c_x^L − c_x^R ~ U(−100, 0) px), and summarise them with `calib_stats`.
fn synthesised_table(n: usize) -> Result<(Table, serde_json::Value)> {
    let (_, row) = TABLE_3_6.iter().find(|(r, _)| *r == "SCARED+StMIS").expect("row exists");
    let mut rng = sample_rng(SEED, "calibrations");
    let mut normal = |m: f64, s: f64| Dist::normal(m, s).sample(&mut rng);
    let mut stats = Vec::new();
    let mut drawn: Vec<Vec<f64>> = vec![Vec::new(); 6];
    for _ in 0..n {
        let e: Vec<f64> = row.iter().map(|&(m, s)| normal(m, s)).collect();
        for (d, v) in drawn.iter_mut().zip(&e) {
            d.push(*v);
        }
        let rl = rotation_zyx(e[0].to_radians(), e[1].to_radians(), e[2].to_radians());
        let rr = rotation_zyx(e[3].to_radians(), e[4].to_radians(), e[5].to_radians());
        let (r, t_mm) = stereo_extrinsics_from_rotations(&rl, &rr, 4.2);
        let off = normal(-50.0, 25.0);
        let left = Intrinsics::new(1068.0, 1068.0, 640.0, 512.0, 1280, 1024)?;
        let right = Intrinsics { cx: 640.0 - off, ..left };
        let c = StereoCalibration {
            width: 1280,
            height: 1024,
            left,
            left_dist: Distortion::brown_conrady(-0.001, 0.002, 0.0001, 0.0, 0.0),
            right,
            right_dist: Distortion::brown_conrady(-0.0015, 0.004, 0.0001, 0.0, 0.0),
            r,
            t_mm,
        };
        stats.push(calib_stats(&c)?);
    }
    let s = summarize(&stats);
    let thesis = {
        let mut t = s.clone();
        for (i, &(m, sd)) in row.iter().enumerate() {
            let a = if i < 3 { &mut t.left_euler_deg[i] } else { &mut t.right_euler_deg[i - 3] };
            a.mean = m;
            a.std = sd;
        }
        t
    };
    let mut sample = s.clone();
    for (i, d) in drawn.iter().enumerate() {
        let m = MeanStd::of(d);
        if i < 3 {
            sample.left_euler_deg[i] = m;
        } else {
            sample.right_euler_deg[i - 3] = m;
        }
    }
    let mut table = table_3_6(&[
        ("thesis Table 3.6, SCARED+StMIS (the Gaussians)".to_string(), thesis),
        ("angles drawn for the synthesised calibrations".to_string(), sample),
        ("recovered by calib_stats from the calibrations (R, T, K)".to_string(), s.clone()),
    ]);
    table.rows[0][1] = "–".into(); // the thesis row is a distribution, not n calibrations
    Ok((table, serde_json::to_value(&s)?))
}

/// A sample augmented under both GT rules, with the photometric checks of the transformed GT.
struct BothRules {
    exact: AugmentedStereo,
    thesis: AugmentedStereo,
    /// Mean |L − R(x − d, y)| of the original pair under the original GT (grey levels).
    ph_original: f64,
    /// The same on the augmented pair, exact GT with its vertical residual, (x − d', y + v').
    ph_exact: f64,
    /// Exact GT, rows only (x − d', y).
    ph_exact_row: f64,
    /// Thesis-rule GT, rows only.
    ph_thesis: f64,
    /// EPE between the two rules' disparities, its maximum, and the number of pixels compared.
    epe: (f64, f64, usize),
}

impl BothRules {
    fn new(s: &StereoSample, p: &StereoAugmentation) -> Result<Self> {
        let exact = augment_stereo(s, p, GtRule::Exact)?;
        let thesis = augment_stereo(s, p, GtRule::Thesis)?;
        let d0 = s.disp_left.as_ref().context("source disparity")?;
        let de = exact.disp_left.as_ref().context("exact disparity")?;
        let dt = thesis.disp_left.as_ref().context("thesis disparity")?;
        let vres = de.vertical_residual.as_ref().context("vertical residual")?;
        let on = |a: &AugmentedStereo, d: &Image<f32>, v: Option<&Image<f32>>| {
            photometric(&a.left.image, &a.right.image, d, v, Some(&a.left.valid), Some(&a.right.valid))
        };
        let ph_exact = on(&exact, &de.disparity, Some(vres));
        let ph_exact_row = on(&exact, &de.disparity, None);
        let ph_thesis = on(&thesis, &dt.disparity, None);
        let epe = disparity_difference(dt, de);
        let ph_original = photometric(&s.left, &s.right, d0, None, None, None);
        Ok(BothRules { exact, thesis, ph_original, ph_exact, ph_exact_row, ph_thesis, epe })
    }

    fn exact_disp(&self) -> &AugmentedDisparity {
        self.exact.disp_left.as_ref().expect("checked in new")
    }

    fn thesis_disp(&self) -> &AugmentedDisparity {
        self.thesis.disp_left.as_ref().expect("checked in new")
    }
}

/// Common colour range (px, rounded outwards) of the finite values of disparity maps.
fn common_range(maps: &[&Image<f32>]) -> (f64, f64) {
    let finite = maps.iter().flat_map(|m| m.data.iter()).filter(|v| v.is_finite()).map(|&v| v as f64);
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    (lo.floor(), hi.ceil())
}

/// The real Middlebury 2014 "Motorcycle" pair (741×500, `../shared/data/middlebury-motorcycle`)
/// augmented with a Table 3.6 draw: before/after images, transformed GT, photometric check.
/// `None` when the data are absent.
fn middlebury_subsection(dir: &Path, cfg: &CatsConfig) -> Result<Option<(String, serde_json::Value)>> {
    let Some(d) = super::shared_data("middlebury-motorcycle") else { return Ok(None) };
    let left = io::read_rgb8(d.join("motorcycle_left.png"))?;
    let right = io::read_rgb8(d.join("motorcycle_right.png"))?;
    let disp = io::read_pfm(d.join("motorcycle_disp.pfm"))?;
    // Cameras of the quarter-size pair (calib.txt / 4, README of the data set): doffs = 31.086 px.
    let f = 994.97775;
    let kl = Intrinsics::new(f, f, 311.193, 254.87675, left.width, left.height)?;
    let kr = Intrinsics::new(f, f, 342.27875, 254.87675, left.width, left.height)?;
    let s = StereoSample { left, right, disp_left: Some(disp), disp_right: None, occ_left: None, occ_right: None };
    let p =
        cfg.sample(&mut sample_rng(SEED, "demo/middlebury"), &kl, &Distortion::default(), &kr, &Distortion::default());
    let b = BothRules::new(&s, &p)?;
    let (d0, de) = (s.disp_left.as_ref().context("source disparity")?, &b.exact_disp().disparity);
    let (w, h) = (s.left.width, s.left.height);
    let before = hcat(&[&with_guides(&s.left, 40), &with_guides(&s.right, 40)], 6);
    let after = hcat(&[&with_guides(&b.exact.left.image, 40), &with_guides(&b.exact.right.image, 40)], 6);
    io::write_png(dir.join("middlebury_pairs.png"), &vcat(&[&before, &after], 6))?;
    let (lo, hi) = common_range(&[d0, de]);
    let dmap = |d: &Image<f32>, label: &str| {
        with_colorbar(&colorize(&disp_f64(d), lo, hi, Colormap::Turbo), lo, hi, Colormap::Turbo, label)
    };
    io::write_png(
        dir.join("middlebury_disparity.png"),
        &hcat(&[&dmap(d0, "original GT disparity (px)"), &dmap(de, "CATS-transformed GT, exact rule (px)")], 6),
    )?;
    let (ph0, ph_exact, ph_thesis) = (b.ph_original, b.ph_exact, b.ph_thesis);
    let (epe, emax, n_cmp) = b.epe;
    let html = format!(
        "<h3>Real data: Middlebury 2014 Motorcycle</h3><p>The real rectified pair ({w}×{h}, f = {f:.1} px, doffs = 31.09 px) \
         with its ground-truth disparity, augmented by the same CATS configuration (left Euler angles [{:.3}, {:.3}, {:.3}]°, \
         right [{:.3}, {:.3}, {:.3}]°, Δx<sub>right</sub> = {:.1} px). The transformed GT still explains the images: the \
         photometric error of the augmented pair under its new GT is {ph_exact:.2} grey levels (exact rule) against {ph0:.2} for \
         the original pair under the original GT; the thesis rule gives {ph_thesis:.2}, and differs from the exact rule by an \
         EPE of {epe:.3} px (max {emax:.3} px over {n_cmp} px).</p>\n\
         <figure><img src=\"stereo/middlebury_pairs.png\"><figcaption>Top: original left | right. Bottom: CATS-augmented \
         left | right (red rows: the same image rows in both views).</figcaption></figure>\n\
         <figure><img src=\"stereo/middlebury_disparity.png\"><figcaption>GT disparity before and after augmentation \
         (common colour scale).</figcaption></figure>\n",
        p.left.euler_deg[0],
        p.left.euler_deg[1],
        p.left.euler_deg[2],
        p.right.euler_deg[0],
        p.right.euler_deg[1],
        p.right.euler_deg[2],
        p.dx_right_px,
    );
    let summary = serde_json::json!({
        "sample": {"left_euler_deg": p.left.euler_deg, "right_euler_deg": p.right.euler_deg, "dx_right_px": p.dx_right_px},
        "photometric_mae": {"original": ph0, "exact_2d": ph_exact, "thesis_row": ph_thesis},
        "epe_thesis_vs_exact_px": epe,
        "max_diff_thesis_vs_exact_px": emax,
    });
    Ok(Some((html, summary)))
}

/// Table 3.6 computed by `calib_stats` from the real calibrations in `../shared/data/calib`
/// (SCARED datasets and the EndoVis 2017 kidney calibration); `None` when absent.
fn real_calibration_table() -> Result<Option<(Table, serde_json::Value)>> {
    let Some(d) = super::shared_data("calib") else { return Ok(None) };
    let mut files: Vec<_> = std::fs::read_dir(&d)
        .with_context(|| format!("reading {}", d.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "yaml" || e == "yml"))
        .collect();
    files.sort();
    let mut stats = Vec::new();
    let mut names = Vec::new();
    for f in &files {
        let c = StereoCalibration::read_with_size(f, 1280, 1024)?;
        stats.push(calib_stats(&c).with_context(|| format!("{}", f.display()))?);
        names.push(f.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default());
    }
    if stats.is_empty() {
        return Ok(None);
    }
    let s = summarize(&stats);
    let table = table_3_6(&[(format!("real calibrations ({})", names.join(", ")), s.clone())]);
    Ok(Some((table, serde_json::to_value(&s)?)))
}

pub fn section(out: &Path) -> Result<DemoSection> {
    let dir = out.join("stereo");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let k = default_camera(W, H);
    let scene = Scene::default();
    let s = scene.stereo_sample(&k, BASELINE_MM, 2);
    let cfg = CatsConfig::thesis("SCARED+StMIS")?;
    // Pick the first seeded draw whose Δx_right makes part (not all) of the disparities negative.
    let mut p: Option<StereoAugmentation> = None;
    for i in 0..50 {
        let q = cfg.sample(
            &mut sample_rng(SEED, &format!("demo/{i}")),
            &k,
            &Distortion::default(),
            &k,
            &Distortion::default(),
        );
        if (-45.0..-30.0).contains(&q.dx_right_px) {
            p = Some(q);
            break;
        }
    }
    let p = p.context("no suitable draw")?;
    let b = BothRules::new(&s, &p)?;
    let (exact, de, dt) = (&b.exact, b.exact_disp(), b.thesis_disp());
    let d0 = s.disp_left.as_ref().context("source disparity")?;

    // Figures.
    let before = hcat(&[&with_guides(&s.left, 30), &with_guides(&s.right, 30)], 6);
    let after = hcat(&[&with_guides(&exact.left.image, 30), &with_guides(&exact.right.image, 30)], 6);
    io::write_png(dir.join("cats_pairs.png"), &vcat(&[&before, &after], 6))?;
    let (lo, hi) = common_range(&[d0, &de.disparity, &dt.disparity]);
    let dmap = |d: &Image<f32>, label: &str| {
        with_colorbar(&colorize(&disp_f64(d), lo, hi, Colormap::Turbo), lo, hi, Colormap::Turbo, label)
    };
    let row1 =
        hcat(&[&dmap(d0, "original GT disparity (px)"), &dmap(&de.disparity, "augmented GT, exact rule (px)")], 6);
    let diff = Image::from_vec(
        W,
        H,
        1,
        de.disparity
            .data
            .iter()
            .zip(&dt.disparity.data)
            .map(|(a, b)| if a.is_finite() && b.is_finite() { (b - a) as f64 } else { f64::NAN })
            .collect(),
    )?;
    let dm = diff.data.iter().filter(|v| v.is_finite()).fold(0.0f64, |m, v| m.max(v.abs())).max(0.5);
    let row2 = hcat(
        &[
            &dmap(&dt.disparity, "augmented GT, thesis rule (px)"),
            &with_colorbar(
                &colorize(&diff, -dm, dm, Colormap::Viridis),
                -dm,
                dm,
                Colormap::Viridis,
                "thesis − exact (px)",
            ),
        ],
        6,
    );
    io::write_png(dir.join("cats_disparity.png"), &vcat(&[&row1, &row2], 6))?;
    let vres = de.vertical_residual.as_ref().context("vertical residual")?;
    let vr = vres.map(|v| if v.is_finite() { v as f64 } else { f64::NAN });
    let vm = vr.data.iter().filter(|v| v.is_finite()).fold(0.0f64, |m, v| m.max(v.abs())).max(0.1);
    io::write_png(
        dir.join("cats_vertical_residual.png"),
        &with_colorbar(
            &colorize(&vr, -vm, vm, Colormap::Viridis),
            -vm,
            vm,
            Colormap::Viridis,
            "vertical residual y'_R − y'_L (px)",
        ),
    )?;

    // Numbers.
    let (ph0, ph_exact, ph_exact_row, ph_thesis) = (b.ph_original, b.ph_exact, b.ph_exact_row, b.ph_thesis);
    let (epe, emax, n_cmp) = b.epe;
    let vres = de.vertical_residual.as_ref().context("vertical residual")?;
    let finite = |d: &Image<f32>| d.data.iter().filter(|v| v.is_finite()).map(|&v| v as f64).collect::<Vec<_>>();
    let (d0v, dev) = (finite(d0), finite(&de.disparity));
    let range = |v: &[f64]| {
        (v.iter().cloned().fold(f64::INFINITY, f64::min), v.iter().cloned().fold(f64::NEG_INFINITY, f64::max))
    };
    let neg = dev.iter().filter(|&&v| v < 0.0).count() as f64 / dev.len().max(1) as f64;
    let (r0, r1) = (range(&d0v), range(&dev));
    let vmax = vres.data.iter().filter(|v| v.is_finite()).fold(0.0f32, |m, v| m.max(v.abs()));
    let (table, table_json) = synthesised_table(40)?;

    let middlebury = middlebury_subsection(&dir, &cfg)?;
    let real_table = real_calibration_table()?;

    let mut html = String::new();
    let _ = write!(
        html,
        "<h3>Built-in scene</h3><p>A rectified stereo pair rendered analytically ({W}×{H}, f = {:.0} px, baseline {BASELINE_MM} mm; slanted textured plane \
         and box) is turned into an uncalibrated-laparoscope-like pair by CATS (eqs. 3.5–3.9): each camera is rotated about its \
         centre by Euler angles drawn from Table 3.6 (SCARED+StMIS), and the right principal point is shifted so that \
         Δx<sub>right</sub> = {:.1} px is added to the disparities (drawn from U(−100, 0)). Red guide rows show the vertical \
         misalignment the rotations introduce.</p>\n\
         <figure><img src=\"stereo/cats_pairs.png\"><figcaption>Top: original left | right. Bottom: augmented left | right.</figcaption></figure>\n\
         <table><tr><th></th><th>φ (x)</th><th>θ (y)</th><th>ψ (z)</th></tr>\
         <tr><td>left (deg)</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>\
         <tr><td>right (deg)</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr></table>\n\
         <figure><img src=\"stereo/cats_disparity.png\"><figcaption>Disparities (common colour scale) and the difference of \
         the two GT rules. The thesis rule warps the GT with the left homography and adds Δx<sub>right</sub>; it ignores the right \
         camera's rotation, which shifts the right view by ≈ f·(θ<sub>R</sub> − θ<sub>L</sub>).</figcaption></figure>\n\
         <figure><img src=\"stereo/cats_vertical_residual.png\"><figcaption>Exact rule: vertical offset of each correspondence \
         in the augmented pair.</figcaption></figure>\n",
        k.fx,
        p.dx_right_px,
        p.left.euler_deg[0],
        p.left.euler_deg[1],
        p.left.euler_deg[2],
        p.right.euler_deg[0],
        p.right.euler_deg[1],
        p.right.euler_deg[2]
    );
    let _ = writeln!(
        html,
        "<table><tr><th>check</th><th>value</th></tr>\
         <tr><td>photometric MAE, original pair, original GT (grey levels)</td><td>{ph0:.2}</td></tr>\
         <tr><td>photometric MAE, augmented pair, exact GT at (x − d', y + v')</td><td>{ph_exact:.2}</td></tr>\
         <tr><td>photometric MAE, augmented pair, exact GT at (x − d', y)</td><td>{ph_exact_row:.2}</td></tr>\
         <tr><td>photometric MAE, augmented pair, thesis GT at (x − d', y)</td><td>{ph_thesis:.2}</td></tr>\
         <tr><td>EPE(thesis rule, exact rule) (px), max</td><td>{epe:.3}, {emax:.3} over {n_cmp} px</td></tr>\
         <tr><td>max |vertical residual| (px)</td><td>{vmax:.3}</td></tr>\
         <tr><td>disparity range before → after (px)</td><td>[{:.1}, {:.1}] → [{:.1}, {:.1}], {:.0}% negative</td></tr>\
         <tr><td>valid fraction augmented left / right</td><td>{:.3} / {:.3}</td></tr></table>",
        r0.0,
        r0.1,
        r1.0,
        r1.1,
        100.0 * neg,
        exact.left.valid.count() as f64 / (W * H) as f64,
        exact.right.valid.count() as f64 / (W * H) as f64,
    );
    let _ = write!(
        html,
        "<h3>Table 3.6 from calibrations</h3><p>Forty SCARED-like calibrations are synthesised with camera rotations drawn \
         from the thesis' SCARED+StMIS Gaussians; <code>laparo_stereo::calib_stats</code> (the library behind <code>laparo cats \
         stats</code>) computes each camera's rotation from the ideal rectified frame (μ, σ in degrees) from R, T alone and recovers the drawn angles \
         to within 1e-3 degrees.</p>\n{}",
        table.to_html()
    );
    match &real_table {
        Some((t, _)) => {
            let _ = write!(
                html,
                "<p>The same statistics from the real stereo-endoscope calibrations in <code>../shared/data/calib</code> \
                 (<code>laparo cats stats</code>):</p>\n{}",
                t.to_html()
            );
        }
        None => html.push_str("<p>(../shared/data/calib is absent: the real-calibration table is skipped.)</p>\n"),
    }
    match &middlebury {
        Some((h, _)) => html.push_str(h),
        None => html
            .push_str("<p>(../shared/data/middlebury-motorcycle is absent: the real-pair example is skipped.)</p>\n"),
    }
    let sgm = sgm_subsection(&dir)?;
    if let Some((h, _)) = &sgm {
        html.push_str(h);
    }
    let summary = serde_json::json!({
        "sgm_matching": sgm.map(|(_, j)| j),
        "sample": {"left_euler_deg": p.left.euler_deg, "right_euler_deg": p.right.euler_deg, "dx_right_px": p.dx_right_px},
        "photometric_mae": {"original": ph0, "exact_2d": ph_exact, "exact_row": ph_exact_row, "thesis_row": ph_thesis},
        "epe_thesis_vs_exact_px": epe,
        "max_vertical_residual_px": vmax,
        "disparity_range_before": [r0.0, r0.1],
        "disparity_range_after": [r1.0, r1.1],
        "negative_fraction_after": neg,
        "synthesised_calibration_stats": table_json,
        "real_calibration_stats": real_table.map(|(_, j)| j),
        "middlebury": middlebury.map(|(_, j)| j),
    });
    Ok(DemoSection { title: "Stereo: CATS camera augmentation (§3.3)".into(), html, summary })
}

/// SGM on the real Middlebury pair with the right image moved 40 px (GT d − 40: mixed-sign,
/// half negative), range [−48, 32): `laparo stereo match` (issue 14). `None` when absent.
fn sgm_subsection(dir: &Path) -> Result<Option<(String, serde_json::Value)>> {
    use laparo_stereo::{fill_background, match_pair, SgmParams};
    let Some(d) = super::shared_data("middlebury-motorcycle") else { return Ok(None) };
    let left = io::read_rgb8(d.join("motorcycle_left.png"))?;
    let right0 = io::read_rgb8(d.join("motorcycle_right.png"))?;
    let gt0 = io::read_pfm(d.join("motorcycle_disp.pfm"))?;
    let (w, h, k) = (left.width, left.height, 40usize);
    let mut right = Image::filled(w, h, 3, 0u8);
    for y in 0..h {
        for x in k..w {
            right.pixel_mut(x, y).copy_from_slice(right0.pixel(x - k, y));
        }
    }
    let gt = gt0.map(|v| v - k as f32);
    let t = std::time::Instant::now();
    let out = match_pair(&left, &right, &SgmParams::new(-48, 32))?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let mut filled = out.disparity.data.clone();
    fill_background(&mut filled, w, h);
    let (mut n, mut nv, mut e, mut b3, mut neg) = (0usize, 0usize, 0f64, 0usize, 0usize);
    let mut err = Image::filled(w, h, 1, f64::NAN);
    #[allow(clippy::needless_range_loop)]
    for i in 0..w * h {
        let g = gt.data[i] as f64;
        if !g.is_finite() {
            continue;
        }
        n += 1;
        neg += (g < 0.0) as usize;
        nv += out.disparity.data[i].is_finite() as usize;
        let v = if filled[i].is_finite() { filled[i] as f64 } else { 0.0 };
        e += (v - g).abs();
        b3 += ((v - g).abs() > 3.0) as usize;
        err.data[i] = (v - g).abs();
    }
    let (epe, bad3, dens) = (e / n as f64, 100.0 * b3 as f64 / n as f64, nv as f64 / n as f64);
    let (lo, hi) = common_range(&[&gt]);
    let dmap = |d: &Image<f32>, label: &str| {
        with_colorbar(&colorize(&disp_f64(d), lo, hi, Colormap::Turbo), lo, hi, Colormap::Turbo, label)
    };
    let emap = with_colorbar(&colorize(&err, 0.0, 5.0, Colormap::Magma), 0.0, 5.0, Colormap::Magma, "|error| (px)");
    io::write_png(
        dir.join("sgm_middlebury.png"),
        &hcat(&[&dmap(&out.disparity, "SGM disparity (px)"), &dmap(&gt, "GT − 40 (px)"), &emap], 6),
    )?;
    let html = format!(
        "<h3>Matching: SGM with a signed range (<code>laparo stereo match</code>)</h3><p>The Motorcycle pair with its right \
         image moved 40 px to the right, so the true disparities are d − 40 ({:.0} % negative, as on raw laparoscope \
         pairs), matched over [−48, 32) with the default mode (census 9×7, 4 paths, uniqueness, left–right check, speckle \
         filter) in {ms:.0} ms: {:.1} % of the GT pixels valid, EPE {epe:.3} px and Bad-3 {bad3:.2} % with invalid pixels \
         filled by the row background. No border strips are invalidated.</p>\n\
         <figure><img src=\"stereo/sgm_middlebury.png\"><figcaption>SGM disparity (invalid: dark grey) | GT | error after \
         filling.</figcaption></figure>\n",
        100.0 * neg as f64 / n as f64,
        100.0 * dens
    );
    let summary = serde_json::json!({"range": [-48, 32], "shift_px": k, "ms": ms, "density": dens, "epe_filled_px": epe, "bad3_filled_pct": bad3});
    Ok(Some((html, summary)))
}
