//! Symmetric positive definite sparse systems with a fixed pattern (faer supernodal Cholesky): the
//! symbolic analysis is done once, every numeric factorisation reuses it.
use crate::{RegisterError, Result};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use faer::{Mat, Side};

/// A fixed lower-triangular pattern (entries listed as (row, col) with row ≥ col; repeats are summed).
pub(crate) struct SpdPattern {
    n: usize,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    llt: SymbolicLlt<usize>,
}

impl SpdPattern {
    /// Analyse the pattern of an n×n matrix.
    pub(crate) fn new(n: usize, entries: &[(usize, usize)]) -> Result<Self> {
        let idx: Vec<Pair<usize, usize>> = entries.iter().map(|&(r, c)| Pair::new(r, c)).collect();
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(n, n, &idx)
            .map_err(|e| RegisterError::bad("sparse pattern", format!("{e:?}")))?;
        let llt = SymbolicLlt::try_new(symbolic.as_ref(), Side::Lower)
            .map_err(|e| RegisterError::bad("sparse Cholesky (symbolic)", format!("{e:?}")))?;
        Ok(SpdPattern { n, symbolic, argsort, llt })
    }

    /// Numeric Cholesky factor of the matrix whose entries (in the order of `new`) are `values`.
    pub(crate) fn factor(&self, values: &[f64]) -> Result<Llt<usize, f64>> {
        let m = SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, values)
            .map_err(|e| RegisterError::bad("sparse matrix", format!("{e:?}")))?;
        Llt::try_new_with_symbolic(self.llt.clone(), m.as_ref(), Side::Lower)
            .map_err(|e| RegisterError::bad("sparse Cholesky", format!("not positive definite ({e:?})")))
    }

    /// Matrix size.
    pub(crate) fn n(&self) -> usize {
        self.n
    }
}

/// Solve L Lᵀ X = B for the columns of B (n × k, column-major `b[c][i]`).
pub(crate) fn solve_columns(llt: &Llt<usize, f64>, b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = b.first().map_or(0, |c| c.len());
    let rhs = Mat::from_fn(n, b.len(), |i, c| b[c][i]);
    let x = llt.solve(&rhs);
    (0..b.len()).map(|c| (0..n).map(|i| x[(i, c)]).collect()).collect()
}
