//! `laparo-bench mpm` end to end (moved from the `laparo` CLI tests with the harness).

#[test]
fn bench_json_small() {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_laparo-bench"))
        .args([
            "mpm",
            "--dim",
            "2",
            "--particles",
            "400",
            "--n-grid",
            "64",
            "--steps",
            "20",
            "--repeats",
            "1",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in ["dim", "particles", "n_grid", "steps", "forward_s", "forward_backward_s", "peak_rss_mb"] {
        assert!(v.get(k).is_some(), "missing {k}");
    }
    assert_eq!(v["dim"], 2);
    assert_eq!(v["particles"], 400);
    assert!(v["forward_backward_s"].as_f64().unwrap() > 0.0);
}
