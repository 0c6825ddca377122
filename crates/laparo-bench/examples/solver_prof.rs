//! Solver stage profile on the bumpy bowl (development aid):
//! `cargo run --release -p laparo-bench --example solver_prof -- [STEP] [REPEATS] [MODE]`.
use laparo_cpc::ordering::nested_dissection_leaf;
use laparo_cpc::scene::bumpy_bowl_spec;
use laparo_cpc::{ConformalParams, CpcMesh, CpcSystem, CpcTopology, MeshParams};
use std::time::Instant;

fn med(mut v: Vec<f64>) -> f64 {
    laparo_core::stats::median(&mut v)
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let step: usize = a.get(1).map_or(4, |s| s.parse().unwrap());
    let reps: usize = a.get(2).map_or(15, |s| s.parse().unwrap());
    let mode = a.get(3).cloned().unwrap_or_else(|| "all".into());
    let sc = bumpy_bowl_spec().render().unwrap();
    let mp = MeshParams { grid_step_px: step, ..MeshParams::default() };
    let mesh = CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &mp).unwrap();
    let conf = ConformalParams::default();
    let mut t_nd = vec![];
    let mut t_topo = vec![];
    let mut t_split = vec![];
    let mut t_whole = vec![];
    let mut sys = CpcSystem::assemble(&mesh, &conf).unwrap();
    for _ in 0..reps {
        if mode == "all" || mode == "topo" {
            let t = Instant::now();
            let o = nested_dissection_leaf(&mesh.p_init, step, 8);
            t_nd.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(o);
            let t = Instant::now();
            let tp = CpcTopology::new(&mesh).unwrap();
            t_topo.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(tp);
        }
        if mode == "fresh" {
            let sys2 = CpcSystem::assemble(&mesh, &conf).unwrap();
            let t = Instant::now();
            let p = sys2.solve(0.9).unwrap();
            t_split.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(p);
            let t = Instant::now();
            let p = sys2.solve(0.9).unwrap();
            t_whole.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(p);
        }
        if mode == "all" || mode == "solve" {
            sys.set_domain_split(true);
            let t = Instant::now();
            let p = sys.solve(0.9).unwrap();
            t_split.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(p);
            sys.set_domain_split(false);
            let t = Instant::now();
            let p = sys.solve(0.9).unwrap();
            t_whole.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(p);
        }
    }
    println!(
        "n {} nnz {} factor {} flops {:.3e}  nd {:.3} topo {:.3} solve split {:.3} whole {:.3}",
        mesh.n_vertices(),
        sys.topology().nnz_lower(),
        sys.topology().factor_len(),
        sys.topology().factor_flops(),
        if t_nd.is_empty() { 0.0 } else { med(t_nd) },
        if t_topo.is_empty() { 0.0 } else { med(t_topo) },
        if t_split.is_empty() { 0.0 } else { med(t_split) },
        if t_whole.is_empty() { 0.0 } else { med(t_whole) },
    );
}
