//! `laparo-bench cpc`: mesh + assembly + solve + warp timings of Conformal Perspective Correction
//! at several grid steps on the bumpy-bowl scene of `../shared/bench/cpc_ref/scene.py` (its
//! `scene.npz`, or the Rust port of that scene), for a first frame (new topology) and for a next
//! video frame with the same topology (formerly `laparo cpc bench`).
use crate::timing::{med, vmin};
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::atomic::write_atomic;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::io;
use laparo_cpc::scene;
use laparo_cpc::{metrics, ConformalParams, CpcMesh, CpcSolver, MeshParams, Warp};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `laparo-bench cpc` (those of the former `laparo cpc bench`).
#[derive(Args)]
pub struct BenchArgs {
    /// scene.npz written by ../shared/bench/cpc_ref/scene.py (default: the Rust port of that scene).
    #[arg(long)]
    pub scene_npz: Option<PathBuf>,
    /// Grid steps (px).
    #[arg(long, value_delimiter = ',', default_values_t = vec![8usize, 4, 2])]
    pub steps: Vec<usize>,
    /// Repeats per measurement (median reported).
    #[arg(long, default_value_t = 9)]
    pub repeats: usize,
    /// λ used for the timed solve.
    #[arg(long, default_value_t = 0.9)]
    pub lambda: f64,
    /// Write the figures as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Threads of the numeric Cholesky factorisation (1 = sequential; the result is the same).
    #[arg(long, default_value_t = 1)]
    pub solver_threads: usize,
}

pub fn run(a: BenchArgs) -> Result<()> {
    laparo_cpc::solve::validate_lambda(a.lambda)?;
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    let spec = scene::bumpy_bowl_spec();
    let (image, depth, roi, source) = match &a.scene_npz {
        Some(p) => {
            let d = io::read_npz(p, Some("depth")).with_context(|| format!("reading depth from {}", p.display()))?;
            let depth = DepthMap::new(
                d.width,
                d.height,
                DepthUnit::Mm,
                d.data.iter().map(|&z| if z.is_finite() { z } else { f64::NAN }).collect(),
            )?;
            let img = io::read_npz(p, Some("img")).with_context(|| format!("reading img from {}", p.display()))?;
            let image = img.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8);
            let roi = depth.valid_mask();
            (image, depth, roi, p.display().to_string())
        }
        None => {
            let sc = spec.render()?;
            (sc.image, sc.depth, sc.roi, "Rust port of scene.py".to_string())
        }
    };
    let k = spec.intrinsics;
    println!(
        "bumpy bowl 640x480 ({source}), ROI {} px ({:.1} %), λ = {}, median of {} repeats, {} rayon threads, {} solver thread(s)",
        roi.count(),
        100.0 * roi.count() as f64 / (640.0 * 480.0),
        a.lambda,
        a.repeats,
        rayon::current_num_threads(),
        a.solver_threads
    );
    let pb = ProgressBar::new((a.steps.len() * a.repeats) as u64);
    pb.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}").unwrap());
    let mut rows = Vec::new();
    let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
    for &s in &a.steps {
        let mp = MeshParams { grid_step_px: s, ..MeshParams::default() };
        let conf = ConformalParams::default();
        // Per stage, for a first frame (new topology) and for a next video frame with the same
        // topology (CpcSolver reuses pattern, ordering, symbolic factorisation and buffers).
        let (mut tm, mut ta, mut ts, mut tw, mut tt, mut t20) = (vec![], vec![], vec![], vec![], vec![], vec![]);
        let (mut ta0, mut ta1, mut ta2, mut twn, mut twi) = (vec![], vec![], vec![], vec![], vec![]);
        // Automatic λ (sweep + fit of eq. 4.14) on the default grid (to 1 − 10⁻⁵, 31 λ) and on the
        // grid before issue 11's extension (to 0.999, 27 λ), alternately in the same run.
        let (mut tauto, mut tauto_old) = (vec![], vec![]);
        let grid_new = laparo_cpc::lambda::default_lambda_grid();
        let grid_old: Vec<f64> = grid_new.iter().copied().filter(|&l| l <= 0.999).collect();
        let (mut nm, mut na, mut ns, mut nw, mut nt) = (vec![], vec![], vec![], vec![], vec![]);
        let mut video = CpcSolver::new();
        video.set_factor_threads(a.solver_threads);
        video.assemble(&CpcMesh::build(&roi, &depth, &k, &mp)?, &conf)?;
        // First frames: a solver whose cached topology is forgotten before each frame (a video
        // whose ROI changes); its factor-buffer pool recycles the buffers of dropped topologies.
        let mut first = CpcSolver::new();
        first.set_factor_threads(a.solver_threads);
        let mut last = None;
        for _ in 0..a.repeats {
            pb.set_message(format!("step {s} px"));
            for next in [false, true] {
                if !next {
                    first.clear();
                }
                let solver = if next { &mut video } else { &mut first };
                let t0 = Instant::now();
                let mesh = CpcMesh::build(&roi, &depth, &k, &mp)?;
                let t1 = Instant::now();
                let sys = solver.assemble(&mesh, &conf)?;
                let t2 = Instant::now();
                let p = sys.solve(a.lambda)?;
                let t3 = Instant::now();
                let w = Warp::new(&mesh, p.clone(), 640, 480)?;
                let t3b = Instant::now();
                let (wi, _) = w.warp_image(&image)?;
                let t4 = Instant::now();
                std::hint::black_box(wi);
                if next {
                    if !sys.topology_reused {
                        bail!("the topology was not reused on an identical frame");
                    }
                    nm.push(ms(t0, t1));
                    na.push(ms(t1, t2));
                    ns.push(ms(t2, t3));
                    nw.push(ms(t3, t4));
                    nt.push(ms(t0, t4));
                    continue;
                }
                tm.push(ms(t0, t1));
                ta0.push(sys.assembly_ms[0]);
                ta1.push(sys.assembly_ms[1]);
                ta2.push(sys.assembly_ms[2]);
                ta.push(ms(t1, t2));
                ts.push(ms(t2, t3));
                tw.push(ms(t3, t4));
                twn.push(ms(t3, t3b));
                twi.push(ms(t3b, t4));
                tt.push(ms(t0, t4));
                let t5 = Instant::now();
                for l in (0..20).map(|i| 0.05 + 0.94 * i as f64 / 19.0) {
                    let q = sys.solve(l)?;
                    std::hint::black_box(metrics::delta_area(&q, &mesh.p_init, &mesh.faces));
                }
                t20.push(t5.elapsed().as_secs_f64() * 1e3);
                for (g, out) in [(&grid_old, &mut tauto_old), (&grid_new, &mut tauto)] {
                    let t6 = Instant::now();
                    std::hint::black_box(laparo_cpc::lambda::auto_lambda(&sys, &mesh, g)?.ell);
                    out.push(t6.elapsed().as_secs_f64() * 1e3);
                }
                last = Some((mesh, sys, p));
            }
            pb.inc(1);
        }
        let (mesh, sys, p) = last.unwrap();
        let row = json!({
            "grid_step_px": s, "n_vertices": mesh.n_vertices(), "n_triangles": mesh.n_triangles(), "n_unknowns": sys.n_unknowns(), "nnz": sys.nnz(),
            "complex_unknowns": mesh.n_vertices(), "complex_nnz_lower": sys.topology().nnz_lower(), "complex_factor_len": sys.topology().factor_len(),
            "min_ms_mesh": vmin(&tm), "min_ms_assemble": vmin(&ta), "min_ms_solve": vmin(&ts), "min_ms_warp": vmin(&tw), "min_ms_total": vmin(&tt),
            "min_ms_sweep20": vmin(&t20),
            "min_ms_total_next": vmin(&nt),
            "ms_mesh": med(tm), "ms_assemble": med(ta),
            "ms_assemble_terms": med(ta0), "ms_assemble_values": med(ta1), "ms_assemble_symbolic": med(ta2), "ms_solve": med(ts),
            "ms_warp": med(tw), "ms_warp_new": med(twn), "ms_warp_image": med(twi), "ms_total": med(tt),
            "ms_mesh_next": med(nm), "ms_assemble_next": med(na), "ms_solve_next": med(ns), "ms_warp_next": med(nw), "ms_total_next": med(nt),
            "ms_sweep20": med(t20),
            "ms_auto_lambda": med(tauto.clone()), "ms_auto_lambda_old_grid": med(tauto_old.clone()),
            "min_ms_auto_lambda": vmin(&tauto), "min_ms_auto_lambda_old_grid": vmin(&tauto_old),
            "n_lambda_auto": grid_new.len(), "n_lambda_auto_old_grid": grid_old.len(),
            "angle_error_deg_before": metrics::angle_error_deg(&mesh.p_init, &mesh.x3d, &mesh.faces),
            "angle_error_deg_after": metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces),
            "delta_area": metrics::delta_area(&p, &mesh.p_init, &mesh.faces), "n_flipped": metrics::n_flipped(&p, &mesh.faces),
        });
        rows.push(row);
    }
    pb.finish_and_clear();
    println!("first frame (new topology), then next frame with the same topology (cached symbolic factorisation):");
    println!(
        "{:>5} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>11} {:>11} {:>11} {:>7} {:>6}",
        "step",
        "verts",
        "tris",
        "mesh ms",
        "asm ms",
        "solve ms",
        "warp ms",
        "total ms",
        "asm next",
        "total next",
        "sweep20 ms",
        "angle°",
        "flips"
    );
    for r in &rows {
        let f = |k: &str| r[k].as_f64().unwrap();
        println!(
            "{:>5} {:>8} {:>8} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>11.2} {:>11.2} {:>11.1} {:>7.3} {:>6}",
            r["grid_step_px"],
            r["n_vertices"],
            r["n_triangles"],
            f("ms_mesh"),
            f("ms_assemble"),
            f("ms_solve"),
            f("ms_warp"),
            f("ms_total"),
            f("ms_assemble_next"),
            f("ms_total_next"),
            f("ms_sweep20"),
            f("angle_error_deg_after"),
            r["n_flipped"]
        );
    }
    for r in &rows {
        let f = |k: &str| r[k].as_f64().unwrap();
        println!(
            "step {}: automatic λ (sweep + fit) {:.1} ms over {} λ (min {:.1}), grid to 0.999: {:.1} ms over {} λ (min {:.1}); ratio {:.3}",
            r["grid_step_px"],
            f("ms_auto_lambda"),
            r["n_lambda_auto"],
            f("min_ms_auto_lambda"),
            f("ms_auto_lambda_old_grid"),
            r["n_lambda_auto_old_grid"],
            f("min_ms_auto_lambda_old_grid"),
            f("ms_auto_lambda") / f("ms_auto_lambda_old_grid")
        );
    }
    println!("(medians; minima and the per-stage split of the warp are in --json)");
    if let Some(p) = &a.json {
        let v = json!({"scene": source, "lambda": a.lambda, "repeats": a.repeats, "threads": rayon::current_num_threads(), "solver_threads": a.solver_threads, "rows": rows});
        write_atomic(p, serde_json::to_string_pretty(&v)?.as_bytes())?;
    }
    Ok(())
}
