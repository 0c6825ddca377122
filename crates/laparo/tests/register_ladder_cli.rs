//! The RODS-MPM ladder's flags through the CLI: bad values are refused by name before any work, and the
//! rung names are listed by the error of an unknown one.
mod common;
use common::laparo_in;

#[test]
fn at_rest_weight_and_rung_names_are_checked_at_the_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for bad in ["-1", "nan", "inf"] {
        let flag = format!("--at-rest-weight={bad}");
        let (ok, _, err) = laparo_in(
            &["register", "--organ", "o.obj", "--landmarks", "l.json", "--target", "t.json", "--out", "out", &flag],
            d,
        );
        assert!(!ok && err.contains("--at-rest-weight"), "{bad}: {err}");
        let (ok, _, err) = laparo_in(&["register", "benchmark", "--quick", &flag, "--out", "b"], d);
        assert!(!ok && err.contains("--at-rest-weight"), "{bad}: {err}");
    }
    let (ok, _, err) = laparo_in(&["register", "benchmark", "--quick", "--methods", "none,rods-l9", "--out", "b"], d);
    assert!(!ok, "{err}");
    for rung in ["rods-l0", "rods-l1-blind", "rods-l1", "rods-l2", "rods-l3"] {
        assert!(err.contains(rung), "the error lists {rung}: {err}");
    }
    assert!(!d.join("b").exists() && !d.join("out").exists(), "nothing written");
}
