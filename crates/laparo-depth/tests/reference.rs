//! Agreement with the numpy reference `../shared/bench/depth_eval_ref.py` on committed random
//! inputs (`fixtures/*.npy`, reference numbers in `fixtures/reference.json`, produced by
//! `scripts/check_depth_ref.py --write-fixtures`), through the same file path as
//! `laparo depth eval-pair`.
use laparo_depth::align::{Alignment, PredKind};
use laparo_depth::eval::evaluate_files;
use laparo_depth::metrics::{PairOptions, METRIC_NAMES};
use std::path::Path;

#[test]
fn matches_numpy_reference_fixtures() {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures"));
    let idx: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("reference.json")).unwrap()).unwrap();
    let cases = idx["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 5);
    let mut worst: f64 = 0.0;
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let kind: PredKind = c["pred_kind"].as_str().unwrap().parse().unwrap();
        let unit = c["gt_unit"].as_str().unwrap().parse().unwrap();
        let mask = c["mask"].as_str().map(|m| dir.join(m));
        let r = evaluate_files(
            &dir.join(format!("{name}_pred.npy")),
            kind,
            &dir.join(format!("{name}_gt.npy")),
            unit,
            mask.as_deref(),
            &PairOptions::default(),
        )
        .unwrap();
        let reference = &c["reference"];
        assert_eq!(r.n_valid as u64, reference["n_valid"].as_u64().unwrap(), "{name}");
        let got = serde_json::to_value(&r).unwrap();
        for a in Alignment::ALL {
            for k in METRIC_NAMES {
                let x = got[a.key()][k].as_f64().unwrap();
                let y = reference[a.key()][k].as_f64().unwrap();
                let rel = (x - y).abs() / y.abs().max(1e-12);
                assert!(rel <= 1e-9, "{name} {} {k}: laparo {x} numpy {y} (rel {rel:e})", a.key());
                worst = worst.max(rel);
            }
        }
    }
    eprintln!("max relative difference to depth_eval_ref.py: {worst:e}");
}
