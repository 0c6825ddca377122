//! Acceptance tests of issue 4 (CPC), on rendered synthetic scenes.
use laparo_core::camera::Intrinsics;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::Image;
use laparo_cpc::pipeline::LambdaChoice;
use laparo_cpc::scene::*;
use laparo_cpc::*;

fn small_k() -> Intrinsics {
    Intrinsics::new(250.0, 250.0, 160.0, 120.0, 320, 240).unwrap()
}

fn plane60() -> Scene {
    SceneSpec {
        intrinsics: small_k(),
        surface: Surface::Plane,
        half_mm: 60.0,
        pose: tilted_pose(60.0, 100.0),
        texture: Texture::Procedural { seed: 3 },
        march_step_mm: 0.5,
    }
    .render()
    .unwrap()
}

fn bumpy45() -> (SceneSpec, Scene) {
    let spec = SceneSpec {
        intrinsics: small_k(),
        surface: Surface::Bumpy { rcurv_mm: 150.0, bumps: SCENE_PY_BUMPS.to_vec() },
        half_mm: 55.0,
        pose: tilted_pose_xy(45.0, 10.0, 100.0),
        texture: Texture::Procedural { seed: 5 },
        march_step_mm: 0.5,
    };
    let sc = spec.render().unwrap();
    (spec, sc)
}

fn solve_on(sc: &Scene, step: usize, conf: ConformalParams, lambda: f64) -> (CpcMesh, Vec<[f64; 2]>) {
    let mp = MeshParams { grid_step_px: step, ..Default::default() };
    let mesh = CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &mp).unwrap();
    let sys = CpcSystem::assemble(&mesh, &conf).unwrap();
    let p = sys.solve(lambda).unwrap();
    (mesh, p)
}

#[test]
fn oblique_plane_60deg_lambda_0999_is_a_similarity() {
    let sc = plane60();
    let (mesh, p) = solve_on(&sc, 4, ConformalParams::default(), 0.999);
    let before = metrics::angle_error_deg(&mesh.p_init, &mesh.x3d, &mesh.faces);
    let after = metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces);
    eprintln!("plane 60°: angle error before {before:.3}°, after {after:.4}°");
    assert!(before > 8.0, "the oblique view must distort angles ({before})");
    assert!(after < 0.5, "λ = 0.999 must be conformal: {after}°");
    assert_eq!(metrics::n_flipped(&p, &mesh.faces), 0);
}

#[test]
fn eq46_as_printed_is_not_conformal() {
    // The second row of eq. 4.6 as printed (no minus signs) does not express eq. 4.3.
    let sc = plane60();
    let conf = ConformalParams { convention: RowConvention::AsPrinted, ..Default::default() };
    let (mesh, p) = solve_on(&sc, 4, conf, 0.999);
    let after = metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces);
    eprintln!("plane 60°, eq. 4.6 as printed: angle error {after:.3}°");
    assert!(after > 5.0, "as printed the rows should not make the plane conformal ({after}°)");
}

#[test]
fn generalised_theta_is_also_conformal_on_the_plane() {
    let sc = plane60();
    let conf = ConformalParams { theta_rad: 60f64.to_radians(), ..Default::default() };
    let (mesh, p) = solve_on(&sc, 4, conf, 0.999);
    let after = metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces);
    assert!(after < 0.5, "θ = 60°: {after}°");
}

#[test]
fn lambda_zero_is_the_identity_warp() {
    let sc = plane60();
    let params = CpcParams { lambda: LambdaChoice::Fixed(0.0), ..CpcParams::default() };
    let r = cpc_warp(&sc.image, &sc.depth, &sc.intrinsics, &sc.roi, &params).unwrap();
    assert_eq!(r.warp.p_flat, r.warp.mesh().p_init);
    let (ox, oy) = (r.warp.origin[0], r.warp.origin[1]);
    assert_eq!(ox.fract(), 0.0);
    let maps = r.warp.maps();
    let mut n = 0;
    for y in 0..r.warp.height {
        for x in 0..r.warp.width {
            if !r.mask.get(x, y, 0) {
                continue;
            }
            n += 1;
            let (u, v) = (x as f64 + ox, y as f64 + oy);
            assert_eq!(maps.backward.get(x, y, 0), u);
            assert_eq!(maps.backward.get(x, y, 1), v);
            for c in 0..3 {
                assert_eq!(r.warped.get(x, y, c), sc.image.get(u as usize, v as usize, c), "pixel ({x},{y})");
            }
            assert_eq!(maps.forward.get(u as usize, v as usize, 0), x as f64);
            assert_eq!(maps.forward.get(u as usize, v as usize, 1), y as f64);
        }
    }
    assert!(n > 10_000, "identity warp covers {n} pixels");
    assert_eq!(r.stats.delta_area, 0.0);
}

#[test]
fn bumpy_surface_trade_off_is_monotone_in_lambda() {
    let (_, sc) = bumpy45();
    let mesh = CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &MeshParams::default()).unwrap();
    let sys = CpcSystem::assemble(&mesh, &ConformalParams::default()).unwrap();
    let grid = [0.0, 0.1, 0.3, 0.5, 0.7, 0.9];
    let mut prev: Option<(f64, f64)> = None;
    for &l in &grid {
        let p = sys.solve(l).unwrap();
        let ang = metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces);
        let da = metrics::delta_area(&p, &mesh.p_init, &mesh.faces);
        eprintln!("λ = {l}: angle error {ang:.3}°, δ_area {da:.4}");
        if let Some((pa, pd)) = prev {
            assert!(ang < pa, "angle error must decrease: {pa} -> {ang} at λ = {l}");
            assert!(da > pd, "δ_area must increase: {pd} -> {da} at λ = {l}");
        }
        prev = Some((ang, da));
    }
}

#[test]
fn lambda_means_the_same_at_every_grid_step() {
    let (_, sc) = bumpy45();
    for &l in &[0.5, 0.9] {
        let errs: Vec<f64> = [2usize, 4, 8]
            .iter()
            .map(|&s| {
                let (mesh, p) = solve_on(&sc, s, ConformalParams::default(), l);
                metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces)
            })
            .collect();
        eprintln!("λ = {l}: angle errors at steps 2/4/8 px: {errs:?}");
        let (lo, hi) = (errs.iter().cloned().fold(f64::INFINITY, f64::min), errs.iter().cloned().fold(0.0, f64::max));
        assert!(hi <= 1.2 * lo, "grid dependence too strong at λ = {l}: {errs:?}");
    }
}

fn scene_npz() -> Option<std::path::PathBuf> {
    if let Some(p) = std::env::var_os("LAPARO_CPC_SCENE_NPZ") {
        return Some(p.into());
    }
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bench/cpc_ref/scene.npz");
    p.exists().then_some(p)
}

#[test]
fn bumpy_bowl_default_settings_flip_no_triangle() {
    let spec = bumpy_bowl_spec();
    let sc = spec.render().unwrap();
    let mut scenes = vec![("Rust port of scene.py", sc.roi.clone(), sc.depth.clone())];
    match scene_npz() {
        Some(p) => {
            let d = laparo_core::io::read_npz(&p, Some("depth")).unwrap();
            let depth = DepthMap::from_image(&d, DepthUnit::Mm).unwrap().to_unit(DepthUnit::Mm);
            let depth = DepthMap::new(
                d.width,
                d.height,
                DepthUnit::Mm,
                depth.data.iter().map(|&z| if z.is_finite() { z } else { f64::NAN }).collect(),
            )
            .unwrap();
            let roi = depth.valid_mask();
            // The Rust port renders the same scene: same ROI, same depth (both bisect to ~1e-12 mm).
            let same_roi = roi.data.iter().zip(&sc.roi.data).filter(|(a, b)| a != b).count();
            let max_dz = depth
                .data
                .iter()
                .zip(&sc.depth.data)
                .filter(|(a, b)| a.is_finite() && b.is_finite())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            eprintln!("port vs scene.npz: {same_roi} ROI pixels differ, max |Δz| = {max_dz:.2e} mm");
            assert!(same_roi <= 20, "ROI differs at {same_roi} pixels");
            assert!(max_dz < 1e-3, "depth differs by {max_dz} mm");
            scenes.push(("scene.npz", roi, depth));
        }
        None => eprintln!(
            "SKIP part: ../shared/bench/cpc_ref/scene.npz absent (run scene.py there); using the Rust port only"
        ),
    }
    for (name, roi, depth) in scenes {
        let mesh = CpcMesh::build(&roi, &depth, &spec.intrinsics, &MeshParams::default()).unwrap();
        let sys = CpcSystem::assemble(&mesh, &ConformalParams::default()).unwrap();
        let p = sys.solve(pipeline::DEFAULT_LAMBDA).unwrap();
        let flips = metrics::n_flipped(&p, &mesh.faces);
        eprintln!(
            "{name}: {} px ROI, {} triangles, {} grazing dropped, flips {flips}",
            roi.count(),
            mesh.n_triangles(),
            mesh.report.dropped_grazing
        );
        assert_eq!(flips, 0, "{name}");
    }
}

#[test]
fn point_round_trip_and_image_consistency() {
    let (_, sc) = bumpy45();
    let params = CpcParams { lambda: LambdaChoice::Fixed(0.9), ..CpcParams::default() };
    let r = cpc_warp(&sc.image, &sc.depth, &sc.intrinsics, &sc.roi, &params).unwrap();
    let w = &r.warp;
    // Deterministic pseudo-random points in the original image.
    let mut state = 12345u64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut n = 0;
    let mut max_err: f64 = 0.0;
    let mut diffs = Vec::new();
    while n < 2000 {
        let (u, v) = (rnd() * 319.0, rnd() * 239.0);
        let Some(q) = w.original_to_warped(u, v) else { continue };
        let back = w.warped_to_original(q[0], q[1]).expect("a warped point maps back");
        max_err = max_err.max(((back[0] - u).powi(2) + (back[1] - v).powi(2)).sqrt());
        n += 1;
        // Image consistency at keypoints: warped image (bicubic warp, read back bilinearly) vs original.
        let (qx, qy) = (q[0], q[1]);
        let (x0, y0) = (qx.floor() as usize, qy.floor() as usize);
        if x0 + 1 < w.width
            && y0 + 1 < w.height
            && [(0, 0), (1, 0), (0, 1), (1, 1)].iter().all(|&(a, b)| r.mask.get(x0 + a, y0 + b, 0))
        {
            let back = w.warped_to_original(qx, qy).unwrap();
            for c in 0..3 {
                let a = r.warped.sample_bilinear(qx, qy, c).unwrap();
                let b = sc.image.sample_bilinear(back[0], back[1], c).unwrap();
                diffs.push((a - b).abs());
            }
        }
    }
    eprintln!("round trip max error {max_err:.2e} px over {n} points");
    assert!(max_err < 1e-6);
    // Integer warped pixels are the pipeline's (bicubic) samples of the original at the backward
    // position of the warp.
    assert_eq!(CpcParams::default().interp, laparo_core::remap::Interp::Bicubic);
    let mut n_checked = 0;
    for y in (0..w.height).step_by(3) {
        for x in (0..w.width).step_by(3) {
            if let (Some(q), true) = (w.backward_pixel(x, y), r.mask.get(x, y, 0)) {
                let one = laparo_core::remap::CoordMap {
                    width: 1,
                    height: 1,
                    xy: vec![[q[0].clamp(0.0, 319.0) as f32, q[1].clamp(0.0, 239.0) as f32]],
                };
                let (b, _) =
                    laparo_core::remap::remap(&sc.image, &one, laparo_core::remap::Interp::Bicubic, 0).unwrap();
                for c in 0..3 {
                    assert!((r.warped.get(x, y, c) as i32 - b.data[c] as i32).abs() <= 1, "pixel ({x}, {y})");
                }
                n_checked += 1;
            }
        }
    }
    assert!(n_checked > 1000, "{n_checked}");
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let p95 = {
        let mut d = diffs.clone();
        d.sort_by(|a, b| a.partial_cmp(b).unwrap());
        d[d.len() * 95 / 100]
    };
    eprintln!("image consistency at {} keypoints: mean |Δ| {mean:.2}, p95 {p95:.2} grey levels", diffs.len() / 3);
    assert!(mean < 4.0 && p95 < 15.0, "mean {mean}, p95 {p95}");
}

#[test]
fn bad_inputs_are_clear_errors() {
    let k = small_k();
    let img = Image::filled(320, 240, 3, 100u8);
    let roi = Image::filled(320, 240, 1, true);
    let depth = DepthMap::new(320, 240, DepthUnit::Mm, vec![100.0; 320 * 240]).unwrap();
    let p = CpcParams::default();
    let msg = |r: Result<CpcResult>| r.err().map(|e| e.to_string()).unwrap_or_default();
    // depth of the wrong size
    let d2 = DepthMap::new(160, 120, DepthUnit::Mm, vec![100.0; 160 * 120]).unwrap();
    assert!(msg(cpc_warp(&img, &d2, &k, &roi, &p)).contains("size mismatch"));
    // all-NaN depth
    let dn = DepthMap::new(320, 240, DepthUnit::Mm, vec![f64::NAN; 320 * 240]).unwrap();
    assert!(msg(cpc_warp(&img, &dn, &k, &roi, &p)).contains("depth"));
    // empty ROI
    let empty = Image::filled(320, 240, 1, false);
    assert!(msg(cpc_warp(&img, &depth, &k, &empty, &p)).contains("empty"));
    // one-pixel ROI
    let mut one = empty.clone();
    one.set(100, 100, 0, true);
    assert!(msg(cpc_warp(&img, &depth, &k, &one, &p)).contains("no usable triangle"));
    // non-positive focal length
    let bad_k = Intrinsics { fx: 0.0, ..k };
    assert!(msg(cpc_warp(&img, &depth, &bad_k, &roi, &p)).contains("focal"));
    let neg_k = Intrinsics { fy: -5.0, ..k };
    assert!(msg(cpc_warp(&img, &depth, &neg_k, &roi, &p)).contains("focal"));
    // λ outside [0, 1)
    for l in [1.0, -0.1, 1.5, f64::NAN] {
        let pl = CpcParams { lambda: LambdaChoice::Fixed(l), ..CpcParams::default() };
        assert!(msg(cpc_warp(&img, &depth, &k, &roi, &pl)).contains("lambda"), "λ = {l}");
    }
    // grid step 0
    let mut p0 = CpcParams::default();
    p0.mesh.grid_step_px = 0;
    assert!(msg(cpc_warp(&img, &depth, &k, &roi, &p0)).contains("grid step"));
}
