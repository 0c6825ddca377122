//! Numbers from flags and files are checked at the boundary (issue 49): NaN, infinities, values out
//! of range and sizes beyond a memory budget are refused quickly, naming the flag or the file and
//! field, instead of hanging, aborting on an allocation or writing NaN results.
mod common;
use common::{laparo_in, laparo_within, write_texture_png};
use std::path::Path;

/// `args` fails within `secs` and its message contains every one of `needles`.
fn refused(args: &[&str], cwd: &Path, secs: u64, needles: &[&str]) {
    let (ok, err) = laparo_within(args, cwd, secs);
    assert!(!ok, "{args:?} succeeded");
    for n in needles {
        assert!(err.contains(n), "{args:?}: no {n:?} in: {err}");
    }
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

#[test]
fn cpc_sequence_refuses_tilts_and_frame_counts_that_hung() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let seq =
        |extra: &[&'static str]| [&["cpc", "sequence", "--texture", "procedural", "--out", "o"][..], extra].concat();
    refused(&seq(&["--max-tilt", "nan"]), d, 10, &["--max-tilt", "finite"]);
    refused(&seq(&["--max-tilt", "1e308"]), d, 10, &["--max-tilt"]);
    refused(&seq(&["--tilt0", "80", "--max-tilt", "10"]), d, 10, &["--tilt0 80"]);
    refused(&seq(&["--tilt0", "30", "--max-tilt", "10"]), d, 10, &["--max-tilt 10", "--tilt0 30"]);
    refused(&seq(&["--frames", "1000000000"]), d, 10, &["--frames"]);
    refused(&seq(&["--roi-erosion", "inf"]), d, 10, &["--roi-erosion"]);
    assert!(!d.join("o").exists(), "nothing written");
}

#[test]
fn mesh_tetra_refuses_a_spacing_beyond_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let obj = "v 0 0 0\nv 30 0 0\nv 0 30 0\nv 30 30 0\nv 0 0 30\nv 30 0 30\nv 0 30 30\nv 30 30 30\n\
               f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\nf 3 7 4\nf 4 7 8\nf 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n";
    std::fs::write(dir.path().join("box.obj"), obj).unwrap();
    let t = |e: &'static str| ["mesh", "tetra", "--surface", "box.obj", "--edge-mm", e, "--out", "b.vtk"];
    refused(&t("0.052"), dir.path(), 20, &["--edge-mm 0.052", "box.obj", "lattice tetrahedra"]);
    refused(&t("nan"), dir.path(), 10, &["--edge-mm"]);
    refused(
        &["mesh", "tetra", "--surface", "box.obj", "--edge-mm=-3", "--out", "b.vtk"],
        dir.path(),
        10,
        &["--edge-mm"],
    );
    let (ok, err) = laparo_within(&t("6"), dir.path(), 60);
    assert!(ok, "{err}");
}

/// A PNG header announcing `w`×`h` grey pixels (the size check reads only the header).
fn png_header_only(path: &Path, w: u32, h: u32) {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend((data.len() as u32).to_be_bytes());
        let mut c = kind.to_vec();
        c.extend(data);
        out.extend(&c);
        // CRC-32 (IEEE) of type + data
        let mut crc = 0xFFFF_FFFFu32;
        for &b in &c {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
            }
        }
        out.extend((!crc).to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 0, 0, 0, 0]); // 8-bit grey, deflate, no filter, no interlace
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", &[0x78, 0x01, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    chunk(&mut png, b"IEND", &[]);
    std::fs::write(path, png).unwrap();
}

#[test]
fn stereo_match_refuses_huge_pairs_and_non_finite_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    png_header_only(&d.join("L.png"), 20000, 20000);
    png_header_only(&d.join("R.png"), 20000, 20000);
    let m = |l: &'static str, r: &'static str| {
        ["stereo", "match", "--left", l, "--right", r, "--range", "-16:0", "--out", "o"]
    };
    refused(&m("L.png", "R.png"), d, 20, &["--left L.png", "20000x20000", "bytes of matching memory"]);
    write_texture_png(&d.join("l.png"), 64, 48, 1);
    write_texture_png(&d.join("r.png"), 64, 48, 2);
    for (flag, v) in [("--focal-px", "nan"), ("--baseline-mm", "0"), ("--baseline-mm", "inf"), ("--focal-px", "-0.5")] {
        let other = if flag == "--focal-px" { ["--baseline-mm", "4"] } else { ["--focal-px", "500"] };
        let flag_v = format!("{flag}={v}"); // `=`: a negative value is not taken for a flag
        let args = [&m("l.png", "r.png")[..], &[flag_v.as_str()], &other].concat();
        refused(&args, d, 20, &[flag]);
    }
    let args =
        [&m("l.png", "r.png")[..], &["--focal-px", "500", "--baseline-mm", "4", "--cx-offset-px", "nan"]].concat();
    refused(&args, d, 20, &["--cx-offset-px"]);
    let (ok, err) =
        laparo_within(&[&m("l.png", "r.png")[..], &["--focal-px", "500", "--baseline-mm", "4"]].concat(), d, 60);
    assert!(ok, "{err}");
}

#[test]
fn features_match_refuses_bad_homographies_and_thresholds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_texture_png(&d.join("a.png"), 64, 64, 3);
    write_texture_png(&d.join("b.png"), 64, 64, 4);
    let m = |h: &str, eps: &str| {
        std::fs::write(d.join("h.json"), h).unwrap();
        laparo_within(
            &[
                "features",
                "match",
                "--image1",
                "a.png",
                "--image2",
                "b.png",
                "--homography",
                "h.json",
                "--eps-px",
                eps,
                "--out",
                "o",
            ],
            d,
            30,
        )
    };
    for (h, needle) in [
        ("[[1e308,0,0],[0,1,0],[0,0,1]]", "ill-conditioned"),
        ("[[-1e308,0,0],[0,1,0],[0,0,1]]", "ill-conditioned"),
        ("[[1,0,0],[0,1],[0,0,1,5]]", "3 rows of 3"),
        ("[[1,0,0],[0,1,0],[0,0]]", "3 rows of 3"),
        ("[[1,0,0],[0,\"1\",0],[0,0,1]]", "[1][1]"),
        ("[[1,0,0],[0,null,0],[0,0,1]]", "[1][1]"),
        ("[1,0,0,0,1,0,0,0]", "3x3"),
    ] {
        let (ok, err) = m(h, "3");
        assert!(!ok && err.contains("--homography") && err.contains(needle), "{h}: {err}");
    }
    let (ok, err) = m("[[1,0,0],[0,1,0],[0,0,1]]", "inf");
    assert!(!ok && err.contains("--eps-px"), "{err}");
    let (ok, err) = m("{\"H\": [1,0,2,0,1,3,0,0,1]}", "3");
    assert!(ok, "{err}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("o/matches.json")).unwrap()).unwrap();
    assert!(j["matches"].as_array().unwrap().iter().all(|r| r["transfer_error_px"].is_number()), "no null errors");
}

#[test]
fn cpc_eval_refuses_malformed_and_impossible_poses() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ok, _, err) = laparo_in(&["cpc", "pair", "--kind", "easy", "--texture", "procedural", "--out", "p"], d);
    assert!(ok, "{err}");
    let poses: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("p/poses.json")).unwrap()).unwrap();
    let run = |p: &serde_json::Value| {
        std::fs::write(d.join("poses.json"), p.to_string()).unwrap();
        let mut args: Vec<String> = vec!["cpc".into(), "eval".into()];
        for (f, file) in [
            ("image1", "image1.png"),
            ("depth1", "depth1.npy"),
            ("mask1", "mask1.png"),
            ("image2", "image2.png"),
            ("depth2", "depth2.npy"),
            ("mask2", "mask2.png"),
            ("intrinsics", "intrinsics.json"),
        ] {
            args.extend([format!("--{f}"), format!("p/{file}")]);
        }
        args.extend(["--poses", "poses.json", "--out", "o"].map(String::from));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        laparo_within(&args, d, 300)
    };
    let with = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut p = poses.clone();
        f(&mut p["view2"]["cam_from_world"]);
        run(&p)
    };
    type Edit = Box<dyn Fn(&mut serde_json::Value)>;
    let cases: Vec<(Edit, &str)> = vec![
        (Box::new(|c| c["R"][0][1] = "0".into()), "view2.cam_from_world.R[0][1]"),
        (Box::new(|c| c["R"][1][2] = serde_json::Value::Null), "view2.cam_from_world.R[1][2]"),
        (Box::new(|c| c["R"][2].as_array_mut().unwrap().push(0.into())), "ragged"),
        (Box::new(|c| c["t_mm"][2] = 1e308.into()), "t_mm[2]"),
        (Box::new(|c| c["t_mm"] = serde_json::json!([0.0, 0.0, 0.0])), "behind or around"),
        (
            Box::new(|c| {
                let t: Vec<f64> = c["t_mm"].as_array().unwrap().iter().map(|x| -x.as_f64().unwrap()).collect();
                c["t_mm"] = serde_json::json!(t);
            }),
            "behind or around",
        ),
    ];
    for (f, needle) in &cases {
        let (ok, err) = with(f.as_ref());
        assert!(!ok && err.contains("poses.json") && err.contains(needle), "{needle}: {err}");
    }
    let (ok, err) = run(&poses);
    assert!(ok, "the rendered pair's own poses: {err}");
}

#[test]
fn register_rigid_refuses_a_source_in_other_units_without_blaming_landmarks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cube: Vec<[f64; 3]> =
        (0..8).map(|i| [(i & 1) as f64 * 30.0, (i >> 1 & 1) as f64 * 30.0, (i >> 2) as f64 * 30.0]).collect();
    let obj = |s: f64| cube.iter().map(|p| format!("v {} {} {}\n", p[0] * s, p[1] * s, p[2] * s)).collect::<String>();
    std::fs::write(d.join("t.obj"), obj(1.0)).unwrap();
    std::fs::write(d.join("s.obj"), obj(1e15)).unwrap();
    let (ok, err) =
        laparo_within(&["register", "rigid", "--source", "s.obj", "--target", "t.obj", "--out", "o"], d, 30);
    assert!(!ok && err.contains("--source s.obj") && !err.contains("landmarks"), "{err}");
    std::fs::write(d.join("s.obj"), obj(1e-6)).unwrap();
    let (ok, err) =
        laparo_within(&["register", "rigid", "--source", "s.obj", "--target", "t.obj", "--out", "o"], d, 30);
    assert!(!ok && err.contains("1000x") && !err.contains("landmarks"), "{err}");
}

#[test]
fn fem_solve_refuses_absurd_loads_and_duplicated_tetrahedra() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let vtk = |cells: &[&str]| {
        format!(
            "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n\
             0 0 0\n10 0 0\n0 10 0\n0 0 10\n0 0 -10\nCELLS {} {}\n{}\nCELL_TYPES {}\n{}\n",
            cells.len(),
            5 * cells.len(),
            cells.join("\n"),
            cells.len(),
            vec!["10"; cells.len()].join("\n")
        )
    };
    std::fs::write(d.join("two.vtk"), vtk(&["4 0 1 2 3", "4 0 2 1 4"])).unwrap();
    std::fs::write(d.join("dup.vtk"), vtk(&["4 0 1 2 3", "4 0 2 1 4", "4 1 0 2 3"])).unwrap();
    std::fs::write(d.join("fixed.json"), r#"{"vertices": [0, 1, 2, 4]}"#).unwrap();
    let loads = |f: &str| {
        std::fs::write(
            d.join("loads.json"),
            format!(r#"{{"nodal_forces": [{{"vertex": 3, "force_mn": [0, 0, {f}]}}]}}"#),
        )
        .unwrap()
    };
    let solve = |mesh: &str| {
        laparo_within(
            &["fem", "solve", "--mesh", mesh, "--fixed", "fixed.json", "--loads", "loads.json", "--out", "o"],
            d,
            60,
        )
    };
    loads("-1e300");
    let (ok, err) = solve("two.vtk");
    assert!(!ok && err.contains("loads.json") && err.contains("absurd"), "{err}");
    loads("1");
    let (ok, err) = solve("dup.vtk");
    assert!(!ok && err.contains("--mesh dup.vtk") && err.contains("duplicated element"), "{err}");
    let (ok, err) = solve("two.vtk");
    assert!(ok, "{err}");
}
