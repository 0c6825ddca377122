//! Every reader, fed truncated or corrupted versions of valid files, returns an error naming the
//! file (or, for a harmless corruption, a value) and never panics or tries a huge allocation.
use laparo_core::calib::{read_filestorage, StereoCalibration};
use laparo_core::io;
use laparo_core::mesh::{self, TetMesh, TriMesh};
use laparo_core::{DepthUnit, Image};
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use std::path::Path;

type Reader = fn(&Path) -> Result<(), String>;

fn r<T>(x: laparo_core::Result<T>) -> Result<(), String> {
    x.map(|_| ()).map_err(|e| e.to_string())
}

fn sample_files(dir: &Path) -> Vec<(String, Reader)> {
    let img8 = Image::from_vec(7, 5, 3, (0..105).map(|i| (i * 7) as u8).collect()).unwrap();
    let img16 = Image::from_vec(7, 5, 1, (0..35).map(|i| i * 1000).collect::<Vec<u16>>()).unwrap();
    let f32img = Image::from_vec(7, 5, 1, (0..35).map(|i| i as f32 * 0.5).collect()).unwrap();
    let f64img = f32img.map(f64::from);
    io::write_png(dir.join("a.png"), &img8).unwrap();
    io::write_jpeg(dir.join("a.jpg"), &img8, 90).unwrap();
    io::write_png16(dir.join("d.png"), &img16).unwrap();
    io::write_npy_f64(dir.join("a.npy"), &f64img).unwrap();
    io::write_npz_f64(dir.join("a.npz"), &[("x", &f64img)]).unwrap();
    io::write_pfm(dir.join("a.pfm"), &f32img).unwrap();
    io::write_tiff_f32(dir.join("a.tif"), &f32img).unwrap();
    let cal = StereoCalibration {
        width: 640,
        height: 480,
        left: laparo_core::Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap(),
        left_dist: laparo_core::Distortion::brown_conrady(-0.1, 0.01, 0.0, 0.0, 0.0),
        right: laparo_core::Intrinsics::new(501.0, 499.0, 321.0, 241.0, 640, 480).unwrap(),
        right_dist: laparo_core::Distortion::default(),
        r: Matrix3::identity(),
        t_mm: Vector3::new(-5.0, 0.0, 0.0),
    };
    cal.write_opencv_yaml(dir.join("c.yaml")).unwrap();
    cal.write_json(dir.join("c.json")).unwrap();
    let v: Vec<Vector3<f64>> =
        (0..8).map(|i| Vector3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
    let tri = TriMesh { vertices: v.clone(), faces: vec![[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6]] };
    let tet = TetMesh { vertices: v, tets: vec![[0, 1, 2, 4], [1, 3, 2, 7]] };
    mesh::write_obj(dir.join("m.obj"), &tri).unwrap();
    mesh::write_ply(dir.join("m.ply"), &tri).unwrap();
    mesh::write_ply_with(dir.join("ma.ply"), &tri, mesh::PlyEncoding::Ascii, None).unwrap();
    mesh::write_stl(dir.join("m.stl"), &tri, false).unwrap();
    mesh::write_stl(dir.join("ma.stl"), &tri, true).unwrap();
    mesh::write_msh(dir.join("m.msh"), &tet).unwrap();
    mesh::write_vtk(dir.join("m.vtk"), &tet).unwrap();
    vec![
        ("a.png".into(), (|p| r(io::read_image(p))) as Reader),
        ("a.jpg".into(), |p| r(io::read_rgb8(p))),
        ("d.png".into(), |p| r(io::read_depth(p, DepthUnit::Mm))),
        ("a.npy".into(), |p| r(io::read_npy(p))),
        ("a.npz".into(), |p| r(io::read_npz(p, Some("x")))),
        ("a.pfm".into(), |p| r(io::read_pfm(p))),
        ("a.tif".into(), |p| r(io::read_tiff_f32(p))),
        ("c.yaml".into(), |p| r(StereoCalibration::read(p))),
        ("c.json".into(), |p| r(StereoCalibration::read(p))),
        ("m.obj".into(), |p| r(mesh::read_mesh(p))),
        ("m.ply".into(), |p| r(mesh::read_mesh(p))),
        ("ma.ply".into(), |p| r(mesh::read_mesh(p))),
        ("m.stl".into(), |p| r(mesh::read_mesh(p))),
        ("ma.stl".into(), |p| r(mesh::read_mesh(p))),
        ("m.msh".into(), |p| r(mesh::read_msh(p))),
        ("m.vtk".into(), |p| r(mesh::read_vtk(p))),
    ]
}

#[test]
fn truncated_files_give_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for (name, read) in sample_files(dir.path()) {
        let src = dir.path().join(&name);
        read(&src).unwrap_or_else(|e| panic!("{name} must read: {e}"));
        let bytes = std::fs::read(&src).unwrap();
        let bad = dir.path().join(format!("cut_{name}"));
        // Every cut that removes part of the content must fail (text formats may end at a line
        // boundary legitimately only when nothing is missing, so cut well inside the data).
        for cut in [0, 1, 5, bytes.len() / 3, bytes.len() / 2, bytes.len() * 2 / 3] {
            std::fs::write(&bad, &bytes[..cut]).unwrap();
            match read(&bad) {
                Err(e) => assert!(e.contains(&format!("cut_{name}")), "{name} cut at {cut}: {e}"),
                Ok(()) => panic!("{name} cut at {cut} of {} bytes was accepted", bytes.len()),
            }
        }
    }
}

#[test]
fn corrupted_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for (name, read) in sample_files(dir.path()) {
        let bytes = std::fs::read(dir.path().join(&name)).unwrap();
        let bad = dir.path().join(format!("bad_{name}"));
        for _ in 0..60 {
            let mut b = bytes.clone();
            for _ in 0..rng.gen_range(1..6) {
                let i = rng.gen_range(0..b.len());
                b[i] = match rng.gen_range(0..3) {
                    0 => rng.gen(),
                    1 => b'9',
                    _ => b' ',
                };
            }
            let cut = rng.gen_range(b.len() / 2..=b.len());
            std::fs::write(&bad, &b[..cut]).unwrap();
            if let Err(e) = read(&bad) {
                assert!(e.contains(&format!("bad_{name}")), "{name}: {e}");
            }
        }
    }
}

#[test]
fn huge_announced_sizes_are_rejected_without_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.npy");
    let hdr = "{'descr': '<f8', 'fortran_order': False, 'shape': (4000000000, 4000000000), }";
    let mut h = hdr.to_string();
    while !(10 + h.len() + 1).is_multiple_of(64) {
        h.push(' ');
    }
    h.push('\n');
    let mut f = b"\x93NUMPY\x01\x00".to_vec();
    f.extend_from_slice(&(h.len() as u16).to_le_bytes());
    f.extend_from_slice(h.as_bytes());
    f.extend_from_slice(&[0u8; 64]);
    std::fs::write(&p, &f).unwrap();
    let e = io::read_npy(&p).unwrap_err().to_string();
    assert!(e.contains("huge.npy") && e.contains("truncated"), "{e}");
    let p = dir.path().join("huge.pfm");
    std::fs::write(&p, b"Pf\n4000000000 4000000000\n-1.0\n\0\0\0\0").unwrap();
    assert!(io::read_pfm(&p).unwrap_err().to_string().contains("huge.pfm"));
    let p = dir.path().join("huge.ply");
    std::fs::write(
        &p,
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0",
    )
    .unwrap();
    assert!(mesh::read_ply(&p).unwrap_err().to_string().contains("huge.ply"));
    let p = dir.path().join("huge.msh");
    std::fs::write(&p, b"$NOD\n4000000000000\n1 0 0 0\n$ENDNOD\n").unwrap();
    assert!(mesh::read_msh(&p).unwrap_err().to_string().contains("huge.msh"));
    let p = dir.path().join("huge.yaml");
    std::fs::write(
        &p,
        "%YAML:1.0\nM: !!opencv-matrix\n   rows: 4000000000\n   cols: 4000000000\n   dt: d\n   data: [ 1. ]\n",
    )
    .unwrap();
    assert!(read_filestorage(&p).unwrap_err().to_string().contains("huge.yaml"));
}
