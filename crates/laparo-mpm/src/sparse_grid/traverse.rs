//! Parallel traversal of the particles of a built grid: coloured (scatters) and in particle order
//! (gathers).
use super::{SparseGrid, StencilWindow};
use rayon::prelude::*;

impl<const D: usize> SparseGrid<D> {
    /// Run `f(particle, its block's neighbourhood)` for every particle, colour by colour,
    /// same-colour tasks in parallel. `f` may write to the stencil nodes of its particle (disjoint
    /// across a colour).
    /// `prefetch(q)` is called for the particle `q` a few places ahead in the task's order (the
    /// coloured order jumps around the particle arrays, which the hardware prefetchers do not follow).
    pub(crate) fn for_each_coloured(
        &self,
        prefetch: impl Fn(usize) + Sync,
        f: impl Fn(usize, &StencilWindow<D>) + Sync,
    ) {
        const AHEAD: usize = 8;
        for tasks in &self.colors {
            if tasks.is_empty() {
                continue;
            }
            let min_len = tasks.len().div_ceil(4 * rayon::current_num_threads()).max(1);
            tasks.par_iter().with_min_len(min_len).for_each(|&[b0, b1]| {
                let (start, end) =
                    (self.pblocks[b0 as usize].start as usize, self.pblocks[b1 as usize - 1].end as usize);
                let order = &self.order[start..end];
                for &q in order.iter().take(AHEAD) {
                    prefetch(q as usize);
                }
                let mut i = 0;
                for pb in b0 as usize..b1 as usize {
                    let blk = self.pblocks[pb];
                    let nbr = &self.window(pb);
                    for &p in &self.order[blk.start as usize..blk.end as usize] {
                        if let Some(&q) = order.get(i + AHEAD) {
                            prefetch(q as usize);
                        }
                        i += 1;
                        f(p as usize, nbr);
                    }
                }
            });
        }
    }

    /// Run `f(particle, its block's neighbourhood)` for every particle, in particle-index order
    /// (contiguous chunks in parallel: the per-particle arrays are streamed sequentially). For
    /// gathers: `f` must only write to per-particle data.
    pub(crate) fn for_each_particle(&self, f: impl Fn(usize, &StencilWindow<D>) + Sync) {
        let n = self.pblock_of.len();
        let min_len = n.div_ceil(16 * rayon::current_num_threads()).max(1);
        self.pblock_of.par_iter().enumerate().with_min_len(min_len).for_each(|(p, &pb)| {
            f(p, &self.window(pb as usize));
        });
    }
}
