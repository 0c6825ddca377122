//! Sobolev-type preconditioner: a symmetric Gaussian smoothing of per-particle vectors through a
//! background lattice, S = N^{-1/2} Pᵀ B P N^{-1/2} (P: linear splat to nodes of spacing h, B: separable
//! Gaussian blur, N: row sums of Pᵀ B P). v₀ = v_warm + S θ, so ∂L/∂θ = S ∂L/∂v₀ (S is symmetric).
//!
//! Per-particle initial velocities are ill-conditioned (P2G averages ≈ 2^D particles per cell;
//! `register.md` pitfall 2): smoothing over 2–4 Δx removes the directions the simulation cannot see.
use laparo_mpm::Vector;

/// The smoothing operator over fixed rest positions.
pub struct Smoother<const D: usize> {
    dims: [usize; D],
    base: Vec<usize>,
    frac: Vec<[f64; D]>,
    taps: Vec<f64>,
    scale: Vec<f64>,
}

impl<const D: usize> Smoother<D> {
    /// Smoothing of standard deviation `sigma` (length units) over `positions`, lattice spacing `h`.
    /// `sigma <= 0` gives the identity.
    pub fn new(positions: &[Vector<D>], sigma: f64, h: f64) -> Option<Self> {
        if !(sigma > 0.0) || positions.is_empty() {
            return None;
        }
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
        let mut s = Smoother { dims, base, frac, taps, scale: vec![1.0; positions.len()] };
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

    fn apply_raw(&self, g: &[Vector<D>]) -> Vec<Vector<D>> {
        let n_nodes: usize = self.dims.iter().product();
        let mut grid = vec![Vector::<D>::zeros(); n_nodes];
        for (p, gp) in g.iter().enumerate() {
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
        (0..g.len()).map(|p| self.corners(p).fold(Vector::<D>::zeros(), |a, (o, w)| a + grid[o] * w)).collect()
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
