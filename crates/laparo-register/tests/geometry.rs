//! Deformation transfer (affine maps reproduced to 1e-9 mm), display surface (closed 2-manifold within
//! 1 mm of a sphere), rigid alignment (known motions recovered), organ sampling and its errors.
use laparo_mpm::{ellipsoid_lattice, Vector};
use laparo_register::distance::{ClosestPoint, TriangleSurface};
use laparo_register::organ::{organ_from_mesh, organ_from_points, OrganConfig, Roi};
use laparo_register::rigid::*;
use laparo_register::surface::{particle_surface, SurfaceConfig};
use laparo_register::transfer::Transfer;
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::HashMap;

#[test]
fn transfer_reproduces_affine_maps_3d_and_2d() {
    let rest = ellipsoid_lattice(Vector::<3>::new(10.0, 20.0, 30.0), Vector::<3>::new(20.0, 15.0, 10.0), 1.0);
    let a = Matrix3::new(1.3, 0.2, -0.1, 0.05, 0.8, 0.3, -0.2, 0.1, 1.1);
    let b = Vector::<3>::new(5.0, -3.0, 2.0);
    let def: Vec<Vector<3>> = rest.iter().map(|p| a * p + b).collect();
    let tr = Transfer::new(&rest, 1.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut inside, mut extra) = (0, 0);
    for _ in 0..5000 {
        // points inside and slightly outside the ellipsoid
        let q = Vector::<3>::new(
            10.0 + rng.gen_range(-21.0..21.0),
            20.0 + rng.gen_range(-16.0..16.0),
            30.0 + rng.gen_range(-11.0..11.0),
        );
        let t = tr.apply(&q, &def).unwrap();
        let err = (t.position - (a * q + b)).norm();
        assert!(err < 1e-9, "affine transfer error {err:e} mm");
        assert!(!t.straddles);
        if t.extrapolated {
            extra += 1
        } else {
            inside += 1
        }
    }
    assert!(inside > 1000 && extra > 100);
    let rest2 = ellipsoid_lattice(Vector::<2>::new(0.0, 0.0), Vector::<2>::new(8.0, 5.0), 0.5);
    let a2 = nalgebra::Matrix2::new(0.9, 0.4, -0.3, 1.2);
    let def2: Vec<Vector<2>> = rest2.iter().map(|p| a2 * p).collect();
    let tr2 = Transfer::new(&rest2, 0.5).unwrap();
    for _ in 0..2000 {
        let q = Vector::<2>::new(rng.gen_range(-8.0..8.0), rng.gen_range(-5.0..5.0));
        assert!((tr2.apply(&q, &def2).unwrap().position - a2 * q).norm() < 1e-9);
    }
}

#[test]
fn transfer_flags_a_cut() {
    // a 2D block whose right half moves away by 4 spacings: cells across x = 0 straddle
    let rest = laparo_mpm::box_lattice(Vector::<2>::new(-5.0, 0.0), Vector::<2>::new(5.0, 4.0), 1.0);
    let def: Vec<Vector<2>> =
        rest.iter().map(|p| if p[0] > 0.0 { p + Vector::<2>::new(4.0, 0.0) } else { *p }).collect();
    let tr = Transfer::new(&rest, 1.0).unwrap();
    assert!(tr.apply(&Vector::<2>::new(0.0, 2.0), &def).unwrap().straddles);
    assert!(!tr.apply(&Vector::<2>::new(-3.0, 2.0), &def).unwrap().straddles);
}

#[test]
fn sphere_surface_is_closed_manifold_within_1mm() {
    let c = Vector::<3>::new(0.0, 0.0, 0.0);
    let x = ellipsoid_lattice(c, Vector::<3>::repeat(20.0), 1.0);
    let (v, f) = particle_surface(&x, 1.0, &SurfaceConfig::default()).unwrap();
    // closed 2-manifold: every edge in exactly two faces, with opposite directions
    let mut edges: HashMap<(usize, usize), i32> = HashMap::new();
    for t in &f {
        for e in 0..3 {
            *edges.entry((t[e], t[(e + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "directed edge used {n} times");
        assert_eq!(edges.get(&(b, a)), Some(&1), "edge ({a},{b}) is not shared by two consistently oriented faces");
    }
    // every vertex a disc: Euler characteristic of a sphere
    let nv = f.iter().flat_map(|t| t.iter()).collect::<std::collections::HashSet<_>>().len() as i64;
    let chi = nv - (edges.len() / 2) as i64 + f.len() as i64;
    assert_eq!(chi, 2, "Euler characteristic {chi}");
    // outward orientation: positive volume ≈ 4/3 π 20³
    let vol: f64 = f.iter().map(|t| v[t[0]].dot(&v[t[1]].cross(&v[t[2]])) / 6.0).sum();
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 8000.0;
    assert!((vol / exact - 1.0).abs() < 0.05, "volume {vol} vs {exact}");
    // Hausdorff distance to the sphere ≤ 1 mm, both ways
    let h1 = v.iter().map(|p| ((p - c).norm() - 20.0).abs()).fold(0.0, f64::max);
    let surf = TriangleSurface::new(v.clone(), f.clone());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut h2: f64 = 0.0;
    for _ in 0..3000 {
        let d =
            Vector::<3>::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)).normalize();
        h2 = h2.max(surf.distance(&(c + d * 20.0)));
    }
    eprintln!("sphere surface: {} vertices, {} faces, Hausdorff {h1:.3} / {h2:.3} mm", v.len(), f.len());
    assert!(h1 <= 1.0 && h2 <= 1.0, "Hausdorff {h1} / {h2} mm");
}

#[test]
fn umeyama_and_icp_recover_known_motions() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let src: Vec<Vector3<f64>> = (0..300)
        .map(|_| Vector3::new(rng.gen_range(-50.0..50.0), rng.gen_range(-30.0..30.0), rng.gen_range(-20.0..20.0)))
        .collect();
    let r = *Rotation3::from_euler_angles(0.3, -0.2, 0.5).matrix();
    let t = Vector3::new(10.0, -5.0, 3.0);
    let s = 1.2;
    let dst: Vec<Vector3<f64>> = src.iter().map(|p| r * p * s + t).collect();
    let est = umeyama(&src, &dst, true).unwrap();
    assert!((est.rotation - r).norm() < 1e-12 && (est.translation - t).norm() < 1e-10 && (est.scale - s).abs() < 1e-12);
    let rigid: Vec<Vector3<f64>> = src.iter().map(|p| r * p + t).collect();
    // ICP from a perturbed start
    let init = Similarity {
        rotation: *Rotation3::from_euler_angles(0.25, -0.15, 0.45).matrix(),
        translation: t + Vector3::new(2.0, 1.0, -1.0),
        scale: 1.0,
    };
    let res = icp(&src, &rigid, None, init, &IcpConfig::default()).unwrap();
    assert!(res.rmse < 1e-6, "ICP rmse {}", res.rmse);
    // trimmed: 30 % outliers on the target only
    let mut partial = rigid[..200].to_vec();
    partial.extend((0..60).map(|_| Vector3::new(rng.gen_range(200.0..300.0), 0.0, 0.0)));
    let res = icp(&src[..200], &partial, None, init, &IcpConfig { overlap: 0.9, ..Default::default() }).unwrap();
    assert!((res.transform.rotation - r).norm() < 1e-6, "trimmed ICP");
    assert!(umeyama(&src[..2], &dst[..2], false).is_err());
}

#[test]
fn ransac_plane_and_gravity_projection() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let n = Vector3::new(0.1, 0.2, 1.0).normalize();
    let mut pts: Vec<Vector3<f64>> = (0..400)
        .map(|_| {
            let p = Vector3::new(rng.gen_range(-50.0..50.0), rng.gen_range(-50.0..50.0), 0.0);
            p - n * (n.dot(&p) - 7.0)
        })
        .collect();
    pts.extend(
        (0..100)
            .map(|_| Vector3::new(rng.gen_range(-50.0..50.0), rng.gen_range(-50.0..50.0), rng.gen_range(20.0..60.0))),
    );
    let plane = ransac_plane(&pts, 0.5, 200, 1).unwrap();
    assert!((plane.normal - n).norm() < 1e-9 && (plane.offset - 7.0).abs() < 1e-9 && plane.inliers == 400);
    // project a point down onto a unit square (two triangles) at z = 0
    let v = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(1.0, 1.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
    ];
    let f = vec![[0, 1, 2], [0, 2, 3]];
    let hit = project_along(
        &[Vector3::new(0.3, 0.6, 5.0), Vector3::new(3.0, 3.0, 5.0)],
        &Vector3::new(0.0, 0.0, -1.0),
        &v,
        &f,
    );
    assert!((hit[0].unwrap() - Vector3::new(0.3, 0.6, 0.0)).norm() < 1e-12);
    assert!(hit[1].is_none());
}

fn p2ilf() -> Option<std::path::PathBuf> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj");
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIP: {} absent", p.display());
        None
    }
}

#[test]
fn p2ilf_liver_procrustes_icp_recovers_rigid_motion() {
    let Some(path) = p2ilf() else { return };
    let mesh = laparo_core::mesh::read_mesh(&path).unwrap();
    let src: Vec<Vector3<f64>> = mesh.vertices.clone();
    let r = *Rotation3::from_euler_angles(0.2, 0.35, -0.4).matrix();
    let t = Vector3::new(30.0, -12.0, 45.0);
    let dst: Vec<Vector3<f64>> = src.iter().map(|p| r * p + t).collect();
    // Procrustes from 10 landmarks annotated with 2 mm noise, then ICP on the whole surface
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let ids: Vec<usize> = (0..10).map(|k| k * src.len() / 10).collect();
    let a: Vec<Vector3<f64>> = ids.iter().map(|&i| src[i]).collect();
    let b: Vec<Vector3<f64>> = ids
        .iter()
        .map(|&i| dst[i] + Vector3::new(rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0)))
        .collect();
    let init = umeyama(&a, &b, false).unwrap();
    let normals = laparo_core::mesh::TriMesh::new(dst.clone(), mesh.faces.clone()).unwrap().vertex_normals();
    for mode in [IcpMode::PointToPoint, IcpMode::PointToPlane] {
        let res = icp(&src, &dst, Some(&normals), init, &IcpConfig { mode, ..Default::default() }).unwrap();
        let err = src.iter().map(|p| (res.transform.apply(p) - (r * p + t)).norm()).fold(0.0, f64::max);
        eprintln!("P2ILF {mode:?}: max error {err:.2e} mm after {} iterations", res.iterations);
        assert!(err < 0.01, "{mode:?}: {err} mm");
    }
}

#[test]
fn p2ilf_liver_organ_and_bad_inputs() {
    let Some(path) = p2ilf() else { return };
    let cfg = OrganConfig { spacing_mm: 6.0, ..Default::default() };
    let organ = organ_from_mesh(&path, &cfg).unwrap();
    let n = organ.scene.n_particles();
    // volume 2,509 cm³ at 6 mm spacing: ≈ 11.6k particles
    assert!((n as f64 / (2.509e6 / 216.0) - 1.0).abs() < 0.05, "{n} particles");
    let far = organ.landmark_particles(&[Vector::<3>::new(1e4, 0.0, 0.0)], "L.json");
    assert!(far.unwrap_err().to_string().contains("L.json"));
    // memory and CFL errors name the parameter
    let e = organ_from_mesh(&path, &OrganConfig { spacing_mm: 0.3, ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("spacing_mm"), "{e}");
    // within a memory budget below every step's checkpoints (n × T × 230 B ≈ 0.53 GB), two-level checkpointing:
    // segments of k steps with (⌈200/k⌉ + k) × n × 230 B ≤ 0.1 GB
    let tight = OrganConfig { spacing_mm: 6.0, memory_limit_bytes: Some(0.1e9), ..Default::default() };
    let o = organ_from_mesh(&path, &tight).unwrap();
    let k = o.scene.checkpoint_segment;
    let steps_worth = 0.1e9 / (n as f64 * 230.0);
    assert!(k > 1 && (200usize.div_ceil(k) + k) as f64 <= steps_worth, "segment {k}, {steps_worth} steps' worth");
    assert!((200usize.div_ceil(k + 1) + k + 1) as f64 > steps_worth, "segment {k} is not the longest");
    assert!(o.warnings.iter().any(|w| w.contains(&format!("checkpoints every {k} steps"))), "{:?}", o.warnings);
    assert_eq!(organ.scene.checkpoint_segment, 0);
    let e = organ_from_mesh(&path, &OrganConfig { memory_limit_bytes: Some(0.03e9), ..tight }).unwrap_err();
    assert!(e.to_string().contains("spacing_mm") && e.to_string().contains("√T"), "{e}");
    let e =
        organ_from_mesh(&path, &OrganConfig { spacing_mm: 6.0, dt_s: Some(1e-2), ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("CFL"), "{e}");
    // ROI: a ball, boundary particles fixed
    let c = organ.rest_model()[n / 2];
    let roi = OrganConfig {
        spacing_mm: 6.0,
        roi: Some(Roi::Ball { center: [c[0], c[1], c[2]], radius_mm: 40.0 }),
        ..Default::default()
    };
    let o2 = organ_from_points(organ.rest_model(), &roi, "liver").unwrap();
    assert!(o2.fixed_count > 0 && o2.fixed_count < o2.scene.n_particles());
    // non-closed surface
    let dir = tempfile::tempdir().unwrap();
    let open = dir.path().join("open.obj");
    std::fs::write(&open, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let e = organ_from_mesh(&open, &cfg).unwrap_err().to_string();
    assert!(e.contains("open.obj") && e.contains("not closed"), "{e}");
}
