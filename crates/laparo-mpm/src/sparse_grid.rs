//! Sparse background grid: only the 4^D-node blocks touched by particle stencils are allocated.
//!
//! Particles are sorted by the block of their stencil base node ("particle blocks"); a particle in
//! block b touches nodes of blocks b and b+1 along every axis. Particle blocks are given one of 2^D
//! colours by the parity of their block coordinates; blocks of one colour touch disjoint nodes, so
//! a colour can scatter in parallel without atomics, and the order of the additions into every node
//! is fixed (colour by colour, particles in sorted order): results are bit-identical whatever the
//! number of threads. In 2D the colour tasks are chunks of consecutive particle blocks balanced by
//! particle count (see `balanced_stripe_tasks`).
//!
//! The build is split so that little of it is serial: the block key of every particle is computed in
//! parallel by the previous step's G2P (while the new position is at hand, [`BlockKeyer`]), and the
//! counting sort ([`SparseGrid::build_from_keys`]) runs alongside the stress pass of P2G, which does
//! not need the grid. Each particle block gets a node window ([`StencilWindow`]: the node indices of
//! the 6^D nodes its stencils can reach), so the kernels find a stencil's node indices by 3^D loads at
//! fixed offsets.
use crate::error::MpmError;
use crate::linalg::{Matrix, Vector};
use crate::scene::GridSpec;
use rayon::prelude::*;

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

/// Block side in cells (≥ 3 so that same-colour particle blocks never share a node).
pub const BLOCK: usize = 4;
const BLOCK_SHIFT: u32 = 2;
const INACTIVE: u32 = u32::MAX;

/// Stencil base node of a particle: floor(x/Δx − 0.5) per axis, or `None` when the 3-node stencil
/// is not inside the grid (nodes 0..n_grid−1).
#[inline(always)]
pub fn particle_base<const D: usize>(x: &Vector<D>, grid: &GridSpec) -> Option<[i32; D]> {
    let inv_dx = 1.0 / grid.dx;
    let mut b = [0i32; D];
    for d in 0..D {
        let q = x[d] * inv_dx - 0.5;
        if !(q >= 0.0 && q < (grid.n_grid as f64 - 2.0)) {
            return None;
        }
        b[d] = q as i32;
    }
    Some(b)
}

/// Number of nodes in a block: 4^D.
pub const fn block_nodes(d: usize) -> usize {
    BLOCK.pow(d as u32)
}

/// A run of sorted particles sharing one base block.
#[derive(Clone, Copy, Debug)]
pub struct ParticleBlock {
    /// Range into [`SparseGrid::order`].
    pub start: u32,
    /// End of the range (exclusive).
    pub end: u32,
}

/// The sparse grid of one time step (rebuilt each step from the particle positions).
pub struct SparseGrid<const D: usize> {
    spec: GridSpec,
    blocks_per_axis: usize,
    table: Vec<u32>,
    /// Block coordinates of the active blocks (dense index → block coordinate).
    pub blocks: Vec<[u32; D]>,
    /// Particle blocks (runs of [`Self::order`]).
    pub pblocks: Vec<ParticleBlock>,
    /// Per colour, the tasks of the coloured scatters: ranges [start, end) of particle blocks (see
    /// [`coloured_axes`]).
    pub colors: Vec<Vec<[u32; 2]>>,
    /// Particle indices sorted by base block.
    pub order: Vec<u32>,
    /// Neighbourhood of every particle block (same index as [`Self::pblocks`]).
    pub pnbr: Vec<BlockNbr<D>>,
    /// Node window of every particle block ([`window_len`] entries each, see [`StencilWindow`]).
    pub pwin: Vec<u32>,
    /// Particle block of every particle (by particle index).
    pub pblock_of: Vec<u32>,
    /// Node mass m_i.
    pub mass: Vec<f64>,
    /// Node momentum (m v)_i after P2G; node velocity after the grid update.
    pub mom: Vec<Vector<D>>,
    /// Node velocity after the grid update (boundary conditions applied).
    pub vel: Vec<Vector<D>>,
    /// Per node: which velocity components the wall condition zeroed (bit d), for the adjoint.
    pub wall_mask: Vec<u8>,
    keys: Vec<u32>,
    counts: Vec<u32>,
    distinct: Vec<u32>,
}

/// The 2^D blocks a particle block's stencils touch: first-node index of each neighbour block
/// (bit d of the slot = +1 along axis d) and the block's first node coordinate.
#[derive(Clone, Copy, Debug)]
pub struct BlockNbr<const D: usize> {
    /// First node index (block index · 4^D) of neighbour block `slot`.
    pub first: [u32; 8],
    /// Global node coordinate of the block's first node.
    pub origin: [i32; D],
}

/// Side of a particle block's node window: the block's 4 nodes and 2 of the next block along each
/// axis (a stencil starts at a local coordinate 0..3 and spans 3 nodes).
pub const WINDOW: usize = BLOCK + 2;

/// Number of entries of a node window: 6^D.
pub const fn window_len(d: usize) -> usize {
    WINDOW.pow(d as u32)
}

/// Span of window entries a stencil covers from its first node: 2 (6^(D−1) + … + 1) + 1.
const fn stencil_span(d: usize) -> usize {
    (window_len(d) - 1) / (WINDOW - 1) * 2 + 1
}

/// The node indices around one particle block: a dense 6^D window (axis 0 slowest) of the node
/// indices of the block and its neighbours, built once per block by [`SparseGrid::build`], so that a
/// particle's 3^D stencil node indices are 3^D loads at fixed offsets from its base node's entry.
#[derive(Clone, Copy, Debug)]
pub struct StencilWindow<'a, const D: usize> {
    win: &'a [u32],
    origin: [i32; D],
}

impl<const D: usize> StencilWindow<'_, D> {
    /// Node indices of the 3^D stencil (stencil order, first 3^D entries) of a particle of this
    /// block with base node `b`.
    #[inline(always)]
    pub fn nodes(&self, b: &[i32; D]) -> [u32; 27] {
        let mut off = 0usize;
        for (bd, od) in b.iter().zip(&self.origin) {
            let l0 = (bd - od) as usize;
            debug_assert!(l0 < BLOCK);
            off = off * WINDOW + l0;
        }
        // One bounds check per particle; the per-node offsets below are constants < the span.
        let win = &self.win[off..off + stencil_span(D)];
        let mut out = [0u32; 27];
        for_stencil_offsets::<D>(|k, o| {
            let mut r = 0;
            for &od in o {
                r = r * WINDOW + od;
            }
            out[k] = win[r];
        });
        out
    }
}

/// Maps a particle position to the key of its base block (see [`SparseGrid::keyer`]).
#[derive(Clone, Copy, Debug)]
pub struct BlockKeyer {
    inv_dx: f64,
    /// n_grid − 2: the base node must be below it.
    upper: f64,
    blocks_per_axis: usize,
}

impl BlockKeyer {
    /// Key of the block of the stencil base node of a particle at `x` (row-major block coordinate,
    /// axis 0 slowest), or `u32::MAX` when the stencil leaves the grid (same test and arithmetic as
    /// [`particle_base`], with 1/Δx computed once).
    #[inline(always)]
    pub fn key<const D: usize>(&self, x: &Vector<D>) -> u32 {
        let mut k = 0;
        for d in 0..D {
            let q = x[d] * self.inv_dx - 0.5;
            if !(q >= 0.0 && q < self.upper) {
                return INACTIVE;
            }
            // SAFETY: q is finite and in [0, n_grid − 2).
            let b = unsafe { q.to_int_unchecked::<i32>() } as usize;
            k = k * self.blocks_per_axis + (b >> BLOCK_SHIFT);
        }
        k as u32
    }
}

/// `nodes[i]` for a stencil node index `i` from [`BlockNbr::nodes`] of a grid with `nodes.len()` =
/// [`SparseGrid::n_nodes`] (checked once by the caller): in bounds by construction of the grid, so
/// the per-node bounds check is spared (still checked in debug builds).
#[inline(always)]
pub(crate) fn node_at<T>(nodes: &[T], i: usize) -> &T {
    debug_assert!(i < nodes.len());
    // SAFETY: see above; block neighbour slots are active blocks, local offsets < 4^D.
    unsafe { nodes.get_unchecked(i) }
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

impl<const D: usize> SparseGrid<D> {
    /// An empty grid for `spec`.
    pub fn new(spec: GridSpec) -> Self {
        let blocks_per_axis = spec.n_grid.div_ceil(BLOCK);
        SparseGrid {
            spec,
            blocks_per_axis,
            table: vec![INACTIVE; blocks_per_axis.pow(D as u32)],
            blocks: Vec::new(),
            pblocks: Vec::new(),
            colors: vec![Vec::new(); 1 << D],
            order: Vec::new(),
            pnbr: Vec::new(),
            pwin: Vec::new(),
            pblock_of: Vec::new(),
            mass: Vec::new(),
            mom: Vec::new(),
            vel: Vec::new(),
            wall_mask: Vec::new(),
            keys: Vec::new(),
            counts: vec![0; blocks_per_axis.pow(D as u32)],
            distinct: Vec::new(),
        }
    }

    /// Grid specification.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Number of allocated nodes.
    pub fn n_nodes(&self) -> usize {
        self.mass.len()
    }

    #[inline(always)]
    fn block_key(&self, c: &[usize; D]) -> usize {
        let mut k = 0;
        for &cd in c {
            k = k * self.blocks_per_axis + cd;
        }
        k
    }

    /// What [`BlockKeyer::key`] needs (a small copyable value for the kernels that compute the
    /// keys of the next step's positions).
    pub fn keyer(&self) -> BlockKeyer {
        BlockKeyer {
            inv_dx: 1.0 / self.spec.dx,
            upper: self.spec.n_grid as f64 - 2.0,
            blocks_per_axis: self.blocks_per_axis,
        }
    }

    /// Global node coordinate of node `n`.
    #[inline(always)]
    pub fn node_coord(&self, n: usize) -> [usize; D] {
        let b = &self.blocks[n / block_nodes(D)];
        let mut l = n % block_nodes(D);
        let mut out = [0usize; D];
        for d in 0..D {
            out[d] = b[d] as usize * BLOCK + (l % BLOCK);
            l /= BLOCK;
        }
        out
    }

    /// Rebuild for particle positions `x` at `step`: sort particles into blocks, activate the
    /// blocks their stencils touch, colour the particle blocks, zero the node arrays.
    pub fn build(&mut self, x: &[Vector<D>], step: usize) -> Result<(), MpmError> {
        let keyer = self.keyer();
        let mut keys = std::mem::take(&mut self.keys);
        keys.clear();
        keys.extend(x.iter().map(|xp| keyer.key(xp)));
        let r = self.build_from_keys(&keys, step);
        self.keys = keys;
        r
    }

    /// [`Self::build`] from the block keys of the particles ([`BlockKeyer::key`] of their positions,
    /// e.g. computed in parallel by the previous step's G2P): the serial part of the build.
    pub fn build_from_keys(&mut self, keys: &[u32], step: usize) -> Result<(), MpmError> {
        let n = keys.len();
        // Counting sort of the particles by base block (stable: particle index order within a block).
        self.distinct.clear();
        for (p, &k) in keys.iter().enumerate() {
            if k == INACTIVE {
                for &k in &self.distinct {
                    self.counts[k as usize] = 0;
                }
                self.distinct.clear();
                return Err(MpmError::OutsideDomain { particle: p, step });
            }
            let c = &mut self.counts[k as usize];
            if *c == 0 {
                self.distinct.push(k);
            }
            *c += 1;
        }
        self.distinct.sort_unstable();
        let mut offset = 0u32;
        for &k in &self.distinct {
            let c = self.counts[k as usize];
            self.counts[k as usize] = offset;
            offset += c;
        }
        self.order.clear();
        self.order.resize(n, 0);
        for (p, &k) in keys.iter().enumerate() {
            let c = &mut self.counts[k as usize];
            self.order[*c as usize] = p as u32;
            *c += 1;
        }
        // Now counts[k] = end of block k's run in `order`.
        // Activate blocks in order of first touch (the block table is all INACTIVE between builds).
        self.blocks.clear();
        self.pblocks.clear();
        self.pnbr.clear();
        self.pwin.clear();
        let nn = block_nodes(D) as u32;
        let mut start = 0u32;
        for &key in &self.distinct {
            let c0 = self.key_coord(key as usize);
            let mut nbr = [0u32; 8];
            for (nb, slot) in nbr.iter_mut().enumerate().take(1 << D) {
                let c: [usize; D] = std::array::from_fn(|d| c0[d] + ((nb >> d) & 1));
                if c.iter().all(|&v| v < self.blocks_per_axis) {
                    let k = self.block_key(&c);
                    if self.table[k] == INACTIVE {
                        self.table[k] = self.blocks.len() as u32;
                        self.blocks.push(std::array::from_fn(|d| c[d] as u32));
                    }
                    *slot = self.table[k] * nn;
                }
            }
            let end = self.counts[key as usize];
            // From here on counts[key] is the particle block of key (reset to 0 below).
            self.counts[key as usize] = self.pblocks.len() as u32;
            self.pblocks.push(ParticleBlock { start, end });
            self.pnbr.push(BlockNbr { first: nbr, origin: c0.map(|v| (v * BLOCK) as i32) });
            // Node window: entry (w_0, …, w_{D−1}) is node (w_d mod 4)_d of neighbour block
            // (w_d ≥ 4)_d (blocks outside the grid give unused entries).
            // Rows along the last axis: 4 nodes of one neighbour block then 2 of the next.
            let last = D - 1;
            let mut w = [0usize; D];
            for _ in 0..window_len(D) / WINDOW {
                let (mut slot, mut local) = (0usize, 0u32);
                for (d, &wd) in w.iter().enumerate().take(last) {
                    slot |= (wd >> BLOCK_SHIFT) << d;
                    local += ((wd & (BLOCK - 1)) as u32) << (BLOCK_SHIFT * d as u32);
                }
                let step = 1u32 << (BLOCK_SHIFT * last as u32);
                let (lo, hi) = (nbr[slot] + local, nbr[slot | (1 << last)] + local);
                self.pwin.extend([lo, lo + step, lo + 2 * step, lo + 3 * step, hi, hi + step]);
                // Next row (axis D − 2 fastest).
                for d in (0..last).rev() {
                    w[d] += 1;
                    if w[d] < WINDOW {
                        break;
                    }
                    w[d] = 0;
                }
            }
            start = end;
        }
        self.pblock_of.clear();
        self.pblock_of.extend(keys.iter().map(|&k| self.counts[k as usize]));
        for &k in &self.distinct {
            self.counts[k as usize] = 0;
        }
        for b in &self.blocks {
            let c: [usize; D] = std::array::from_fn(|d| b[d] as usize);
            let k = self.block_key(&c);
            self.table[k] = INACTIVE;
        }
        self.colour_tasks();
        let nodes = self.blocks.len() * nn as usize;
        self.mass.clear();
        self.mass.resize(nodes, 0.0);
        self.mom.clear();
        self.mom.resize(nodes, Vector::<D>::zeros());
        // Fully overwritten by the grid update: no need to zero.
        self.vel.resize(nodes, Vector::<D>::zeros());
        self.wall_mask.resize(nodes, 0);
        Ok(())
    }

    /// Block coordinate of block key `k` (inverse of `block_key`).
    fn key_coord(&self, mut k: usize) -> [usize; D] {
        let mut c = [0usize; D];
        for d in (0..D).rev() {
            c[d] = k % self.blocks_per_axis;
            k /= self.blocks_per_axis;
        }
        c
    }

    /// The colour tasks of the particle blocks (in key order), see [`coloured_axes`].
    fn colour_tasks(&mut self) {
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

    /// Node window of particle block `pb`.
    #[inline(always)]
    pub fn window(&self, pb: usize) -> StencilWindow<'_, D> {
        let wl = window_len(D);
        StencilWindow { win: &self.pwin[pb * wl..(pb + 1) * wl], origin: self.pnbr[pb].origin }
    }

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

    /// Move the particle layout (sort order, blocks, colours) and node results (mass, velocity,
    /// wall mask) of this step into `cp`, taking `cp`'s buffers in exchange (no copy).
    pub fn swap_checkpoint(&mut self, cp: &mut GridCheckpoint<D>) {
        std::mem::swap(&mut self.order, &mut cp.order);
        std::mem::swap(&mut self.pblocks, &mut cp.pblocks);
        std::mem::swap(&mut self.colors, &mut cp.colors);
        std::mem::swap(&mut self.pnbr, &mut cp.pnbr);
        std::mem::swap(&mut self.pwin, &mut cp.pwin);
        std::mem::swap(&mut self.pblock_of, &mut cp.pblock_of);
        std::mem::swap(&mut self.mass, &mut cp.mass);
        std::mem::swap(&mut self.vel, &mut cp.vel);
        std::mem::swap(&mut self.wall_mask, &mut cp.wall_mask);
    }
}

/// What the reverse pass needs of one step's grid: the particle layout (so the sparse grid is not
/// rebuilt) and the node masses, velocities and wall masks (so P2G is not redone).
#[derive(Default)]
pub struct GridCheckpoint<const D: usize> {
    /// Particle indices sorted by base block.
    pub order: Vec<u32>,
    /// Particle blocks.
    pub pblocks: Vec<ParticleBlock>,
    /// Scatter tasks per colour.
    pub colors: Vec<Vec<[u32; 2]>>,
    /// Neighbourhood per particle block.
    pub pnbr: Vec<BlockNbr<D>>,
    /// Node window per particle block.
    pub pwin: Vec<u32>,
    /// Particle block of every particle.
    pub pblock_of: Vec<u32>,
    /// Node masses.
    pub mass: Vec<f64>,
    /// Node velocities after the grid update.
    pub vel: Vec<Vector<D>>,
    /// Wall masks.
    pub wall_mask: Vec<u8>,
}

/// Stencil base node floor(x/Δx − ½) (same arithmetic as [`particle_base`]) of a particle that
/// [`SparseGrid::build`] accepted (so the value is in [0, n_grid − 2)).
#[inline(always)]
pub fn base_of<const D: usize>(x: &Vector<D>, inv_dx: f64) -> [i32; D] {
    std::array::from_fn(|d| {
        let q = x[d] * inv_dx - 0.5;
        debug_assert!(q >= 0.0 && q < i32::MAX as f64);
        // SAFETY: q is finite and in [0, n_grid − 2) for every particle of a built grid.
        unsafe { q.to_int_unchecked::<i32>() }
    })
}

/// Quadratic B-spline weights (eq. 5.6's N) of a particle: fx = x/Δx − base ∈ [0.5, 1.5), and per
/// axis the weights of nodes base+0,1,2 and their derivatives with respect to fx.
#[inline(always)]
pub fn bspline<const D: usize>(
    x: &Vector<D>,
    base: &[i32; D],
    inv_dx: f64,
) -> (Vector<D>, [[f64; 3]; D], [[f64; 3]; D]) {
    let mut fx = Vector::<D>::zeros();
    let mut w = [[0.0; 3]; D];
    let mut dw = [[0.0; 3]; D];
    for d in 0..D {
        let f = x[d] * inv_dx - base[d] as f64;
        fx[d] = f;
        w[d] = [0.5 * (1.5 - f) * (1.5 - f), 0.75 - (f - 1.0) * (f - 1.0), 0.5 * (f - 0.5) * (f - 0.5)];
        dw[d] = [f - 1.5, -2.0 * (f - 1.0), f - 0.5];
    }
    (fx, w, dw)
}

/// Per-axis terms of an affine function of the node offset, u(o) = c + M (o − fx) s = c + Σ_d
/// M[:, d] (o_d − fx_d) s: entry [d][o] is M[:, d] (o − fx_d) s, with `c` folded into axis 0. A node's
/// value is then [`affine_at`]: D − 1 vector additions instead of a matrix–vector product.
#[inline(always)]
pub fn affine_terms<const D: usize>(c: &Vector<D>, m: &Matrix<D>, fx: &Vector<D>, s: f64) -> [[Vector<D>; 3]; D] {
    let mut t = [[Vector::<D>::zeros(); 3]; D];
    for (d, td) in t.iter_mut().enumerate() {
        let col = m.column(d).into_owned();
        for (o, tdo) in td.iter_mut().enumerate() {
            *tdo = col * ((o as f64 - fx[d]) * s);
            if d == 0 {
                *tdo += c;
            }
        }
    }
    t
}

/// Value at stencil offset `o` of the affine function whose [`affine_terms`] are `t`.
#[inline(always)]
pub fn affine_at<const D: usize>(t: &[[Vector<D>; 3]; D], o: &[usize; D]) -> Vector<D> {
    let mut u = t[0][o[0]];
    for d in 1..D {
        u += t[d][o[d]];
    }
    u
}

/// ∂w/∂fx_d of a stencil node: dw_d[o_d] Π_{e≠d} w_e[o_e].
#[inline(always)]
pub fn weight_grad<const D: usize>(w: &[[f64; 3]; D], dw: &[[f64; 3]; D], o: &[usize; D]) -> Vector<D> {
    let mut g = Vector::<D>::zeros();
    for d in 0..D {
        let mut v = dw[d][o[d]];
        for e in 0..D {
            if e != d {
                v *= w[e][o[e]];
            }
        }
        g[d] = v;
    }
    g
}

/// Offset of stencil entry `k` along axis `d` (axis 0 slowest).
#[inline(always)]
pub fn stencil_offset<const D: usize>(k: usize) -> [usize; D] {
    let mut o = [0usize; D];
    let mut rem = k;
    for d in (0..D).rev() {
        o[d] = rem % 3;
        rem /= 3;
    }
    o
}

/// Visit the 3^D stencil nodes of a particle in stencil order (axis 0 slowest) with their offsets
/// and weights w = Π_d w[d][o_d]; the loops are fully unrolled for D = 2, 3.
#[inline(always)]
pub fn for_stencil<const D: usize>(w: &[[f64; 3]; D], mut f: impl FnMut(usize, &[usize; D], f64)) {
    let a1 = 1usize.min(D - 1);
    if D == 2 {
        let mut k = 0;
        for i in 0..3 {
            for j in 0..3 {
                let mut o = [0usize; D];
                o[0] = i;
                o[D - 1] = j;
                f(k, &o, w[0][i] * w[D - 1][j]);
                k += 1;
            }
        }
    } else {
        let mut k = 0;
        for i in 0..3 {
            for j in 0..3 {
                let wij = w[0][i] * w[a1][j];
                for (l, &wl) in w[D - 1].iter().enumerate() {
                    let mut o = [0usize; D];
                    o[0] = i;
                    o[a1] = j;
                    o[D - 1] = l;
                    f(k, &o, wij * wl);
                    k += 1;
                }
            }
        }
    }
}

/// Visit the 3^D stencil offsets in stencil order (axis 0 slowest).
#[inline(always)]
pub fn for_stencil_offsets<const D: usize>(mut f: impl FnMut(usize, &[usize; D])) {
    let w = [[0.0; 3]; D];
    for_stencil::<D>(&w, |k, o, _| f(k, o));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::stencil_len;

    /// Node indices touched by the particles of each colour task, per colour.
    fn task_nodes<const D: usize>(g: &SparseGrid<D>, x: &[Vector<D>]) -> Vec<Vec<Vec<u32>>> {
        let inv_dx = 1.0 / g.spec().dx;
        g.colors
            .iter()
            .map(|tasks| {
                tasks
                    .iter()
                    .map(|&[b0, b1]| {
                        let mut nodes = Vec::new();
                        for pb in b0 as usize..b1 as usize {
                            let blk = g.pblocks[pb];
                            for &p in &g.order[blk.start as usize..blk.end as usize] {
                                let st = g.window(pb).nodes(&base_of(&x[p as usize], inv_dx));
                                nodes.extend_from_slice(&st[..stencil_len(D)]);
                            }
                        }
                        nodes.sort_unstable();
                        nodes.dedup();
                        nodes
                    })
                    .collect()
            })
            .collect()
    }

    fn check<const D: usize>(x: &[Vector<D>], n_grid: usize) {
        let mut g = SparseGrid::<D>::new(GridSpec::unit(n_grid));
        g.build(x, 0).unwrap();
        // Every particle in exactly one task; same-colour tasks touch disjoint nodes; stencil node
        // indices agree with the node coordinates.
        let mut seen = vec![0u32; x.len()];
        for tasks in &g.colors {
            for &[b0, b1] in tasks {
                for pb in b0..b1 {
                    let blk = g.pblocks[pb as usize];
                    for &p in &g.order[blk.start as usize..blk.end as usize] {
                        seen[p as usize] += 1;
                    }
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        for colour in task_nodes(&g, x) {
            let mut all: Vec<u32> = colour.iter().flatten().copied().collect();
            let n = all.len();
            all.sort_unstable();
            all.dedup();
            assert_eq!(all.len(), n, "same-colour tasks share a node");
        }
        let inv_dx = 1.0 / g.spec().dx;
        for (p, xp) in x.iter().enumerate() {
            let b = base_of(xp, inv_dx);
            let st = g.window(g.pblock_of[p] as usize).nodes(&b);
            for_stencil_offsets::<D>(|k, o| {
                let c = g.node_coord(st[k] as usize);
                for d in 0..D {
                    assert_eq!(c[d] as i32, b[d] + o[d] as i32);
                }
            });
        }
    }

    #[test]
    fn colour_tasks_are_node_disjoint() {
        // Deterministic pseudo-random clouds: a wide 2D body (several chunks per colour), a narrow
        // one, a sparse scatter, and a 3D body.
        let mut r = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            (r >> 11) as f64 / (1u64 << 53) as f64
        };
        for (lo, hi, n) in
            [([0.1, 0.2], [0.8, 0.6], 20000), ([0.4, 0.1], [0.47, 0.9], 3000), ([0.05, 0.05], [0.95, 0.95], 500)]
        {
            let x: Vec<Vector<2>> =
                (0..n).map(|_| Vector::<2>::from_fn(|d, _| lo[d] + (hi[d] - lo[d]) * rnd())).collect();
            check::<2>(&x, 96);
        }
        let x: Vec<Vector<3>> = (0..5000).map(|_| Vector::<3>::from_fn(|_, _| 0.3 + 0.4 * rnd())).collect();
        check::<3>(&x, 48);
    }
}
