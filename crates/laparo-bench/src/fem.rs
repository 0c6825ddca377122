//! `laparo-bench fem`: the fill-reducing ordering of the FEM ground truth's sparse Cholesky on the P2ILF
//! liver (non-anatomical cut, TET10, fixed posterior region): AMD against geometric nested dissection,
//! one symbolic and one numeric factorisation of the tangent at rest per mesh size, same run.
use crate::timing::peak_rss_mb;
use anyhow::{Context, Result};
use clap::Args;
use laparo_fem::mesh::{non_anatomical, tetrahedralize_surface, NonAnatomicalParams, ScenarioFrame, TetraParams};
use laparo_fem::solid::{factorization_profile, FillOrdering, Loads, Quadrature, SolidProblem, Tet10Mesh};
use laparo_fem::NeoHookean;
use std::path::PathBuf;

/// Options of `laparo-bench fem`.
#[derive(Args)]
pub struct BenchArgs {
    /// Tetrahedron edges (mm), comma separated.
    #[arg(long, default_value = "12,10,8")]
    pub edge_mm: String,
    /// Closed liver surface (mm).
    #[arg(long, default_value = "../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj")]
    pub liver: PathBuf,
    /// Orderings, comma separated, among amd, nd.
    #[arg(long, default_value = "amd,nd")]
    pub orderings: String,
    /// Only the ordering and symbolic analysis: the factor's size (its memory, 8 bytes per nonzero),
    /// for meshes whose numeric factorisation would not fit.
    #[arg(long)]
    pub symbolic_only: bool,
}

pub fn run(a: BenchArgs) -> Result<()> {
    let surface = laparo_core::mesh::read_mesh(&a.liver).with_context(|| format!("--liver {}", a.liver.display()))?;
    for e in a.edge_mm.split(',') {
        let edge: f64 = e.trim().parse().with_context(|| format!("--edge-mm: {e:?} is not a number"))?;
        let (mesh, _) = tetrahedralize_surface(
            surface.clone(),
            &a.liver.display().to_string(),
            &TetraParams { edge_mm: edge, ..Default::default() },
        )?;
        let mut scn = non_anatomical(&mesh, &ScenarioFrame::default(), &NonAnatomicalParams::default())?;
        // a fragment the blade cuts free is resected, as in `laparo register benchmark`
        laparo_register::benchmark::build::drop_detached_fragments(&mut scn);
        let m = Tet10Mesh::from_linear(&scn.cut.mesh)?;
        let fixed = SolidProblem::fixed_vertices(&m, &scn.fixed_nodes)?;
        let p = SolidProblem::new(m, NeoHookean::liver(), &fixed, &Loads::default(), Quadrature::Degree2)?;
        for o in a.orderings.split(',') {
            let ordering = match o.trim() {
                "amd" => FillOrdering::Amd,
                "nd" => FillOrdering::NestedDissection,
                other => anyhow::bail!("--orderings: unknown ordering {other:?} (amd, nd)"),
            };
            let f = factorization_profile(&p, ordering, !a.symbolic_only)?;
            println!(
                "{}",
                serde_json::json!({"edge_mm": edge, "ordering": format!("{ordering:?}"), "free_dofs": f.free_dofs,
                    "tangent_nnz": f.tangent_nnz, "factor_nnz": f.factor_nnz, "symbolic_s": f.symbolic_s,
                    "factor_values_gb": f.factor_nnz as f64 * 8.0 / 1e9,
                    "numeric_s": f.numeric_s, "peak_rss_mb": peak_rss_mb()})
            );
        }
    }
    Ok(())
}
