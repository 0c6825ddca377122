//! Minimal 5-point solver for the essential matrix (Stewénius, Engels & Nistér 2006, "Recent
//! developments on direct relative orientation", §3; Nistér 2004 for the constraints).
//!
//! 1. The five epipolar constraints x̂₂ᵀ E x̂₁ = 0 span a 4-D null space: E = x X + y Y + z Z + W.
//! 2. The ten cubic constraints det E = 0 (one) and 2 E Eᵀ E − tr(E Eᵀ) E = 0 (nine) in (x, y, z)
//!    are expanded into a 10 × 20 coefficient matrix (monomials of degree ≤ 3).
//! 3. Gauss–Jordan elimination of the ten cubic monomials leaves them as linear combinations of
//!    the basis q = (x², xy, xz, y², yz, z², x, y, z, 1) of the quotient ring (grevlex), from
//!    which the 10 × 10 action matrix of multiplication by x is read off: M q = x q.
//! 4. Each real eigenvalue x of M (Schur) has the eigenvector q(x, y, z); its unknowns follow from
//!    a 6 × 5 least-squares solve (`eigen_yz`), and up to three Gauss–Newton steps on the ten
//!    cubic equations polish (x, y, z) to machine precision.
//!
//! The polynomial bookkeeping is a dense array of the 20 monomials of degree ≤ 3 ordered by
//! degree, so a degree-d polynomial uses the first 1, 4, 10 or 20 entries.
use nalgebra::{Matrix3, SMatrix, SVector, Schur};

/// Exponents (a, b, c) of xᵃ yᵇ zᶜ, ordered by degree: 1 | x y z | x² xy xz y² yz z² | x³ x²y
/// x²z xy² xyz xz² y³ y²z yz² z³.
const MONO: [[u8; 3]; 20] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [2, 0, 0],
    [1, 1, 0],
    [1, 0, 1],
    [0, 2, 0],
    [0, 1, 1],
    [0, 0, 2],
    [3, 0, 0],
    [2, 1, 0],
    [2, 0, 1],
    [1, 2, 0],
    [1, 1, 1],
    [1, 0, 2],
    [0, 3, 0],
    [0, 2, 1],
    [0, 1, 2],
    [0, 0, 3],
];

/// Index of xᵃ yᵇ zᶜ in [`MONO`] (a + b + c ≤ 3).
const fn mono_index(a: u8, b: u8, c: u8) -> usize {
    let mut i = 0;
    while i < 20 {
        if MONO[i][0] == a && MONO[i][1] == b && MONO[i][2] == c {
            return i;
        }
        i += 1;
    }
    usize::MAX
}

/// Product table: `PROD[i][j]` = index of MONO[i]·MONO[j] (usize::MAX when of degree > 3).
const PROD: [[usize; 20]; 20] = {
    let mut t = [[usize::MAX; 20]; 20];
    let mut i = 0;
    while i < 20 {
        let mut j = 0;
        while j < 20 {
            let (a, b, c) = (MONO[i][0] + MONO[j][0], MONO[i][1] + MONO[j][1], MONO[i][2] + MONO[j][2]);
            if a + b + c <= 3 {
                t[i][j] = mono_index(a, b, c);
            }
            j += 1;
        }
        i += 1;
    }
    t
};

/// Number of monomials of degree ≤ d (d = 0..3).
const LEN: [usize; 4] = [1, 4, 10, 20];

/// A polynomial in (x, y, z) of degree ≤ 3 with its degree bound.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Poly {
    c: [f64; 20],
    deg: usize,
}

impl Poly {
    fn zero(deg: usize) -> Self {
        Poly { c: [0.0; 20], deg }
    }

    /// x a + y b + z c + d.
    fn linear(a: f64, b: f64, c: f64, d: f64) -> Self {
        let mut p = Poly::zero(1);
        p.c[..4].copy_from_slice(&[d, a, b, c]);
        p
    }

    /// Product (degree bound = sum of the bounds, at most 3).
    fn mul(&self, o: &Poly) -> Poly {
        let deg = self.deg + o.deg;
        debug_assert!(deg <= 3);
        let mut r = Poly::zero(deg);
        for (i, &a) in self.c[..LEN[self.deg]].iter().enumerate() {
            if a == 0.0 {
                continue;
            }
            for (&k, &b) in PROD[i][..LEN[o.deg]].iter().zip(&o.c[..LEN[o.deg]]) {
                r.c[k] += a * b;
            }
        }
        r
    }

    fn add(&self, o: &Poly) -> Poly {
        let mut r = Poly::zero(self.deg.max(o.deg));
        for i in 0..20 {
            r.c[i] = self.c[i] + o.c[i];
        }
        r
    }

    fn scale(&self, s: f64) -> Poly {
        let mut r = *self;
        r.c.iter_mut().for_each(|v| *v *= s);
        r
    }

    /// Value at (x, y, z).
    #[cfg(test)]
    fn eval(&self, x: f64, y: f64, z: f64) -> f64 {
        monomials(x, y, z).iter().zip(&self.c).map(|(m, c)| m * c).sum()
    }
}

/// The 20 monomials at (x, y, z), in [`MONO`] order.
fn monomials(x: f64, y: f64, z: f64) -> [f64; 20] {
    let (x2, y2, z2) = (x * x, y * y, z * z);
    [
        1.0,
        x,
        y,
        z,
        x2,
        x * y,
        x * z,
        y2,
        y * z,
        z2,
        x2 * x,
        x2 * y,
        x2 * z,
        x * y2,
        x * y * z,
        x * z2,
        y2 * y,
        y2 * z,
        y * z2,
        z2 * z,
    ]
}

/// Gradient of the 20 monomials w.r.t. (x, y, z), in [`MONO`] order.
fn monomial_gradients(x: f64, y: f64, z: f64) -> [[f64; 3]; 20] {
    let (x2, y2, z2) = (x * x, y * y, z * z);
    [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [2.0 * x, 0.0, 0.0],
        [y, x, 0.0],
        [z, 0.0, x],
        [0.0, 2.0 * y, 0.0],
        [0.0, z, y],
        [0.0, 0.0, 2.0 * z],
        [3.0 * x2, 0.0, 0.0],
        [2.0 * x * y, x2, 0.0],
        [2.0 * x * z, 0.0, x2],
        [y2, 2.0 * x * y, 0.0],
        [y * z, x * z, x * y],
        [z2, 0.0, 2.0 * x * z],
        [0.0, 3.0 * y2, 0.0],
        [0.0, 2.0 * y * z, y2],
        [0.0, z2, 2.0 * y * z],
        [0.0, 0.0, 3.0 * z2],
    ]
}

/// The epipolar row of one normalised correspondence: x̂₂ᵀ E x̂₁ = r · vec(E) (row-major E).
fn epipolar_row(a: [f64; 2], b: [f64; 2]) -> [f64; 9] {
    let [x, y] = a;
    let [u, v] = b;
    [u * x, u * y, u, v * x, v * y, v, x, y, 1.0]
}

/// Orthonormal basis (X, Y, Z, W) of the null space of the 5 × 9 epipolar matrix, via the SVD
/// of its 9 × 9 zero-padded version; None when the five rows have rank < 5 (degenerate sample).
pub(crate) fn null_space_5x9(rows: &[[f64; 9]; 5]) -> Option<[[f64; 9]; 4]> {
    let mut a = SMatrix::<f64, 9, 9>::zeros();
    for (i, r) in rows.iter().enumerate() {
        for j in 0..9 {
            a[(i, j)] = r[j];
        }
    }
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t?;
    let mut order: [usize; 9] = [0, 1, 2, 3, 4, 5, 6, 7, 8];
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let s = &svd.singular_values;
    if s[order[0]].is_nan() || s[order[0]] <= 0.0 || s[order[4]] <= 1e-10 * s[order[0]] {
        return None;
    }
    let mut out = [[0.0; 9]; 4];
    for (k, o) in out.iter_mut().enumerate() {
        for j in 0..9 {
            o[j] = vt[(order[5 + k], j)];
        }
    }
    Some(out)
}

/// The ten cubic constraints (det E, then the nine entries of 2 E Eᵀ E − tr(E Eᵀ) E, row-major)
/// for E = x X + y Y + z Z + W (Nistér 2004 eqs. 3 and 4).
pub(crate) fn cubic_constraints(basis: &[[f64; 9]; 4]) -> [Poly; 10] {
    let [bx, by, bz, bw] = basis;
    let e: [Poly; 9] = std::array::from_fn(|k| Poly::linear(bx[k], by[k], bz[k], bw[k]));
    let at = |i: usize, j: usize| &e[3 * i + j];
    // det E by cofactor expansion along the first row
    let minor = |r1: usize, r2: usize, c1: usize, c2: usize| {
        at(r1, c1).mul(at(r2, c2)).add(&at(r1, c2).mul(at(r2, c1)).scale(-1.0))
    };
    let det = at(0, 0)
        .mul(&minor(1, 2, 1, 2))
        .add(&at(0, 1).mul(&minor(1, 2, 0, 2)).scale(-1.0))
        .add(&at(0, 2).mul(&minor(1, 2, 0, 1)));
    // E Eᵀ (symmetric, degree 2)
    let mut eet = [Poly::zero(2); 9];
    for i in 0..3 {
        for j in i..3 {
            let mut s = Poly::zero(2);
            for k in 0..3 {
                s = s.add(&at(i, k).mul(at(j, k)));
            }
            eet[3 * i + j] = s;
            eet[3 * j + i] = s;
        }
    }
    let trace = eet[0].add(&eet[4]).add(&eet[8]);
    // ½ tr(E Eᵀ) I subtracted from E Eᵀ, then times E: (E Eᵀ − ½ tr I) E = ½ (2 E Eᵀ E − tr E)
    let mut lam = eet;
    for i in 0..3 {
        lam[4 * i] = lam[4 * i].add(&trace.scale(-0.5));
    }
    let mut out = [Poly::zero(3); 10];
    out[0] = det;
    for i in 0..3 {
        for j in 0..3 {
            let mut s = Poly::zero(3);
            for k in 0..3 {
                s = s.add(&lam[3 * i + k].mul(at(k, j)));
            }
            out[1 + 3 * i + j] = s.scale(2.0);
        }
    }
    out
}

/// Column of MONO index `m` in the eliminated order: the ten cubic monomials (MONO 10..20) first,
/// then q = (x², xy, xz, y², yz, z², x, y, z, 1).
const Q_MONO: [usize; 10] = [4, 5, 6, 7, 8, 9, 1, 2, 3, 0];

/// The 10 × 10 action matrix of multiplication by x on q, or None if the cubic block is singular.
fn action_matrix(eqs: &[Poly; 10]) -> Option<SMatrix<f64, 10, 10>> {
    let mut c = SMatrix::<f64, 10, 10>::zeros();
    let mut d = SMatrix::<f64, 10, 10>::zeros();
    for (i, p) in eqs.iter().enumerate() {
        for k in 0..10 {
            c[(i, k)] = p.c[10 + k];
            d[(i, k)] = p.c[Q_MONO[k]];
        }
    }
    // cubic monomials = −G q with G = C⁻¹ D (Gauss–Jordan with partial pivoting)
    let lu = c.lu();
    let g = lu.solve(&d)?;
    if !g.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut m = SMatrix::<f64, 10, 10>::zeros();
    // x·(x², xy, xz, y², yz, z²) = x³, x²y, x²z, xy², xyz, xz² = cubic monomials 0..6
    for r in 0..6 {
        for k in 0..10 {
            m[(r, k)] = -g[(r, k)];
        }
    }
    // x·x = x², x·y = xy, x·z = xz, x·1 = x
    m[(6, 0)] = 1.0;
    m[(7, 1)] = 1.0;
    m[(8, 2)] = 1.0;
    m[(9, 6)] = 1.0;
    Some(m)
}

/// The eigenvector of M for the eigenvalue x, reduced to its unknowns: with q₉ = 1 the last four
/// rows of (M − x I) q = 0 give q₆ = x, q₀ = x², q₁ = x y, q₂ = x z, so the first six rows are
/// linear in u = (y, z, y², yz, z²) (treated as independent): a 6 × 5 least-squares problem (QR).
pub(crate) fn eigen_yz(m: &SMatrix<f64, 10, 10>, x: f64) -> Option<[f64; 2]> {
    // row r: x q_r − Σ_k M_rk q_k = 0 with q = (x², x y, x z, u₂, u₃, u₄, x, y, z, 1)
    let mut a = SMatrix::<f64, 6, 5>::zeros();
    let mut b = SVector::<f64, 6>::zeros();
    for r in 0..6 {
        let mk = |k: usize| m[(r, k)] - if k == r { x } else { 0.0 };
        // known part: q₀ = x², q₆ = x, q₉ = 1
        b[r] = -(mk(0) * x * x + mk(6) * x + mk(9));
        // y appears in q₁ = x y and q₇ = y; z in q₂ = x z and q₈ = z
        a[(r, 0)] = mk(1) * x + mk(7);
        a[(r, 1)] = mk(2) * x + mk(8);
        a[(r, 2)] = mk(3);
        a[(r, 3)] = mk(4);
        a[(r, 4)] = mk(5);
    }
    let qr = a.qr();
    let rhs = qr.q().transpose() * b;
    let u = qr.r().solve_upper_triangular(&rhs)?;
    (u[0].is_finite() && u[1].is_finite()).then_some([u[0], u[1]])
}

/// Gauss–Newton polish of (x, y, z) on the ten cubic equations (zero residual at a solution).
fn polish(eqs: &[Poly; 10], s: [f64; 3]) -> [f64; 3] {
    let resid = |s: [f64; 3]| -> (SVector<f64, 10>, f64) {
        let m = monomials(s[0], s[1], s[2]);
        let r = SVector::<f64, 10>::from_fn(|i, _| eqs[i].c.iter().zip(&m).map(|(a, b)| a * b).sum());
        let n = r.norm_squared();
        (r, n)
    };
    let (mut best, (mut r, mut n)) = (s, resid(s));
    for _ in 0..3 {
        if n == 0.0 {
            break;
        }
        let g = monomial_gradients(best[0], best[1], best[2]);
        let j = SMatrix::<f64, 10, 3>::from_fn(|i, v| (0..20).map(|k| eqs[i].c[k] * g[k][v]).sum());
        let jtj = j.transpose() * j;
        let Some(step) = jtj.cholesky().map(|ch| ch.solve(&(j.transpose() * r))) else { break };
        let cand = [best[0] - step[0], best[1] - step[1], best[2] - step[2]];
        let (r2, n2) = resid(cand);
        if n2 < n {
            (best, r, n) = (cand, r2, n2);
        } else {
            break;
        }
    }
    best
}

/// Essential matrices (unit Frobenius norm, up to 10) consistent with five normalised
/// correspondences `(a[i], b[i])`: x̂₂ᵀ E x̂₁ = 0 with x̂₁ = `a[i]`, x̂₂ = `b[i]`. Empty when the
/// sample is degenerate (rank < 5, singular elimination) or has no real solution.
pub fn five_point(a: &[[f64; 2]; 5], b: &[[f64; 2]; 5]) -> Vec<Matrix3<f64>> {
    let rows: [[f64; 9]; 5] = std::array::from_fn(|i| epipolar_row(a[i], b[i]));
    let Some(basis) = null_space_5x9(&rows) else { return vec![] };
    let eqs = cubic_constraints(&basis);
    let Some(m) = action_matrix(&eqs) else { return vec![] };
    let schur = Schur::new(m);
    let ev = schur.complex_eigenvalues();
    let scale = m.norm().max(1.0);
    let mut out: Vec<Matrix3<f64>> = Vec::with_capacity(10);
    for l in ev.iter() {
        if l.im.abs() > 1e-8 * scale.max(l.re.abs()) {
            continue;
        }
        let Some([y, z]) = eigen_yz(&m, l.re) else { continue };
        let s = polish(&eqs, [l.re, y, z]);
        let mut e = Matrix3::zeros();
        for k in 0..9 {
            e[(k / 3, k % 3)] = s[0] * basis[0][k] + s[1] * basis[1][k] + s[2] * basis[2][k] + basis[3][k];
        }
        let n = e.norm();
        if !(n > 0.0 && n.is_finite()) {
            continue;
        }
        let e = e / n;
        // a double real eigenvalue (or numerical twin) gives the same E twice
        if out.iter().any(|f| (f - e).norm().min((f + e).norm()) < 1e-10) {
            continue;
        }
        out.push(e);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn product_table_is_consistent() {
        // (x + 2)(y − z) = xy − xz + 2y − 2z
        let p = Poly::linear(1.0, 0.0, 0.0, 2.0).mul(&Poly::linear(0.0, 1.0, -1.0, 0.0));
        for (x, y, z) in [(0.3, -1.2, 2.0), (1.5, 0.25, -0.7)] {
            assert!((p.eval(x, y, z) - (x + 2.0) * (y - z)).abs() < 1e-14);
        }
        // (x + y + z + 1)³ at (1, 1, 1) = 64, via two products
        let l = Poly::linear(1.0, 1.0, 1.0, 1.0);
        assert_eq!(l.mul(&l).mul(&l).eval(1.0, 1.0, 1.0), 64.0);
        // gradients against central differences of the monomials
        let (x, y, z, h) = (0.7, -1.3, 0.4, 1e-6);
        let g = monomial_gradients(x, y, z);
        for k in 0..20 {
            let d = [
                (monomials(x + h, y, z)[k] - monomials(x - h, y, z)[k]) / (2.0 * h),
                (monomials(x, y + h, z)[k] - monomials(x, y - h, z)[k]) / (2.0 * h),
                (monomials(x, y, z + h)[k] - monomials(x, y, z - h)[k]) / (2.0 * h),
            ];
            for v in 0..3 {
                assert!((g[k][v] - d[v]).abs() < 1e-8, "monomial {k} ({:?}), variable {v}", MONO[k]);
            }
        }
        let g = monomial_gradients(2.0, 3.0, 5.0);
        // d(x²y)/dx = 2xy = 12, d(xyz)/dz = xy = 6
        assert_eq!(g[mono_index(2, 1, 0)][0], 12.0);
        assert_eq!(g[mono_index(1, 1, 1)][2], 6.0);
    }
}
