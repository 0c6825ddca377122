//! A 10 mm box of liver tissue, bottom fixed, its top sheared by a uniform traction τ: the solver's
//! reactions at the fixed nodes balance τ·A. `cargo run -p laparo-fem --example sheared_box`
use laparo_fem::prelude::*;
use nalgebra::Vector3;

pub fn main() -> Result<()> {
    let lin = laparo_fem::mesh::shapes::kuhn_box([2, 2, 2], 5.0); // 2³ cubes of 6 tetrahedra
    let on_top = |f: &[usize; 3]| f.iter().all(|&v| (lin.vertices[v].z - 10.0).abs() < 1e-9);
    let top: Vec<[usize; 3]> = lin.boundary().faces.into_iter().filter(on_top).collect();
    let mesh = Tet10Mesh::from_linear(&lin)?;
    let bottom: Vec<usize> = (0..mesh.n_vertices).filter(|&i| mesh.nodes[i].z < 1e-9).collect();
    let fixed = SolidProblem::fixed_vertices(&mesh, &bottom)?;
    let tau = Vector3::new(0.2, 0.0, -0.1); // kPa
    let face_tractions = top.iter().map(|&face| FaceTraction { face, traction_kpa: tau }).collect();
    let loads = Loads { face_tractions, ..Default::default() };
    let p = SolidProblem::new(mesh, NeoHookean::liver(), &fixed, &loads, Quadrature::Degree2)?;
    let s = solve(&p, &SolverSettings { steps: 5, ..Default::default() })?;
    let u: Vec<f64> = s.displacement.iter().flat_map(|d| d.iter().copied()).collect();
    let f = p.assemble(&u, false).expect("no inverted element at equilibrium").internal_force;
    let reaction: Vector3<f64> = (0..p.mesh.n_nodes())
        .filter(|&i| p.is_prescribed(i))
        .map(|i| Vector3::from_column_slice(&f[3 * i..][..3]))
        .sum();
    println!("max |u| {:.3} mm, min J {:.4}, reaction {:?} mN", s.max_displacement_mm, s.min_j, reaction);
    assert!((reaction + tau * 100.0).norm() < 1e-6, "the reaction balances τ·A (A = 100 mm²)");
    Ok(())
}
