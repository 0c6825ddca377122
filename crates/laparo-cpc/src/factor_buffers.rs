//! Recycled numeric-factorisation buffers (factor values and faer workspace).
//!
//! A new mesh topology (the first frame, or a video whose ROI or kept triangles change) needs
//! ≈ 7 MB of factor values and faer workspace at 4 px. Freshly allocated, that memory is
//! page-faulted in during the factorisation (≈ 1 ms per frame measured); instead, the buffers of
//! the topologies a [`crate::CpcSolver`] drops are kept in that solver's small [`FactorPool`] and
//! handed to its next topology. There is no process-wide state: each solver owns its pool, shared
//! (`Arc`) with the topologies it builds, which return their buffers when dropped. faer overwrites
//! the factor values (it zero-fills them itself), so a recycled buffer is not cleared.
use faer::c64;
use faer::dyn_stack::{MemBuffer, StackReq};
use std::sync::Mutex;

/// At most this many buffer pairs are kept (two halves of a split system, plus spares).
const POOL_LEN: usize = 4;

/// Factor values and workspace of one Cholesky factorisation.
pub(crate) struct FactorBuffers {
    /// Factor values (at least the symbolic factorisation's `len_val`).
    pub vals: Vec<c64>,
    /// faer workspace.
    pub mem: MemBuffer,
    mem_req: StackReq,
}

/// The buffers of dropped topologies, owned by one [`crate::CpcSolver`].
#[derive(Default)]
pub(crate) struct FactorPool {
    free: Mutex<Vec<FactorBuffers>>,
}

impl FactorPool {
    /// Number of buffer pairs held.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.free.lock().map_or(0, |p| p.len())
    }

    /// Return `b` to the pool (dropped when it is full).
    pub fn give_back(&self, b: FactorBuffers) {
        if let Ok(mut pool) = self.free.lock() {
            if pool.len() < POOL_LEN {
                pool.push(b);
            }
        }
    }
}

impl FactorBuffers {
    /// Buffers for `len_val` factor values and a workspace of `req`, recycled from `pool` when it
    /// holds large enough ones, else freshly allocated.
    pub fn take(pool: Option<&FactorPool>, len_val: usize, req: StackReq) -> FactorBuffers {
        let fits = |b: &FactorBuffers| {
            b.vals.capacity() >= len_val
                && b.mem_req.size_bytes() >= req.size_bytes()
                && b.mem_req.align_bytes() >= req.align_bytes()
        };
        let recycled = pool
            .and_then(|p| p.free.lock().ok())
            .and_then(|mut free| free.iter().position(fits).map(|i| free.swap_remove(i)));
        match recycled {
            Some(mut b) => {
                // Values already in the buffer are overwritten by the factorisation.
                b.vals.resize(len_val, c64::new(0.0, 0.0));
                b
            }
            None => FactorBuffers { vals: vec![c64::new(0.0, 0.0); len_val], mem: MemBuffer::new(req), mem_req: req },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pool_recycles_large_enough_buffers_and_is_bounded() {
        let pool = FactorPool::default();
        let req = StackReq::new::<u8>(1024);
        let b = FactorBuffers::take(Some(&pool), 100, req);
        let ptr = b.vals.as_ptr();
        pool.give_back(b);
        assert_eq!(pool.len(), 1);
        // A smaller request reuses the same allocation.
        let b = FactorBuffers::take(Some(&pool), 50, req);
        assert_eq!((b.vals.as_ptr(), b.vals.len(), pool.len()), (ptr, 50, 0));
        pool.give_back(b);
        // A larger one does not fit: fresh buffers, the small ones stay pooled.
        let big = FactorBuffers::take(Some(&pool), 1000, req);
        assert_eq!((big.vals.len(), pool.len()), (1000, 1));
        for _ in 0..10 {
            pool.give_back(FactorBuffers::take(None, 10, req));
        }
        assert_eq!(pool.len(), POOL_LEN);
    }
}
