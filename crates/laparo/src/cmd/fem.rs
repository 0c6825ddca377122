//! `laparo fem ...`: the FEM ground truth of the in-silico incision benchmark (thesis §5.4.2):
//! quasi-static nearly incompressible Neo-Hookean (eq. 5.3) on quadratic tetrahedra.
use anyhow::{bail, Context, Result};
use clap::{Subcommand, ValueEnum};
use laparo_core::image::Image;
use laparo_core::io::write_npy_f64;
use laparo_core::mesh::{read_msh, read_vtk, TetMesh};
use laparo_fem::solid::{
    solve, FaceTraction, LinearSolver, Loads, NodalForce, Quadrature, SolidProblem, SolverSettings, Tet10Mesh,
};
use laparo_fem::NeoHookean;
use nalgebra::Vector3;
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum FemCmd {
    /// Solve for the static equilibrium under dead loads (see crates/laparo-fem/README.md, "FEM ground
    /// truth", for the JSON formats). Writes `displacement.npy` ((V, 3) mm at the linear vertices),
    /// `displacement_tet10.npy` ((N, 3) mm at every TET10 node), `displacement.vtk` (ParaView, point
    /// data `displacement`) and `report.json` into --out.
    Solve(SolveArgs),
}

#[derive(Clone, Copy, ValueEnum)]
pub enum QuadArg {
    /// 4 points, degree 2.
    Degree2,
    /// 14 points, degree 5.
    Degree5,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum SolverArg {
    /// Direct (sparse Cholesky) for small meshes, two-level beyond a 32 MiB factor.
    Auto,
    /// Sparse Cholesky of the tangent, reused as a CG preconditioner.
    Direct,
    /// CG with a two-level preconditioner (TET10 Gauss–Seidel, linear-tet coarse Cholesky): memory linear
    /// in the mesh.
    TwoLevel,
}

#[derive(clap::Args)]
pub struct SolveArgs {
    /// Linear tetrahedral mesh (.msh Gmsh or .vtk legacy), lengths in mm (see --scale).
    #[arg(long)]
    mesh: PathBuf,
    /// Multiply the mesh coordinates by this (e.g. 10 for a mesh in cm).
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Fixed vertices: {"vertices": [i, ...]} (0-based linear-mesh vertex ids).
    #[arg(long)]
    fixed: PathBuf,
    /// Loads: {"face_tractions": [{"face": [a,b,c], "traction_kpa": [x,y,z]} or {"face": [a,b,c],
    /// "normal_traction_kpa": p}], "nodal_forces": [{"vertex": i, "force_mn": [x,y,z]}]}.
    #[arg(long)]
    loads: PathBuf,
    /// Load increments.
    #[arg(long, default_value_t = 20)]
    steps: usize,
    /// Young's modulus E (kPa).
    #[arg(long, default_value_t = 4.1)]
    young_kpa: f64,
    /// Poisson's ratio ν.
    #[arg(long, default_value_t = 0.49)]
    poisson: f64,
    /// Convergence: ‖residual‖ ≤ rel_tol × ‖applied load‖.
    #[arg(long, default_value_t = 1e-8)]
    rel_tol: f64,
    /// Element quadrature.
    #[arg(long, value_enum, default_value = "degree2")]
    quadrature: QuadArg,
    /// Solver of the Newton directions.
    #[arg(long, value_enum, default_value = "auto")]
    solver: SolverArg,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FixedJson {
    vertices: Vec<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TractionJson {
    face: [usize; 3],
    #[serde(default)]
    traction_kpa: Option<[f64; 3]>,
    #[serde(default)]
    normal_traction_kpa: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ForceJson {
    vertex: usize,
    force_mn: [f64; 3],
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct LoadsJson {
    #[serde(default)]
    face_tractions: Vec<TractionJson>,
    #[serde(default)]
    nodal_forces: Vec<ForceJson>,
}

pub fn run(c: FemCmd) -> Result<()> {
    match c {
        FemCmd::Solve(a) => solve_cmd(&a),
    }
}

fn read_tets(path: &Path) -> Result<TetMesh> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    Ok(match ext.as_str() {
        "msh" => read_msh(path)?,
        "vtk" => read_vtk(path)?,
        _ => bail!("--mesh {}: expected a .msh or .vtk tetrahedral mesh", path.display()),
    })
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path, what: &str) -> Result<T> {
    let s = std::fs::read_to_string(path).with_context(|| format!("{what} {}: cannot read", path.display()))?;
    serde_json::from_str(&s).with_context(|| format!("{what} {}: invalid JSON", path.display()))
}

fn solve_cmd(a: &SolveArgs) -> Result<()> {
    if !(a.scale.is_finite() && a.scale > 0.0) {
        bail!("--scale {}: must be finite and > 0", a.scale);
    }
    laparo_core::atomic::refuse_overwrite_in(
        &a.out,
        &["displacement.npy", "displacement_tet10.npy", "displacement.vtk", "report.json"],
        &[&a.mesh, &a.fixed, &a.loads],
    )
    .context("--out")?;
    let mut lin = read_tets(&a.mesh).with_context(|| format!("--mesh {}", a.mesh.display()))?;
    for v in &mut lin.vertices {
        *v *= a.scale;
    }
    let fixed: FixedJson = read_json(&a.fixed, "--fixed")?;
    let loads_json: LoadsJson = read_json(&a.loads, "--loads")?;
    let material = NeoHookean::from_young_poisson(a.young_kpa, a.poisson).context("--young-kpa / --poisson")?;
    let mesh = Tet10Mesh::from_linear(&lin).with_context(|| format!("--mesh {}", a.mesh.display()))?;
    let dirichlet = SolidProblem::fixed_vertices(&mesh, &fixed.vertices)
        .with_context(|| format!("--fixed {}", a.fixed.display()))?;
    let mut loads = Loads::default();
    for (k, t) in loads_json.face_tractions.iter().enumerate() {
        let what = format!("--loads {}: face_tractions[{k}]", a.loads.display());
        if let Some(&v) = t.face.iter().find(|&&v| v >= lin.vertices.len()) {
            bail!("{what}: vertex {v} out of range ({} vertices)", lin.vertices.len());
        }
        let traction = match (t.traction_kpa, t.normal_traction_kpa) {
            (Some(v), None) => FaceTraction { face: t.face, traction_kpa: Vector3::from(v) },
            (None, Some(p)) => FaceTraction::normal(&lin.vertices, t.face, p, &what)?,
            _ => bail!("{what}: give exactly one of traction_kpa or normal_traction_kpa"),
        };
        loads.face_tractions.push(traction);
    }
    for (k, f) in loads_json.nodal_forces.iter().enumerate() {
        if f.vertex >= lin.vertices.len() {
            bail!(
                "--loads {}: nodal_forces[{k}]: vertex {} out of range ({} vertices)",
                a.loads.display(),
                f.vertex,
                lin.vertices.len()
            );
        }
        loads.nodal_forces.push(NodalForce { node: f.vertex, force_mn: Vector3::from(f.force_mn) });
    }
    let quadrature = match a.quadrature {
        QuadArg::Degree2 => Quadrature::Degree2,
        QuadArg::Degree5 => Quadrature::Degree5,
    };
    let problem = SolidProblem::new(mesh, material, &dirichlet, &loads, quadrature)
        .with_context(|| format!("--fixed {} / --loads {}", a.fixed.display(), a.loads.display()))?;
    let linear = match a.solver {
        SolverArg::Auto => LinearSolver::default(),
        SolverArg::Direct => LinearSolver::Direct,
        SolverArg::TwoLevel => LinearSolver::TwoLevel,
    };
    let settings = SolverSettings { steps: a.steps, rel_tol: a.rel_tol, linear, ..Default::default() };
    let sol = solve(&problem, &settings)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("--out {}: cannot create", a.out.display()))?;
    let to_img = |d: &[Vector3<f64>]| -> Result<Image<f64>> {
        Ok(Image::from_vec(3, d.len(), 1, d.iter().flat_map(|v| v.iter().copied()).collect())?)
    };
    write_npy_f64(a.out.join("displacement.npy"), &to_img(sol.vertex_displacements())?)?;
    write_npy_f64(a.out.join("displacement_tet10.npy"), &to_img(&sol.displacement)?)?;
    write_vtk_displacement(&a.out.join("displacement.vtk"), &lin, sol.vertex_displacements())?;
    let f_total: Vector3<f64> = problem.external_force().chunks(3).map(|c| Vector3::new(c[0], c[1], c[2])).sum();
    let report = serde_json::json!({
        "mesh": a.mesh.display().to_string(),
        "scale": a.scale,
        "vertices": lin.vertices.len(),
        "tets": lin.tets.len(),
        "tet10_nodes": problem.mesh.n_nodes(),
        "fixed_vertices": fixed.vertices.len(),
        "young_kpa": a.young_kpa,
        "poisson": a.poisson,
        "quadrature": quadrature,
        "settings": settings,
        "total_external_force_mn": [f_total.x, f_total.y, f_total.z],
        "solution": sol,
    });
    laparo_core::atomic::write_atomic(&a.out.join("report.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    let t = &sol.timings;
    println!(
        "{}: {} TET10 nodes, {} free DOFs, {} increments, {} Newton iterations, max |u| {:.4} mm, min J {:.4}; \
         {:.2} s ({} solver: assembly {:.2} s, {} factorisations {:.2} s, {} CG iterations, solves {:.2} s) -> {}",
        a.mesh.display(),
        problem.mesh.n_nodes(),
        sol.free_dofs,
        sol.steps.len(),
        t.newton_iterations,
        sol.max_displacement_mm,
        sol.min_j,
        t.total_s,
        sol.linear_solver,
        t.assembly_s,
        t.factorizations,
        t.factorization_s,
        t.pcg_iterations,
        t.solve_s,
        a.out.display()
    );
    Ok(())
}

/// Legacy ASCII VTK of the linear tets with point data `displacement` (mm).
fn write_vtk_displacement(path: &Path, mesh: &TetMesh, u: &[Vector3<f64>]) -> Result<()> {
    laparo_core::mesh::write_vtk_fields(
        path,
        "laparo fem displacement (mm)",
        &mesh.vertices,
        &mesh.tets,
        &[laparo_core::mesh::VtkField::new("displacement", laparo_core::mesh::VtkValues::Vector(u))],
        &[],
    )
    .with_context(|| format!("writing {}", path.display()))
}
