//! Colour partition of the particle blocks for the scatters without atomics (see the module
//! header of `sparse_grid`): 3D one task per block, 2D balanced chunks of block columns.
use super::{BlockNbr, SparseGrid, BLOCK};

/// Number of leading axes along which particle blocks are coloured. In 3D all of them (2³ colours,
/// a scatter task is one block). In 2D only axis 0: a task is a chunk of consecutive block columns
/// (processed in order by one thread, see `balanced_stripe_tasks`), and chunks of equal colour touch
/// disjoint nodes; 2 colour phases per scatter instead of 4 halve the synchronisations of a small 2D
/// step.
pub const fn coloured_axes(d: usize) -> usize {
    if d == 2 {
        1
    } else {
        d
    }
}

impl<const D: usize> SparseGrid<D> {
    /// The colour tasks of the particle blocks (in key order), see [`coloured_axes`].
    pub(super) fn colour_tasks(&mut self) {
        self.colors.resize(1 << D, Vec::new());
        for c in self.colors.iter_mut() {
            c.clear();
        }
        if coloured_axes(D) < D {
            self.balanced_stripe_tasks();
            return;
        }
        // All axes coloured (3D): every block is its own task, coloured by the parity of its
        // coordinates.
        for (pb, nbr) in self.pnbr.iter().enumerate() {
            let colour: usize = (0..D).map(|d| ((nbr.origin[d] as usize / BLOCK) & 1) << d).sum();
            self.colors[colour].push([pb as u32, pb as u32 + 1]);
        }
    }

    /// 2D colour tasks: K chunks of consecutive particle blocks (key order, i.e. by block column
    /// along axis 0), of about n/K particles each, chunk c in colour c mod 2. A chunk spanning block
    /// columns [a, b] touches the nodes of columns [a, b + 1]; chunks c and c + 2 are kept disjoint
    /// by making every chunk extend at least over the column after the one where the chunk before it
    /// ended. So each colour phase has K/2 tasks of equal work (K = 4 for the 8–15 occupied columns of
    /// a body of 32–60 cells: 2 equal tasks per phase, which is what 2 threads need), instead of one
    /// task per block column with the split of columns between threads left to chance. The chunks
    /// depend on the particles only (not on the thread count), so the order of additions into every
    /// node stays fixed. A narrow body degrades to one block column per chunk.
    fn balanced_stripe_tasks(&mut self) {
        let col = |nbr: &BlockNbr<D>| nbr.origin[0] as i64 / BLOCK as i64;
        let npb = self.pblocks.len();
        if npb == 0 {
            return;
        }
        let mut ncols = 1;
        for w in self.pnbr.windows(2) {
            ncols += (col(&w[1]) != col(&w[0])) as usize;
        }
        let k = 4 * (ncols / 8).max(1);
        let total = self.pblocks[npb - 1].end as u64;
        let mut start = 0usize;
        // Block column of the last particle block of the chunk before the current one.
        let mut prev_last_col = i64::MIN / 2;
        let mut chunk = 0usize;
        while start < npb {
            let target = (chunk as u64 + 1) * total / k as u64;
            let mut end = start + 1;
            while end < npb
                && ((self.pblocks[end - 1].end as u64) < target || col(&self.pnbr[end]) <= prev_last_col + 1)
            {
                end += 1;
            }
            if chunk + 1 == k {
                end = npb;
            }
            self.colors[chunk % 2].push([start as u32, end as u32]);
            prev_last_col = col(&self.pnbr[end - 1]);
            start = end;
            chunk += 1;
        }
    }
}
