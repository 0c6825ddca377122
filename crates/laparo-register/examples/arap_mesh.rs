//! ARAP / DRBC / LDDMM baselines on tet meshes (thesis §5.4.2), two modes (not run in CI):
//!
//! `cargo run --release -p laparo-register --example arap_mesh -- compare MESH.msh OUT.json [--scale S]
//!  [--energy spokes|elements] [--iterations N]`: laparo's ARAP with hard constraints only (the
//! lowest 15 % of the nodes along z fixed, the highest 15 % moved by (4, 0, 6) mm × S/10), written with
//! the mesh to OUT.json for `scripts/arap_vs_libigl.py`, which runs libigl's `igl.arap` on the same
//! problem and compares.
//!
//! `cargo run --release -p laparo-register --example arap_mesh -- timing [--cells N] [--only arap|drbc|lddmm]
//!  [--arap-iterations N] [--verbose]`: wall time of the
//! three baselines on an N³-cell box (default 16: 4,913 nodes, 24,576 tets, 6 mm cells) with 50
//! landmarks in two "lip" groups pulled apart, scored against polylines, bottom face fixed.
use laparo_register::baselines::*;
use laparo_register::distance::Polyline;
use laparo_register::loss::GroupTarget;
use nalgebra::Vector3;
use std::sync::Arc;

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn compare(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let (mesh_path, out) = (&args[1], &args[2]);
    let scale: f64 = arg(args, "--scale", 10.0);
    let iterations: usize = arg(args, "--iterations", 50);
    let energy = match arg(args, "--energy", "elements".to_string()).as_str() {
        "spokes" => ArapEnergy::Spokes,
        _ => ArapEnergy::Elements,
    };
    let mut mesh = laparo_core::mesh::read_msh(mesh_path)?;
    for v in &mut mesh.vertices {
        *v *= scale;
    }
    let n = mesh.vertices.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| mesh.vertices[a].z.total_cmp(&mesh.vertices[b].z).then(a.cmp(&b)));
    let m = (0.15 * n as f64).ceil() as usize;
    let shift = Vector3::new(4.0, 0.0, 6.0) * (scale / 10.0);
    let mut p = BaselineProblem::new(mesh.clone(), vec![]);
    p.fix_at_rest(&order[..m]);
    for &i in &order[n - m..] {
        p.fixed.push((i, mesh.vertices[i] + shift));
    }
    let cfg = ArapConfig { energy, iterations, tolerance_mm: 0.0, ..Default::default() };
    // best of 3 (same run) to time the solver, not the page cache
    let mut best = f64::INFINITY;
    let mut res = None;
    for _ in 0..3 {
        let r = arap(&p, &cfg)?;
        best = best.min(r.report.seconds);
        res = Some(r);
    }
    let res = res.expect("ran");
    let json = serde_json::json!({
        "vertices": mesh.vertices.iter().map(|v| [v.x, v.y, v.z]).collect::<Vec<_>>(),
        "tets": mesh.tets,
        "fixed": p.fixed.iter().map(|f| f.0).collect::<Vec<_>>(),
        "fixed_positions": p.fixed.iter().map(|f| [f.1.x, f.1.y, f.1.z]).collect::<Vec<_>>(),
        "energy": format!("{energy:?}").to_lowercase(),
        "iterations": iterations,
        "laparo_positions": res.positions.iter().map(|v| [v.x, v.y, v.z]).collect::<Vec<_>>(),
        "laparo_seconds": best,
    });
    laparo_core::atomic::write_atomic(std::path::Path::new(out), serde_json::to_string(&json)?.as_bytes())?;
    println!(
        "{} nodes, {} tets, {} fixed; laparo ARAP ({energy:?}, {iterations} it): {best:.4} s",
        n,
        mesh.tets.len(),
        p.fixed.len()
    );
    Ok(())
}

fn timing(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let c: usize = arg(args, "--cells", 16);
    let h = 6.0;
    let mesh = box_tet_mesh([c, c, c], h, Vector3::zeros());
    let top = c as f64 * h;
    let mid = 0.5 * top;
    let node_at = |x: f64, y: f64, z: f64| {
        (0..mesh.vertices.len())
            .min_by(|&a, &b| {
                let pa = (mesh.vertices[a] - Vector3::new(x, y, z)).norm();
                let pb = (mesh.vertices[b] - Vector3::new(x, y, z)).norm();
                pa.total_cmp(&pb)
            })
            .expect("nodes")
    };
    let mut groups = Vec::new();
    for (name, side) in [("left lip", -1.0), ("right lip", 1.0)] {
        let pts: Vec<MaterialPoint> = (0..25)
            .map(|k| {
                let x = 0.1 * top + 0.8 * top * k as f64 / 24.0;
                MaterialPoint::node(node_at(x, mid + side * h, top))
            })
            .collect();
        // the lip opens by 4 mm and sinks 3 mm, as a smooth curve
        let line: Vec<Vector3<f64>> = (0..=40)
            .map(|k| {
                let x = k as f64 / 40.0 * top;
                let s = (std::f64::consts::PI * x / top).sin();
                Vector3::new(x, mid + side * (h + 4.0 * s), top - 3.0 * s)
            })
            .collect();
        groups.push(MeshLandmarkGroup {
            name: name.into(),
            points: pts,
            target: GroupTarget::Shared(Arc::new(Polyline::open(line))),
            weight: 1.0,
        });
    }
    let mut p = BaselineProblem::new(mesh.clone(), groups);
    let bottom: Vec<usize> = (0..mesh.vertices.len()).filter(|&i| mesh.vertices[i].z == 0.0).collect();
    p.fix_at_rest(&bottom);
    println!(
        "box {c}^3 cells: {} nodes, {} tets, {} landmarks, {} fixed",
        mesh.vertices.len(),
        mesh.tets.len(),
        p.landmark_count(),
        p.fixed.len()
    );
    let show = |r: &BaselineResult| {
        let maxd = r.positions.iter().zip(&mesh.vertices).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        println!(
            "{:6}: {:7.3} s, {:4} it, converged {}, mean landmark distance {:.3} -> {:.4} mm, max displacement {:.2} mm",
            r.report.method, r.report.seconds, r.report.iterations, r.report.converged,
            r.report.initial_mean_distance_mm, r.report.mean_distance_mm, maxd
        );
    };
    let only: String = arg(args, "--only", String::new());
    let verbose = args.iter().any(|a| a == "--verbose");
    let show = |r: &BaselineResult| {
        show(r);
        if verbose {
            println!(
                "  history (mm): {:?}",
                r.report.history_mm.iter().map(|d| (d * 1e4).round() / 1e4).collect::<Vec<_>>()
            );
        }
    };
    if only.is_empty() || only == "arap" {
        let iterations: usize = arg(args, "--arap-iterations", ArapConfig::default().iterations);
        show(&arap(&p, &ArapConfig { iterations, ..Default::default() })?);
        show(&arap(&p, &ArapConfig { energy: ArapEnergy::Elements, iterations, ..Default::default() })?);
    }
    if only.is_empty() || only == "drbc" {
        show(&drbc(&p, &DrbcConfig::default())?);
    }
    if only.is_empty() || only == "lddmm" {
        show(&lddmm(&p, &LddmmConfig::default())?);
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(|s| s.as_str()) {
        Some("compare") if args.len() >= 3 => compare(&args),
        Some("timing") => timing(&args),
        _ => {
            eprintln!("usage: arap_mesh compare MESH.msh OUT.json [--scale S] [--energy spokes|elements] [--iterations N]\n       arap_mesh timing [--cells N]");
            std::process::exit(2)
        }
    }
}
