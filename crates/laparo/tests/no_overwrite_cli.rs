//! No command writes over one of its inputs (issue 49): every file a command writes is checked
//! against every file it reads — by path and by hard link — before anything is read or written, and
//! the error names both. One case per command of the third black-box campaign.
mod common;
use common::{laparo_in, write_texture_png};
use std::path::Path;

/// Run `args` in `cwd`, expect a refusal naming `output` and `input`, and `input` unchanged.
fn refused(args: &[&str], cwd: &Path, input: &Path, output: &str) {
    let before = std::fs::read(input).unwrap();
    let (ok, _, err) = laparo_in(args, cwd);
    assert!(!ok, "{args:?} succeeded");
    let name = input.file_name().unwrap().to_string_lossy();
    assert!(
        (err.contains("would overwrite the input") || err.contains("hard link to the input"))
            && err.contains(name.as_ref())
            && err.contains(output),
        "{args:?}: {err}"
    );
    assert_eq!(std::fs::read(input).unwrap(), before, "{args:?} changed {}", input.display());
}

const CUBE_OBJ: &str = "v 0 0 0\nv 30 0 0\nv 0 30 0\nv 30 30 0\nv 0 0 30\nv 30 0 30\nv 0 30 30\nv 30 30 30\n\
f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\nf 3 7 4\nf 4 7 8\nf 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n";

const TET_VTK: &str = "# vtk DataFile Version 2.0\ntet\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n\
0 0 0\n10 0 0\n0 10 0\n0 0 10\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";

#[test]
fn features_colmap_db_over_a_frame() {
    let dir = tempfile::tempdir().unwrap();
    let fr = dir.path().join("fr");
    std::fs::create_dir_all(&fr).unwrap();
    write_texture_png(&fr.join("00.png"), 96, 96, 1);
    write_texture_png(&fr.join("01.png"), 96, 96, 2);
    refused(
        &["features", "colmap", "--images", "fr", "--colmap-db", "fr/00.png"],
        dir.path(),
        &fr.join("00.png"),
        "fr/00.png",
    );
    // a database beside the frames is fine (it is not one of them)
    let (ok, _, err) =
        laparo_in(&["features", "colmap", "--images", "fr", "--colmap-db", "fr/database.db"], dir.path());
    assert!(ok, "{err}");
}

#[test]
fn register_synth_targets_over_the_organ() {
    let dir = tempfile::tempdir().unwrap();
    let organ = dir.path().join("org.obj");
    std::fs::write(&organ, CUBE_OBJ).unwrap();
    std::fs::write(dir.path().join("c.json"), "[]").unwrap();
    let args = ["register", "synth-targets", "--organ", "org.obj", "--contours", "c.json"];
    let with = |l: &'static str, t: &'static str| [&args[..], &["--landmarks-out", l, "--targets-out", t]].concat();
    refused(&with("org.obj", "t.json"), dir.path(), &organ, "org.obj");
    refused(&with("l.json", "./c.json"), dir.path(), &dir.path().join("c.json"), "c.json");
    // a hard link to the organ under another name
    std::fs::hard_link(&organ, dir.path().join("lm.json")).unwrap();
    refused(&with("lm.json", "t.json"), dir.path(), &organ, "lm.json");
    // the two outputs the same file
    let (ok, _, err) = laparo_in(&with("l.json", "sub/../l.json"), dir.path());
    assert!(!ok && err.contains("same file"), "{err}");
}

#[test]
fn features_detect_over_its_mask() {
    let dir = tempfile::tempdir().unwrap();
    write_texture_png(&dir.path().join("i.png"), 64, 64, 3);
    write_texture_png(&dir.path().join("m.png"), 64, 64, 4);
    let m = dir.path().join("m.png");
    refused(&["features", "detect", "--image", "i.png", "--mask", "m.png", "--out", "m.png"], dir.path(), &m, "m.png");
    let (ok, _, err) =
        laparo_in(&["features", "detect", "--image", "i.png", "--mask", "m.png", "--out", "k.json"], dir.path());
    assert!(ok, "{err}");
}

#[test]
fn mesh_tetra_report_over_the_surface() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("s.obj");
    std::fs::write(&s, CUBE_OBJ).unwrap();
    let args = ["mesh", "tetra", "--surface", "s.obj", "--edge-mm", "10", "--out", "s.vtk", "--report", "s.obj"];
    refused(&args, dir.path(), &s, "s.obj");
    refused(&["mesh", "tetra", "--surface", "s.obj", "--out", "./s.obj"], dir.path(), &s, "s.obj");
}

#[test]
fn mesh_incision_into_the_folder_of_its_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("cut.vtk");
    std::fs::write(&m, TET_VTK).unwrap();
    refused(
        &["mesh", "incision", "--mesh", "cut.vtk", "--scenario", "anatomical", "--out", "."],
        dir.path(),
        &m,
        "cut.vtk",
    );
}

#[test]
fn fem_solve_into_the_folder_of_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("displacement.vtk");
    std::fs::write(&m, TET_VTK).unwrap();
    std::fs::write(dir.path().join("fixed.json"), r#"{"vertices": [0, 1, 2]}"#).unwrap();
    let loads = dir.path().join("report.json");
    std::fs::write(&loads, r#"{"nodal_forces": [{"vertex": 3, "force_mn": [0, 0, 1]}]}"#).unwrap();
    let args = ["fem", "solve", "--mesh", "displacement.vtk", "--fixed", "fixed.json", "--loads", "report.json"];
    refused(&[&args[..], &["--out", "."]].concat(), dir.path(), &m, "displacement.vtk");
    std::fs::rename(&m, dir.path().join("m.vtk")).unwrap();
    let args = ["fem", "solve", "--mesh", "m.vtk", "--fixed", "fixed.json", "--loads", "report.json", "--out", "."];
    refused(&args, dir.path(), &loads, "report.json");
}

#[test]
fn register_rigid_into_the_folder_of_its_source() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("source_aligned.ply");
    std::fs::write(&src, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n").unwrap();
    std::fs::write(dir.path().join("t.obj"), CUBE_OBJ).unwrap();
    let args = ["register", "rigid", "--source", "source_aligned.ply", "--target", "t.obj", "--out", "."];
    refused(&args, dir.path(), &src, "source_aligned.ply");
}

#[test]
fn cpc_eval_table_over_its_poses() {
    let dir = tempfile::tempdir().unwrap();
    let poses = dir.path().join("table.json");
    std::fs::write(&poses, "{}").unwrap();
    let mut args: Vec<String> = vec!["cpc".into(), "eval".into()];
    for f in ["image1", "depth1", "mask1", "image2", "depth2", "mask2", "intrinsics"] {
        args.extend([format!("--{f}"), format!("{f}.x")]);
    }
    args.extend(["--poses", "table.json", "--out", "."].map(String::from));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(&args, dir.path(), &poses, "table.json");
}

#[test]
fn features_match_json_over_its_homography() {
    let dir = tempfile::tempdir().unwrap();
    write_texture_png(&dir.path().join("a.png"), 64, 64, 5);
    write_texture_png(&dir.path().join("b.png"), 64, 64, 6);
    let h = dir.path().join("matches.json");
    std::fs::write(&h, "[[1,0,0],[0,1,0],[0,0,1]]").unwrap();
    let args =
        ["features", "match", "--image1", "a.png", "--image2", "b.png", "--homography", "matches.json", "--out", "."];
    refused(&args, dir.path(), &h, "matches.json");
    let (ok, _, err) = laparo_in(
        &["features", "match", "--image1", "a.png", "--image2", "b.png", "--homography", "matches.json", "--out", "m"],
        dir.path(),
    );
    assert!(ok, "{err}");
}

#[test]
fn depth_stereo_and_cpc_writers_check_their_files_too() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for f in ["d.npy", "s.json", "e.json", "k.json", "disp.pfm", "c.yaml", "metrics.json", "gt.pfm", "lambda.json"] {
        std::fs::write(d.join(f), f).unwrap();
    }
    let args = ["depth", "reproject", "--depth", "d.npy", "--sensor-intrinsics", "s.json", "--extrinsics", "e.json"];
    refused(&[&args[..], &["--intrinsics", "k.json", "--out", "./d.npy"]].concat(), d, &d.join("d.npy"), "d.npy");
    let args = ["stereo", "disp2depth", "--disp", "disp.pfm", "--calib", "c.yaml", "--out", "z.npy", "--ply", "c.yaml"];
    refused(&args, d, &d.join("c.yaml"), "c.yaml");
    let args = ["stereo", "eval", "--pred", "metrics.json", "--gt", "gt.pfm", "--out", "."];
    refused(&args, d, &d.join("metrics.json"), "metrics.json");
    let args = ["cpc", "lambda", "--depth", "d.npy", "--intrinsics", "lambda.json", "--out", "."];
    refused(&args, d, &d.join("lambda.json"), "lambda.json");
}

#[test]
fn guide_stages_check_their_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for f in ["cloud.ply", "model.obj", "pose.json", "poly.json"] {
        std::fs::write(d.join(f), f).unwrap();
    }
    std::fs::create_dir_all(d.join("sc")).unwrap();
    let args = ["guide", "rigid", "--cloud", "cloud.ply", "--model", "model.obj", "--initial-pose", "pose.json"];
    refused(&[&args[..], &["--out", "pose.json"]].concat(), d, &d.join("pose.json"), "pose.json");
    let args = ["guide", "landmarks", "--polyline", "poly.json", "--model", "model.obj", "--scenario", "sc"];
    refused(&[&args[..], &["--out", "./model.obj"]].concat(), d, &d.join("model.obj"), "model.obj");
    let (ok, _, err) = laparo_in(&["guide", "stereo", "--scenario", "sc", "--pair", "past", "--out", "sc"], d);
    assert!(!ok && err.contains("would overwrite the input"), "{err}");
}
