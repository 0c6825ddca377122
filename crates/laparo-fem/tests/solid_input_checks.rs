//! Inputs that made `fem solve` silently wrong (issue 49): duplicated tetrahedra (stiffness counted
//! twice), a tetrahedron folded over its neighbour, non-finite or absurd loads (a −1e300 mN load
//! "converged" in 0 Newton iterations with zero displacement), and a solve that returns the rest
//! state while the free nodes carry a load.
use laparo_core::mesh::TetMesh;
use laparo_fem::mesh::shapes::kuhn_box;
use laparo_fem::solid::{
    check_elements, solve, Loads, NodalForce, Quadrature, SolidProblem, SolverSettings, Tet10Mesh,
};
use laparo_fem::{FemError, NeoHookean};
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// The 20 mm box of 2×2×2 cubes (Kuhn tets of both orientations), bottom fixed, `forces` applied.
fn problem(forces: &[(usize, V3)]) -> laparo_fem::Result<SolidProblem> {
    let mesh = Tet10Mesh::from_linear(&kuhn_box([2, 2, 2], 10.0))?;
    let bottom: Vec<usize> = (0..mesh.n_vertices).filter(|&i| mesh.nodes[i].z < 1e-9).collect();
    let fixed = SolidProblem::fixed_vertices(&mesh, &bottom)?;
    let loads = Loads {
        nodal_forces: forces.iter().map(|&(node, force_mn)| NodalForce { node, force_mn }).collect(),
        ..Default::default()
    };
    SolidProblem::new(mesh, NeoHookean::liver(), &fixed, &loads, Quadrature::Degree2)
}

fn top_vertex() -> usize {
    let m = kuhn_box([2, 2, 2], 10.0);
    (0..m.vertices.len()).find(|&i| m.vertices[i].z > 19.0).unwrap()
}

#[test]
fn a_duplicated_tetrahedron_is_refused() {
    let mut m = kuhn_box([2, 2, 2], 10.0);
    assert!(check_elements(&m).is_ok(), "a conforming mesh with both orientations passes");
    let n = m.tets.len();
    let mut dup = m.tets[3];
    dup.rotate_left(1); // same vertices, another order (and orientation)
    m.tets.push(dup);
    match Tet10Mesh::from_linear(&m) {
        Err(FemError::DuplicateElement { first, second, .. }) => assert_eq!((first, second), (3, n)),
        other => panic!("expected a duplicate element, got {:?}", other.map(|_| ())),
    }
}

#[test]
fn a_tetrahedron_folded_over_its_neighbour_is_refused() {
    let v = vec![
        V3::zeros(),
        V3::new(10.0, 0.0, 0.0),
        V3::new(0.0, 10.0, 0.0),
        V3::new(0.0, 0.0, 10.0),
        V3::new(1.0, 1.0, 5.0), // on the same side of face (0, 1, 2) as vertex 3
    ];
    let m = TetMesh::new(v.clone(), vec![[0, 1, 2, 3], [0, 2, 1, 4]]).unwrap();
    let e = Tet10Mesh::from_linear(&m).unwrap_err();
    assert!(matches!(e, FemError::InvertedElement { first: 0, second: 1, face: [0, 1, 2] }), "{e}");
    assert!(e.to_string().contains("inverted"), "{e}");
    // the same two tets on either side of the face are a valid mesh
    let mut v = v;
    v[4] = V3::new(1.0, 1.0, -5.0);
    assert!(Tet10Mesh::from_linear(&TetMesh::new(v, vec![[0, 1, 2, 3], [0, 2, 1, 4]]).unwrap()).is_ok());
}

#[test]
fn non_finite_and_absurd_loads_are_refused() {
    let top = top_vertex();
    // −1e300 mN: finite, but strains of order 1e293
    let e = problem(&[(top, V3::new(0.0, 0.0, -1e300))]).err().expect("absurd load refused");
    assert!(matches!(e, FemError::LoadOutOfScale { what: "absurd", .. }), "{e}");
    assert!(e.to_string().contains("E·L²"), "{e}");
    // two finite forces on one node that overflow when summed
    let e = problem(&[(top, V3::new(1e308, 0.0, 0.0)), (top, V3::new(1e308, 0.0, 0.0))]).err().expect("overflow");
    assert!(matches!(e, FemError::LoadOutOfScale { what: "not finite", .. }), "{e}");
    // 1e9 mN on a 20 mm box of E = 4.1 kPa (E·L² ≈ 5e3 mN) is absurd; 5 mN is a load
    assert!(matches!(problem(&[(top, V3::new(0.0, 0.0, 1e9))]), Err(FemError::LoadOutOfScale { .. })));
    let p = problem(&[(top, V3::new(0.0, 0.0, 5.0))]).unwrap();
    let s = solve(&p, &SolverSettings { steps: 2, ..Default::default() }).unwrap();
    assert!(s.timings.newton_iterations > 0 && s.max_displacement_mm > 0.0);
}

#[test]
fn a_solve_that_never_moves_under_a_load_is_an_error() {
    let top = top_vertex();
    // 100 mN on a fixed vertex (taken by the support) and 1 mN on a free one: with a loose tolerance the
    // rest state's residual (1 mN) passes the test against the applied load (100 mN).
    let p = problem(&[(0, V3::new(0.0, 0.0, 100.0)), (top, V3::new(0.0, 0.0, 1.0))]).unwrap();
    let loose = SolverSettings { steps: 1, rel_tol: 0.5, ..Default::default() };
    match solve(&p, &loose) {
        Err(FemError::NoNewtonStep { free_load_mn, .. }) => assert!((free_load_mn - 1.0).abs() < 1e-9),
        other => panic!("expected NoNewtonStep, got {:?}", other.map(|s| s.timings.newton_iterations)),
    }
    let s = solve(&p, &SolverSettings { steps: 1, ..Default::default() }).unwrap();
    assert!(s.timings.newton_iterations > 0 && s.max_displacement_mm > 0.0);
    // a load carried by the supports alone leaves the body at rest, without error
    let p = problem(&[(0, V3::new(0.0, 0.0, 100.0))]).unwrap();
    let s = solve(&p, &loose).unwrap();
    assert_eq!(s.max_displacement_mm, 0.0);
}
