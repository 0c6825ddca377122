//! `laparo-bench stereo-match`: laparo's SGM (`laparo_stereo::match_pair`) and OpenCV StereoSGBM
//! (`../shared/bench/sgbm_ref.py`) on the same input and range, interleaved round by round
//! (the machine is shared: best-of over rounds). With a GT disparity it prints the metrics of
//! `sgbm_ref.py` for both: density, EPE and Bad-k over valid pixels and with invalid pixels
//! filled by the row background.
use anyhow::{bail, Context};
use clap::Args;
use laparo_core::image::Image;
use laparo_stereo::{fill_background, match_pair_with, Paths, SgmParams, SgmWorkspace};
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

/// Options.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Left image (default: the shared Middlebury Motorcycle pair).
    #[arg(long)]
    pub left: Option<PathBuf>,
    /// Right image.
    #[arg(long)]
    pub right: Option<PathBuf>,
    /// GT disparity (PFM/NPY/NPZ, left view); default the Motorcycle GT with the default pair.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// No GT: timings and disparity statistics only.
    #[arg(long)]
    pub no_gt: bool,
    /// Disparity range [LO, HI) (px).
    #[arg(long, num_args = 2, value_names = ["LO", "HI"], allow_hyphen_values = true, default_values_t = [0, 64])]
    pub range: Vec<i32>,
    /// laparo modes: comma list of `default` (4 paths), `accurate` (8 paths).
    #[arg(long, default_value = "default,accurate")]
    pub modes: String,
    /// Rounds (laparo then OpenCV in each round; best-of over rounds).
    #[arg(long, default_value_t = 3)]
    pub rounds: usize,
    /// Timed calls per mode per round (after one warm-up).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// The OpenCV peer script; skipped when absent.
    #[arg(long, default_value = "../shared/bench/sgbm_ref.py")]
    pub peer: PathBuf,
    /// OpenCV modes for the peer (comma list of SGBM, SGBM_3WAY, HH, HH4).
    #[arg(long, default_value = "SGBM_3WAY,HH4")]
    pub peer_modes: String,
    /// OpenCV block sizes (comma list).
    #[arg(long, default_value = "5")]
    pub peer_blocks: String,
    /// Python interpreter.
    #[arg(long, default_value = "python3")]
    pub python: String,
    /// Override P1 of the laparo modes (census bits).
    #[arg(long)]
    pub p1: Option<u16>,
    /// Override P2 of the laparo modes.
    #[arg(long)]
    pub p2: Option<u16>,
    /// Override the P2 adaptation γ of the laparo modes.
    #[arg(long)]
    pub gamma: Option<u16>,
    /// Override the uniqueness margin (%) of the laparo modes.
    #[arg(long)]
    pub uniqueness: Option<u8>,
    /// Write each laparo mode's disparity and confidence here (`<mode>_disparity.pfm`,
    /// `<mode>_confidence.pfm`, first round) to compare builds bit for bit.
    #[arg(long)]
    pub save: Option<PathBuf>,
    /// Write all figures here (JSON).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

const MB: &str = "../shared/data/middlebury-motorcycle";

/// Metrics of one prediction as `sgbm_ref.py` computes them (strict > k).
fn metrics(pred: &[f32], gt: &Image<f64>) -> serde_json::Value {
    let (w, h) = (gt.width, gt.height);
    let mut filled = pred.to_vec();
    fill_background(&mut filled, w, h);
    let (mut n, mut nb, mut ev, mut ef) = (0usize, 0usize, 0f64, 0f64);
    let ks = [1.0, 2.0, 3.0];
    let (mut bv, mut bf) = ([0usize; 3], [0usize; 3]);
    for i in 0..w * h {
        let g = gt.data[i];
        if !g.is_finite() {
            continue;
        }
        n += 1;
        let f = if filled[i].is_finite() { filled[i] as f64 } else { 0.0 };
        let e = (f - g).abs();
        ef += e;
        for (j, k) in ks.iter().enumerate() {
            if e > *k {
                bf[j] += 1;
            }
        }
        if pred[i].is_finite() {
            nb += 1;
            let e = (pred[i] as f64 - g).abs();
            ev += e;
            for (j, k) in ks.iter().enumerate() {
                if e > *k {
                    bv[j] += 1;
                }
            }
        }
    }
    let pct = |c: usize, m: usize| 100.0 * c as f64 / m.max(1) as f64;
    serde_json::json!({
        "density": nb as f64 / n.max(1) as f64,
        "epe_valid": ev / nb.max(1) as f64, "epe_filled": ef / n.max(1) as f64,
        "bad1_valid": pct(bv[0], nb), "bad2_valid": pct(bv[1], nb), "bad3_valid": pct(bv[2], nb),
        "bad1_filled": pct(bf[0], n), "bad2_filled": pct(bf[1], n), "bad3_filled": pct(bf[2], n),
    })
}

fn params(a: &BenchArgs, mode: &str, lo: i32, hi: i32) -> anyhow::Result<SgmParams> {
    let mut p = match mode {
        "default" => SgmParams::new(lo, hi),
        "accurate" => SgmParams::accurate(lo, hi),
        m => bail!("unknown laparo mode {m:?} (default, accurate)"),
    };
    p.p1 = a.p1.unwrap_or(p.p1);
    p.p2 = a.p2.unwrap_or(p.p2);
    p.p2_gamma = a.gamma.unwrap_or(p.p2_gamma);
    p.uniqueness_pct = a.uniqueness.unwrap_or(p.uniqueness_pct);
    Ok(p)
}

/// Run the benchmark.
pub fn run(a: BenchArgs) -> anyhow::Result<()> {
    let default_pair = a.left.is_none();
    let left = a.left.clone().unwrap_or_else(|| PathBuf::from(format!("{MB}/motorcycle_left.png")));
    let right = a.right.clone().unwrap_or_else(|| PathBuf::from(format!("{MB}/motorcycle_right.png")));
    let gt_path = if a.no_gt {
        None
    } else {
        a.gt.clone().or_else(|| default_pair.then(|| PathBuf::from(format!("{MB}/motorcycle_disp.npy"))))
    };
    let l = laparo_core::io::read_image(&left).with_context(|| format!("left image {}", left.display()))?;
    let r = laparo_core::io::read_image(&right).with_context(|| format!("right image {}", right.display()))?;
    let gt = match &gt_path {
        Some(p) => Some(laparo_core::io::read_float_map(p).with_context(|| format!("GT {}", p.display()))?),
        None => None,
    };
    let (lo, hi) = (a.range[0], a.range[1]);
    let threads = rayon::current_num_threads();
    println!(
        "stereo-match: {} {}x{}, range [{lo}, {hi}), {threads} threads, {} rounds x {} repeats, best-of",
        left.display(),
        l.width,
        l.height,
        a.rounds,
        a.repeats
    );
    let modes: Vec<String> = a.modes.split(',').map(|s| s.trim().to_string()).collect();
    let mut best_ms: Vec<f64> = vec![f64::INFINITY; modes.len()];
    let mut acc: Vec<serde_json::Value> = vec![serde_json::Value::Null; modes.len()];
    let mut peer_best: std::collections::BTreeMap<String, (f64, serde_json::Value)> = Default::default();
    let have_peer = a.peer.exists();
    if !have_peer {
        println!("SKIP peer: {} not found", a.peer.display());
    }
    for round in 0..a.rounds.max(1) {
        for (mi, m) in modes.iter().enumerate() {
            let p = params(&a, m, lo, hi)?;
            // One workspace per mode, reused by its repeats (a video matches pair after pair).
            let mut ws = SgmWorkspace::new();
            let mut out = match_pair_with(&mut ws, &l, &r, &p)?; // warm-up
            for _ in 0..a.repeats.max(1) {
                let t = Instant::now();
                out = match_pair_with(&mut ws, &l, &r, &p)?;
                best_ms[mi] = best_ms[mi].min(t.elapsed().as_secs_f64() * 1e3);
            }
            if round == 0 {
                if let Some(dir) = &a.save {
                    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
                    laparo_core::io::write_pfm(dir.join(format!("{m}_disparity.pfm")), &out.disparity)?;
                    laparo_core::io::write_pfm(dir.join(format!("{m}_confidence.pfm")), &out.confidence)?;
                }
                let mut v = match &gt {
                    Some(g) => metrics(&out.disparity.data, g),
                    None => serde_json::json!({}),
                };
                let valid: Vec<f32> = out.disparity.data.iter().cloned().filter(|d| d.is_finite()).collect();
                v["valid_share_image"] = serde_json::json!(valid.len() as f64 / out.disparity.data.len() as f64);
                v["paths"] = serde_json::json!(if p.paths == Paths::Eight { 8 } else { 4 });
                v["avx2"] = serde_json::json!(out.stats.avx2);
                acc[mi] = v;
            }
        }
        if have_peer {
            let tmp = std::env::temp_dir().join(format!("laparo_sgbm_{}.json", std::process::id()));
            let mut cmd = Command::new(&a.python);
            cmd.arg(&a.peer)
                .args(["--left", &left.to_string_lossy(), "--right", &right.to_string_lossy()])
                .args(["--range", &lo.to_string(), &hi.to_string()])
                .args(["--modes", &a.peer_modes, "--blocks", &a.peer_blocks, "--threads", &threads.to_string()])
                .args(["--repeats", &a.repeats.to_string(), "--json", &tmp.to_string_lossy()]);
            match &gt_path {
                Some(g) => cmd.args(["--gt", &g.to_string_lossy()]),
                None => cmd.arg("--no-gt"),
            };
            let o = cmd.output().context("running the OpenCV peer")?;
            if !o.status.success() {
                bail!("peer failed: {}", String::from_utf8_lossy(&o.stderr));
            }
            let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&tmp)?)?;
            let _ = std::fs::remove_file(&tmp);
            for rec in j["results"].as_array().cloned().unwrap_or_default() {
                let key = format!("OpenCV {} bs{}", rec["mode"].as_str().unwrap_or("?"), rec["block"]);
                let ms = rec["ms_min"].as_f64().unwrap_or(f64::INFINITY);
                let e = peer_best.entry(key).or_insert((f64::INFINITY, rec.clone()));
                if ms < e.0 {
                    *e = (ms, rec);
                }
            }
        }
    }
    let ref_ms = peer_best.iter().find(|(k, _)| k.contains("SGBM_3WAY")).map(|(_, v)| v.0);
    println!(
        "| method | ms (best of {}) | vs 3WAY | density | EPE valid | EPE filled | Bad-1 f % | Bad-2 f % | Bad-3 f % |",
        a.rounds * a.repeats
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let row = |name: &str, ms: f64, v: &serde_json::Value| {
        let f = |k: &str| v[k].as_f64().map(|x| format!("{x:.3}")).unwrap_or("—".into());
        let ratio = ref_ms.map(|r| format!("{:.2}×", ms / r)).unwrap_or("—".into());
        println!(
            "| {name} | {ms:.1} | {ratio} | {} | {} | {} | {} | {} | {} |",
            f("density"),
            f("epe_valid"),
            f("epe_filled"),
            f("bad1_filled"),
            f("bad2_filled"),
            f("bad3_filled")
        );
    };
    let mut all = serde_json::Map::new();
    for (mi, m) in modes.iter().enumerate() {
        row(&format!("laparo {m}"), best_ms[mi], &acc[mi]);
        let mut v = acc[mi].clone();
        v["ms_best"] = serde_json::json!(best_ms[mi]);
        all.insert(format!("laparo {m}"), v);
    }
    for (k, (ms, rec)) in &peer_best {
        row(k, *ms, rec);
        all.insert(k.clone(), rec.clone());
    }
    if let Some(p) = &a.json {
        laparo_core::atomic::write_atomic(
            p,
            serde_json::to_string_pretty(&serde_json::Value::Object(all))?.as_bytes(),
        )?;
    }
    Ok(())
}
