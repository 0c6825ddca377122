//! `laparo`: the command-line interface of the laparo toolkit.
//!
//! One subcommand per module, in the order of the guidance pipeline (thesis Fig. 1.3):
//! `depth` (RoDEM), `cats` / `stereo` (CATS), `cpc`, `mpm`, and `demo`, which runs every module
//! on built-in data and writes an HTML report.
use clap::{Parser, Subcommand};

mod cmd;
mod demo;

#[derive(Parser)]
#[command(
    name = "laparo",
    version,
    about = "Vision-based surgical guidance: depth robustness, stereo camera augmentation, conformal perspective correction, differentiable MPM registration"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// RoDEM: accuracy and robustness of monocular depth estimation (thesis §3.2, App. C).
    #[command(subcommand)]
    Depth(cmd::depth::DepthCmd),
    /// CATS: camera augmentation for uncalibrated stereo laparoscopes (thesis §3.3).
    #[command(subcommand)]
    Cats(cmd::cats::CatsCmd),
    /// Calibrated stereo: rectification, disparity/depth, evaluation (thesis §2.2, §3.3).
    #[command(subcommand)]
    Stereo(cmd::stereo::StereoCmd),
    /// Conformal Perspective Correction (thesis Ch. 4).
    #[command(subcommand)]
    Cpc(cmd::cpc::CpcCmd),
    /// Differentiable Material Point Method simulation (thesis §5.2.3–5.2.4).
    #[command(subcommand)]
    Mpm(cmd::mpm::MpmCmd),
    /// RODS-MPM deformable registration (thesis Ch. 5) and rigid alignment (App. A).
    Register(Box<cmd::register::RegisterArgs>),
    /// Volume meshing and incisions for the in-silico incision benchmark (thesis §5.4.2).
    #[command(subcommand)]
    Mesh(cmd::mesh::MeshCmd),
    /// The guidance pipeline end to end in silico: scenario, stereo, rigid, RODS-MPM, overlay (thesis §5.4.3).
    Guide(Box<cmd::guide::GuideArgs>),
    /// Keypoints, descriptors, matching and COLMAP export (thesis §4.2, §4.5).
    #[command(subcommand)]
    Features(cmd::features::FeaturesCmd),
    /// FEM ground truth of the in-silico incision benchmark: Neo-Hookean TET10 (thesis §5.4.2).
    #[command(subcommand)]
    Fem(cmd::fem::FemCmd),
    /// Run every module on built-in data and write an HTML report.
    Demo(demo::DemoArgs),
    /// Benchmarks moved to the separate `laparo-bench` binary (this only says how to run it).
    Bench {
        /// Ignored; pass them to `laparo-bench`.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
        args: Vec<String>,
    },
}

/// Die quietly of SIGPIPE when stdout is closed early (`laparo … | head -1`), as Unix tools do:
/// Rust ignores SIGPIPE, so every `println!` after the reader left would panic with a backtrace
/// (exit 101). With the default action the process ends at the first write to the closed pipe,
/// which the shell reports as 141 without a message; files are written atomically, so nothing is
/// left half-written.
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_DFL at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() {
    restore_sigpipe();
    let cli = Cli::parse();
    let run = move || match cli.command {
        Command::Depth(c) => cmd::depth::run(c),
        Command::Cats(c) => cmd::cats::run(c),
        Command::Stereo(c) => cmd::stereo::run(c),
        Command::Cpc(c) => cmd::cpc::run(c),
        Command::Mpm(c) => cmd::mpm::run(c),
        Command::Register(a) => cmd::register::run(*a),
        Command::Mesh(c) => cmd::mesh::run(c),
        Command::Features(c) => cmd::features::run(c),
        Command::Fem(c) => cmd::fem::run(c),
        Command::Guide(a) => cmd::guide::run(*a),
        Command::Demo(a) => demo::run(a),
        Command::Bench { .. } => Err(anyhow::anyhow!(
            "the benchmarks are not part of `laparo`; run `laparo-bench <depth|cats|stereo|cpc|mpm> ...` \
             (`cargo run --release -p laparo-bench -- --help`, see BENCHMARKS.md)"
        )),
    };
    // The command runs on a worker of the rayon pool, not on the main thread: the library's
    // parallel regions (thousands per MPM run, a dozen per CPC frame) then start and end on a pool
    // thread instead of being injected from outside and waking a blocked main thread each time
    // (measured: MPM 2D forward+backward 0.12 → 0.09 s per iteration). 8 MiB stacks, as the main
    // thread has.
    let result = match rayon::ThreadPoolBuilder::new().stack_size(8 << 20).build() {
        Ok(pool) => pool.install(run),
        Err(_) => run(),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
