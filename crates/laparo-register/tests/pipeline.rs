//! End-to-end `run_job` on a small box organ: outputs written, report consistent, resume, bad inputs.
use laparo_register::io::{read_landmarks, read_targets};
use laparo_register::optimize::OptimizerConfig;
use laparo_register::organ::OrganConfig;
use laparo_register::pipeline::{run_job, Job};
use std::path::Path;

fn box_obj(path: &Path, lo: [f64; 3], hi: [f64; 3]) {
    let mut s = String::new();
    for i in 0..8 {
        let p = [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ];
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    // outward-oriented faces of the cube (1-based)
    for f in [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]] {
        s.push_str(&format!("f {} {} {}\nf {} {} {}\n", f[0], f[1], f[2], f[0], f[2], f[3]));
    }
    std::fs::write(path, s).unwrap();
}

fn job(dir: &Path) -> Job {
    let organ = dir.join("organ.obj");
    box_obj(&organ, [0.0, 0.0, 0.0], [40.0, 24.0, 16.0]);
    let tumour = dir.join("tumour.obj");
    box_obj(&tumour, [15.0, 8.0, 5.0], [22.0, 14.0, 10.0]);
    std::fs::write(
        dir.join("L.json"),
        r#"{"groups": [{"name": "tip", "points": [[39.0, 12.0, 8.0], [39.0, 4.0, 8.0]]}, {"name": "edge", "points": [[20.0, 23.0, 8.0]]}]}"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("T.json"),
        r#"{"groups": [{"name": "tip", "type": "points", "points": [[42.0, 12.0, 8.0], [42.0, 4.0, 8.0]]},
                      {"name": "edge", "type": "polyline", "points": [[0.0, 25.5, 8.0], [40.0, 25.5, 8.0]]}]}"#,
    )
    .unwrap();
    let landmarks = read_landmarks(&dir.join("L.json")).unwrap();
    let targets = read_targets(&dir.join("T.json"), &landmarks).unwrap();
    // a grey 320×240 image and its camera
    laparo_core::io::write_png(dir.join("img.png"), &laparo_core::image::Image::filled(320, 240, 3, 128u8)).unwrap();
    std::fs::write(
        dir.join("cam.json"),
        r#"{"fx": 300, "fy": 300, "cx": 160, "cy": 120, "width": 320, "height": 240, "k1": -0.1}"#,
    )
    .unwrap();
    Job {
        organ,
        organ_config: OrganConfig { spacing_mm: 2.0, steps: 60, ..Default::default() },
        landmarks,
        targets,
        region_weight: 0.0,
        optimizer: OptimizerConfig { iterations: 6, ..Default::default() },
        tumour: Some(tumour),
        overlay: Some((dir.join("img.png"), dir.join("cam.json"))),
        out: dir.join("out"),
        resume: false,
        checkpoint_every: 2,
        crack: None,
        landmark_offsets: false,
    }
}

#[test]
fn box_organ_end_to_end_and_resume() {
    let dir = tempfile::tempdir().unwrap();
    let j = job(dir.path());
    let r = run_job(&j, &mut |_| {}).unwrap();
    assert_eq!(r.particles, 20 * 12 * 8);
    assert!(r.mean_distance_mm[1] < 0.6 * r.mean_distance_mm[0], "{:?}", r.mean_distance_mm);
    for f in [
        "particles_registered.ply",
        "particles_rest.ply",
        "surface_registered.ply",
        "organ_deformed.obj",
        "tumour_deformed.obj",
        "overlay.png",
        "loss.csv",
        "loss.png",
        "report.json",
        "checkpoint_v0.json",
    ] {
        assert!(j.out.join(f).exists(), "{f} missing");
    }
    // the tumour moved with the body and lies inside it (no extrapolation)
    assert_eq!(r.tumour_flags.unwrap()[0], 0);
    let csv = std::fs::read_to_string(j.out.join("loss.csv")).unwrap();
    assert_eq!(csv.lines().count(), r.iterations + 2);
    // the overlay differs from the grey background where the organ projects
    let o = laparo_core::io::read_rgb8(j.out.join("overlay.png")).unwrap();
    assert!(o.data.iter().filter(|&&v| v != 128).count() > 1000);
    // resume: starts from the checkpoint (its loss), does not restart from the rest state
    let mut j2 = j.clone();
    j2.resume = true;
    j2.optimizer.iterations = 1;
    let r2 = run_job(&j2, &mut |_| {}).unwrap();
    assert!(r2.resumed_from.is_some());
    assert!(
        (r2.mean_distance_mm[0] - r.mean_distance_mm[1]).abs() < 1e-9,
        "{} vs {}",
        r2.mean_distance_mm[0],
        r.mean_distance_mm[1]
    );
}

#[test]
fn bad_inputs_name_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let mut j = job(dir.path());
    // landmark outside the body
    std::fs::write(dir.path().join("L2.json"), r#"{"groups": [{"name": "tip", "points": [[90.0, 12.0, 8.0]]}]}"#)
        .unwrap();
    let lm = read_landmarks(&dir.path().join("L2.json")).unwrap();
    j.targets = vec![laparo_register::io::TargetSpec::Points(vec![lm[0].points[0]])];
    j.landmarks = lm;
    let e = run_job(&j, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("landmark 0") && e.contains("outside the body"), "{e}");
    // empty target file
    std::fs::write(
        dir.path().join("empty.ply"),
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
    )
    .unwrap();
    let e = read_targets(&dir.path().join("empty.ply"), &j.landmarks).unwrap_err().to_string();
    assert!(e.contains("empty.ply"), "{e}");
    // empty landmark file and a bad JSON
    std::fs::write(dir.path().join("L3.json"), r#"{"groups": []}"#).unwrap();
    assert!(read_landmarks(&dir.path().join("L3.json")).unwrap_err().to_string().contains("L3.json"));
    std::fs::write(dir.path().join("L4.json"), "{").unwrap();
    assert!(read_landmarks(&dir.path().join("L4.json")).unwrap_err().to_string().contains("L4.json"));
    // target count mismatch for paired points
    std::fs::write(
        dir.path().join("T2.json"),
        r#"{"groups": [{"name": "tip", "points": [[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]]}]}"#,
    )
    .unwrap();
    assert!(read_targets(&dir.path().join("T2.json"), &j.landmarks).unwrap_err().to_string().contains("T2.json"));
}

/// `--crack`: a plane across the middle of the box (x = 20 mm, normal +x) labels the particles within the band
/// by side (counted by hand from the rest lattice), and with the two ends pulled apart the lips separate: the
/// registered particles next to the crack jump across it, where one field keeps them together.
#[test]
fn a_crack_surface_lets_the_lips_separate() {
    let dir = tempfile::tempdir().unwrap();
    let mut j = job(dir.path());
    std::fs::write(
        dir.path().join("L5.json"),
        r#"{"groups": [{"name": "right", "points": [[39.0, 12.0, 8.0], [39.0, 4.0, 8.0], [39.0, 20.0, 8.0]]},
                       {"name": "left", "points": [[1.0, 12.0, 8.0], [1.0, 4.0, 8.0], [1.0, 20.0, 8.0]]}]}"#,
    )
    .unwrap();
    std::fs::write(
        dir.path().join("T5.json"),
        r#"{"groups": [{"name": "right", "type": "points", "points": [[43.0, 12.0, 8.0], [43.0, 4.0, 8.0], [43.0, 20.0, 8.0]]},
                       {"name": "left", "type": "points", "points": [[-3.0, 12.0, 8.0], [-3.0, 4.0, 8.0], [-3.0, 20.0, 8.0]]}]}"#,
    )
    .unwrap();
    j.landmarks = read_landmarks(&dir.path().join("L5.json")).unwrap();
    j.targets = read_targets(&dir.path().join("T5.json"), &j.landmarks).unwrap();
    (j.tumour, j.overlay, j.optimizer.iterations) = (None, None, 12);
    let plane = laparo_core::mesh::TriMesh {
        vertices: [[20.0, -5.0, -5.0], [20.0, 30.0, -5.0], [20.0, 30.0, 25.0], [20.0, -5.0, 25.0]]
            .iter()
            .map(|p| nalgebra::Vector3::new(p[0], p[1], p[2]))
            .collect(),
        faces: vec![[0, 1, 2], [0, 2, 3]], // normal +x: side +1 is x > 20
    };
    let crack = laparo_register::crack::CrackSurface::from_mesh(&plane, "plane", Some(5.0)).unwrap();
    let gap = |out: &Path| -> f64 {
        // mean x displacement of the particles within 2 mm right of the crack minus those within 2 mm left
        let rest = laparo_core::mesh::read_ply(out.join("particles_rest.ply")).unwrap().vertices;
        let reg = laparo_core::mesh::read_ply(out.join("particles_registered.ply")).unwrap().vertices;
        let mean = |lo: f64, hi: f64| {
            let d: Vec<f64> =
                rest.iter().zip(&reg).filter(|(p, _)| p.x > lo && p.x < hi).map(|(p, q)| q.x - p.x).collect();
            assert!(!d.is_empty());
            d.iter().sum::<f64>() / d.len() as f64
        };
        mean(20.0, 22.0) - mean(18.0, 20.0)
    };
    let one = run_job(&j, &mut |_| {}).unwrap();
    assert!(one.crack.is_none());
    let gap_one = gap(&j.out);
    j.crack = Some(crack.clone());
    j.out = dir.path().join("out_crack");
    let two = run_job(&j, &mut |_| {}).unwrap();
    let labels = two.crack.unwrap();
    // rest lattice x = 1, 3, …, 39 mm (20 × 12 × 8 particles): within 5 mm of x = 20 lie x = 15, 17, 19 (side −1)
    // and 21, 23, 25 (side +1), 12 × 8 particles each
    assert_eq!(labels.particles, [3 * 96, 3 * 96]);
    assert_eq!((labels.band_mm, labels.faces), (5.0, 2));
    let gap_two = gap(&j.out);
    assert!(gap_two > 4.0 && gap_two > 3.0 * gap_one.abs(), "gap with crack {gap_two} mm, without {gap_one} mm");
    // a crack surface that misses the organ is refused, naming it
    let mut far = plane.clone();
    far.vertices.iter_mut().for_each(|v| v.x += 100.0);
    j.crack = Some(laparo_register::crack::CrackSurface::from_mesh(&far, "plane", None).unwrap());
    let e = run_job(&j, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("crack surface") && e.contains("misses the organ"), "{e}");
    // degenerate or empty surfaces are refused at the boundary
    let flat = laparo_core::mesh::TriMesh { vertices: plane.vertices.clone(), faces: vec![[0, 1, 1]] };
    assert!(laparo_register::crack::CrackSurface::from_mesh(&flat, "flat.ply", None)
        .unwrap_err()
        .to_string()
        .contains("flat.ply"));
    let none = laparo_core::mesh::TriMesh { vertices: vec![], faces: vec![] };
    assert!(laparo_register::crack::CrackSurface::from_mesh(&none, "none.ply", None).is_err());
}

/// Landmarks scored at their material points: at rest, with every target at its own landmark, the loss is
/// exactly 0, where the thesis' nearest-particle scoring reads the lattice offset. The box's rest lattice is
/// x = 1, 3, …, 39, y = 1, …, 23, z = 1, …, 15 mm, so a landmark at (40, 12, 8) on the face x = 40 is √3 mm
/// from its nearest particle (39, 11 or 13, 7 or 9), and one at (39, 12, 8) is √2 mm from its.
#[test]
fn landmark_offsets_score_the_material_point() {
    let dir = tempfile::tempdir().unwrap();
    let j = job(dir.path());
    let organ = laparo_register::organ::organ_from_mesh(&j.organ, &j.organ_config).unwrap();
    let pts = vec![nalgebra::Vector3::new(40.0, 12.0, 8.0), nalgebra::Vector3::new(39.0, 12.0, 8.0)];
    let groups = vec![laparo_register::io::SourceGroup { name: "face".into(), points: pts.clone(), weight: 1.0 }];
    let targets = vec![laparo_register::io::TargetSpec::Points(pts)];
    let mut loss = laparo_register::pipeline::build_loss(&organ, &groups, &targets, 0.0, "landmarks").unwrap();
    let thesis = loss.mean_distance(&organ.scene.positions);
    assert!((thesis - (3f64.sqrt() + 2f64.sqrt()) / 2.0).abs() < 1e-5, "{thesis}");
    loss.offsets = laparo_register::pipeline::landmark_offsets(&organ, &groups, &loss);
    assert_eq!(loss.offsets[0].len(), 2);
    assert!((loss.offsets[0][0].norm() - 3f64.sqrt()).abs() < 1e-5);
    assert!(loss.mean_distance(&organ.scene.positions) < 1e-12);
}

/// The cut assumed from one lip: a lip along the box's top face (z = 16 mm) at y = 12 swept 10 mm inward
/// gives a ribbon from z = 18 (2 mm above) to z = 6 with one pair of triangles per segment; it labels the
/// particles within the band on either side of y = 12 as an independent clamp-to-rectangle count does, and
/// a lip of one point, a repeated point, a zero depth are refused by name.
#[test]
fn a_cut_swept_from_one_lip_labels_both_sides() {
    use laparo_register::crack::CrackSurface;
    use nalgebra::Vector3;
    let dir = tempfile::tempdir().unwrap();
    let j = job(dir.path());
    let surface = laparo_register::organ::organ_surface(&j.organ).unwrap();
    // the box has two triangles per face: the lip keeps 12 mm from its sides so that only top-face triangles
    // have their centroid within the normals' 10 mm radius
    let lip: Vec<Vector3<f64>> = [12.0, 17.0, 22.0, 28.0].iter().map(|&x| Vector3::new(x, 12.0, 16.0)).collect();
    let c = CrackSurface::swept_from_lip(&surface, &lip, 10.0, Some(5.0), "lip").unwrap();
    assert_eq!((c.vertices.len(), c.faces.len()), (8, 6));
    for (k, p) in lip.iter().enumerate() {
        assert!((c.vertices[2 * k] - (p + Vector3::new(0.0, 0.0, 2.0))).norm() < 1e-9);
        assert!((c.vertices[2 * k + 1] - (p - Vector3::new(0.0, 0.0, 10.0))).norm() < 1e-9);
    }
    let mut organ = laparo_register::organ::organ_from_mesh(&j.organ, &j.organ_config).unwrap();
    let rest = organ.rest_model();
    let labels = laparo_register::crack::label_organ(&mut organ, &c, &rest, &rest).unwrap();
    // independent count: the ribbon is the rectangle y = 12, 12 ≤ x ≤ 28, 6 ≤ z ≤ 18 (normal ±y), so the
    // closest point clamps x and z; a particle within 5 mm takes a side where its offset is within 60° of ±y
    let mut expected = [0usize; 2];
    for p in &rest {
        let c = Vector3::new(p.x.clamp(12.0, 28.0), 12.0, p.z.clamp(6.0, 18.0));
        let d = p - c;
        if d.norm() <= 5.0 && d.y.abs() > 0.5 * d.norm() {
            expected[(d.y > 0.0) as usize] += 1;
        }
    }
    assert!(expected[0] >= 8 * 5 * 3, "at least the 8 columns × 5 layers × 3 rows beside the ribbon");
    let mut got = labels.particles;
    got.sort_unstable();
    expected.sort_unstable();
    assert_eq!(got, expected, "{labels:?}");
    for (bad, what) in [(vec![lip[0]], "1 distinct point"), (vec![lip[0], lip[0]], "1 distinct point")] {
        let e = CrackSurface::swept_from_lip(&surface, &bad, 10.0, None, "lip `a`").unwrap_err().to_string();
        assert!(e.contains("lip `a`") && e.contains(what), "{e}");
    }
    let e = CrackSurface::swept_from_lip(&surface, &lip, 0.0, None, "lip").unwrap_err().to_string();
    assert!(e.contains("depth"), "{e}");
}

/// Loads as the unknown through `run_job`, on the cut assumed from the lip: from rest, damped, the two lips
/// pulled apart across y = 12 separate, the run ends nearly at rest (KE(T) < 5 % of the elastic energy over a
/// 300-step horizon), the energy audit balances with the loads' work, `report.json` records the unknown, and
/// a resume of a loads run is refused.
#[test]
fn loads_on_an_assumed_cut_open_the_lips_at_rest() {
    use nalgebra::Vector3;
    let dir = tempfile::tempdir().unwrap();
    let mut j = job(dir.path());
    let lip = |y: f64| -> Vec<Vector3<f64>> { (0..7).map(|k| Vector3::new(8.0 + 4.0 * k as f64, y, 16.0)).collect() };
    j.landmarks = vec![
        laparo_register::io::SourceGroup { name: "a".into(), points: lip(11.0), weight: 1.0 },
        laparo_register::io::SourceGroup { name: "b".into(), points: lip(13.0), weight: 1.0 },
    ];
    j.targets =
        vec![laparo_register::io::TargetSpec::Polyline(lip(9.0)), laparo_register::io::TargetSpec::Polyline(lip(15.0))];
    (j.tumour, j.overlay, j.optimizer.iterations) = (None, None, 10);
    j.organ_config.steps = 300;
    j.landmark_offsets = true;
    j.optimizer.unknown = laparo_register::optimize::Unknown::Loads { damping_per_horizon: 10.0 };
    let surface = laparo_register::organ::organ_surface(&j.organ).unwrap();
    let mid: Vec<Vector3<f64>> = lip(12.0);
    j.crack = Some(laparo_register::crack::CrackSurface::swept_from_lip(&surface, &mid, 10.0, None, "lip").unwrap());
    let r = run_job(&j, &mut |_| {}).unwrap();
    assert!(r.mean_distance_mm[1] < 0.5 * r.mean_distance_mm[0], "{:?}", r.mean_distance_mm);
    let e = r.energy;
    assert!(e.kinetic_initial == 0.0, "loads start from rest: {e:?}");
    assert!(e.kinetic_final < 0.05 * e.elastic_final, "{e:?}");
    // the audit balances with the loads' work: damping and the transfers only remove energy
    assert!(e.external_work > 0.0 && e.dissipated >= 0.0, "{e:?}");
    let text = std::fs::read_to_string(j.out.join("report.json")).unwrap();
    assert!(text.contains("\"loads\""), "report records the unknown");
    j.resume = true;
    let err = run_job(&j, &mut |_| {}).unwrap_err().to_string();
    assert!(err.contains("resume") && err.contains("loads"), "{err}");
}
