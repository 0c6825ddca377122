//! CLI test of `laparo stereo match --self-rectify --self-rectify-features fast|sift` (issue 14):
//! both matchers run end to end on Middlebury Motorcycle (a rectified pair, so the fitted
//! rectification must leave the inliers' rows aligned) and record which one ran; an unknown value
//! is a clear error naming the flag.
use std::path::PathBuf;
mod common;
use common::laparo;

fn motorcycle() -> Option<(PathBuf, PathBuf)> {
    let d = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/middlebury-motorcycle"));
    let (l, r) = (d.join("motorcycle_left.png"), d.join("motorcycle_right.png"));
    if l.is_file() && r.is_file() {
        Some((l, r))
    } else {
        eprintln!("SKIP: {} is absent; --self-rectify-features CLI test not run", d.display());
        None
    }
}

#[test]
fn self_rectify_features_fast_and_sift_run_and_unknown_is_an_error() {
    let Some((l, r)) = motorcycle() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (l, r) = (l.to_str().unwrap(), r.to_str().unwrap());
    for kind in ["fast", "sift"] {
        let out = dir.path().join(kind);
        let (ok, _, err) = laparo(&[
            "stereo",
            "match",
            "--left",
            l,
            "--right",
            r,
            "--self-rectify",
            "--self-rectify-features",
            kind,
            "--range",
            "0:64",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{kind}: {err}");
        let info: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("self_rectification.json")).unwrap()).unwrap();
        assert_eq!(info["features"], kind, "{info}");
        let rect = &info["rectification"];
        let (n_in, dy) = (rect["n_inliers"].as_u64().unwrap(), rect["dy_rectified"]["median_abs"].as_f64().unwrap());
        eprintln!("{kind}: {} matches, {n_in} inliers, rectified inlier median |dy| {dy:.3} px", info["n_matches"]);
        assert!(n_in >= 100, "{kind}: {n_in} inliers");
        assert!(dy < 0.3, "{kind}: median |dy| {dy}");
        assert!(out.join("disparity.pfm").is_file(), "{kind}: no disparity.pfm");
    }
    // an unknown matcher: non-zero exit, the message names the flag and the value, nothing written
    let out = dir.path().join("bad");
    let (ok, _, err) = laparo(&[
        "stereo",
        "match",
        "--left",
        l,
        "--right",
        r,
        "--self-rectify",
        "--self-rectify-features",
        "surf",
        "--range",
        "0:64",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(err.contains("--self-rectify-features") && err.contains("surf"), "{err}");
    assert!(!out.exists(), "no output for a rejected flag");
    // the flag alone (without --self-rectify) is refused by the parser, naming both flags
    let (ok, _, err) = laparo(&[
        "stereo",
        "match",
        "--left",
        l,
        "--right",
        r,
        "--self-rectify-features",
        "fast",
        "--range",
        "0:64",
        "--out",
        dir.path().join("x").to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(err.contains("--self-rectify-features") && err.contains("--self-rectify"), "{err}");
}
