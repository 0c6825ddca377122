//! COLMAP database: schema, pair ids, blob layout, and a Python sqlite3 + numpy round trip.
use laparo_features::colmap::*;
use laparo_features::{Descriptors, Keypoint, Match};
use rusqlite::Connection;

fn kp(x: f64, y: f64) -> Keypoint {
    Keypoint { x, y, size_px: 4.0, angle_rad: 0.25, response: 1.0, octave: 0 }
}

fn write_db(path: &std::path::Path) {
    let mut db = ColmapDatabase::create(path).unwrap();
    let cam = ColmapCamera {
        model: CameraModel::Pinhole,
        width: 640,
        height: 480,
        params: vec![500.0, 501.0, 320.0, 240.0],
        prior_focal_length: true,
    };
    let c = db.add_camera(&cam).unwrap();
    let ids: Vec<u32> = (0..3).map(|i| db.add_image(&format!("im{i}.png"), c).unwrap()).collect();
    assert_eq!(ids, vec![1, 2, 3]);
    db.add_keypoints(1, &[kp(0.0, 0.0), kp(10.0, 20.0), kp(3.5, 7.25)]).unwrap();
    db.add_keypoints(2, &[kp(1.0, 2.0), kp(5.0, 6.0)]).unwrap();
    db.add_keypoints(3, &[]).unwrap();
    let mut sift = vec![0f32; 2 * 128];
    sift[0] = 3.0;
    sift[1] = 1.0; // row 0: L1 = 4 → sqrt(3/4), sqrt(1/4) → 443.4 → 255, 256 → 255
    sift[128 + 5] = 100.0; // row 1: one value → sqrt(1) = 1 → 255
    sift[128 + 6] = 1e-3 * 100.0 / (1.0 - 1e-3); // tiny second value
    db.add_descriptors(1, &Descriptors::Float { dim: 128, data: sift }).unwrap();
    db.add_descriptors(2, &Descriptors::Binary { bytes: 32, data: vec![7u8; 64] }).unwrap();
    let m = [Match { i1: 0, i2: 1, distance: 1.0 }, Match { i1: 2, i2: 0, distance: 2.0 }];
    db.add_matches(1, 2, &m).unwrap();
    // Passed as (2, 1): columns must come out swapped.
    db.add_matches(3, 1, &[Match { i1: 9, i2: 4, distance: 0.0 }]).unwrap();
    let g = TwoViewGeometry {
        config: TwoViewConfig::Uncalibrated,
        inliers: m.to_vec(),
        f: [0.0, 0.0, 0.1, 0.0, 0.0, -0.2, -0.1, 0.2, 0.0],
        e: [0.0; 9],
        h: [2.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0],
        qvec: [1.0, 0.0, 0.0, 0.0],
        tvec: [0.0; 3],
    };
    db.add_two_view_geometry(1, 2, &g).unwrap();
    db.add_two_view_geometry(3, 1, &g).unwrap();
    db.finish().unwrap();
}

#[test]
fn pair_ids_match_colmap() {
    assert_eq!(pair_id(1, 2), 2147483649);
    assert_eq!(pair_id(2, 1), 2147483649);
    assert_eq!(pair_id(3, 7), 6442450948);
    assert_eq!(pair_id_to_image_ids(6442450948), (3, 7));
    assert_eq!(pair_id_to_image_ids(pair_id(40000, 12)), (12, 40000));
}

#[test]
fn sift_to_u8_follows_colmap_l1_root() {
    let mut d = vec![0f32; 128];
    d[0] = 1.0;
    d[1] = 3.0;
    d[2] = 12.0; // L1 = 16: sqrt(1/16)=0.25 → 128, sqrt(3/16)=0.433 → 221.7 → 222, sqrt(12/16) → 255 (clipped)
    let u = sift_to_colmap_u8(&d);
    assert_eq!(&u[..4], &[128, 222, 255, 0]);
    assert!(sift_to_colmap_u8(&[0.0; 128]).iter().all(|&v| v == 0));
}

#[test]
fn schema_columns_and_blobs() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub/database.db");
    write_db(&path);
    // No temporary left behind.
    let names: Vec<String> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["database.db".to_string()]);
    let c = Connection::open(&path).unwrap();
    let cols = |t: &str| -> Vec<String> {
        let mut st = c.prepare(&format!("PRAGMA table_info({t})")).unwrap();
        st.query_map([], |r| r.get::<_, String>(1)).unwrap().map(|r| r.unwrap()).collect()
    };
    assert_eq!(cols("cameras"), ["camera_id", "model", "width", "height", "params", "prior_focal_length"]);
    assert_eq!(
        cols("images"),
        [
            "image_id",
            "name",
            "camera_id",
            "prior_qw",
            "prior_qx",
            "prior_qy",
            "prior_qz",
            "prior_tx",
            "prior_ty",
            "prior_tz"
        ]
    );
    assert_eq!(cols("keypoints"), ["image_id", "rows", "cols", "data"]);
    assert_eq!(cols("descriptors"), ["image_id", "rows", "cols", "data"]);
    assert_eq!(cols("matches"), ["pair_id", "rows", "cols", "data"]);
    assert_eq!(
        cols("two_view_geometries"),
        ["pair_id", "rows", "cols", "data", "config", "F", "E", "H", "qvec", "tvec"]
    );
    let (model, params): (i64, Vec<u8>) =
        c.query_row("SELECT model, params FROM cameras", [], |r| Ok((r.get(0)?, r.get(1)?))).unwrap();
    assert_eq!(model, 1);
    assert_eq!(params.len(), 32);
    assert_eq!(f64::from_le_bytes(params[8..16].try_into().unwrap()), 501.0);
    let kp: (i64, i64, Vec<u8>) = c
        .query_row("SELECT rows, cols, data FROM keypoints WHERE image_id = 1", [], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?))
        })
        .unwrap();
    assert_eq!((kp.0, kp.1, kp.2.len()), (3, 4, 3 * 4 * 4));
    let f = |i: usize| f32::from_le_bytes(kp.2[4 * i..4 * i + 4].try_into().unwrap());
    assert_eq!([f(0), f(1), f(2), f(3)], [0.5, 0.5, 2.0, 0.25]); // +0.5 shift, scale = size/2
    assert_eq!([f(8), f(9)], [4.0, 7.75]);
    let d: (i64, i64, Vec<u8>) = c
        .query_row("SELECT rows, cols, data FROM descriptors WHERE image_id = 1", [], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?))
        })
        .unwrap();
    assert_eq!((d.0, d.1, d.2.len()), (2, 128, 256));
    assert_eq!(&d.2[..3], &[255, 255, 0]);
    let m: (i64, i64, i64, Vec<u8>) = c
        .query_row("SELECT pair_id, rows, cols, data FROM matches WHERE pair_id = 2147483649", [], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))
        })
        .unwrap();
    assert_eq!((m.1, m.2, m.3.len()), (2, 2, 2 * 8));
    let u = |b: &[u8], i: usize| u32::from_le_bytes(b[4 * i..4 * i + 4].try_into().unwrap());
    assert_eq!((u(&m.3, 0), u(&m.3, 1), u(&m.3, 2), u(&m.3, 3)), (0, 1, 2, 0));
    let swapped: Vec<u8> =
        c.query_row("SELECT data FROM matches WHERE pair_id = ?1", [pair_id(1, 3) as i64], |r| r.get(0)).unwrap();
    assert_eq!((u(&swapped, 0), u(&swapped, 1)), (4, 9));
    let g: (i64, i64, Vec<u8>, Vec<u8>, Vec<u8>) = c
        .query_row(
            "SELECT rows, config, F, H, qvec FROM two_view_geometries WHERE pair_id = ?1",
            [pair_id(1, 3) as i64],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)),
        )
        .unwrap();
    assert_eq!((g.0, g.1, g.2.len(), g.3.len(), g.4.len()), (2, 3, 72, 72, 32));
    let d64 = |b: &[u8], i: usize| f64::from_le_bytes(b[8 * i..8 * i + 8].try_into().unwrap());
    // Swapped pair: F transposed (F[0][2] = 0.1 moves to [2][0]); H inverted (2 → 0.5, 1 → −0.5).
    assert_eq!((d64(&g.2, 2), d64(&g.2, 6)), (-0.1, 0.1));
    assert_eq!((d64(&g.3, 0), d64(&g.3, 2)), (0.5, -0.5));
    let n_images: i64 = c.query_row("SELECT COUNT(*) FROM images", [], |r| r.get(0)).unwrap();
    assert_eq!(n_images, 3);
}

#[test]
fn bad_camera_and_duplicate_image_are_errors_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("db.db");
    {
        let mut db = ColmapDatabase::create(&path).unwrap();
        let cam = ColmapCamera {
            model: CameraModel::Opencv,
            width: 1,
            height: 1,
            params: vec![1.0; 4],
            prior_focal_length: false,
        };
        assert!(db.add_camera(&cam).unwrap_err().to_string().contains("camera params"));
        let cam = ColmapCamera { params: vec![1.0; 8], ..cam };
        let c = db.add_camera(&cam).unwrap();
        db.add_image("a.png", c).unwrap();
        let e = db.add_image("a.png", c).unwrap_err().to_string();
        assert!(e.contains("db.db") && e.contains("UNIQUE"), "{e}");
        // dropped without finish
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "an unfinished export leaves no file");
}

#[test]
fn python_sqlite3_numpy_round_trip() {
    let ok = std::process::Command::new("python3")
        .args(["-c", "import numpy, sqlite3"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if !ok {
        eprintln!("SKIP python_sqlite3_numpy_round_trip: python3 with numpy not available");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("database.db");
    write_db(&path);
    let script = r#"
import sqlite3, sys, numpy as np
c = sqlite3.connect(sys.argv[1])
def blob(q, dt, shape_q=None):
    r, k, d = c.execute(q).fetchone()
    return np.frombuffer(d, dtype=dt).reshape(r, k)
kp = blob("SELECT rows, cols, data FROM keypoints WHERE image_id=1", np.float32)
de = blob("SELECT rows, cols, data FROM descriptors WHERE image_id=1", np.uint8)
m = blob("SELECT rows, cols, data FROM matches WHERE pair_id=2147483649", np.uint32)
cam = np.frombuffer(c.execute("SELECT params FROM cameras").fetchone()[0], np.float64)
H = np.frombuffer(c.execute("SELECT H FROM two_view_geometries WHERE pair_id=2147483649").fetchone()[0], np.float64).reshape(3, 3)
pid = [r[0] for r in c.execute("SELECT pair_id FROM matches ORDER BY pair_id")]
out = [kp.ravel().tolist(), de[:, :3].ravel().tolist(), m.ravel().tolist(), cam.tolist(), H.ravel().tolist(), [p % 2147483647 for p in pid], [(p - p % 2147483647) // 2147483647 for p in pid]]
print(repr(out))
"#;
    let out = std::process::Command::new("python3").args(["-c", script, path.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let got = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let expect = "[[0.5, 0.5, 2.0, 0.25, 10.5, 20.5, 2.0, 0.25, 4.0, 7.75, 2.0, 0.25], [255, 255, 0, 0, 0, 0], [0, 1, 2, 0], [500.0, 501.0, 320.0, 240.0], [2.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0], [2, 3], [1, 1]]";
    assert_eq!(got, expect);
}
