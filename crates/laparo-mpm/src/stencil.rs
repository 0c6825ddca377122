//! Quadratic B-spline stencil arithmetic of the MPM transfers (eq. 5.6): base node, weights and
//! their derivatives, separable affine terms, stencil traversal (unrolled for D = 2, 3).
use crate::linalg::{Matrix, Vector};

/// Stencil base node floor(x/Δx − ½) (same arithmetic as [`GridSpec::stencil_base`](crate::grid_spec::GridSpec::stencil_base)) of a particle that
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
