//! The discrete quasi-static problem: TET10 mesh, Neo-Hookean law (eq. 5.3), Dirichlet conditions,
//! dead loads; total potential energy Π(u) = Σ_e ∫ ψ(F) dV − t f_ext·u, its gradient (internal minus
//! external forces) and Hessian (tangent stiffness), assembled in parallel in a fixed order.
use super::quadrature::{tet10_shape, tet10_shape_grad, Quadrature};
use super::tet10::Tet10Mesh;
use crate::error::{FemError, Result};
use crate::material::NeoHookean;
use nalgebra::{DMatrix, Matrix3, SMatrix, Vector3};
use rayon::prelude::*;
use std::sync::Arc;

/// A prescribed displacement (mm) of one TET10 node, reached at load factor 1 (ramped linearly).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dirichlet {
    /// TET10 node id (vertex ids of the linear mesh are node ids too).
    pub node: usize,
    /// Displacement at load factor 1 (mm).
    pub value_mm: Vector3<f64>,
}

/// A uniform dead traction (kPa = mN/mm², reference configuration) on a linear boundary triangle,
/// integrated with the quadratic face shape functions (vertices get 0, mid-edge nodes A·t/3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceTraction {
    /// Linear-mesh vertex ids of the triangle.
    pub face: [usize; 3],
    /// Traction vector (kPa); e.g. ±p n_face for equal and opposite tractions on two cut faces.
    pub traction_kpa: Vector3<f64>,
}

impl FaceTraction {
    /// A pressure `p_kpa` along the unit normal (b − a) × (c − a) of the triangle `face` of the linear
    /// mesh with vertices `vertices` (mm); errors name `what` for an out-of-range id or a zero-area face.
    pub fn normal(vertices: &[Vector3<f64>], face: [usize; 3], p_kpa: f64, what: &str) -> Result<Self> {
        if let Some(&v) = face.iter().find(|&&v| v >= vertices.len()) {
            return Err(FemError::bad(what, format!("vertex {v} out of range ({} vertices)", vertices.len())));
        }
        let x = |i: usize| vertices[face[i]];
        let n = (x(1) - x(0)).cross(&(x(2) - x(0)));
        if n.norm() == 0.0 || !n.norm().is_finite() {
            return Err(FemError::bad(what, format!("degenerate face {face:?}")));
        }
        Ok(FaceTraction { face, traction_kpa: n.normalize() * p_kpa })
    }
}

/// A dead point force (mN) on one TET10 node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodalForce {
    /// TET10 node id.
    pub node: usize,
    /// Force (mN).
    pub force_mn: Vector3<f64>,
}

/// Body force density b(X) (kPa/mm = mN/mm³) as a function of the reference position X (mm).
pub type BodyForce = Arc<dyn Fn(&Vector3<f64>) -> Vector3<f64> + Send + Sync>;

/// All dead loads, scaled together by the load factor t ∈ [0, 1].
#[derive(Clone, Default)]
pub struct Loads {
    /// Face tractions.
    pub face_tractions: Vec<FaceTraction>,
    /// Nodal forces.
    pub nodal_forces: Vec<NodalForce>,
    /// Optional body force density.
    pub body_force: Option<BodyForce>,
}

/// Element quantities wanted from an evaluation.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Want {
    Energy,
    Force,
    Tangent,
}

pub(crate) struct ElemOut {
    pub energy: f64,
    pub force: [f64; 30],
    pub tangent: Option<Box<[f64; 900]>>,
    pub min_j: f64,
}

/// Global assembled quantities at one state.
pub struct Assembled {
    /// Strain energy Σ_e ∫ ψ dV (µJ = kPa·mm³ … mN·mm).
    pub strain_energy: f64,
    /// Internal force f_int (mN), 3 per node.
    pub internal_force: Vec<f64>,
    /// Tangent stiffness as 3×3 node blocks (mN/mm) in the pattern of [`SolidProblem`], when asked.
    pub(crate) blocks: Option<Vec<f64>>,
    /// Minimum det F over all quadrature points.
    pub min_j: f64,
}

/// The discrete problem (mm, kPa, mN).
pub struct SolidProblem {
    /// The TET10 mesh.
    pub mesh: Tet10Mesh,
    /// The material (eq. 5.3).
    pub material: NeoHookean,
    /// Quadrature rule of the element integrals.
    pub quadrature: Quadrature,
    /// Prescribed displacement at load factor 1 per node (`None` = free).
    pub(crate) prescribed: Vec<Option<Vector3<f64>>>,
    /// External force at load factor 1 (mN), 3 per node.
    pub(crate) f_ext: Vec<f64>,
    /// Quadrature weights and reference gradients.
    qp: Vec<(f64, SMatrix<f64, 10, 3>)>,
    /// Node-block adjacency (CSR): neighbours of node A are `cols[row_ptr[A]..row_ptr[A+1]]`, sorted.
    pub(crate) row_ptr: Vec<usize>,
    pub(crate) cols: Vec<usize>,
    /// Per element, block index of each (a, b) pair (row-major 10×10).
    elem_blocks: Vec<[u32; 100]>,
    /// Per element, the factor s_e on both Lamé constants (μ s_e, λ s_e); empty: 1 everywhere.
    element_scale: Vec<f64>,
}

const CHUNK: usize = 2048;

/// Node adjacency (CSR over `n` nodes, each row sorted, self included) of elements given by their node lists.
pub(crate) fn node_adjacency<'a>(n: usize, elements: impl Iterator<Item = &'a [usize]>) -> (Vec<usize>, Vec<usize>) {
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
    for el in elements {
        for &a in el {
            adj[a].extend_from_slice(el);
        }
    }
    let mut row_ptr = Vec::with_capacity(n + 1);
    let mut cols = Vec::new();
    row_ptr.push(0);
    for l in adj.iter_mut() {
        l.sort_unstable();
        l.dedup();
        cols.extend_from_slice(l);
        row_ptr.push(cols.len());
    }
    (row_ptr, cols)
}

impl SolidProblem {
    /// Set up the problem; errors on out-of-range ids, non-finite values, missing Dirichlet
    /// conditions (rigid-body modes) and bad faces.
    pub fn new(
        mesh: Tet10Mesh,
        material: NeoHookean,
        dirichlet: &[Dirichlet],
        loads: &Loads,
        quadrature: Quadrature,
    ) -> Result<Self> {
        let n = mesh.n_nodes();
        let mut prescribed = vec![None; n];
        for d in dirichlet {
            if d.node >= n {
                return Err(FemError::bad("fixed nodes", format!("node {} out of range (mesh has {n} nodes)", d.node)));
            }
            if !d.value_mm.iter().all(|v| v.is_finite()) {
                return Err(FemError::bad("fixed nodes", format!("node {}: non-finite displacement", d.node)));
            }
            prescribed[d.node] = Some(d.value_mm);
        }
        check_rigid_modes(&mesh, &prescribed)?;
        let mut f_ext = vec![0.0; 3 * n];
        for (k, ft) in loads.face_tractions.iter().enumerate() {
            if ft.face.iter().any(|&v| v >= mesh.n_vertices) {
                return Err(FemError::bad(
                    "loads",
                    format!("face_tractions[{k}]: vertex id out of range in {:?}", ft.face),
                ));
            }
            if !ft.traction_kpa.iter().all(|v| v.is_finite()) {
                return Err(FemError::bad("loads", format!("face_tractions[{k}]: non-finite traction")));
            }
            let nodes =
                mesh.face_nodes(ft.face).map_err(|e| FemError::bad("loads", format!("face_tractions[{k}]: {e}")))?;
            let x = |i: usize| mesh.nodes[ft.face[i]];
            let area = 0.5 * (x(1) - x(0)).cross(&(x(2) - x(0))).norm();
            // ∫ N dA on a flat 6-node triangle: 0 at the vertices, A/3 at the mid-edge nodes.
            for &m in &nodes[3..] {
                for c in 0..3 {
                    f_ext[3 * m + c] += area / 3.0 * ft.traction_kpa[c];
                }
            }
        }
        for (k, nf) in loads.nodal_forces.iter().enumerate() {
            if nf.node >= n || !nf.force_mn.iter().all(|v| v.is_finite()) {
                return Err(FemError::bad(
                    "loads",
                    format!("nodal_forces[{k}]: node {} out of range or non-finite force", nf.node),
                ));
            }
            for c in 0..3 {
                f_ext[3 * nf.node + c] += nf.force_mn[c];
            }
        }
        if let Some(b) = &loads.body_force {
            let rule = Quadrature::Degree5.points();
            let per: Vec<[f64; 30]> = (0..mesh.elements.len())
                .into_par_iter()
                .map(|e| {
                    let mut fe = [0.0; 30];
                    for q in &rule {
                        let nv = tet10_shape(&q.xi);
                        let bx = b(&mesh.position(e, &q.xi));
                        let w = q.weight * mesh.jac_det[e];
                        for a in 0..10 {
                            for c in 0..3 {
                                fe[3 * a + c] += w * nv[a] * bx[c];
                            }
                        }
                    }
                    fe
                })
                .collect();
            for (e, fe) in per.iter().enumerate() {
                for (a, &node) in mesh.elements[e].iter().enumerate() {
                    for c in 0..3 {
                        f_ext[3 * node + c] += fe[3 * a + c];
                    }
                }
            }
            if !f_ext.iter().all(|v| v.is_finite()) {
                return Err(FemError::bad("loads", "body force is not finite"));
            }
        }
        check_load_scale(&mesh, &material, &f_ext)?;
        let qp = quadrature.points().iter().map(|q| (q.weight, tet10_shape_grad(&q.xi))).collect();
        let (row_ptr, cols) = node_adjacency(n, mesh.elements.iter().map(|el| &el[..]));
        let elem_blocks = mesh
            .elements
            .par_iter()
            .map(|el| {
                let mut bi = [0u32; 100];
                for a in 0..10 {
                    let row = &cols[row_ptr[el[a]]..row_ptr[el[a] + 1]];
                    for b in 0..10 {
                        let p = row.binary_search(&el[b]).expect("neighbour in pattern");
                        bi[10 * a + b] = (row_ptr[el[a]] + p) as u32;
                    }
                }
                bi
            })
            .collect();
        if cols.len() > u32::MAX as usize {
            return Err(FemError::bad("tet mesh", "too large (block count exceeds u32)"));
        }
        Ok(Self {
            mesh,
            material,
            quadrature,
            prescribed,
            f_ext,
            qp,
            row_ptr,
            cols,
            elem_blocks,
            element_scale: Vec::new(),
        })
    }

    /// A heterogeneous material: element `e` gets the Lamé constants (s_e μ, s_e λ) of [`Self::material`]
    /// (e.g. a stiffer inclusion; ν unchanged). The Neo-Hookean energy density of eq. 5.3 is linear in
    /// (μ, λ), so ψ, P and ∂P/∂F of element `e` are those of the base material times s_e: the factor
    /// multiplies the element's quadrature weights, with no other change to the assembly. One factor per
    /// element, each finite and > 0 ([`FemError::InvalidParameter`] naming `element_scale` else).
    pub fn with_element_scale(mut self, scale: Vec<f64>) -> Result<Self> {
        let ne = self.mesh.elements.len();
        if scale.len() != ne {
            return Err(FemError::param(
                "element_scale",
                scale.len() as f64,
                format!("need one factor per element ({ne} elements)"),
            ));
        }
        if let Some((e, &s)) = scale.iter().enumerate().find(|(_, s)| !(s.is_finite() && **s > 0.0)) {
            return Err(FemError::param("element_scale", s, format!("element {e}: must be finite and > 0")));
        }
        self.element_scale = scale;
        Ok(self)
    }

    /// Stiffness factor of element `e` (1 unless set by [`Self::with_element_scale`]).
    pub fn element_scale(&self, e: usize) -> f64 {
        self.element_scale.get(e).copied().unwrap_or(1.0)
    }

    /// Zero displacement on the given linear-mesh vertices and on the mid-edge nodes of edges
    /// joining two of them.
    pub fn fixed_vertices(mesh: &Tet10Mesh, vertices: &[usize]) -> Result<Vec<Dirichlet>> {
        let mut fixed = vec![false; mesh.n_vertices];
        for &v in vertices {
            if v >= mesh.n_vertices {
                return Err(FemError::bad(
                    "fixed nodes",
                    format!("vertex {v} out of range (mesh has {} vertices)", mesh.n_vertices),
                ));
            }
            fixed[v] = true;
        }
        let mut out: Vec<Dirichlet> = (0..mesh.n_vertices)
            .filter(|&v| fixed[v])
            .map(|node| Dirichlet { node, value_mm: Vector3::zeros() })
            .collect();
        let mut mids: Vec<usize> =
            mesh.edge_nodes.iter().filter(|((a, b), _)| fixed[*a] && fixed[*b]).map(|(_, &m)| m).collect();
        mids.sort_unstable();
        out.extend(mids.into_iter().map(|node| Dirichlet { node, value_mm: Vector3::zeros() }));
        Ok(out)
    }

    /// External force at load factor 1 (mN), 3 per node.
    pub fn external_force(&self) -> &[f64] {
        &self.f_ext
    }

    /// Whether node `i` has a prescribed displacement.
    pub fn is_prescribed(&self, i: usize) -> bool {
        self.prescribed[i].is_some()
    }

    /// Prescribed displacement of node `i` at load factor 1 (mm).
    pub fn prescribed_value(&self, i: usize) -> Option<Vector3<f64>> {
        self.prescribed[i]
    }

    pub(crate) fn element(&self, e: usize, u: &[f64], want: Want) -> Option<ElemOut> {
        let el = &self.mesh.elements[e];
        let jinv = &self.mesh.jac_inv[e];
        // the element's stiffness factor scales ψ, P and ∂P/∂F alike: fold it into the volume weight
        let det = self.mesh.jac_det[e] * self.element_scale(e);
        let mut ue = SMatrix::<f64, 3, 10>::zeros();
        for (a, &node) in el.iter().enumerate() {
            for c in 0..3 {
                ue[(c, a)] = u[3 * node + c];
            }
        }
        let mut out = ElemOut {
            energy: 0.0,
            force: [0.0; 30],
            tangent: if want == Want::Tangent { Some(Box::new([0.0; 900])) } else { None },
            min_j: f64::INFINITY,
        };
        for (w, gref) in &self.qp {
            let g: SMatrix<f64, 10, 3> = gref * jinv; // ∇_X N_a (row a)
            let f: Matrix3<f64> = Matrix3::identity() + ue * g;
            let jdet = f.determinant();
            if jdet.is_nan() || jdet <= 0.0 {
                return None;
            }
            out.min_j = out.min_j.min(jdet);
            let dv = w * det;
            out.energy += dv * self.material.energy_density(&f)?;
            if want == Want::Energy {
                continue;
            }
            let p = self.material.pk1(&f)?;
            let pg = p * g.transpose(); // 3×10: Σ_j P_ij ∇N_a,j
            for a in 0..10 {
                for i in 0..3 {
                    out.force[3 * a + i] += dv * pg[(i, a)];
                }
            }
            if let Some(k) = out.tangent.as_mut() {
                let t = self.material.tangent(&f)?;
                // C[(ij), (b,k)] = Σ_l A[(ij),(kl)] ∇N_b,l
                let mut cm = SMatrix::<f64, 9, 30>::zeros();
                for b in 0..10 {
                    for kk in 0..3 {
                        for r in 0..9 {
                            let mut s = 0.0;
                            for l in 0..3 {
                                s += t[(r, 3 * kk + l)] * g[(b, l)];
                            }
                            cm[(r, 3 * b + kk)] = s;
                        }
                    }
                }
                for a in 0..10 {
                    for i in 0..3 {
                        let row = 3 * a + i;
                        for col in 0..30 {
                            let mut s = 0.0;
                            for j in 0..3 {
                                s += g[(a, j)] * cm[(3 * i + j, col)];
                            }
                            k[30 * row + col] += dv * s;
                        }
                    }
                }
            }
        }
        Some(out)
    }

    /// Evaluate every element in parallel and hand the results to `sink` in element order.
    fn for_elements(&self, u: &[f64], want: Want, mut sink: impl FnMut(usize, ElemOut)) -> bool {
        let ne = self.mesh.elements.len();
        let mut start = 0;
        while start < ne {
            let end = (start + CHUNK).min(ne);
            let outs: Vec<Option<ElemOut>> = (start..end).into_par_iter().map(|e| self.element(e, u, want)).collect();
            for (k, o) in outs.into_iter().enumerate() {
                match o {
                    Some(o) => sink(start + k, o),
                    None => return false,
                }
            }
            start = end;
        }
        true
    }

    /// Strain energy Σ_e ∫ ψ(F) dV (mN·mm); `None` if an element inverts (J ≤ 0 at a quadrature point).
    pub fn strain_energy(&self, u: &[f64]) -> Option<f64> {
        let mut s = 0.0;
        self.for_elements(u, Want::Energy, |_, o| s += o.energy).then_some(s)
    }

    /// Total potential energy Π = strain energy − t f_ext·u (mN·mm).
    pub fn potential_energy(&self, u: &[f64], t: f64) -> Option<f64> {
        let w: f64 = self.f_ext.iter().zip(u).map(|(f, x)| f * x).sum();
        Some(self.strain_energy(u)? - t * w)
    }

    /// Assemble energy, internal force and (if `tangent`) the tangent blocks; `None` if an element inverts.
    pub fn assemble(&self, u: &[f64], tangent: bool) -> Option<Assembled> {
        let n = self.mesh.n_nodes();
        let mut fi = vec![0.0; 3 * n];
        let mut blocks = if tangent { Some(vec![0.0; 9 * self.cols.len()]) } else { None };
        let mut energy = 0.0;
        let mut min_j = f64::INFINITY;
        let want = if tangent { Want::Tangent } else { Want::Force };
        let ok = self.for_elements(u, want, |e, o| {
            energy += o.energy;
            min_j = min_j.min(o.min_j);
            let el = &self.mesh.elements[e];
            for (a, &node) in el.iter().enumerate() {
                for c in 0..3 {
                    fi[3 * node + c] += o.force[3 * a + c];
                }
            }
            if let (Some(bl), Some(k)) = (blocks.as_mut(), o.tangent.as_ref()) {
                let bi = &self.elem_blocks[e];
                for a in 0..10 {
                    for b in 0..10 {
                        let base = 9 * bi[10 * a + b] as usize;
                        for i in 0..3 {
                            for kk in 0..3 {
                                bl[base + 3 * i + kk] += k[30 * (3 * a + i) + 3 * b + kk];
                            }
                        }
                    }
                }
            }
        });
        ok.then_some(Assembled { strain_energy: energy, internal_force: fi, blocks, min_j })
    }

    /// Dense tangent stiffness ∂f_int/∂u (mN/mm) over all 3n DOFs, for tests on small meshes.
    pub fn tangent_dense(&self, u: &[f64]) -> Option<DMatrix<f64>> {
        let a = self.assemble(u, true)?;
        let bl = a.blocks?;
        let n = self.mesh.n_nodes();
        let mut k = DMatrix::zeros(3 * n, 3 * n);
        for r in 0..n {
            for p in self.row_ptr[r]..self.row_ptr[r + 1] {
                let c = self.cols[p];
                for i in 0..3 {
                    for kk in 0..3 {
                        k[(3 * r + i, 3 * c + kk)] = bl[9 * p + 3 * i + kk];
                    }
                }
            }
        }
        Some(k)
    }

    /// Displacement field (3 per node) interpolated on the mesh: L2 norm of `u − exact` over the
    /// domain (mm·mm^{3/2}), with the degree-5 rule.
    pub fn l2_error(&self, u: &[Vector3<f64>], exact: impl Fn(&Vector3<f64>) -> Vector3<f64> + Sync) -> f64 {
        let rule = Quadrature::Degree5.points();
        let per: Vec<f64> = (0..self.mesh.elements.len())
            .into_par_iter()
            .map(|e| {
                rule.iter()
                    .map(|q| {
                        let d = self.mesh.interpolate(e, &q.xi, u) - exact(&self.mesh.position(e, &q.xi));
                        q.weight * self.mesh.jac_det[e] * d.norm_squared()
                    })
                    .sum::<f64>()
            })
            .collect();
        per.iter().sum::<f64>().sqrt()
    }
}

/// Every connected piece of the mesh needs ≥ 3 non-collinear prescribed nodes, else rigid-body
/// modes make the stiffness singular.
/// Loads above this multiple of E·L² (E Young's modulus, L the mesh's bounding-box diagonal) are refused
/// by [`SolidProblem::new`]: they would mean strains of that order, a unit or sign error, not a load.
pub const MAX_LOAD_RATIO: f64 = 1e3;

/// [`FemError::LoadOutOfScale`] when the total external force Σ_nodes |f| is not finite or exceeds
/// [`MAX_LOAD_RATIO`] × E·L².
fn check_load_scale(mesh: &Tet10Mesh, material: &NeoHookean, f_ext: &[f64]) -> Result<()> {
    // hypot: components of 1e300 give 1.7e300, not an overflow to infinity.
    let total: f64 = f_ext.chunks(3).map(|c| c[0].hypot(c[1]).hypot(c[2])).sum();
    let (mu, la) = (material.mu_kpa, material.lambda_kpa);
    let young_kpa = mu * (3.0 * la + 2.0 * mu) / (la + mu);
    let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
    for p in &mesh.nodes[..mesh.n_vertices] {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let size_mm = (hi - lo).norm();
    let scale = young_kpa * size_mm * size_mm;
    let limit_mn = MAX_LOAD_RATIO * scale;
    let what = if !total.is_finite() {
        "not finite"
    } else if total > limit_mn {
        "absurd"
    } else {
        return Ok(());
    };
    Err(FemError::LoadOutOfScale {
        total_mn: total,
        limit_mn,
        max_ratio: MAX_LOAD_RATIO,
        young_kpa,
        size_mm,
        strain: total / scale,
        what,
    })
}

fn check_rigid_modes(mesh: &Tet10Mesh, prescribed: &[Option<Vector3<f64>>]) -> Result<()> {
    let n = mesh.n_nodes();
    if prescribed.iter().all(Option::is_none) {
        return Err(FemError::bad(
            "fixed nodes",
            "none given: rigid-body modes make the stiffness singular; fix at least 3 non-collinear vertices",
        ));
    }
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for el in &mesh.elements {
        let r0 = find(&mut parent, el[0]);
        for &a in &el[1..] {
            let ra = find(&mut parent, a);
            if ra != r0 {
                parent[ra] = r0;
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for el in &mesh.elements {
        groups.entry(find(&mut parent, el[0])).or_default();
    }
    for (i, pr) in prescribed.iter().enumerate() {
        if pr.is_some() {
            let r = find(&mut parent, i);
            if let Some(g) = groups.get_mut(&r) {
                g.push(i);
            }
        }
    }
    let (lo, hi) =
        mesh.nodes.iter().fold((Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)), |(lo, hi), x| {
            (lo.inf(x), hi.sup(x))
        });
    let diam = (hi - lo).norm().max(1e-300);
    for (root, fixed) in &groups {
        let ok = fixed.first().is_some_and(|&p0| {
            let x0 = mesh.nodes[p0];
            let far = fixed.iter().map(|&i| mesh.nodes[i]).max_by(|a, b| (a - x0).norm().total_cmp(&(b - x0).norm()));
            let Some(x1) = far else { return false };
            let d = x1 - x0;
            if d.norm() <= 1e-9 * diam {
                return false;
            }
            let dn = d.normalize();
            fixed.iter().any(|&i| {
                let v = mesh.nodes[i] - x0;
                (v - dn * v.dot(&dn)).norm() > 1e-6 * diam
            })
        });
        if !ok {
            return Err(FemError::bad(
                "fixed nodes",
                format!(
                    "the mesh piece containing node {root} has {} fixed node(s), not 3 non-collinear: rigid-body modes make the stiffness singular",
                    fixed.len()
                ),
            ));
        }
    }
    Ok(())
}
