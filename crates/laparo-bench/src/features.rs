//! `laparo-bench features`: detect + describe time per 640×480 image (SIFT, ORB; one thread by
//! default) and detector quality on the shared textures, with the OpenCV peer
//! `../shared/bench/features_ref.py` run in the same session; brute-force matching times
//! (2000 × 2000 Hamming, 2000 × 2000 SIFT L2).
use crate::timing::time_min_median;
use anyhow::{Context, Result};
use clap::Args;
use laparo_features::refcheck::{evaluate_homography, load_gray_crop, similarity_h};
use laparo_features::{
    detect_and_describe, match_features, Descriptors, DetectorConfig, Features, Keypoint, MatchConfig,
};
use rand::{Rng, SeedableRng};
use std::path::PathBuf;

/// Options of `laparo-bench features`.
#[derive(Args)]
pub struct BenchArgs {
    /// Images (default: brick, gravel, retina, coffee of ../shared/data/textures).
    #[arg(long, num_args = 1..)]
    pub images: Vec<PathBuf>,
    /// Timed runs per image and detector (after one warm-up; minimum and median reported).
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// Threads for laparo (rayon) and OpenCV.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Python with numpy + opencv-python-headless<5: run the peer script in the same session.
    #[arg(long)]
    pub peer_python: Option<PathBuf>,
    /// The peer script.
    #[arg(long, default_value = "../shared/bench/features_ref.py")]
    pub peer_script: PathBuf,
}

/// CPU time of this process, ms (CLOCK_PROCESS_CPUTIME_ID): on a shared, loaded machine the
/// wall time of a long single-threaded job is inflated by the other jobs' share of the cores,
/// its CPU time is not.
fn cpu_ms() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes into the timespec we own.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 * 1e3 + ts.tv_nsec as f64 * 1e-6
}

/// One untimed warm-up, then the minimum CPU time (ms) of `runs` calls.
fn cpu_min(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    (0..runs.max(1))
        .map(|_| {
            let t = cpu_ms();
            f();
            cpu_ms() - t
        })
        .fold(f64::INFINITY, f64::min)
}

/// OpenCV detect+describe CPU time on the peer's own images (its `load_gray`), one thread.
const PEER_CPU: &str = r#"
import sys, json, time, importlib.util, cv2
spec = importlib.util.spec_from_file_location("fr", sys.argv[1]); fr = importlib.util.module_from_spec(spec); spec.loader.exec_module(fr)
cv2.setNumThreads(1); runs = int(sys.argv[2]); out = {}
for p in sys.argv[3:]:
    img = fr.load_gray(p, 640, 480)
    for name, det in (("SIFT", cv2.SIFT_create()), ("ORB", cv2.ORB_create(nfeatures=2000))):
        det.detectAndCompute(img, None); ts = []
        for _ in range(runs):
            t = time.process_time(); det.detectAndCompute(img, None); ts.append(time.process_time() - t)
        out[p.split("/")[-1] + ":" + name] = 1000 * min(ts)
print(json.dumps(out))
"#;

fn random_features(n: usize, binary: bool, seed: u64) -> Features {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let keypoints = vec![Keypoint { x: 0.0, y: 0.0, size_px: 1.0, angle_rad: 0.0, response: 0.0, octave: 0 }; n];
    let descriptors = if binary {
        Descriptors::Binary { bytes: 32, data: (0..n * 32).map(|_| rng.gen()).collect() }
    } else {
        Descriptors::Float { dim: 128, data: (0..n * 128).map(|_| rng.gen_range(0.0..64.0f32)).collect() }
    };
    Features { keypoints, descriptors }
}

pub fn run(a: BenchArgs) -> Result<()> {
    let images = if a.images.is_empty() {
        ["brick.png", "gravel.png", "retina.jpg", "coffee.png"]
            .iter()
            .map(|n| PathBuf::from("../shared/data/textures").join(n))
            .collect()
    } else {
        a.images.clone()
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build()?;
    let h = similarity_h(30.0, 0.8, 319.5, 239.5);
    let mut results = serde_json::Map::new();
    for p in &images {
        let img = load_gray_crop(p, 640, 480).with_context(|| format!("reading {}", p.display()))?;
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        for det in ["sift", "orb"] {
            let cfg = DetectorConfig::by_name(det)?;
            let q = evaluate_homography(&img, &cfg, &h, &MatchConfig::default(), 3.0)?;
            let t = pool.install(|| {
                time_min_median(a.runs, || {
                    std::hint::black_box(detect_and_describe(&img, &cfg, None).expect("valid image"));
                })
            });
            let tc = pool.install(|| {
                cpu_min(a.runs, || {
                    std::hint::black_box(detect_and_describe(&img, &cfg, None).expect("valid image"));
                })
            });
            println!(
                "{name:12} {:5} kp {:5}  rep {:.3}  prec {:.3}  MS {:.3}  matches {:5}  t {:.1} ms (min) / {:.1} (median)  cpu {:.1} ms (min)",
                det.to_uppercase(), q.kp1, q.repeatability, q.precision, q.matching_score, q.matches, t.0, t.1, tc
            );
            results.insert(
                format!("{name}:{}", det.to_uppercase()),
                serde_json::json!({
                    "kp1": q.kp1, "repeatability": q.repeatability, "precision": q.precision,
                    "matching_score": q.matching_score, "matches": q.matches,
                    "ms_detect_describe_min": t.0, "ms_detect_describe_median": t.1, "cpu_ms_min": tc,
                }),
            );
        }
    }
    let (ha, hb) = (random_features(2000, true, 1), random_features(2000, true, 2));
    let (fa, fb) = (random_features(2000, false, 3), random_features(2000, false, 4));
    let cfg = MatchConfig::default();
    let tham_cpu = pool.install(|| {
        cpu_min(a.runs.max(5), || {
            std::hint::black_box(match_features(&ha, &hb, &MatchConfig { mutual: false, ..cfg }).expect("same kind"));
        })
    });
    let (tham, tl2) = pool.install(|| {
        (
            time_min_median(a.runs.max(5), || {
                std::hint::black_box(match_features(&ha, &hb, &cfg).expect("same kind"));
            }),
            time_min_median(a.runs.max(3), || {
                std::hint::black_box(match_features(&fa, &fb, &cfg).expect("same kind"));
            }),
        )
    });
    // The timed matcher runs both directions (mutual check): report that and one direction.
    let one_way = MatchConfig { mutual: false, ..cfg };
    let tham1 = pool.install(|| {
        time_min_median(a.runs.max(5), || {
            std::hint::black_box(match_features(&ha, &hb, &one_way).expect("same kind"));
        })
    });
    println!("matching 2000x2000 Hamming (32 B): one-way {:.2} ms (cpu {:.2}), mutual {:.2} ms (min); SIFT L2 (128-D) mutual {:.1} ms (min); {} thread(s)", tham1.0, tham_cpu, tham.0, tl2.0, a.threads);
    results.insert("match_hamming_2000x2000".into(), serde_json::json!({"one_way_min_ms": tham1.0, "one_way_cpu_min_ms": tham_cpu, "mutual_min_ms": tham.0, "mutual_median_ms": tham.1}));
    results.insert("match_l2_2000x2000".into(), serde_json::json!({"mutual_min_ms": tl2.0, "mutual_median_ms": tl2.1}));
    let mut out = serde_json::json!({"laparo": env!("CARGO_PKG_VERSION"), "threads": a.threads, "results": results});
    if let Some(py) = &a.peer_python {
        let tmp = std::env::temp_dir().join(format!("features_ref_{}.json", std::process::id()));
        let o = std::process::Command::new(py)
            .arg(&a.peer_script)
            .args(&images)
            .args([
                "--detectors",
                "SIFT,ORB",
                "--threads",
                &a.threads.to_string(),
                "--repeats",
                &a.runs.to_string(),
                "--json",
            ])
            .arg(&tmp)
            .output()
            .with_context(|| format!("running {} {}", py.display(), a.peer_script.display()))?;
        if !o.status.success() {
            anyhow::bail!("peer failed: {}", String::from_utf8_lossy(&o.stderr));
        }
        print!("{}", String::from_utf8_lossy(&o.stdout));
        let peer: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&tmp)?)?;
        let _ = std::fs::remove_file(&tmp);
        println!(
            "ratio laparo / OpenCV {} (detect+describe, min of {} runs, {} thread(s)):",
            peer["opencv"], a.runs, a.threads
        );
        for (k, v) in &out["results"].as_object().cloned().unwrap_or_default() {
            if let (Some(l), Some(c)) =
                (v["ms_detect_describe_min"].as_f64(), peer["results"][k]["ms_detect_describe_min"].as_f64())
            {
                println!("  {k:20} laparo {l:8.1} ms  OpenCV {c:8.1} ms  ratio {:.2}", l / c);
            }
        }
        out["peer"] = peer;
        if a.threads == 1 {
            let o = std::process::Command::new(py)
                .args(["-c", PEER_CPU])
                .arg(&a.peer_script)
                .arg(a.runs.to_string())
                .args(&images)
                .output()
                .context("running the OpenCV CPU-time peer")?;
            if !o.status.success() {
                anyhow::bail!("CPU-time peer failed: {}", String::from_utf8_lossy(&o.stderr));
            }
            let cpu: serde_json::Value = serde_json::from_slice(&o.stdout)?;
            println!("ratio laparo / OpenCV, process CPU time (min of {} runs, 1 thread):", a.runs);
            for (k, v) in &out["results"].as_object().cloned().unwrap_or_default() {
                if let (Some(l), Some(c)) = (v["cpu_ms_min"].as_f64(), cpu[k].as_f64()) {
                    println!("  {k:20} laparo {l:8.1} ms  OpenCV {c:8.1} ms  ratio {:.2}", l / c);
                }
            }
            out["peer_cpu_ms_min"] = cpu;
        }
    }
    println!("{}", serde_json::to_string(&out)?);
    Ok(())
}
