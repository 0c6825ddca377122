//! Manifest format: TOML/JSON round trip, sequences (frames before the gesture are the clean
//! reference, thesis §3.2.7), structural validation listing every problem, scaffold layout.
use laparo_core::image::Image;
use laparo_core::io::{write_npy_f64, write_png};
use laparo_core::DepthUnit;
use laparo_depth::align::PredKind;
use laparo_depth::eval::{evaluate_manifest, EvalConfig};
use laparo_depth::manifest::{scaffold, Manifest, ScaffoldOptions};
use laparo_depth::report::summarize;
use std::path::Path;

const TOML: &str = r#"
version = 1
gt_unit = "mm"
baseline = "a"

[[methods]]
name = "a"
kind = "depth"
predictions = "pred/a/{scene}_{name}.npy"

[[sequences]]
scene = "liver"
perturbation = "incision"
name = "seq1"
gesture_start = "0002"

[[frames]]
id = "liver/incision/seq1/0000"
scene = "liver"
perturbation = "incision"
sequence = "seq1"
rgb = "rgb/0000.png"
gt = "gt/0000.npy"

[[frames]]
id = "liver/incision/seq1/0001"
scene = "liver"
perturbation = "incision"
sequence = "seq1"
rgb = "rgb/0001.png"
gt = "gt/0001.npy"

[[frames]]
id = "liver/incision/seq1/0002"
scene = "liver"
perturbation = "incision"
sequence = "seq1"
rgb = "rgb/0002.png"
gt = "gt/0002.npy"

[[frames]]
id = "liver/incision/seq1/0003"
scene = "liver"
perturbation = "incision"
sequence = "seq1"
rgb = "rgb/0003.png"
gt = "gt/0003.npy"
"#;

fn write_files(dir: &Path, errs: &[f64]) {
    // GT 100 mm everywhere; predicted depth (m) 0.1·(1 + err): Abs Rel = err without alignment.
    for (i, e) in errs.iter().enumerate() {
        write_png(dir.join(format!("rgb/{i:04}.png")), &Image::from_vec(4, 3, 3, vec![9u8; 36]).unwrap()).unwrap();
        write_npy_f64(dir.join(format!("gt/{i:04}.npy")), &Image::from_vec(4, 3, 1, vec![100.0; 12]).unwrap()).unwrap();
        write_npy_f64(
            dir.join(format!("pred/a/liver_{i:04}.npy")),
            &Image::from_vec(4, 3, 1, vec![0.1 * (1.0 + e); 12]).unwrap(),
        )
        .unwrap();
    }
}

#[test]
fn sequence_frames_before_the_gesture_are_the_clean_reference() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("m.toml");
    std::fs::write(&p, TOML).unwrap();
    let m = Manifest::read(&p).unwrap();
    assert_eq!(m.gt_unit, DepthUnit::Mm);
    assert_eq!(m.methods[0].kind, PredKind::Depth);
    let r = m.resolve().unwrap();
    assert_eq!(r.frames.iter().map(|f| f.severity).collect::<Vec<_>>(), vec![0, 0, 1, 1]);
    write_files(d.path(), &[0.1, 0.1, 0.2, 0.4]);
    let out = evaluate_manifest(&m, &EvalConfig::default(), &|_| {}).unwrap();
    let s = summarize(&out, "a").unwrap();
    let none = &s.alignments[0].robustness[0];
    assert_eq!(s.alignments[0].alignment.key(), "none");
    // Clean = 0.1; perturbed (one severity level) mean = 0.3 -> RR = (1 − 0.3) / (1 − 0.1).
    assert!((none.clean_error.abs_rel.unwrap() - 0.1).abs() < 1e-12);
    assert!((none.mrr.abs_rel.unwrap() - 0.7 / 0.9).abs() < 1e-12);
    assert_eq!(none.mce.abs_rel, Some(1.0));

    // JSON round trip keeps everything.
    let j = d.path().join("m.json");
    m.write(&j).unwrap();
    let m2 = Manifest::read(&j).unwrap();
    assert_eq!(m2.frames, m.frames);
    assert_eq!(m2.sequences, m.sequences);
    let t = d.path().join("m2.toml");
    m2.write(&t).unwrap();
    assert_eq!(Manifest::read(&t).unwrap().methods, m.methods);
}

#[test]
fn validation_lists_every_problem() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("m.toml");
    let bad = TOML
        .replace("gesture_start = \"0002\"", "")
        .replace("baseline = \"a\"", "baseline = \"zz\"")
        .replace("id = \"liver/incision/seq1/0003\"", "id = \"liver/incision/seq1/0002\"");
    std::fs::write(&p, bad).unwrap();
    let m = Manifest::read(&p).unwrap();
    let rep = m.validate(None);
    let all = rep.problems.join("\n");
    assert!(all.contains("gesture_start is not set"), "{all}");
    assert!(all.contains("baseline 'zz'"), "{all}");
    assert!(all.contains("listed twice"), "{all}");
    // No file was written: 4 RGB + 4 GT + 4 predictions missing, all listed.
    assert_eq!(rep.problems.iter().filter(|p| p.starts_with("missing")).count(), 12, "{all}");
    let e = m.resolve().unwrap_err().to_string();
    assert!(e.contains("m.toml") && e.contains("3 problem(s)"), "{e}");
    // Unreadable manifests name the file.
    std::fs::write(&p, "version = 1\ngt_unit = \"cm\"\n").unwrap();
    let e = Manifest::read(&p).unwrap_err().to_string();
    assert!(e.contains("m.toml"), "{e}");
}

#[test]
fn scaffold_understands_levels_and_sequences() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path();
    let rgb = Image::from_vec(2, 2, 3, vec![1u8; 12]).unwrap();
    let gt = Image::from_vec(2, 2, 1, vec![50.0; 4]).unwrap();
    for (level, names) in [("clean", vec!["a"]), ("s2", vec!["b"]), ("seq7", vec!["0001", "0002", "0003"])] {
        for n in names {
            let b = root.join("kidney/smoke").join(level);
            write_png(b.join(format!("rgb/{n}.png")), &rgb).unwrap();
            write_npy_f64(b.join(format!("depth/{n}.npy")), &gt).unwrap();
            write_npy_f64(root.join("predictions/M/kidney/smoke").join(level).join(format!("{n}.npy")), &gt).unwrap();
        }
    }
    std::fs::write(root.join("kidney/smoke/seq7/gesture_start.txt"), "0002\n").unwrap();
    let m = scaffold(
        root,
        &ScaffoldOptions {
            gt_unit: DepthUnit::Mm,
            depth_methods: vec!["M".into()],
            predictions_dir: "predictions".into(),
        },
    )
    .unwrap();
    assert_eq!(m.frames.len(), 5);
    assert_eq!(m.methods.len(), 1);
    assert_eq!(m.methods[0].kind, PredKind::Depth);
    assert_eq!(m.sequences.len(), 1);
    assert_eq!(m.sequences[0].gesture_start, "0002");
    assert!(m.validate(None).ok(), "{:?}", m.validate(None).problems);
    let r = m.resolve().unwrap();
    let sev: Vec<(String, u32)> = r.frames.iter().map(|f| (f.id.clone(), f.severity)).collect();
    assert!(sev.contains(&("kidney/smoke/clean/a".into(), 0)));
    assert!(sev.contains(&("kidney/smoke/s2/b".into(), 2)));
    assert!(sev.contains(&("kidney/smoke/seq7/0001".into(), 0)));
    assert!(sev.contains(&("kidney/smoke/seq7/0003".into(), 1)));
}
