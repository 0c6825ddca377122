//! `laparo-bench`: the timing harnesses of the laparo modules, kept out of the product (the
//! `laparo` CLI and the libraries hold only what users call).
//!
//! One subcommand per module, each timing the same work as before issue 10's `laparo <group>
//! bench`, with the same options and output: `depth` (RoDEM per-image evaluation, optionally
//! against numpy `depth_eval_ref.py`), `cats` (homography warps, optionally against OpenCV
//! `warp_ref.py`), `stereo` (rectification maps + remap), `cpc` (mesh + assembly + solve + warp)
//! and `mpm` (forward and forward+backward of the DiffTaichi RODS box problem). Peer scripts live
//! in `../shared/bench/`; `scripts/bench_vs_peers.sh` and `scripts/bench_before_after.sh` drive
//! this binary.
use clap::{Parser, Subcommand};

mod cats;
mod cpc;
mod depth;
mod features;
mod fem;
mod geo;
mod mpm;
mod register;
mod stereo;
mod stereo_match;
mod timing;

#[derive(Parser)]
#[command(name = "laparo-bench", version, about = "Timing harnesses of laparo and same-input peer comparisons")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Time the per-image evaluation (3 alignments, 640x480) against the numpy reference.
    Depth(depth::BenchArgs),
    /// Benchmark the CATS warps against OpenCV warpPerspective (../shared/bench/warp_ref.py).
    Cats(cats::BenchArgs),
    /// Time rectification (map building and bilinear remap of both images) on a real pair.
    Stereo(stereo::BenchArgs),
    /// Time CPC mesh + assembly + solve + warp at several grid steps on the bumpy-bowl scene.
    Cpc(cpc::BenchArgs),
    /// MPM forward and forward+backward wall time per iteration on the DiffTaichi RODS box problem.
    Mpm(mpm::BenchArgs),
    /// RODS-MPM registration on the thesis 3D configuration (optionally vs DiffTaichi, same session).
    Register(register::BenchArgs),
    /// SGM matching (laparo_stereo::match_pair) against OpenCV StereoSGBM (../shared/bench/sgbm_ref.py), interleaved.
    StereoMatch(stereo_match::BenchArgs),
    /// SIFT/ORB detect+describe and matching vs OpenCV (../shared/bench/features_ref.py).
    Features(features::BenchArgs),
    /// RANSAC H/F and self-rectification timings (optionally against OpenCV stereoRectifyUncalibrated).
    Geo(geo::BenchArgs),
    /// FEM ground truth: fill and time of the tangent's Cholesky with AMD vs nested dissection (P2ILF liver).
    Fem(fem::BenchArgs),
}

fn main() {
    let cli = Cli::parse();
    let run = move || match cli.command {
        Command::Depth(a) => depth::run(a),
        Command::Cats(a) => cats::run(a),
        Command::Stereo(a) => stereo::run(a),
        Command::Cpc(a) => cpc::run(a),
        Command::Mpm(a) => mpm::run(a),
        Command::Register(a) => register::run(a),
        Command::StereoMatch(a) => stereo_match::run(a),
        Command::Features(a) => features::run(a),
        Command::Geo(a) => geo::run(a),
        Command::Fem(a) => fem::run(a),
    };
    // As the `laparo` CLI: the command runs on a worker of the rayon pool (8 MiB stacks), so the
    // libraries' parallel regions start and end on a pool thread; timings are then those a
    // `laparo` user sees.
    let result = match rayon::ThreadPoolBuilder::new().stack_size(8 << 20).build() {
        Ok(pool) => pool.install(run),
        Err(_) => run(),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
