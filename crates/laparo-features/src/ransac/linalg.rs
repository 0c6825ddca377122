//! Small dense helpers shared by the solvers (Hartley normalisation, null vectors).
use nalgebra::{Matrix3, SMatrix, SymmetricEigen};

/// Hartley's isotropic normalisation T: centroid to the origin, mean distance √2.
/// Returns None when all points coincide.
pub(crate) fn normalisation(p: &[[f64; 2]], idx: &[usize]) -> Option<Matrix3<f64>> {
    let n = idx.len() as f64;
    let (mut cx, mut cy) = (0.0, 0.0);
    for &i in idx {
        cx += p[i][0];
        cy += p[i][1];
    }
    cx /= n;
    cy /= n;
    let mut d = 0.0;
    for &i in idx {
        d += ((p[i][0] - cx).powi(2) + (p[i][1] - cy).powi(2)).sqrt();
    }
    d /= n;
    if !(d > 1e-12 && d.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / d;
    Some(Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0))
}

/// Apply a normalisation (affine, last row 0 0 1).
#[inline]
pub(crate) fn apply(t: &Matrix3<f64>, p: [f64; 2]) -> [f64; 2] {
    [t[(0, 0)] * p[0] + t[(0, 2)], t[(1, 1)] * p[1] + t[(1, 2)]]
}

/// Unit vector minimising |A v| for A given through its 9×9 normal matrix AᵀA, with the ratio
/// of the two smallest eigenvalues (a near-zero second eigenvalue flags a degenerate set).
pub(crate) fn null_vector9(ata: SMatrix<f64, 9, 9>) -> ([f64; 9], f64, f64) {
    let eig = SymmetricEigen::new(ata);
    let mut order: Vec<usize> = (0..9).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let v = eig.eigenvectors.column(order[0]);
    let mut out = [0.0; 9];
    for k in 0..9 {
        out[k] = v[k];
    }
    (out, eig.eigenvalues[order[0]].max(0.0), eig.eigenvalues[order[1]].max(0.0))
}

/// The two right null vectors of a 7×9 matrix (rows given), by Gauss–Jordan elimination with
/// full pivoting (rank 7 expected; None when the rank is lower, i.e. a degenerate sample).
pub(crate) fn null_space_7x9(rows: &[[f64; 9]; 7]) -> Option<([f64; 9], [f64; 9])> {
    let mut a = *rows;
    let mut col = [0usize, 1, 2, 3, 4, 5, 6, 7, 8]; // column permutation
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    for r in 0..7 {
        // full pivot in the remaining block
        let (mut pr, mut pc, mut pv) = (r, r, 0.0);
        for (i, row) in a.iter().enumerate().skip(r) {
            for (j, v) in row.iter().enumerate().skip(r) {
                if v.abs() > pv {
                    (pr, pc, pv) = (i, j, v.abs());
                }
            }
        }
        if pv < 1e-10 * scale {
            return None;
        }
        a.swap(r, pr);
        if pc != r {
            for row in a.iter_mut() {
                row.swap(r, pc);
            }
            col.swap(r, pc);
        }
        let inv = 1.0 / a[r][r];
        for v in a[r].iter_mut() {
            *v *= inv;
        }
        for i in 0..7 {
            if i != r {
                let f = a[i][r];
                if f != 0.0 {
                    for j in r..9 {
                        a[i][j] -= f * a[r][j];
                    }
                }
            }
        }
    }
    // x_free = e_k, x_pivot = −A[:, free]
    let vec_for = |k: usize| {
        let mut o = [0.0; 9];
        o[col[k]] = 1.0;
        for r in 0..7 {
            o[col[r]] = -a[r][k];
        }
        let n = o.iter().map(|v| v * v).sum::<f64>().sqrt();
        o.iter_mut().for_each(|v| *v /= n);
        o
    };
    Some((vec_for(7), vec_for(8)))
}

/// Row-major 9-vector to a 3×3 matrix.
pub(crate) fn mat3(v: &[f64; 9]) -> Matrix3<f64> {
    Matrix3::new(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8])
}

/// Accumulate the outer product r rᵀ into a 9×9 normal matrix.
#[inline]
pub(crate) fn accumulate(ata: &mut SMatrix<f64, 9, 9>, r: &[f64; 9], w: f64) {
    for i in 0..9 {
        let ri = r[i] * w;
        for j in i..9 {
            ata[(i, j)] += ri * r[j];
        }
    }
}

/// Mirror the upper triangle into the lower one.
pub(crate) fn symmetrise(ata: &mut SMatrix<f64, 9, 9>) {
    for i in 0..9 {
        for j in 0..i {
            ata[(i, j)] = ata[(j, i)];
        }
    }
}

/// Real roots of a x³ + b x² + c x + d (degree drops handled).
pub(crate) fn cubic_roots(a: f64, b: f64, c: f64, d: f64) -> Vec<f64> {
    let scale = a.abs().max(b.abs()).max(c.abs()).max(d.abs());
    if scale == 0.0 {
        return vec![];
    }
    if a.abs() < 1e-12 * scale {
        // quadratic
        if b.abs() < 1e-12 * scale {
            return if c != 0.0 { vec![-d / c] } else { vec![] };
        }
        let disc = c * c - 4.0 * b * d;
        if disc < 0.0 {
            return vec![];
        }
        let q = -0.5 * (c + c.signum() * disc.sqrt());
        let mut r = vec![];
        if q != 0.0 {
            r.push(d / q);
        }
        r.push(q / b);
        return r;
    }
    // depressed cubic t³ + p t + q with x = t − b/(3a)
    let (b, c, d) = (b / a, c / a, d / a);
    let p = c - b * b / 3.0;
    let q = 2.0 * b * b * b / 27.0 - b * c / 3.0 + d;
    let shift = -b / 3.0;
    let disc = (q / 2.0).powi(2) + (p / 3.0).powi(3);
    let mut roots = if disc > 0.0 {
        let s = disc.sqrt();
        vec![(-q / 2.0 + s).cbrt() + (-q / 2.0 - s).cbrt() + shift]
    } else {
        let r = (-p / 3.0).max(0.0).sqrt();
        if r == 0.0 {
            vec![shift]
        } else {
            let phi = (-q / (2.0 * r * r * r)).clamp(-1.0, 1.0).acos();
            (0..3).map(|k| 2.0 * r * ((phi + 2.0 * std::f64::consts::PI * k as f64) / 3.0).cos() + shift).collect()
        }
    };
    // one Newton polish step each
    for x in roots.iter_mut() {
        let f = ((*x + b) * *x + c) * *x + d;
        let df = (3.0 * *x + 2.0 * b) * *x + c;
        if df != 0.0 {
            *x -= f / df;
        }
    }
    roots
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn null_space_is_orthogonal_to_the_rows() {
        let mut rows = [[0.0; 9]; 7];
        for (i, r) in rows.iter_mut().enumerate() {
            for (j, v) in r.iter_mut().enumerate() {
                *v = ((i * 9 + j) as f64 * 0.7).sin() + if i == j { 2.0 } else { 0.0 };
            }
        }
        let (a, b) = null_space_7x9(&rows).unwrap();
        for r in &rows {
            let (da, db): (f64, f64) =
                (r.iter().zip(&a).map(|(x, y)| x * y).sum(), r.iter().zip(&b).map(|(x, y)| x * y).sum());
            assert!(da.abs() < 1e-12 && db.abs() < 1e-12, "{da} {db}");
        }
        // independent: not parallel
        let dot: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        assert!(dot.abs() < 0.99);
        // rank-deficient input: a repeated row
        rows[6] = rows[5];
        assert!(null_space_7x9(&rows).is_none());
    }
    #[test]
    fn cubic_roots_match_known_factors() {
        // (x-1)(x+2)(x-3) = x³ -2x² -5x +6
        let mut r = cubic_roots(1.0, -2.0, -5.0, 6.0);
        r.sort_by(f64::total_cmp);
        assert_eq!(r.len(), 3);
        for (a, b) in r.iter().zip([-2.0, 1.0, 3.0]) {
            assert!((a - b).abs() < 1e-12, "{r:?}");
        }
        // x³ + x + 1: one real root ≈ -0.6823278038
        let r = cubic_roots(1.0, 0.0, 1.0, 1.0);
        assert_eq!(r.len(), 1);
        assert!((r[0] + 0.682_327_803_828_019_3).abs() < 1e-12);
    }
}
