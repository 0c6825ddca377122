//! The SOFA liver (real data, ×10 → mm): agreement with the scikit-fem P2 reference of
//! `scripts/fem_crosscheck_skfem.py`, equilibrium, and bit-identical results for 1 and 2 threads.
use laparo_core::mesh::read_msh;
use laparo_fem::solid::{solve, FaceTraction, Loads, Quadrature, SolidProblem, SolverSettings, Tet10Mesh};
use laparo_fem::NeoHookean;
use nalgebra::Vector3;
use std::collections::HashMap;
use std::path::PathBuf;

/// numpy.quantile (linear interpolation).
fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let pos = q * (s.len() - 1) as f64;
    let (i, f) = (pos.floor() as usize, pos - pos.floor());
    if i + 1 < s.len() {
        s[i] * (1.0 - f) + s[i + 1] * f
    } else {
        s[i]
    }
}

#[test]
fn sofa_liver_matches_scikit_fem_and_is_thread_count_independent() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/meshes/sofa_liver/liver.msh");
    if !path.exists() {
        eprintln!("skipping: {} absent", path.display());
        return;
    }
    let mut lin = read_msh(&path).unwrap();
    for v in &mut lin.vertices {
        *v *= 10.0;
    }
    let z: Vec<f64> = lin.vertices.iter().map(|v| v.z).collect();
    let (zlo, zhi) = (quantile(&z, 0.15), quantile(&z, 0.85));
    let fixed_ids: Vec<usize> = (0..z.len()).filter(|&i| z[i] <= zlo).collect();
    let mut count: HashMap<[usize; 3], usize> = HashMap::new();
    for t in &lin.tets {
        for f in [[t[1], t[2], t[3]], [t[0], t[2], t[3]], [t[0], t[1], t[3]], [t[0], t[1], t[2]]] {
            let mut k = f;
            k.sort_unstable();
            *count.entry(k).or_default() += 1;
        }
    }
    let mut top: Vec<[usize; 3]> =
        count.into_iter().filter(|(f, c)| *c == 1 && f.iter().all(|&i| z[i] >= zhi)).map(|(f, _)| f).collect();
    top.sort_unstable();
    let x = |i: usize| lin.vertices[i];
    let area: f64 = top.iter().map(|f| 0.5 * (x(f[1]) - x(f[0])).cross(&(x(f[2]) - x(f[0]))).norm()).sum();
    let traction = Vector3::new(1.0, 0.0, -1.0).normalize() * (20.0 / area);
    let mesh = Tet10Mesh::from_linear(&lin).unwrap();
    let fixed = SolidProblem::fixed_vertices(&mesh, &fixed_ids).unwrap();
    let loads = Loads {
        face_tractions: top.iter().map(|&face| FaceTraction { face, traction_kpa: traction }).collect(),
        ..Default::default()
    };
    let p = SolidProblem::new(mesh, NeoHookean::liver(), &fixed, &loads, Quadrature::Degree5).unwrap();
    assert_eq!((fixed_ids.len(), top.len()), (28, 34), "selection differs from the cross-check script");
    let settings = SolverSettings { steps: 5, ..Default::default() };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| solve(&p, &settings).unwrap())
    };
    let s2 = run(2);
    // scikit-fem ElementTetP2 on the same problem (scripts/fem_crosscheck_skfem.py): max |u| 4.08645 mm.
    assert!((s2.max_displacement_mm - 4.08645).abs() < 1e-4, "max |u| {}", s2.max_displacement_mm);
    assert!(s2.min_j > 0.9 && s2.min_j < 1.0);
    // Equilibrium: reactions at the clamped nodes balance the 20 mN load.
    let u: Vec<f64> = s2.displacement.iter().flat_map(|d| d.iter().copied()).collect();
    let fint = p.assemble(&u, false).unwrap().internal_force;
    let react: Vector3<f64> = (0..p.mesh.n_nodes())
        .filter(|&i| p.is_prescribed(i))
        .map(|i| Vector3::from_column_slice(&fint[3 * i..3 * i + 3]))
        .sum();
    assert!((react + traction * area).norm() < 1e-6 * 20.0, "reaction {react}");
    let s1 = run(1);
    assert!(s1.displacement == s2.displacement, "results depend on the thread count");
}
