//! Recycled numeric-factorisation buffers (factor values and faer workspace).
//!
//! A new mesh topology (the first frame, or a video whose ROI or kept triangles change) needs
//! ≈ 7 MB of factor values and faer workspace at 4 px. Freshly allocated, that memory is
//! page-faulted in during the factorisation (≈ 1 ms per frame measured); instead, the buffers of
//! dropped topologies are kept in a small process-wide pool and handed to the next one. faer
//! overwrites the factor values (it zero-fills them itself), so a recycled buffer is not cleared.
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

static POOL: Mutex<Vec<FactorBuffers>> = Mutex::new(Vec::new());

impl FactorBuffers {
    /// Buffers for `len_val` factor values and a workspace of `req`, recycled when the pool
    /// holds large enough ones.
    pub fn take(len_val: usize, req: StackReq) -> FactorBuffers {
        let fits = |b: &FactorBuffers| {
            b.vals.capacity() >= len_val
                && b.mem_req.size_bytes() >= req.size_bytes()
                && b.mem_req.align_bytes() >= req.align_bytes()
        };
        let recycled = POOL.lock().ok().and_then(|mut pool| pool.iter().position(fits).map(|i| pool.swap_remove(i)));
        match recycled {
            Some(mut b) => {
                // Values already in the buffer are overwritten by the factorisation.
                b.vals.resize(len_val, c64::new(0.0, 0.0));
                b
            }
            None => FactorBuffers { vals: vec![c64::new(0.0, 0.0); len_val], mem: MemBuffer::new(req), mem_req: req },
        }
    }

    /// Return the buffers to the pool (dropped when it is full).
    pub fn give_back(self) {
        if let Ok(mut pool) = POOL.lock() {
            if pool.len() < POOL_LEN {
                pool.push(self);
            }
        }
    }
}
