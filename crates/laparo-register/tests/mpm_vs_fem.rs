//! Ladder rung L3's physics (issue M4): a damped MPM run under constant loads comes to rest at the static
//! equilibrium the FEM computes. An edge crack in a strip (the fixture of laparo-fem's fracture-mechanics
//! test), pressure on its faces, one end clamped: laparo-fem's TET10 static solution against laparo-mpm on the
//! two-field grid with the same pressure as particle loads and mass-proportional damping.
//!
//! `M4_STEPS`, `M4_ZT` (ζ T Δt) and `M4_S` (spacing, mm) override the horizon, damping and resolution for the
//! measurement in BENCHMARKS.md.
use laparo_fem::material::NeoHookean;
use laparo_fem::mesh::shapes::box_surface;
use laparo_fem::mesh::{cut, tetrahedralize_surface, Blade, TetraParams};
use laparo_fem::solid::{solve, Loads, Quadrature, SolidProblem, SolverSettings, Tet10Mesh};
use laparo_register::crack::{label_organ, CrackSurface};
use laparo_register::organ::{organ_from_points, OrganConfig};
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// Strip 2H × W × B (mm): the crack plane x = H + 0.3 runs from the top face z = B down A mm through the
/// whole width; the end x = 0 is clamped.
const H: f64 = 24.0;
const W: f64 = 8.0;
const B: f64 = 24.0;
const A: f64 = 12.0;
const XC: f64 = H + 0.3;
const E_KPA: f64 = 4.1;
const NU: f64 = 0.3;
const P_KPA: f64 = 4e-3;
/// MPM particle spacing (mm).
const S: f64 = 1.0;
fn spacing() -> f64 {
    std::env::var("M4_S").ok().and_then(|v| v.parse().ok()).unwrap_or(S)
}

#[test]
fn damped_mpm_under_crack_pressure_settles_on_the_fem_static_solution() {
    let sp = spacing();
    // ---- FEM: TET10, 2 mm tetrahedra
    let surf = box_surface(&V3::zeros(), &V3::new(2.0 * H, W, B));
    let m = tetrahedralize_surface(surf, "strip", &TetraParams { edge_mm: 2.0, ..TetraParams::default() }).unwrap().0;
    let mouth: Vec<V3> = (0..=8).map(|i| V3::new(XC, -1.0 + (W + 2.0) * i as f64 / 8.0, B)).collect();
    let c = cut(&m, &Blade::uniform(mouth, -V3::z(), A, 2.0)).unwrap();
    let mesh = Tet10Mesh::from_linear(&c.mesh).unwrap();
    let end: Vec<usize> = (0..c.mesh.vertices.len()).filter(|&k| c.mesh.vertices[k].x < 1e-9).collect();
    let fixed = SolidProblem::fixed_vertices(&mesh, &end).unwrap();
    let loads = Loads { face_tractions: c.crack_pressure(P_KPA), ..Default::default() };
    let material = NeoHookean::from_young_poisson(E_KPA, NU).unwrap();
    let problem = SolidProblem::new(mesh, material, &fixed, &loads, Quadrature::Degree2).unwrap();
    let sol = solve(&problem, &SolverSettings { steps: 1, rel_tol: 1e-10, ..Default::default() }).unwrap();
    let u_fem = sol.vertex_displacements().to_vec();
    let x_fem = &c.mesh.vertices;
    let u_max = u_fem.iter().map(|u| u.norm()).fold(0.0, f64::max);
    // side of each FEM vertex next to the crack: the mean centroid of its tetrahedra
    let mut side_sum = vec![0.0; x_fem.len()];
    for t in &c.mesh.tets {
        let cx = t.iter().map(|&i| x_fem[i].x).sum::<f64>() / 4.0 - XC;
        for &i in t {
            side_sum[i] += cx;
        }
    }
    // ---- MPM: a 1 mm lattice, Δx 2 mm, the crack plane as the two-field surface
    let nx = (2.0 * H / sp) as usize;
    let (ny, nz) = ((W / sp) as usize, (B / sp) as usize);
    let mut pts = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                pts.push(V3::new((i as f64 + 0.5) * sp, (j as f64 + 0.5) * sp, (k as f64 + 0.5) * sp));
            }
        }
    }
    let steps: usize = std::env::var("M4_STEPS").ok().and_then(|v| v.parse().ok()).unwrap_or(1600);
    let zeta_t: f64 = std::env::var("M4_ZT").ok().and_then(|v| v.parse().ok()).unwrap_or(10.0);
    let cfg = OrganConfig { spacing_mm: sp, youngs_modulus_kpa: E_KPA, poisson_ratio: NU, steps, ..Default::default() };
    let mut organ = organ_from_points(pts.clone(), &cfg, "strip").unwrap();
    let plane = laparo_core::mesh::TriMesh {
        vertices: vec![
            V3::new(XC, -2.0, B - A),
            V3::new(XC, W + 2.0, B - A),
            V3::new(XC, W + 2.0, B + 2.0),
            V3::new(XC, -2.0, B + 2.0),
        ],
        faces: vec![[0, 1, 2], [0, 2, 3]],
    };
    let crack = CrackSurface::from_mesh(&plane, "crack plane", Some(3.0)).unwrap();
    label_organ(&mut organ, &crack, &pts, &pts).unwrap();
    let scene = &mut organ.scene;
    scene.fixed = pts.iter().map(|p| p.x < sp).collect();
    // the pressure on each lip as loads on the particle column next to the crack: p × its face area S²
    scene.external_forces = pts
        .iter()
        .map(|p| {
            let next_to_crack = (p.x - XC).abs() < sp && p.z > B - A;
            if next_to_crack {
                V3::new((p.x - XC).signum() * P_KPA * sp * sp, 0.0, 0.0)
            } else {
                V3::zeros()
            }
        })
        .collect();
    scene.damping = zeta_t / (steps as f64 * scene.dt);
    let fin = laparo_mpm::simulate(scene).unwrap().final_state;
    let d = laparo_mpm::diagnostics(scene, &fin);
    assert!(
        d.kinetic_energy <= 1e-3 * d.elastic_energy,
        "not at rest: KE {} vs elastic {}",
        d.kinetic_energy,
        d.elastic_energy
    );
    // ---- compare at the FEM vertices: MPM displacement = mean of the particles within 1.5 sp on the
    // vertex's side of the crack (either side below the crack front)
    let u_mpm: Vec<V3> = fin.x.iter().zip(&scene.positions).map(|(a, b)| a - b).collect();
    let sides = &scene.crack_side;
    let (mut se, mut n, mut worst) = (0.0, 0usize, 0.0f64);
    for (k, x) in x_fem.iter().enumerate() {
        let want_side: i8 =
            if (x.x - XC).abs() < 1.5 * sp && x.z > B - A - 1e-9 { side_sum[k].signum() as i8 } else { 0 };
        let mut acc = V3::zeros();
        let mut m = 0;
        for (p, q) in pts.iter().enumerate() {
            if (q - x).norm() <= 1.5 * sp && (want_side == 0 || sides[p] == want_side) {
                acc += u_mpm[p];
                m += 1;
            }
        }
        if m == 0 {
            continue;
        }
        let e = (acc / m as f64 - u_fem[k]).norm();
        se += e * e;
        worst = worst.max(e);
        n += 1;
    }
    let rms = (se / n as f64).sqrt();
    let um = u_mpm.iter().map(|u| u.norm()).fold(0.0, f64::max);
    eprintln!(
        "spacing {sp} mm, Δt {:.3e} s, T {:.3} s, ζT {zeta_t}: max |u| MPM {um:.4e} mm; KE/elastic {:.2e}",
        scene.dt,
        steps as f64 * scene.dt,
        d.kinetic_energy / d.elastic_energy
    );
    eprintln!(
        "max |u| FEM {u_max:.4e} mm; MPM vs FEM at {n} vertices: RMS {:.3} %, max {:.3} % of max |u|",
        100.0 * rms / u_max,
        100.0 * worst / u_max
    );
    assert!(n > x_fem.len() / 2);
    // issue 47's M4 asks 10 % of max |u|; measured (BENCHMARKS.md, "M4"): RMS 26 % at this setting, 15–21 % with
    // longer horizons or half the spacing, and max |u| still changing with the horizon at KE/elastic ~1e-6.
    // This bound guards the standing, it does not claim M4.
    assert!(rms <= 0.3 * u_max, "RMS {rms} vs max |u| {u_max}");
}
