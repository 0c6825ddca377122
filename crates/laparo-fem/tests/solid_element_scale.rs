//! Heterogeneous stiffness (`SolidProblem::with_element_scale`) against closed forms, and the TET10 node
//! numbering that a displacement field saved per node relies on.
//!
//! * The Neo-Hookean energy of eq. 5.3 is linear in (μ, λ): scaling both by s everywhere scales every
//!   internal force by s, so the equilibrium under loads × s is the unscaled one under loads × 1, exactly
//!   (up to the Newton tolerance), however large the deformation.
//! * Two materials in series: a bar of length L₁ + L₂ (moduli E and s E, ν = 0: no lateral coupling, so a
//!   clamped end is no constraint) under an axial traction t elongates by t L₁ / E + t L₂ / (s E) (two
//!   springs in series); at a strain of 1e-4 the large-strain law is linear to ~1e-4 and quadratic
//!   elements represent the piecewise-linear displacement exactly.
use laparo_fem::material::NeoHookean;
use laparo_fem::mesh::shapes::{box_surface, kuhn_box};
use laparo_fem::mesh::{cut, tetrahedralize_surface, Blade, TetraParams};
use laparo_fem::solid::{solve, FaceTraction, Loads, Quadrature, SolidProblem, SolverSettings, Tet10Mesh, TET10_EDGES};
use laparo_fem::FemError;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// The bar [0, 2h]² × [0, nz h] (mm): bottom clamped, uniform traction `t_kpa` (z) on the top face.
fn bar(nz: usize, h: f64, material: NeoHookean, t_kpa: f64) -> SolidProblem {
    let lin = kuhn_box([2, 2, nz], h);
    let top = nz as f64 * h;
    let faces: Vec<FaceTraction> = lin
        .boundary()
        .faces
        .iter()
        .filter(|f| f.iter().all(|&k| (lin.vertices[k].z - top).abs() < 1e-9))
        .map(|&face| FaceTraction { face, traction_kpa: V3::new(0.0, 0.0, t_kpa) })
        .collect();
    assert_eq!(faces.len(), 8, "2 × 2 squares of 2 triangles on the top face");
    let mesh = Tet10Mesh::from_linear(&lin).unwrap();
    let bottom: Vec<usize> = (0..mesh.n_vertices).filter(|&k| mesh.nodes[k].z.abs() < 1e-9).collect();
    let fixed = SolidProblem::fixed_vertices(&mesh, &bottom).unwrap();
    let loads = Loads { face_tractions: faces, ..Default::default() };
    SolidProblem::new(mesh, material, &fixed, &loads, Quadrature::Degree2).unwrap()
}

fn settings(steps: usize) -> SolverSettings {
    SolverSettings { steps, rel_tol: 1e-11, ..Default::default() }
}

#[test]
fn a_uniform_stiffness_factor_is_a_load_factor() {
    let (s, t) = (3.0, 0.6);
    let base = bar(4, 5.0, NeoHookean::liver(), t);
    let u1 = solve(&base, &settings(6)).unwrap();
    // large deformation: the top moves by a good fraction of the bar's 20 mm
    assert!(u1.max_displacement_mm > 2.0, "max |u| {}", u1.max_displacement_mm);
    let ne = base.mesh.elements.len();
    let stiff = bar(4, 5.0, NeoHookean::liver(), t * s).with_element_scale(vec![s; ne]).unwrap();
    let us = solve(&stiff, &settings(6)).unwrap();
    let diff = u1.displacement.iter().zip(&us.displacement).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-7 * u1.max_displacement_mm, "loads × {s} on stiffness × {s}: max difference {diff:e} mm");
    // the factor acts: the stiff bar under the unscaled load moves far less
    let weak_load = bar(4, 5.0, NeoHookean::liver(), t).with_element_scale(vec![s; ne]).unwrap();
    let uw = solve(&weak_load, &settings(6)).unwrap();
    assert!(
        uw.max_displacement_mm < 0.5 * u1.max_displacement_mm,
        "{} vs {}",
        uw.max_displacement_mm,
        u1.max_displacement_mm
    );
    // and the strain energy at one state is s times the unscaled one (ψ linear in μ, λ)
    let flat: Vec<f64> = u1.displacement.iter().flat_map(|d| [d.x, d.y, d.z]).collect();
    let (e1, es) = (base.strain_energy(&flat).unwrap(), stiff.strain_energy(&flat).unwrap());
    assert!((es - s * e1).abs() < 1e-12 * es.abs(), "{es} vs {s} × {e1}");
}

#[test]
fn two_materials_in_series_elongate_as_two_springs() {
    let (e_kpa, s, t_kpa, h) = (1.0, 4.0, 1e-4, 2.5);
    let material = NeoHookean::from_young_poisson(e_kpa, 0.0).unwrap();
    let p = bar(8, h, material, t_kpa);
    // upper half (z > 10 mm) s times stiffer: element centroids decide, the interface is a mesh plane
    let scale: Vec<f64> = p
        .mesh
        .elements
        .iter()
        .map(|el| if el[..4].iter().map(|&k| p.mesh.nodes[k].z).sum::<f64>() / 4.0 > 10.0 { s } else { 1.0 })
        .collect();
    assert_eq!(scale.iter().filter(|&&f| f == s).count(), scale.len() / 2);
    let p = p.with_element_scale(scale).unwrap();
    let u = solve(&p, &SolverSettings { steps: 1, rel_tol: 1e-9, ..Default::default() }).unwrap();
    let (l1, l2) = (10.0, 10.0);
    let want_top = t_kpa * l1 / e_kpa + t_kpa * l2 / (s * e_kpa);
    let want_mid = t_kpa * l1 / e_kpa;
    for (k, x) in p.mesh.nodes.iter().enumerate() {
        let d = u.displacement[k];
        let want = if x.z <= 10.0 { t_kpa * x.z / e_kpa } else { want_mid + t_kpa * (x.z - 10.0) / (s * e_kpa) };
        assert!((d.z - want).abs() < 1e-3 * want_top, "node {k} at z {}: u_z {:e}, series springs {want:e}", x.z, d.z);
        assert!(d.x.abs() + d.y.abs() < 1e-3 * want_top, "node {k}: lateral {:e} {:e} (ν = 0)", d.x, d.y);
    }
    // a uniform bar of modulus E would stretch by 2 t L / E: the test tells the two apart
    assert!((want_top - 2.0 * t_kpa * l1 / e_kpa).abs() > 0.3 * want_top);
}

#[test]
fn element_scale_is_checked_and_named() {
    let p = bar(2, 5.0, NeoHookean::liver(), 0.1);
    let ne = p.mesh.elements.len();
    let short = bar(2, 5.0, NeoHookean::liver(), 0.1).with_element_scale(vec![1.0; ne - 1]);
    let mut bad = vec![1.0; ne];
    bad[3] = -2.0;
    let negative = p.with_element_scale(bad);
    for r in [short, negative] {
        match r {
            Err(e @ FemError::InvalidParameter { .. }) => assert!(e.to_string().contains("element_scale"), "{e}"),
            Err(e) => panic!("wrong variant: {e}"),
            Ok(_) => panic!("accepted a bad element scale"),
        }
    }
    let nan = bar(2, 5.0, NeoHookean::liver(), 0.1).with_element_scale(vec![f64::NAN; ne]);
    assert!(nan.is_err());
}

#[test]
fn tet10_numbering_of_a_cut_mesh_is_deterministic() {
    let s = box_surface(&V3::zeros(), &V3::new(40.0, 20.0, 20.0));
    let m = tetrahedralize_surface(s, "box", &TetraParams { edge_mm: 4.0, ..TetraParams::default() }).unwrap().0;
    let mouth: Vec<V3> = (0..=10).map(|i| V3::new(20.3, 5.0 + i as f64, 20.0)).collect();
    let c = cut(&m, &Blade::uniform(mouth, -V3::z(), 10.0, 3.0)).unwrap();
    let a = Tet10Mesh::from_linear(&c.mesh).unwrap();
    let b = Tet10Mesh::from_linear(&c.mesh).unwrap();
    assert_eq!(a.elements, b.elements);
    assert_eq!(a.edge_nodes, b.edge_nodes);
    assert_eq!(a.nodes, b.nodes);
    // vertices first, unchanged; then one mid-edge node per edge, numbered by first use in element order
    assert_eq!(a.n_vertices, c.mesh.vertices.len());
    assert_eq!(&a.nodes[..a.n_vertices], &c.mesh.vertices[..]);
    let mut seen = std::collections::HashMap::new();
    for (e, el) in a.elements.iter().enumerate() {
        for (k, &(i, j)) in TET10_EDGES.iter().enumerate() {
            let key = (el[i].min(el[j]), el[i].max(el[j]));
            let next = a.n_vertices + seen.len();
            let id = *seen.entry(key).or_insert(next);
            assert_eq!(el[4 + k], id, "element {e}, edge {k}");
            assert!((a.nodes[id] - (a.nodes[el[i]] + a.nodes[el[j]]) * 0.5).norm() < 1e-12);
        }
    }
    assert_eq!(seen.len() + a.n_vertices, a.n_nodes());
}
