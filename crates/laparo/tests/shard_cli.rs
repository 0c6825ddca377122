//! `--shard I/N` on the dataset jobs (`cats augment`, `depth perturb`, `depth eval`): the three
//! shards of N = 3 together produce byte-identical files to one unsharded run (issue 15).
use laparo_core::image::Image;
use laparo_core::io::{write_npy_f64, write_pfm, write_png};
use laparo_stereo::{default_camera, Scene};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
mod common;
use common::{laparo_ok, run};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file under `root` (relative path → bytes).
fn tree(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(d: &Path, root: &Path, m: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, root, m);
            } else {
                m.insert(p.strip_prefix(root).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    let mut m = BTreeMap::new();
    walk(root, root, &mut m);
    m
}

/// The union of shard trees; a file present in several shards must be identical in all.
fn union(trees: &[BTreeMap<PathBuf, Vec<u8>>]) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut u = BTreeMap::new();
    for t in trees {
        for (k, v) in t {
            if let Some(old) = u.insert(k.clone(), v.clone()) {
                assert_eq!(old, *v, "{} differs between shards", k.display());
            }
        }
    }
    u
}

fn assert_same(a: &BTreeMap<PathBuf, Vec<u8>>, b: &BTreeMap<PathBuf, Vec<u8>>) {
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in a {
        assert!(v == &b[k], "{} differs", k.display());
    }
}

#[test]
fn cats_augment_shards_equal_one_run() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in");
    let k = default_camera(48, 32);
    for i in 0..7 {
        let sm = Scene::default().stereo_sample(&k, 40.0 + 5.0 * i as f64, 1);
        write_png(input.join("left").join(format!("{i:04}.png")), &sm.left).unwrap();
        write_png(input.join("right").join(format!("{i:04}.png")), &sm.right).unwrap();
        write_pfm(input.join("disp").join(format!("{i:04}.pfm")), sm.disp_left.as_ref().unwrap()).unwrap();
    }
    let cfg = input.join("cats.toml");
    std::fs::write(&cfg, format!("source = \"test\"\n[camera]\nfx = {f}\nfy = {f}\n[left.euler_deg]\nx = {{ dist = \"normal\", mean = 0.0, std = 0.5 }}\ny = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\nz = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\n[right.euler_deg]\nx = {{ dist = \"normal\", mean = 0.0, std = 0.5 }}\ny = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\nz = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\n", f = k.fx)).unwrap();
    let run = |out: &Path, shard: Option<&str>| {
        let mut a = vec!["cats", "augment", "--input", s(&input), "--layout", "generic", "--out", s(out)];
        a.extend(["--config", s(&cfg), "--seed", "11"]);
        if let Some(sh) = shard {
            a.extend(["--shard", sh]);
        }
        laparo_ok(&a);
    };
    let full = d.path().join("full");
    run(&full, None);
    let mut shards = Vec::new();
    let shared = d.path().join("shared");
    for i in 0..3 {
        let o = d.path().join(format!("shard{i}"));
        run(&o, Some(&format!("{i}/3")));
        shards.push(tree(&o));
        run(&shared, Some(&format!("{i}/3")));
    }
    let full = tree(&full);
    assert_eq!(full.keys().filter(|k| k.to_string_lossy().ends_with(".cats.json")).count(), 7);
    // Each shard did its own third (7 = 3 + 2 + 2 sidecars), none is empty.
    for (i, t) in shards.iter().enumerate() {
        let n = t.keys().filter(|k| k.to_string_lossy().ends_with(".cats.json")).count();
        assert_eq!(n, if i == 0 { 3 } else { 2 });
    }
    assert_same(&union(&shards), &full);
    assert_same(&tree(&shared), &full);
}

#[test]
fn depth_perturb_shards_equal_one_run() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("rgb");
    for i in 0..5u8 {
        let px: Vec<u8> = (0..24 * 16 * 3).map(|j| ((j * 7 + i as usize * 31) % 251) as u8).collect();
        write_png(input.join(format!("f{i}.png")), &Image::from_vec(24, 16, 3, px).unwrap()).unwrap();
    }
    let run = |out: &Path, shard: Option<&str>| {
        let mut a = vec!["depth", "perturb", "--input", s(&input), "--out", s(out), "--kinds", "smoke,dark,motion"];
        a.extend(["--severities", "1,3", "--seed", "5"]);
        if let Some(sh) = shard {
            a.extend(["--shard", sh]);
        }
        laparo_ok(&a);
    };
    let full = d.path().join("full");
    run(&full, None);
    let shards: Vec<_> = (0..3)
        .map(|i| {
            let o = d.path().join(format!("shard{i}"));
            run(&o, Some(&format!("{i}/3")));
            tree(&o)
        })
        .collect();
    let full = tree(&full);
    assert_eq!(full.keys().filter(|k| k.to_string_lossy().ends_with(".png")).count(), 5 * 3 * 2);
    assert_same(&union(&shards), &full);
}

const W: usize = 20;
const H: usize = 12;

fn depth_dataset(root: &Path) {
    let rgb = Image::from_vec(W, H, 3, vec![100u8; W * H * 3]).unwrap();
    let gt: Vec<f64> = (0..W * H).map(|i| 0.05 + 0.1 * (i % W) as f64 / W as f64 + 0.01 * (i / W) as f64).collect();
    for scene in ["a", "b"] {
        for (pert, levels) in [("smoke", 3u32), ("dark", 2)] {
            for lv in 0..levels {
                let base = root.join(scene).join(pert).join(format!("s{lv}"));
                for f in 0..2 {
                    let name = format!("{f:04}");
                    write_png(base.join("rgb").join(format!("{name}.png")), &rgb).unwrap();
                    write_npy_f64(
                        base.join("depth").join(format!("{name}.npy")),
                        &Image::from_vec(W, H, 1, gt.clone()).unwrap(),
                    )
                    .unwrap();
                    for (m, k) in [("good", 0.02), ("base", 0.07)] {
                        let noise = k * (1.0 + lv as f64) + 0.01 * f as f64;
                        let p: Vec<f64> = gt
                            .iter()
                            .enumerate()
                            .map(|(i, z)| 2.0 / z * (1.0 + noise * (((i * 7919) % 13) as f64 / 6.0 - 1.0)))
                            .collect();
                        let dir = root.join("predictions").join(m).join(scene).join(pert).join(format!("s{lv}"));
                        write_npy_f64(dir.join(format!("{name}.npy")), &Image::from_vec(W, H, 1, p).unwrap()).unwrap();
                    }
                }
            }
        }
    }
}

#[test]
fn depth_eval_shards_merge_to_one_run() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("data");
    depth_dataset(&root);
    laparo_ok(&["depth", "manifest", "scaffold", "--root", s(&root), "--gt-unit", "m"]);
    let man = root.join("manifest.toml");
    let eval = |out: &Path, extra: &[&str]| {
        let mut a = vec!["depth", "eval", "--manifest", s(&man), "--baseline", "base", "--out", s(out)];
        a.extend(["--error-maps", "b/dark/s1/0000"]);
        a.extend(extra);
        laparo_ok(&a);
    };
    let full = d.path().join("full");
    eval(&full, &[]);
    let sharded = d.path().join("sharded");
    for i in [2, 0, 1] {
        eval(&sharded, &["--shard", &format!("{i}/3")]);
    }
    assert_eq!(std::fs::read_dir(&sharded).unwrap().count(), 3, "a shard writes only its shard file");
    eval(&sharded, &["--merge-shards", "3"]);
    let (full, merged) = (tree(&full), tree(&sharded));
    assert!(full.contains_key(Path::new("results.json")) && full.contains_key(Path::new("per_image.csv")));
    assert_same(&merged, &full);
    // A missing shard is an error naming it.
    let part = d.path().join("part");
    eval(&part, &["--shard", "0/2"]);
    let o = run(&["depth", "eval", "--manifest", s(&man), "--out", s(&part), "--merge-shards", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("1/2") && !err.contains("panicked"), "{err}");
}
