//! Sobolev-type preconditioner: a symmetric Gaussian smoothing of per-particle vectors through a
//! background lattice, S = N^{-1/2} Pᵀ B P N^{-1/2} (P: linear splat to nodes of spacing h, B: separable
//! Gaussian blur, N: row sums of Pᵀ B P). v₀ = v_warm + S θ, so ∂L/∂θ = S ∂L/∂v₀ (S is symmetric).
//!
//! Per-particle initial velocities are ill-conditioned (P2G averages ≈ 2^D particles per cell;
//! `register.md` pitfall 2): smoothing over 2–4 Δx removes the directions the simulation cannot see.
//!
//! **Side-aware** ([`Smoother::with_sides`], the preconditioner of a two-field grid): particles labelled by
//! a crack Σ (−1 / +1; 0 = uncut) are blurred on one lattice per side, each holding that side's particles
//! and the uncut ones, S = N^{-1/2} (Σ_k D_k Pᵀ B P D_k) N^{-1/2} with D_k the indicator of side k or uncut:
//! still symmetric, but a particle only ever receives from its own side and the uncut material, never
//! across Σ (a plain Gaussian over the two lips averages their opposite pulls away).
use laparo_mpm::Vector;

/// The smoothing operator over fixed rest positions.
pub struct Smoother<const D: usize> {
    dims: [usize; D],
    base: Vec<usize>,
    frac: Vec<[f64; D]>,
    taps: Vec<f64>,
    scale: Vec<f64>,
    /// Lattices each particle belongs to (bit k: lattice k); all 1 without sides.
    member: Vec<u8>,
    /// Number of lattices (1, or 2 with sides).
    lattices: usize,
}

impl<const D: usize> Smoother<D> {
    /// Smoothing of standard deviation `sigma` (length units) over `positions`, lattice spacing `h`.
    /// `sigma <= 0` gives the identity.
    pub fn new(positions: &[Vector<D>], sigma: f64, h: f64) -> Option<Self> {
        Self::with_sides(positions, &[], sigma, h)
    }

    /// [`Self::new`] blurring within each side of a crack: `sides` per particle (−1, +1, or 0 = uncut;
    /// empty = no crack, the plain smoother). A side-k particle receives only from side-k and uncut particles.
    pub fn with_sides(positions: &[Vector<D>], sides: &[i8], sigma: f64, h: f64) -> Option<Self> {
        if !(sigma > 0.0) || positions.is_empty() {
            return None;
        }
        let sided = sides.len() == positions.len() && sides.iter().any(|&s| s != 0);
        let member: Vec<u8> = (0..positions.len())
            .map(|p| {
                if !sided {
                    1
                } else {
                    match sides[p] {
                        s if s < 0 => 1,
                        s if s > 0 => 2,
                        _ => 3,
                    }
                }
            })
            .collect();
        let lattices = if sided { 2 } else { 1 };
        let radius = (3.0 * sigma / h).ceil() as usize;
        let mut lo = positions[0];
        let mut hi = positions[0];
        for p in positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let origin = lo - Vector::<D>::repeat(h);
        let dims: [usize; D] = std::array::from_fn(|d| ((hi[d] - origin[d]) / h).ceil() as usize + 2);
        let mut base = Vec::with_capacity(positions.len());
        let mut frac = Vec::with_capacity(positions.len());
        for p in positions {
            let mut flat = 0;
            let mut f = [0.0; D];
            for d in 0..D {
                let u = (p[d] - origin[d]) / h;
                let i = (u.floor() as usize).min(dims[d] - 2);
                f[d] = u - i as f64;
                flat = flat * dims[d] + i;
            }
            base.push(flat);
            frac.push(f);
        }
        let taps: Vec<f64> = (0..=2 * radius)
            .map(|k| (-((k as f64 - radius as f64) * h).powi(2) / (2.0 * sigma * sigma)).exp())
            .collect();
        let mut s = Smoother { dims, base, frac, taps, scale: vec![1.0; positions.len()], member, lattices };
        let ones = vec![Vector::<D>::repeat(1.0); positions.len()];
        let rows = s.apply_raw(&ones);
        s.scale = rows.iter().map(|r| 1.0 / r[0].max(1e-300).sqrt()).collect();
        Some(s)
    }

    fn strides(&self) -> [usize; D] {
        let mut st = [1usize; D];
        for d in (0..D.saturating_sub(1)).rev() {
            st[d] = st[d + 1] * self.dims[d + 1];
        }
        st
    }

    fn corners(&self, p: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let st = self.strides();
        (0..1usize << D).map(move |c| {
            let mut off = self.base[p];
            let mut w = 1.0;
            for d in 0..D {
                if c >> d & 1 == 1 {
                    off += st[d];
                    w *= self.frac[p][d];
                } else {
                    w *= 1.0 - self.frac[p][d];
                }
            }
            (off, w)
        })
    }

    /// Σ_k D_k Pᵀ B P D_k g: one splat–blur–gather per lattice.
    fn apply_raw(&self, g: &[Vector<D>]) -> Vec<Vector<D>> {
        let mut out = vec![Vector::<D>::zeros(); g.len()];
        for k in 0..self.lattices {
            let bit = 1u8 << k;
            let grid = self.blur_lattice(g, bit);
            for (p, o) in out.iter_mut().enumerate() {
                if self.member[p] & bit != 0 {
                    *o += self.corners(p).fold(Vector::<D>::zeros(), |a, (i, w)| a + grid[i] * w);
                }
            }
        }
        out
    }

    /// B P D_k g on the lattice of membership bit `bit`.
    fn blur_lattice(&self, g: &[Vector<D>], bit: u8) -> Vec<Vector<D>> {
        let n_nodes: usize = self.dims.iter().product();
        let mut grid = vec![Vector::<D>::zeros(); n_nodes];
        for (p, gp) in g.iter().enumerate() {
            if self.member[p] & bit == 0 {
                continue;
            }
            for (o, w) in self.corners(p) {
                grid[o] += gp * w;
            }
        }
        let st = self.strides();
        let r = (self.taps.len() - 1) / 2;
        let mut tmp = vec![Vector::<D>::zeros(); n_nodes];
        for d in 0..D {
            let n = self.dims[d];
            for (i, out) in tmp.iter_mut().enumerate() {
                let id = i / st[d] % n;
                let mut acc = Vector::<D>::zeros();
                let k0 = r.saturating_sub(id);
                let k1 = (2 * r).min(n - 1 + r - id);
                for k in k0..=k1 {
                    acc += grid[i + k * st[d] - r * st[d]] * self.taps[k];
                }
                *out = acc;
            }
            std::mem::swap(&mut grid, &mut tmp);
        }
        grid
    }

    /// S g.
    pub fn apply(&self, g: &[Vector<D>]) -> Vec<Vector<D>> {
        let u: Vec<Vector<D>> = g.iter().zip(&self.scale).map(|(v, s)| v * *s).collect();
        let mut out = self.apply_raw(&u);
        for (o, s) in out.iter_mut().zip(&self.scale) {
            *o *= *s;
        }
        out
    }
}
