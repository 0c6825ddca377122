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
mod colour;
mod raw;
#[cfg(test)]
mod tests;
mod traverse;

pub(crate) use raw::{field_slots, node_at, prefetch, SyncPtr};

use crate::error::MpmError;
use crate::grid_spec::GridSpec;
use crate::linalg::Vector;
use crate::stencil::for_stencil_offsets;

/// Block side in cells (≥ 3 so that same-colour particle blocks never share a node).
pub const BLOCK: usize = 4;
const BLOCK_SHIFT: u32 = 2;
const INACTIVE: u32 = u32::MAX;

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
    /// Two-field grid (a scene with `crack_side`): per node Σ_p w_ip m_p side_p, whose sign is the
    /// node's own side; empty on a one-field grid. With two fields, `mass`, `mom`, `vel` and
    /// `wall_mask` hold 2 × `side.len()` slots: node i's own field at i, its second field (the
    /// particles of the other side) at i + `side.len()`.
    pub side: Vec<f64>,
    /// Whether [`Self::build_from_keys`] allocates the second field.
    pub two_field: bool,
    counts: Vec<u32>,
    distinct: Vec<u32>,
}

/// Where a particle block sits: its first node's global coordinate (the node indices of the 2^D
/// blocks its stencils touch are in its [`StencilWindow`]).
#[derive(Clone, Copy, Debug)]
pub struct BlockNbr<const D: usize> {
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
    /// [`GridSpec::stencil_base`](crate::grid_spec::GridSpec::stencil_base), with 1/Δx computed once).
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
            side: Vec::new(),
            two_field: false,
            counts: vec![0; blocks_per_axis.pow(D as u32)],
            distinct: Vec::new(),
        }
    }

    /// Grid specification.
    #[cfg(test)]
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Number of node slots: the allocated nodes × the number of fields.
    pub fn n_slots(&self) -> usize {
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
    #[cfg(test)]
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
    #[cfg(test)]
    pub fn build(&mut self, x: &[Vector<D>], step: usize) -> Result<(), MpmError> {
        let keyer = self.keyer();
        let keys: Vec<u32> = x.iter().map(|xp| keyer.key(xp)).collect();
        self.build_from_keys(&keys, step)
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
            self.pnbr.push(BlockNbr { origin: c0.map(|v| (v * BLOCK) as i32) });
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
        self.side.clear();
        if self.two_field {
            self.side.resize(nodes, 0.0);
        }
        let nodes = if self.two_field { 2 * nodes } else { nodes };
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

    /// Node window of particle block `pb`.
    #[inline(always)]
    pub fn window(&self, pb: usize) -> StencilWindow<'_, D> {
        let wl = window_len(D);
        StencilWindow { win: &self.pwin[pb * wl..(pb + 1) * wl], origin: self.pnbr[pb].origin }
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
        std::mem::swap(&mut self.side, &mut cp.side);
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
    /// Node sides of a two-field grid (empty otherwise).
    pub side: Vec<f64>,
}
