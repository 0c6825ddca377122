//! The scenario refuses a virtual camera inside the organ (issue 50, item 3): on the second P2ILF
//! liver the laparoscope, 90 mm from the incision, sat inside the surface and every pixel was liver.
use laparo_core::mesh::{TetMesh, TriMesh};
use laparo_guide::deformation::Deformation;
use laparo_guide::scenario::{generate, point_inside_closed_surface, ScenarioConfig};
use nalgebra::Vector3;

/// A closed, outward-oriented box surface [lo, hi] (12 triangles).
fn box_surface(lo: f64, hi: f64) -> TriMesh {
    let v: Vec<Vector3<f64>> = (0..8)
        .map(|i| {
            Vector3::new(
                if i & 1 == 0 { lo } else { hi },
                if i & 2 == 0 { lo } else { hi },
                if i & 4 == 0 { lo } else { hi },
            )
        })
        .collect();
    let q = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let faces = q.iter().flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]).collect();
    TriMesh { vertices: v, faces }
}

#[test]
fn inside_test_of_a_closed_surface() {
    let b = box_surface(-10.0, 10.0);
    assert!(b.is_closed());
    assert!(point_inside_closed_surface(&Vector3::new(0.0, 0.0, 0.0), &b));
    assert!(point_inside_closed_surface(&Vector3::new(9.9, -9.9, 9.9), &b));
    assert!(!point_inside_closed_surface(&Vector3::new(10.1, 0.0, 0.0), &b));
    assert!(!point_inside_closed_surface(&Vector3::new(0.0, 0.0, -40.0), &b));
}

#[test]
fn scenario_refuses_a_camera_inside_the_organ() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // an organ 400 mm across; the incision (its lips) at its centre: the camera, 90 mm from the
    // incision, is inside
    let organ = box_surface(-200.0, 200.0);
    laparo_core::mesh::write_obj(d.join("organ.obj"), &organ).unwrap();
    laparo_core::io::write_png(d.join("frame.png"), &laparo_core::image::Image::filled(64, 36, 3, 128u8)).unwrap();
    std::fs::write(
        d.join("camera.json"),
        r#"{"fx": 952.0, "fy": 952.0, "cx": 959.5, "cy": 539.5, "width": 1920, "height": 1080}"#,
    )
    .unwrap();
    let rest = TetMesh {
        vertices: vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(5.0, 0.0, 0.0),
            Vector3::new(0.0, 5.0, 0.0),
            Vector3::new(0.0, 0.0, 5.0),
        ],
        tets: vec![[0, 1, 2, 3]],
    };
    let def = Deformation {
        deformed: rest.vertices.clone(),
        rest,
        lips: [vec![0, 1], vec![2, 3]],
        tumour_centre_mm: Vector3::new(1.0, 1.0, 1.0),
        tumour_radius_mm: 1.0,
    };
    def.write(&d.join("deformation")).unwrap();
    let Err(e) = generate(
        &d.join("organ.obj"),
        &d.join("frame.png"),
        &d.join("camera.json"),
        Some(&d.join("deformation")),
        &ScenarioConfig::quick(),
        &d.join("out"),
    ) else {
        panic!("a camera inside the organ was not refused")
    };
    let m = e.to_string();
    assert!(m.contains("inside the organ") && m.contains("organ.obj") && m.contains("90 mm"), "{m}");
}
