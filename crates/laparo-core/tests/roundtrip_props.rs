//! Property tests (fixed seed, deterministic): random images, calibrations, FileStorage documents
//! and meshes survive write → read bit-exactly.
use laparo_core::calib::{FileStorage, FsMatrix, FsNode, StereoCalibration};
use laparo_core::mesh::{self, TriMesh};
use laparo_core::{io, Distortion, Image, Intrinsics};
use nalgebra::Vector3;
use proptest::prelude::*;

fn same_f32(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

fn finite_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6f64..1e6,
        -1e-6f64..1e-6,
        Just(0.0),
        Just(-0.0),
        any::<f64>().prop_filter("finite", |v| v.is_finite())
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(20261122), ..ProptestConfig::default() })]

    #[test]
    fn float_rasters_round_trip(w in 1usize..9, h in 1usize..7, three in any::<bool>(), seed in any::<u64>()) {
        let c = if three { 3 } else { 1 };
        let mut s = seed | 1;
        let data: Vec<f32> = (0..w * h * c).map(|_| {
            s ^= s << 13; s ^= s >> 7; s ^= s << 17;
            f32::from_bits((s >> 32) as u32)
        }).collect();
        let img = Image::from_vec(w, h, c, data).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.pfm");
        io::write_pfm(&p, &img).unwrap();
        let b = io::read_pfm(&p).unwrap();
        prop_assert_eq!((b.width, b.height, b.channels), (w, h, c));
        prop_assert!(same_f32(&b.data, &img.data));
        let p = dir.path().join("a.tif");
        io::write_tiff_f32(&p, &img).unwrap();
        prop_assert!(same_f32(&io::read_tiff_f32(&p).unwrap().data, &img.data));
        let p = dir.path().join("a.npy");
        io::write_npy_f32(&p, &img).unwrap();
        let b = io::read_npy(&p).unwrap();
        // read_npy converts to f64: values are exact, NaN payloads may be quieted
        prop_assert!(b.data.iter().zip(&img.data).all(|(x, y)| (*x as f32).to_bits() == y.to_bits() || (x.is_nan() && y.is_nan())));
    }

    #[test]
    fn png16_round_trip(w in 1usize..9, h in 1usize..7, vals in prop::collection::vec(any::<u16>(), 63)) {
        let img = Image::from_vec(w, h, 1, vals[..w * h].to_vec()).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        io::write_png16(&p, &img).unwrap();
        prop_assert_eq!(io::read_png16(&p).unwrap(), img);
    }

    #[test]
    fn calibration_round_trips(f in 100.0f64..3000.0, c in 0.0f64..1000.0, d in prop::collection::vec(-0.5f64..0.5, 8),
                              ax in -0.2f64..0.2, ay in -0.2f64..0.2, az in -0.2f64..0.2, t in prop::collection::vec(finite_f64(), 3)) {
        let cal = StereoCalibration {
            width: 1280,
            height: 1024,
            left: Intrinsics::new(f, f * 1.001, c, c * 0.8, 1280, 1024).unwrap(),
            left_dist: Distortion::from_opencv(&d[..5]).unwrap(),
            right: Intrinsics::new(f * 0.999, f, c + 1.0, c, 1280, 1024).unwrap(),
            right_dist: Distortion::from_opencv(&d).unwrap(),
            r: laparo_core::se3::rotation_zyx(ax, ay, az),
            t_mm: Vector3::new(t[0], t[1], t[2]),
        };
        let dir = tempfile::tempdir().unwrap();
        let y = dir.path().join("c.yml");
        cal.write_opencv_yaml(&y).unwrap();
        prop_assert_eq!(&StereoCalibration::read(&y).unwrap(), &cal);
        let j = dir.path().join("c.json");
        cal.write_json(&j).unwrap();
        prop_assert_eq!(&StereoCalibration::read(&j).unwrap(), &cal);
    }

    #[test]
    fn filestorage_matrices_round_trip(rows in 1usize..6, cols in 1usize..6, vals in prop::collection::vec(finite_f64(), 25),
                                       name in "[A-Za-z][A-Za-z0-9_]{0,8}", text in "[ -~]{0,20}") {
        let m = FsMatrix::new(rows, cols, vals[..rows * cols].to_vec()).unwrap();
        let fs = FileStorage { path: Default::default(), entries: vec![
            (name.clone(), FsNode::Mat(m.clone())),
            ("note_".to_string() + &name, FsNode::Str(text.clone())),
        ]};
        let back = FileStorage::parse(&fs.to_yaml(), "x").unwrap();
        let bm = back.matrix(&name).unwrap();
        prop_assert_eq!((bm.rows, bm.cols), (rows, cols));
        prop_assert!(bm.data.iter().zip(&m.data).all(|(a, b)| a.to_bits() == b.to_bits() || (*a == 0.0 && *b == 0.0)));
        let note = "note_".to_string() + &name;
        let got = back.get(&note).cloned();
        prop_assert_eq!(got, Some(FsNode::Str(text.clone())), "{}", fs.to_yaml());
    }

    #[test]
    fn meshes_round_trip(pts in prop::collection::vec((finite_f64(), finite_f64(), finite_f64()), 3..12), seed in any::<u64>()) {
        let vertices: Vec<Vector3<f64>> = pts.iter().map(|&(x, y, z)| Vector3::new(x, y, z)).collect();
        let n = vertices.len();
        let mut s = seed | 1;
        let faces: Vec<[usize; 3]> = (0..n).map(|_| {
            let mut f = [0usize; 3];
            for k in f.iter_mut() { s ^= s << 13; s ^= s >> 7; s ^= s << 17; *k = (s % n as u64) as usize; }
            f
        }).collect();
        let m = TriMesh { vertices, faces };
        let dir = tempfile::tempdir().unwrap();
        for name in ["a.obj", "a.ply"] {
            let p = dir.path().join(name);
            mesh::write_mesh(&p, &m).unwrap();
            let b = mesh::read_mesh(&p).unwrap();
            prop_assert_eq!(&b.faces, &m.faces);
            prop_assert!(b.vertices.iter().zip(&m.vertices).all(|(a, b)| a == b));
        }
        let p = dir.path().join("b.ply");
        mesh::write_ply_with(&p, &m, mesh::PlyEncoding::Ascii, None).unwrap();
        let b = mesh::read_ply(&p).unwrap();
        prop_assert!(b.vertices.iter().zip(&m.vertices).all(|(a, b)| a == b));
    }
}
