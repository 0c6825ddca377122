//! The complex Hermitian solve against the real interleaved system, topology reuse across frames
//! and thread-count independence of the solver.
use laparo_cpc::scene;
use laparo_cpc::*;

fn bowl_mesh(step: usize) -> (scene::Scene, CpcMesh) {
    let mut spec = scene::bumpy_bowl_spec();
    // A small version of the bumpy bowl (fast to render), same geometry.
    spec.intrinsics = laparo_core::camera::Intrinsics::new(125.0, 125.0, 80.0, 60.0, 160, 120).unwrap();
    spec.march_step_mm = 1.0;
    let sc = spec.render().unwrap();
    let mesh =
        CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &MeshParams { grid_step_px: step, ..Default::default() })
            .unwrap();
    (sc, mesh)
}

/// The real interleaved normal equations solved with the system's real pattern (the pre-complex solver).
fn real_solve(sys: &CpcSystem, mesh: &CpcMesh, lambda: f64) -> Vec<[f64; 2]> {
    let (_, _, diag) = sys.pattern();
    let mut vals: Vec<f64> = sys.conformal_values().iter().map(|v| lambda * v).collect();
    let w = sys.displacement_weights();
    for (u, &pos) in diag.iter().enumerate() {
        vals[pos] += (1.0 - lambda) * w[u / 2];
    }
    let mut rhs: Vec<f64> =
        mesh.p_init.iter().zip(w).flat_map(|(p, &w)| [(1.0 - lambda) * w * p[0], (1.0 - lambda) * w * p[1]]).collect();
    sys.factor_solve(&vals, &mut rhs).unwrap();
    rhs.chunks_exact(2).map(|c| [c[0], c[1]]).collect()
}

#[test]
fn complex_solve_equals_the_real_interleaved_solve() {
    let (_, mesh) = bowl_mesh(2);
    let sys = CpcSystem::assemble(&mesh, &ConformalParams::default()).unwrap();
    for lambda in [0.3, 0.9, 0.999, 0.999999] {
        let pz = sys.solve(lambda).unwrap();
        let pr = real_solve(&sys, &mesh, lambda);
        let d = pz.iter().zip(&pr).map(|(a, b)| (a[0] - b[0]).abs().max((a[1] - b[1]).abs())).fold(0.0, f64::max);
        eprintln!("λ = {lambda}: max |complex − real| = {d:.2e} px");
        // Both are round-off-exact; their gap grows with the conditioning (∝ 1 / (1 − λ)).
        assert!(d < 1e-9 / (1.0 - lambda), "λ = {lambda}: {d:e} px");
        // Stationarity of eq. 4.11 at the complex solution: λ K p + (1−λ) D (p − P) = 0.
        let x: Vec<f64> = pz.iter().flat_map(|q| [q[0], q[1]]).collect();
        let kx = sys.conformal_matvec(&x);
        let w = sys.displacement_weights();
        let (mut g, mut scale) = (0.0f64, 0.0f64);
        for (v, q) in pz.iter().enumerate() {
            for k in 0..2 {
                let gi = lambda * kx[2 * v + k] + (1.0 - lambda) * w[v] * (q[k] - mesh.p_init[v][k]);
                g = g.max(gi.abs());
                scale = scale.max(((1.0 - lambda) * w[v] * mesh.p_init[v][k]).abs());
            }
        }
        // (round-off of K p grows with the conditioning as λ → 1)
        assert!(g < 1e-6 * scale, "λ = {lambda}: gradient {g:e} (scale {scale:e})");
    }
}

#[test]
fn theta_and_as_printed_rows_still_solve() {
    let (_, mesh) = bowl_mesh(4);
    let th = ConformalParams { theta_rad: 70f64.to_radians(), ..Default::default() };
    let sys = CpcSystem::assemble(&mesh, &th).unwrap();
    let pz = sys.solve(0.9).unwrap();
    let pr = real_solve(&sys, &mesh, 0.9);
    let d = pz.iter().zip(&pr).map(|(a, b)| (a[0] - b[0]).abs().max((a[1] - b[1]).abs())).fold(0.0, f64::max);
    assert!(d < 1e-6, "θ = 70°: {d:e} px");
    // The printed rows lack the complex structure: the real path solves them.
    let ap = ConformalParams { convention: RowConvention::AsPrinted, ..Default::default() };
    let sys = CpcSystem::assemble(&mesh, &ap).unwrap();
    let p = sys.solve(0.9).unwrap();
    let pr = real_solve(&sys, &mesh, 0.9);
    assert_eq!(p, pr);
}

#[test]
fn topology_reuse_and_threads_give_identical_results() {
    let (sc, mesh) = bowl_mesh(4);
    let conf = ConformalParams::default();
    let fresh = CpcSystem::assemble(&mesh, &conf).unwrap();
    assert!(!fresh.topology_reused);
    let p0 = fresh.solve(0.9).unwrap();
    let mut solver = CpcSolver::new();
    let first = solver.assemble(&mesh, &conf).unwrap();
    assert!(!first.topology_reused);
    let mesh2 = CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &MeshParams::default()).unwrap();
    let next = solver.assemble(&mesh2, &conf).unwrap();
    assert!(next.topology_reused, "same ROI and depth: same topology");
    assert_eq!(next.solve(0.9).unwrap(), p0);
    assert_eq!(first.solve(0.9).unwrap(), p0);
    // Repeated solves on the cached factor buffers.
    assert_eq!(next.solve(0.9).unwrap(), p0);
    for threads in [2, 3] {
        let mut s = CpcSolver::new();
        s.set_factor_threads(threads);
        let sys = s.assemble(&mesh, &conf).unwrap();
        assert_eq!(sys.solve(0.9).unwrap(), p0, "{threads} factorisation threads");
    }
    // A different mesh topology is not reused.
    let other =
        CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &MeshParams { grid_step_px: 3, ..Default::default() })
            .unwrap();
    assert!(!solver.assemble(&other, &conf).unwrap().topology_reused);
}

#[test]
fn video_pipeline_matches_single_frame() {
    let (sc, _) = bowl_mesh(4);
    let params = CpcParams::default();
    let a = cpc_warp(&sc.image, &sc.depth, &sc.intrinsics, &sc.roi, &params).unwrap();
    let mut solver = CpcSolver::new();
    for _ in 0..2 {
        let b = cpc_warp_with(&mut solver, &sc.image, &sc.depth, &sc.intrinsics, &sc.roi, &params).unwrap();
        assert_eq!(a.warp.p_flat, b.warp.p_flat);
        assert_eq!(a.warped.data, b.warped.data);
        assert_eq!(a.mask.data, b.mask.data);
    }
}

#[test]
fn two_domain_split_matches_the_whole_system_factorisation() {
    let (_, mesh) = bowl_mesh(2);
    assert!(mesh.n_vertices() >= laparo_cpc::solve::MIN_SPLIT_VERTICES);
    let mut sys = CpcSystem::assemble(&mesh, &ConformalParams::default()).unwrap();
    assert!(sys.topology().is_split());
    let gap = |p: &[[f64; 2]], q: &[[f64; 2]]| {
        p.iter().zip(q).map(|(a, b)| (a[0] - b[0]).abs().max((a[1] - b[1]).abs())).fold(0.0, f64::max)
    };
    for lambda in [0.3, 0.5, 0.9, 0.99, 0.999, 0.999999] {
        sys.set_domain_split(false);
        let whole = sys.solve(lambda).unwrap();
        sys.set_domain_split(true);
        let split = sys.solve(lambda).unwrap();
        // The round-off scale: the same system solved by the real interleaved factorisation.
        let d = gap(&split, &whole);
        let dr = gap(&whole, &real_solve(&sys, &mesh, lambda));
        eprintln!("λ = {lambda}: max |split − whole| = {d:.2e} px, |whole − real| = {dr:.2e} px");
        assert!(d <= 10.0 * dr + 1e-11, "λ = {lambda}: {d:e} px (round-off scale {dr:e} px)");
        if lambda <= 0.9 {
            assert!(d < 1e-9, "λ = {lambda}: {d:e} px");
        }
        // Same result on one and on two rayon threads.
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            assert_eq!(pool.install(|| sys.solve(lambda).unwrap()), split, "λ = {lambda}, {threads} threads");
        }
    }
}
