//! Verification of the TET10 Neo-Hookean solver: patch test, manufactured solution (P2 rate),
//! tangent = finite-difference derivative of the residual, zero load, bad input.
use laparo_core::mesh::TetMesh;
use laparo_fem::solid::{
    solve, Dirichlet, FaceTraction, Loads, NodalForce, Quadrature, SolidProblem, SolverSettings, Tet10Mesh,
};
use laparo_fem::{FemError, NeoHookean};
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use std::sync::Arc;

/// Box [0, l]³ split in n³ cubes of 6 Kuhn tetrahedra; interior vertices jittered by `jitter` × h.
fn box_mesh(n: usize, l: f64, jitter: f64, seed: u64) -> TetMesh {
    let h = l / n as f64;
    let mut m = laparo_fem::mesh::shapes::kuhn_box([n; 3], h);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    for x in m.vertices.iter_mut() {
        let interior = x.iter().all(|&c| c > 0.5 * h && c < l - 0.5 * h);
        if interior && jitter > 0.0 {
            *x += Vector3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
                * (jitter * h);
        }
    }
    TetMesh::new(m.vertices, m.tets).unwrap()
}

/// All TET10 nodes on the boundary surface of the linear mesh.
fn boundary_nodes(lin: &TetMesh, m: &Tet10Mesh) -> Vec<usize> {
    let mut out: Vec<usize> = lin.boundary().faces.iter().flat_map(|f| m.face_nodes(*f).unwrap()).collect();
    out.sort_unstable();
    out.dedup();
    out
}

fn to_vec3(u: &[f64]) -> Vec<Vector3<f64>> {
    u.chunks(3).map(|c| Vector3::new(c[0], c[1], c[2])).collect()
}

#[test]
fn patch_test_affine_deformation_is_reproduced() {
    let lin = box_mesh(3, 10.0, 0.25, 7);
    let m = Tet10Mesh::from_linear(&lin).unwrap();
    let g = Matrix3::new(1.12, 0.05, -0.02, 0.03, 0.93, 0.04, -0.01, -0.06, 1.07);
    let c = Vector3::new(0.3, -0.2, 0.1);
    let exact = |x: &Vector3<f64>| (g - Matrix3::identity()) * x + c;
    let bnd = boundary_nodes(&lin, &m);
    let dir: Vec<Dirichlet> = bnd.iter().map(|&i| Dirichlet { node: i, value_mm: exact(&m.nodes[i]) }).collect();
    let nodes = m.nodes.clone();
    for q in [Quadrature::Degree2, Quadrature::Degree5] {
        let p = SolidProblem::new(m.clone(), NeoHookean::liver(), &dir, &Loads::default(), q).unwrap();
        let s = solve(&p, &SolverSettings { steps: 2, rel_tol: 1e-13, ..Default::default() }).unwrap();
        let mut worst: f64 = 0.0;
        let mut interior = 0;
        for (i, x) in nodes.iter().enumerate() {
            if !p.is_prescribed(i) {
                interior += 1;
                worst = worst.max((s.displacement[i] - exact(x)).norm());
            }
        }
        assert!(interior > 50, "{interior} interior nodes");
        eprintln!("patch test {q:?}: {interior} interior nodes, max error {worst:e} mm");
        assert!(worst < 1e-10, "{q:?}: interior nodes off the affine field by {worst:e} mm");
        let jh = g.determinant();
        assert!((s.min_j - jh).abs() < 1e-9, "min J {} vs det G {jh}", s.min_j);
    }
}

/// u*(X) on the box [0, L]³ and its gradient.
fn manufactured(x: &Vector3<f64>, l: f64) -> (Vector3<f64>, Matrix3<f64>) {
    let a = 0.05 * l;
    let k = std::f64::consts::PI / l;
    let (sx, cx) = (k * x.x).sin_cos();
    let (sy, cy) = (k * x.y).sin_cos();
    let (sz, cz) = (k * x.z).sin_cos();
    let u = Vector3::new(a * sy * cz, a * sz * cx, a * sx * cy);
    let du = Matrix3::new(
        0.0,
        a * k * cy * cz,
        -a * k * sy * sz,
        -a * k * sz * sx,
        0.0,
        a * k * cz * cx,
        a * k * cx * cy,
        -a * k * sx * sy,
        0.0,
    );
    (u, du)
}

#[test]
fn manufactured_solution_converges_at_rate_three() {
    let l = 10.0;
    let mat = NeoHookean::from_young_poisson(4.1, 0.45).unwrap();
    // b = −Div P(F*(X)) by 4th-order central differences of P along each axis.
    let body = move |x: &Vector3<f64>| -> Vector3<f64> {
        let h = 1e-3 * l;
        let p_at = |y: Vector3<f64>| mat.pk1(&(Matrix3::identity() + manufactured(&y, l).1)).unwrap();
        let mut div = Vector3::zeros();
        for j in 0..3 {
            let e = Vector3::ith(j, h);
            let d = (p_at(x - 2.0 * e) - 8.0 * p_at(x - e) + 8.0 * p_at(x + e) - p_at(x + 2.0 * e)) / (12.0 * h);
            div += d.column(j);
        }
        -div
    };
    let mut errs = Vec::new();
    for n in [2, 4, 8] {
        let lin = box_mesh(n, l, 0.0, 1);
        let m = Tet10Mesh::from_linear(&lin).unwrap();
        let dir: Vec<Dirichlet> = boundary_nodes(&lin, &m)
            .into_iter()
            .map(|i| Dirichlet { node: i, value_mm: manufactured(&m.nodes[i], l).0 })
            .collect();
        let loads = Loads { body_force: Some(Arc::new(body)), ..Default::default() };
        let p = SolidProblem::new(m, mat, &dir, &loads, Quadrature::Degree5).unwrap();
        let s = solve(&p, &SolverSettings { steps: 2, rel_tol: 1e-10, ..Default::default() }).unwrap();
        errs.push(p.l2_error(&s.displacement, |x| manufactured(x, l).0));
    }
    let rates: Vec<f64> = errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    eprintln!("manufactured solution: L2 errors {errs:?}, rates {rates:?}");
    assert!(rates[1] > 2.7 && rates[1] < 3.5, "L2 errors {errs:?}, rates {rates:?}");
    assert!(rates[0] > 2.3, "L2 errors {errs:?}, rates {rates:?}");
}

#[test]
fn tangent_is_the_derivative_of_the_residual() {
    let lin = box_mesh(2, 10.0, 0.2, 3);
    let m = Tet10Mesh::from_linear(&lin).unwrap();
    let fixed = SolidProblem::fixed_vertices(&m, &[0, 1, 2, 3]).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for q in [Quadrature::Degree2, Quadrature::Degree5] {
        let p = SolidProblem::new(m.clone(), NeoHookean::liver(), &fixed, &Loads::default(), q).unwrap();
        let u: Vec<f64> = (0..3 * m.n_nodes()).map(|_| rng.gen_range(-0.3..0.3)).collect();
        let k = p.tangent_dense(&u).unwrap();
        let kmax = k.amax();
        assert!((&k - k.transpose()).amax() < 1e-10 * kmax, "tangent not symmetric");
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for j in 0..u.len() {
            let (mut up, mut um) = (u.clone(), u.clone());
            up[j] += h;
            um[j] -= h;
            let fp = p.assemble(&up, false).unwrap().internal_force;
            let fm = p.assemble(&um, false).unwrap().internal_force;
            for i in 0..u.len() {
                worst = worst.max(((fp[i] - fm[i]) / (2.0 * h) - k[(i, j)]).abs());
            }
        }
        eprintln!("tangent {q:?}: max |K − FD| {worst:e}, max |K| {kmax:e}");
        assert!(worst < 1e-6 * kmax, "{q:?}: max |K − FD| {worst:e} vs max |K| {kmax:e}");
        // And the internal force is the derivative of the strain energy.
        let fint = p.assemble(&u, false).unwrap().internal_force;
        for j in (0..u.len()).step_by(7) {
            let (mut up, mut um) = (u.clone(), u.clone());
            up[j] += h;
            um[j] -= h;
            let fd = (p.strain_energy(&up).unwrap() - p.strain_energy(&um).unwrap()) / (2.0 * h);
            assert!((fd - fint[j]).abs() < 1e-6 * (1.0 + fint[j].abs()), "dof {j}: {fd} vs {}", fint[j]);
        }
    }
}

fn bottom_fixed_problem(n: usize, loads: &Loads) -> SolidProblem {
    let lin = box_mesh(n, 10.0, 0.0, 0);
    let m = Tet10Mesh::from_linear(&lin).unwrap();
    let bottom: Vec<usize> = (0..m.n_vertices).filter(|&i| m.nodes[i].z < 1e-9).collect();
    let fixed = SolidProblem::fixed_vertices(&m, &bottom).unwrap();
    SolidProblem::new(m, NeoHookean::liver(), &fixed, loads, Quadrature::Degree2).unwrap()
}

fn top_faces(n: usize) -> Vec<[usize; 3]> {
    let lin = box_mesh(n, 10.0, 0.0, 0);
    lin.boundary().faces.into_iter().filter(|f| f.iter().all(|&v| (lin.vertices[v].z - 10.0).abs() < 1e-9)).collect()
}

/// The n³ box, bottom fixed, its top sheared by the traction (0.2, 0, −0.1) kPa: a finite deformation.
fn sheared_box(n: usize) -> SolidProblem {
    let tau = Vector3::new(0.2, 0.0, -0.1);
    let loads = Loads {
        face_tractions: top_faces(n).iter().map(|&face| FaceTraction { face, traction_kpa: tau }).collect(),
        ..Default::default()
    };
    bottom_fixed_problem(n, &loads)
}

#[test]
fn zero_load_gives_zero_displacement() {
    let p = bottom_fixed_problem(2, &Loads::default());
    let s = solve(&p, &SolverSettings::default()).unwrap();
    assert!(s.displacement.iter().all(|d| d.norm() == 0.0));
    assert!(s.steps.iter().all(|r| r.iterations == 0));
    assert_eq!(s.min_j, 1.0);
}

#[test]
fn uniform_traction_total_force_and_newton_convergence() {
    // Uniform shear traction τ on the top face: Σ f_ext = τ A, the reactions balance it, and
    // Newton converges quadratically (last residual ratios small).
    let tau = Vector3::new(0.2, 0.0, -0.1);
    let faces = top_faces(2);
    let loads = Loads {
        face_tractions: faces.iter().map(|&face| FaceTraction { face, traction_kpa: tau }).collect(),
        ..Default::default()
    };
    let p = bottom_fixed_problem(2, &loads);
    let fe = p.external_force();
    let total: Vector3<f64> = fe.chunks(3).map(|c| Vector3::new(c[0], c[1], c[2])).sum();
    assert!((total - tau * 100.0).norm() < 1e-12, "{total}");
    let s = solve(&p, &SolverSettings { steps: 5, ..Default::default() }).unwrap();
    assert!(s.max_displacement_mm > 0.1 && s.min_j > 0.5 && s.min_j < 1.0, "{} {}", s.max_displacement_mm, s.min_j);
    let a = p.assemble(&s.displacement.iter().flat_map(|d| d.iter().copied()).collect::<Vec<_>>(), false).unwrap();
    let react: Vector3<f64> = (0..p.mesh.n_nodes())
        .filter(|&i| p.is_prescribed(i))
        .map(|i| Vector3::from_column_slice(&a.internal_force[3 * i..3 * i + 3]))
        .sum();
    assert!((react + tau * 100.0).norm() < 1e-6, "reaction {react}");
    for st in &s.steps {
        let h = &st.residual_history;
        assert!(*h.last().unwrap() <= st.tolerance && st.iterations <= 8, "{st:?}");
    }
    // Equal and opposite shear on top: displacement of the top is along +x overall.
    let top_mean: f64 =
        (0..p.mesh.n_vertices).filter(|&i| p.mesh.nodes[i].z > 9.99).map(|i| s.displacement[i].x).sum::<f64>();
    assert!(top_mean > 0.0);
    let _ = to_vec3(&[0.0; 3]);
}

#[test]
fn bad_inputs_are_clear_errors() {
    let lin = box_mesh(1, 10.0, 0.0, 0);
    let m = Tet10Mesh::from_linear(&lin).unwrap();
    let err = |r: Result<SolidProblem, FemError>| r.err().expect("must fail").to_string();
    let e = err(SolidProblem::new(m.clone(), NeoHookean::liver(), &[], &Loads::default(), Quadrature::Degree2));
    assert!(e.contains("rigid"), "{e}");
    let two = SolidProblem::fixed_vertices(&m, &[0, 7]).unwrap();
    let e = err(SolidProblem::new(m.clone(), NeoHookean::liver(), &two, &Loads::default(), Quadrature::Degree2));
    assert!(e.contains("rigid") && e.contains("non-collinear"), "{e}");
    let e = SolidProblem::fixed_vertices(&m, &[99]).unwrap_err().to_string();
    assert!(e.contains("vertex 99"), "{e}");
    let fixed = SolidProblem::fixed_vertices(&m, &[0, 1, 2, 3]).unwrap();
    let loads = Loads {
        face_tractions: vec![FaceTraction { face: [0, 5, 6], traction_kpa: Vector3::x() }],
        ..Default::default()
    };
    let e = err(SolidProblem::new(m.clone(), NeoHookean::liver(), &fixed, &loads, Quadrature::Degree2));
    assert!(e.contains("face_tractions[0]"), "{e}");
    // A huge point force pulls one vertex through the mesh.
    let n = 2;
    let p = bottom_fixed_problem(
        n,
        &Loads {
            nodal_forces: vec![NodalForce {
                node: (n + 1) * (n + 1) * (n + 1) - 1,
                force_mn: Vector3::new(0.0, 0.0, -1e5),
            }],
            ..Default::default()
        },
    );
    let e = solve(&p, &SolverSettings { steps: 2, max_cuts: 4, ..Default::default() }).unwrap_err().to_string();
    eprintln!("inverting load: {e}");
    assert!(e.contains("tractions invert elements at step 1"), "{e}");
    let e = solve(&p, &SolverSettings { steps: 0, ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("steps"), "{e}");
}

#[test]
fn nested_dissection_and_amd_give_the_same_solution() {
    // The fill-reducing ordering changes the factor, not the equilibrium: both orderings converge to the
    // same displacements (to the Newton tolerance), and on a 3D mesh nested dissection's factor is no
    // denser than 1.5× AMD's.
    use laparo_fem::solid::FillOrdering;
    let p = sheared_box(7);
    let run = |ordering| {
        let linear = laparo_fem::solid::LinearSolver::Direct;
        solve(
            &p,
            &SolverSettings { steps: 3, rel_tol: 1e-12, ordering, pcg_max_iterations: 0, linear, ..Default::default() },
        )
        .unwrap()
    };
    // more TET10 nodes than one nested-dissection leaf (2,000 nodes): the dissection runs
    let free = (0..p.mesh.n_nodes()).filter(|&i| !p.is_prescribed(i)).count();
    assert!(free > 3000, "{free} free nodes");
    let (a, b) = (run(FillOrdering::Amd), run(FillOrdering::NestedDissection));
    let diff = a.displacement.iter().zip(&b.displacement).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-9 * a.max_displacement_mm, "max difference {diff} mm of {} mm", a.max_displacement_mm);
    assert_eq!(a.free_dofs, b.free_dofs);
    assert!(b.factor_nnz as f64 <= 1.5 * a.factor_nnz as f64, "ND {} vs AMD {}", b.factor_nnz, a.factor_nnz);
}

#[test]
fn two_level_and_direct_solvers_give_the_same_solution() {
    // The solver of the Newton directions changes the path, not the equilibrium: conjugate gradients
    // with the two-level (TET10 Gauss–Seidel + linear-tetrahedron coarse) preconditioner converge to the
    // displacements of the Cholesky path, at the same Newton tolerance. `Auto` with a budget smaller
    // than the factor picks the two-level solver.
    use laparo_fem::solid::LinearSolver;
    let p = sheared_box(5);
    let run = |linear| solve(&p, &SolverSettings { steps: 3, rel_tol: 1e-11, linear, ..Default::default() }).unwrap();
    let direct = run(LinearSolver::Direct);
    let two = run(LinearSolver::TwoLevel);
    let auto = run(LinearSolver::Auto { factor_budget_bytes: 1 << 10 });
    assert_eq!((direct.linear_solver, two.linear_solver, auto.linear_solver), ("direct", "two-level", "two-level"));
    assert!(direct.max_displacement_mm > 0.5, "a finite deformation: {} mm", direct.max_displacement_mm);
    let diff = direct.displacement.iter().zip(&two.displacement).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-8 * direct.max_displacement_mm, "max difference {diff} mm of {} mm", direct.max_displacement_mm);
    assert_eq!(auto.displacement, two.displacement, "same solver, same result");
    assert!(two.factor_nnz < direct.factor_nnz / 4, "coarse factor {} vs {}", two.factor_nnz, direct.factor_nnz);
    assert!(two.timings.pcg_iterations > 0 && two.min_j > 0.0);
    for s in &two.steps {
        assert!(s.residual_history.last().unwrap() <= &s.tolerance);
    }
}

#[test]
fn a_load_path_reaches_the_equilibria_of_solves_from_rest() {
    // Calibrating a load solves one problem at several load factors; `LoadPath` starts each solve from
    // the highest equilibrium it has stored below the target. Hyperelastic equilibrium does not depend
    // on the path, so each result must equal a solve from rest at that load factor (to the Newton
    // tolerance), with fewer increments; a target that is a stored state needs no Newton iteration.
    use laparo_fem::solid::LoadPath;
    let p = sheared_box(4);
    let settings = SolverSettings { steps: 4, rel_tol: 1e-11, ..Default::default() };
    let mut path = LoadPath::new(&p, &settings).unwrap();
    let full = path.solve_at(1.0).unwrap();
    assert_eq!(full.steps.len(), 4);
    assert_eq!(path.stored_states(), 5, "rest and the four increments");
    // the first solve from rest is `solve` itself, bit for bit
    assert_eq!(full.displacement, solve(&p, &settings).unwrap().displacement);
    assert!(full.max_displacement_mm > 0.5, "a finite deformation: {} mm", full.max_displacement_mm);
    for (target, increments) in [(0.63, 1), (0.5, 1), (1.6, 2)] {
        // 0.63 from the state at 0.5 (0.13 ≤ 0.63 / 4: one increment), 0.5 stored (one zero increment,
        // 0 Newton iterations), 1.6 from 1.0 (0.6 / (1.6 / 4) = 1.5: two increments)
        let warm = path.solve_at(target).unwrap();
        let cold = LoadPath::new(&p, &settings).unwrap().solve_at(target).unwrap();
        assert_eq!(cold.steps.len(), 4);
        assert_eq!(warm.steps.len(), increments, "load factor {target}");
        let diff = warm.displacement.iter().zip(&cold.displacement).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max);
        assert!(
            diff < 1e-8 * cold.max_displacement_mm,
            "load factor {target}: {diff} mm of {} mm",
            cold.max_displacement_mm
        );
        assert!((warm.min_j - cold.min_j).abs() < 1e-8);
        for s in &warm.steps {
            assert!(s.residual_history.last().unwrap() <= &s.tolerance);
        }
        if target == 0.5 {
            assert_eq!(warm.timings.newton_iterations, 0, "a stored equilibrium");
        } else {
            assert!(warm.timings.newton_iterations < cold.timings.newton_iterations);
        }
    }
    let e = path.solve_at(f64::NAN).unwrap_err().to_string();
    assert!(e.contains("load_factor"), "{e}");
}
