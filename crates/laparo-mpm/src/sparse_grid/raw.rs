//! Unchecked node access, prefetch hints and the shared pointer of the colour-partitioned scatters.

/// `nodes[i]` for a stencil node index `i` from [`BlockNbr::nodes`] of a grid with `nodes.len()` =
/// [`SparseGrid::n_slots`] (checked once by the caller): in bounds by construction of the grid, so
/// the per-node bounds check is spared (still checked in debug builds).
#[inline(always)]
pub(crate) fn node_at<T>(nodes: &[T], i: usize) -> &T {
    debug_assert!(i < nodes.len());
    // SAFETY: see above; block neighbour slots are active blocks, local offsets < 4^D.
    unsafe { nodes.get_unchecked(i) }
}

/// Slot of stencil node `i` for a particle of crack side `label` (eq. of the two-field grid, see
/// [`crate::Scene::crack_side`]): the node's second field (i + side.len()) when the particle is on the
/// other side of the node, else i. A node whose side sum is exactly 0 (on the crack, both lips equal)
/// keeps side +1 in its own field and side −1 in the second. `side` is empty on a one-field grid
/// (then `label` is 0).
#[inline(always)]
pub(crate) fn field_slot(side: &[f64], i: usize, label: f64) -> usize {
    if label != 0.0 {
        let s = *node_at(side, i);
        if s * label < 0.0 || (s == 0.0 && label < 0.0) {
            return i + side.len();
        }
    }
    i
}

/// The stencil's node indices `st` mapped to the particle's slots ([`field_slot`]); unchanged (one
/// branch per particle, not per node) for a particle without a crack side.
#[inline(always)]
pub(crate) fn field_slots(st: [u32; 27], side: &[f64], label: f64) -> [u32; 27] {
    if label == 0.0 {
        st
    } else {
        st.map(|i| field_slot(side, i as usize, label) as u32)
    }
}

/// Hint the CPU to load the cache line at `r` (no effect on results; a no-op off x86-64). `r` is only
/// an address: it is never dereferenced.
#[inline(always)]
pub(crate) fn prefetch<T>(r: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults and does not change memory.
    unsafe {
        std::arch::x86_64::_mm_prefetch(r as *const i8, std::arch::x86_64::_MM_HINT_T0)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
}

/// A raw pointer that may cross threads; used for the colour-partitioned scatters whose writes are
/// disjoint by construction.
#[derive(Clone, Copy)]
pub(crate) struct SyncPtr<T>(pub *mut T);
unsafe impl<T> Send for SyncPtr<T> {}
unsafe impl<T> Sync for SyncPtr<T> {}
impl<T> SyncPtr<T> {
    /// # Safety
    /// `i` in bounds and no other thread touches element `i` concurrently.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn at(&self, i: usize) -> &mut T {
        &mut *self.0.add(i)
    }
    /// Address of element `i` (for [`prefetch`]; no reference is made).
    #[inline(always)]
    pub fn addr(&self, i: usize) -> *const T {
        self.0.wrapping_add(i)
    }
}
