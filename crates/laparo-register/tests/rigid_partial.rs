//! `register rigid` onto a partial surface (issue 50, item 1): a view of 45 % of a real liver surface,
//! moved by a known rigid motion. Plain ICP (overlap 1) is pulled off by the unmatched part; the
//! estimated overlap (fixed candidates + fractional ICP, Phillips et al. 2007) recovers the motion.
use laparo_register::rigid::{
    icp, icp_estimate_overlap, icp_fractional, rotation_angle_deg, IcpConfig, Similarity, OVERLAP_CANDIDATES,
};
use nalgebra::{Rotation3, Unit, Vector3};

/// A closed, asymmetric organ-like surface (mm): an ellipsoid 160 × 110 × 70 mm with two lobes.
fn bumpy_organ(n_theta: usize, n_phi: usize) -> Vec<Vector3<f64>> {
    let mut v = Vec::new();
    for i in 0..=n_theta {
        let th = std::f64::consts::PI * i as f64 / n_theta as f64;
        for j in 0..n_phi {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / n_phi as f64;
            let r = 1.0 + 0.25 * (2.0 * th).sin() * ph.cos() + 0.15 * (3.0 * ph).cos() * th.sin().powi(2);
            v.push(Vector3::new(80.0 * r * th.sin() * ph.cos(), 55.0 * r * th.sin() * ph.sin(), 35.0 * r * th.cos()));
        }
    }
    v
}

/// The `fraction` of the points lowest along an oblique axis, moved by `motion`.
fn partial_view(v: &[Vector3<f64>], fraction: f64, motion: &Similarity) -> Vec<Vector3<f64>> {
    let axis = Vector3::new(0.6, 0.3, 0.74).normalize();
    let mut d: Vec<f64> = v.iter().map(|p| p.dot(&axis)).collect();
    d.sort_by(f64::total_cmp);
    let thr = d[((d.len() - 1) as f64 * fraction) as usize];
    v.iter().filter(|p| p.dot(&axis) <= thr).map(|p| motion.apply(p)).collect()
}

fn motion() -> Similarity {
    let axis = Unit::new_normalize(Vector3::new(0.2, -0.4, 1.0));
    Similarity {
        rotation: *Rotation3::from_axis_angle(&axis, 12f64.to_radians()).matrix(),
        translation: Vector3::new(8.0, -5.0, 6.0),
        scale: 1.0,
    }
}

/// The real livers of ../shared/data (P2ILF in mm; SOFA's smooth liver in cm, scaled to mm); each absent
/// one is skipped with a message.
fn shared_livers() -> Vec<(&'static str, Vec<Vector3<f64>>)> {
    let root = std::env::var_os("LAPARO_SHARED_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let mut out = Vec::new();
    for (name, rel, to_mm) in [
        ("p2ilf", "meshes/p2ilf/patient2_1_3d-liver-model.obj", 1.0),
        ("sofa", "meshes/sofa_liver/liver-smooth.obj", 10.0),
    ] {
        let p = root.join(rel);
        match laparo_core::mesh::read_mesh(&p) {
            Ok(m) => out.push((name, m.vertices.iter().map(|v| v * to_mm).collect())),
            Err(e) => eprintln!("SKIP {name}: {} ({e})", p.display()),
        }
    }
    out
}

#[test]
fn estimated_overlap_recovers_a_motion_onto_45_percent_of_a_liver() {
    for (name, organ) in shared_livers() {
        let m = motion();
        let view = partial_view(&organ, 0.45, &m);
        assert!((view.len() as f64 / organ.len() as f64 - 0.45).abs() < 0.01);
        let cfg = IcpConfig::default();
        // plain ICP: pulled off by the 55 % of the liver the view does not contain
        let plain = icp(&organ, &view, None, Similarity::identity(), &cfg).unwrap();
        let plain_deg = rotation_angle_deg(&plain.transform.rotation, &m.rotation);
        let est = icp_estimate_overlap(&organ, &view, None, Similarity::identity(), &cfg, &OVERLAP_CANDIDATES).unwrap();
        let deg = rotation_angle_deg(&est.best.transform.rotation, &m.rotation);
        let dt = (est.best.transform.translation - m.translation).norm();
        eprintln!(
            "{name}: plain ICP {plain_deg:.2}° RMSE {:.3} mm; estimated overlap {:.3}: {deg:.2e}° {dt:.2e} mm; trials {:?}",
            plain.rmse,
            est.overlap,
            est.trials.iter().map(|t| (t.overlap, t.rmse_mm, t.iterations, t.fractional)).collect::<Vec<_>>()
        );
        assert!(plain_deg > 2.0 && plain.rmse > 5.0, "{name}: plain ICP {plain_deg}° RMSE {} mm", plain.rmse);
        if deg < 1e-6 && dt < 1e-6 {
            assert!(est.overlap > 0.3 && est.overlap <= 0.46, "{name}: overlap {}", est.overlap);
            assert!(est.rivals(2.0, 2.0).is_empty(), "{name}: an exact fit has no rival");
        } else {
            // not found from the identity (every overlap stops in a local minimum): the rival fits
            // say the alignment is ambiguous (the CLI warns with them)
            let rivals = est.rivals(2.0, 2.0);
            assert!(!rivals.is_empty(), "{name}: {deg}° {dt} mm off and no rival fit to warn with");
        }
        assert!(name != "p2ilf" || deg < 1e-6, "the issue's case (P2ILF, 45 %): {deg}° off");
    }
}

#[test]
fn fractional_icp_keeps_every_pair_when_the_surfaces_overlap_fully() {
    let organ = bumpy_organ(20, 40);
    let m = motion();
    let moved: Vec<Vector3<f64>> = organ.iter().map(|p| m.apply(p)).collect();
    let start = Similarity { translation: m.translation + Vector3::new(1.0, -1.0, 0.5), ..m };
    let (r, f) = icp_fractional(&organ, &moved, None, start, &IcpConfig::default(), 0.2).unwrap();
    assert!(r.rmse < 1e-9 && (r.transform.translation - m.translation).norm() < 1e-9, "{}", r.rmse);
    // every pair at distance 0: the FRMSD is 0 for any overlap; the ties go to the largest overlap
    assert_eq!(f, 1.0);
}
