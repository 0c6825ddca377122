//! The buffers SGM reuses from one matched pair to the next (census images, S and cost volumes,
//! selections), owned by the caller: fresh allocations of this size cost page faults on every
//! pair. There is no process-wide state; each [`SgmWorkspace`] serves one match at a time.
use super::select::Selection;

/// Reused SGM buffers: a video or a benchmark matches pair after pair of one size, and a fresh
/// 50–300 MB allocation per pair costs more in page faults than the matching itself. Pass the same
/// workspace to [`match_pair_with`](super::match_pair_with) for every pair;
/// [`match_pair`](super::match_pair) uses a fresh one. The output does not depend on the
/// workspace's history (every element is written before it is read).
#[derive(Debug, Default)]
pub struct SgmWorkspace {
    /// Census images of the left and right image.
    pub(crate) census: [Vec<u64>; 2],
    /// The aggregation volumes.
    pub(crate) volumes: Volumes,
}

/// The volumes of [`super::aggregate::aggregate_select`].
#[derive(Debug, Default)]
pub(crate) struct Volumes {
    /// S (u16; empty when the narrow partial sums are used).
    pub s: Vec<u16>,
    /// The first sweep's S as bytes (empty when `s` is used).
    pub s8: Vec<u8>,
    /// Costs C.
    pub cost: Vec<u8>,
    /// Selections (one per pixel).
    pub sel: Vec<Selection>,
}

impl SgmWorkspace {
    /// An empty workspace (buffers are allocated by the first match).
    pub fn new() -> Self {
        Self::default()
    }
}

/// The buffer `slot` resized to `n` elements and taken out of the workspace (contents
/// unspecified: the users write every element before reading it); give it back with
/// [`put_back`].
pub(crate) fn take<T: Copy + Default>(slot: &mut Vec<T>, n: usize) -> Vec<T> {
    let mut v = std::mem::take(slot);
    v.resize(n, T::default());
    v
}

/// Return a buffer taken with [`take`] for the next pair.
pub(crate) fn put_back<T>(slot: &mut Vec<T>, v: Vec<T>) {
    *slot = v;
}
