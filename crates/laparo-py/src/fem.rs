//! `laparo.fem`: volume meshing and the quasi-static Neo-Hookean FEM of the incision benchmark
//! (thesis §5.4.2, eq. 5.3): a closed surface → BCC tetrahedra with a quality report; a linear
//! tetrahedral mesh + fixed vertices + dead loads → the TET10 equilibrium displacement. The same
//! library calls as `laparo mesh tetra` and `laparo fem solve`, on NumPy arrays.
use crate::arrays::*;
use laparo_core::mesh::{TetMesh, TriMesh};
use laparo_fem::mesh::{quality_report, tetrahedralize, QualityReport, Surface, TetraParams};
use laparo_fem::solid::{
    solve, FaceTraction, LinearSolver, Loads, NodalForce, Quadrature, SolidProblem, SolverSettings, Tet10Mesh,
};
use laparo_fem::NeoHookean;
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn surface(vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>, what: &str) -> PyResult<Surface> {
    let v = points3(vertices, "vertices")?;
    let f = index_rows::<3>(faces, "faces", what, v.len())?;
    Surface::new(TriMesh { vertices: v, faces: f }, what).map_err(lib_err)
}

fn mesh_out<'py>(py: Python<'py>, mesh: &TetMesh) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let nodes = to_numpy(py, flat(&mesh.vertices), &[mesh.vertices.len(), 3])?;
    let tets = to_numpy(py, mesh.tets.iter().flatten().map(|&k| k as i64).collect(), &[mesh.tets.len(), 4])?;
    Ok((nodes, tets))
}

/// Tetrahedralise the closed surface (vertices (N, 3) mm, faces (F, 3)) on a BCC lattice; returns
/// (nodes (M, 3) mm, tets (T, 4) int64, quality report dict).
#[pyfunction]
#[pyo3(signature = (vertices, faces, edge_mm=6.0, min_dihedral_deg=10.0, snap_passes=4))]
pub fn fem_tetrahedralize<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    edge_mm: f64,
    min_dihedral_deg: f64,
    snap_passes: usize,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guard(|| {
        if !(edge_mm.is_finite() && edge_mm > 0.0) {
            return Err(bad("edge_mm", format!("{edge_mm}: must be finite and > 0")));
        }
        if !(min_dihedral_deg.is_finite() && (0.0..=60.0).contains(&min_dihedral_deg)) {
            return Err(bad("min_dihedral_deg", format!("{min_dihedral_deg}: must be in [0, 60]")));
        }
        let s = surface(vertices, faces, "surface")?;
        let params = TetraParams { edge_mm, min_dihedral_deg, snap_passes };
        let (mesh, report): (TetMesh, QualityReport) = par(py, || {
            let m = tetrahedralize(&s, &params)?;
            let r = quality_report(&m, Some(&s));
            Ok::<_, laparo_fem::FemError>((m, r))
        })
        .map_err(lib_err)?;
        let (n, t) = mesh_out(py, &mesh)?;
        Ok((n, t, to_py(py, &report)?))
    })
}

/// Quality report of a tetrahedral mesh (nodes (N, 3) mm, tets (T, 4)); with the closed surface it
/// was built from (vertices, faces), also the volume error and boundary distances.
#[pyfunction]
#[pyo3(signature = (nodes, tets, surface_vertices=None, surface_faces=None))]
pub fn fem_quality<'py>(
    py: Python<'py>,
    nodes: &Bound<'py, PyAny>,
    tets: &Bound<'py, PyAny>,
    surface_vertices: Option<&Bound<'py, PyAny>>,
    surface_faces: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let mesh = tet_mesh(nodes, tets)?;
        let s = match (surface_vertices, surface_faces) {
            (Some(v), Some(f)) => Some(surface(v, f, "surface")?),
            (None, None) => None,
            _ => return Err(bad("surface", "give both surface_vertices and surface_faces, or neither")),
        };
        let report = par(py, || quality_report(&mesh, s.as_ref()));
        to_py(py, &report)
    })
}

/// Static equilibrium of the nearly incompressible Neo-Hookean solid (eq. 5.3) on the TET10 mesh of
/// (nodes, tets) under dead loads ramped over `steps` increments (Newton + line search); returns a dict
/// with `displacement` (N, 3) mm at the linear vertices, `tet10_nodes` / `displacement_tet10`
/// (M, 3) mm and the solver `report`.
#[pyfunction]
#[pyo3(signature = (nodes, tets, fixed, face_faces=None, face_tractions_kpa=None, force_vertices=None, forces_mn=None,
    young_kpa=4.1, poisson=0.49, steps=20, rel_tol=1e-8, quadrature="degree2", solver="auto"))]
#[allow(clippy::too_many_arguments)]
pub fn fem_solve<'py>(
    py: Python<'py>,
    nodes: &Bound<'py, PyAny>,
    tets: &Bound<'py, PyAny>,
    fixed: &Bound<'py, PyAny>,
    face_faces: Option<&Bound<'py, PyAny>>,
    face_tractions_kpa: Option<&Bound<'py, PyAny>>,
    force_vertices: Option<&Bound<'py, PyAny>>,
    forces_mn: Option<&Bound<'py, PyAny>>,
    young_kpa: f64,
    poisson: f64,
    steps: usize,
    rel_tol: f64,
    quadrature: &str,
    solver: &str,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let lin = tet_mesh(nodes, tets)?;
        let n = lin.vertices.len();
        let fixed = indices(fixed, "fixed", n)?;
        let material = NeoHookean::from_young_poisson(young_kpa, poisson).map_err(lib_err)?;
        if steps == 0 {
            return Err(bad("steps", "must be ≥ 1"));
        }
        if !(rel_tol.is_finite() && rel_tol > 0.0) {
            return Err(bad("rel_tol", format!("{rel_tol}: must be finite and > 0")));
        }
        let quadrature = match quadrature {
            "degree2" => Quadrature::Degree2,
            "degree5" => Quadrature::Degree5,
            q => return Err(bad("quadrature", format!("{q:?}: expected degree2 or degree5"))),
        };
        let linear = match solver {
            "auto" => LinearSolver::default(),
            "direct" => LinearSolver::Direct,
            "two-level" => LinearSolver::TwoLevel,
            s => return Err(bad("solver", format!("{s:?}: expected auto, direct or two-level"))),
        };
        let mut loads = Loads::default();
        match (face_faces, face_tractions_kpa) {
            (Some(f), Some(t)) => {
                let faces = index_rows::<3>(f, "face_faces", "face_faces", n)?;
                let t = f64_array(t, "face_tractions_kpa")?;
                t.require_finite("face_tractions_kpa")?;
                match t.shape.as_slice() {
                    [m] if *m == faces.len() => {
                        for (k, (face, &p)) in faces.iter().zip(&t.data).enumerate() {
                            let what = format!("face_faces[{k}]");
                            loads
                                .face_tractions
                                .push(FaceTraction::normal(&lin.vertices, *face, p, &what).map_err(lib_err)?);
                        }
                    }
                    [m, 3] if *m == faces.len() => {
                        for (face, v) in faces.iter().zip(t.data.chunks_exact(3)) {
                            loads.face_tractions.push(FaceTraction {
                                face: *face,
                                traction_kpa: nalgebra::Vector3::new(v[0], v[1], v[2]),
                            });
                        }
                    }
                    s => {
                        return Err(bad(
                            "face_tractions_kpa",
                            format!("expected ({0},) normal pressures or ({0}, 3) vectors, got {s:?}", faces.len()),
                        ))
                    }
                }
            }
            (None, None) => {}
            _ => return Err(bad("face_tractions_kpa", "give both face_faces and face_tractions_kpa, or neither")),
        }
        match (force_vertices, forces_mn) {
            (Some(v), Some(f)) => {
                let v = indices(v, "force_vertices", n)?;
                let f = points3(f, "forces_mn")?;
                if f.len() != v.len() {
                    return Err(bad("forces_mn", format!("{} forces for {} force_vertices", f.len(), v.len())));
                }
                loads.nodal_forces.extend(v.iter().zip(&f).map(|(&node, &force_mn)| NodalForce { node, force_mn }));
            }
            (None, None) => {}
            _ => return Err(bad("forces_mn", "give both force_vertices and forces_mn, or neither")),
        }
        let mesh = Tet10Mesh::from_linear(&lin).map_err(lib_err)?;
        let dirichlet = SolidProblem::fixed_vertices(&mesh, &fixed).map_err(lib_err)?;
        let problem = SolidProblem::new(mesh, material, &dirichlet, &loads, quadrature).map_err(lib_err)?;
        let settings = SolverSettings { steps, rel_tol, linear, ..Default::default() };
        let sol = par(py, || solve(&problem, &settings)).map_err(lib_err)?;
        let out = PyDict::new(py);
        out.set_item("displacement", to_numpy(py, flat(sol.vertex_displacements()), &[n, 3])?)?;
        let m = problem.mesh.n_nodes();
        out.set_item("tet10_nodes", to_numpy(py, flat(&problem.mesh.nodes), &[m, 3])?)?;
        out.set_item("displacement_tet10", to_numpy(py, flat(&sol.displacement), &[m, 3])?)?;
        out.set_item("report", to_py(py, &sol)?)?;
        Ok(out.into_any())
    })
}

/// Crack the tetrahedral mesh (nodes, tets) along a blade swept from the `mouth` polyline (P, 3) mm
/// inward along `directions` (3,) or (P, 3) to `depths_mm` (scalar or (P,)); returns a dict with the cut
/// mesh (`nodes`, `tets`: crack nodes duplicated), `crack_faces_a` / `crack_faces_b` (each wound outward
/// from its own side), `lips` (the two mouth polylines as node ids), `original_node`, `tet_side`,
/// `front_nodes`, the blade triangles (`blade_vertices`, `blade_faces`) and, when `landmarks` > 0, that
/// many lip landmarks (half per lip, equally spaced by arc length: `landmark_side`, `landmark_nodes`
/// (L, 2), `landmark_t`, `landmark_positions` (L, 3) mm).
#[pyfunction]
#[pyo3(signature = (nodes, tets, mouth, directions, depths_mm, overshoot_mm=2.0, landmarks=0))]
#[allow(clippy::too_many_arguments)]
pub fn fem_cut<'py>(
    py: Python<'py>,
    nodes: &Bound<'py, PyAny>,
    tets: &Bound<'py, PyAny>,
    mouth: &Bound<'py, PyAny>,
    directions: &Bound<'py, PyAny>,
    depths_mm: &Bound<'py, PyAny>,
    overshoot_mm: f64,
    landmarks: usize,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let mesh = tet_mesh(nodes, tets)?;
        let mouth = points3(mouth, "mouth")?;
        let p = mouth.len();
        let d = f64_array(directions, "directions")?;
        d.require_finite("directions")?;
        let directions: Vec<nalgebra::Vector3<f64>> = match d.shape.as_slice() {
            [3] => vec![nalgebra::Vector3::new(d.data[0], d.data[1], d.data[2]); p],
            [m, 3] if *m == p => d.data.chunks_exact(3).map(|c| nalgebra::Vector3::new(c[0], c[1], c[2])).collect(),
            s => return Err(bad("directions", format!("expected (3,) or ({p}, 3), got {s:?}"))),
        };
        if let Some(i) = directions.iter().position(|v| v.norm() == 0.0) {
            return Err(bad("directions", format!("direction {i} is zero")));
        }
        let directions: Vec<_> = directions.iter().map(|v| v.normalize()).collect();
        let depths: Vec<f64> = match depths_mm.extract::<f64>() {
            Ok(x) => vec![x; p],
            Err(_) => {
                let a = f64_array(depths_mm, "depths_mm")?;
                if a.shape != [p] {
                    return Err(bad("depths_mm", format!("expected a scalar or ({p},), got {:?}", a.shape)));
                }
                a.data
            }
        };
        let blade = laparo_fem::mesh::Blade { mouth, directions, depths, overshoot_mm };
        let cut = par(py, || laparo_fem::mesh::cut(&mesh, &blade)).map_err(lib_err)?;
        let lms = if landmarks > 0 { Some(cut.landmarks(landmarks).map_err(lib_err)?) } else { None };
        let ids = |v: &[usize]| v.iter().map(|&k| k as i64).collect::<Vec<i64>>();
        let tri = |f: &[[usize; 3]]| f.iter().flatten().map(|&k| k as i64).collect::<Vec<i64>>();
        let out = PyDict::new(py);
        let (n, t) = mesh_out(py, &cut.mesh)?;
        out.set_item("nodes", n)?;
        out.set_item("tets", t)?;
        for (k, name) in ["crack_faces_a", "crack_faces_b"].iter().enumerate() {
            out.set_item(*name, to_numpy(py, tri(&cut.crack_faces[k]), &[cut.crack_faces[k].len(), 3])?)?;
        }
        let lips = [
            to_numpy(py, ids(&cut.lips[0]), &[cut.lips[0].len()])?,
            to_numpy(py, ids(&cut.lips[1]), &[cut.lips[1].len()])?,
        ];
        out.set_item("lips", lips.to_vec())?;
        out.set_item("original_node", to_numpy(py, ids(&cut.original_node), &[cut.original_node.len()])?)?;
        let side: Vec<i64> = cut.tet_side.iter().map(|&s| i64::from(s)).collect();
        out.set_item("tet_side", to_numpy(py, side, &[cut.tet_side.len()])?)?;
        out.set_item("front_nodes", to_numpy(py, ids(&cut.front_nodes), &[cut.front_nodes.len()])?)?;
        out.set_item("blade_vertices", to_numpy(py, flat(&cut.blade.vertices), &[cut.blade.vertices.len(), 3])?)?;
        out.set_item("blade_faces", to_numpy(py, tri(&cut.blade.faces), &[cut.blade.faces.len(), 3])?)?;
        if let Some(l) = lms {
            let m = l.items.len();
            out.set_item("landmark_side", to_numpy(py, l.items.iter().map(|x| i64::from(x.side)).collect(), &[m])?)?;
            let pairs: Vec<i64> = l.items.iter().flat_map(|x| [x.a as i64, x.b as i64]).collect();
            out.set_item("landmark_nodes", to_numpy(py, pairs, &[m, 2])?)?;
            out.set_item("landmark_t", to_numpy(py, l.items.iter().map(|x| x.t).collect(), &[m])?)?;
            out.set_item(
                "landmark_positions",
                to_numpy(py, flat(&l.landmark_positions(&cut.mesh.vertices)), &[m, 3])?,
            )?;
        }
        Ok(out.into_any())
    })
}
