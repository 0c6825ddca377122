//! A small L-BFGS (two-loop recursion, backtracking Armijo line search) on flat f64 vectors.

/// Result of [`minimise`].
pub(crate) struct LbfgsOut {
    pub x: Vec<f64>,
    pub iterations: usize,
    pub converged: bool,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimise f from `x0`; `f` returns (value, gradient); `on_iter` sees every accepted iterate.
/// Stops when |∇f|_∞ ≤ `gtol`, after `max_iter` iterations, or when the line search stalls.
pub(crate) fn minimise(
    x0: Vec<f64>,
    mut f: impl FnMut(&[f64]) -> (f64, Vec<f64>),
    max_iter: usize,
    memory: usize,
    gtol: f64,
    mut on_iter: impl FnMut(&[f64]),
) -> LbfgsOut {
    let mut x = x0;
    let (mut fx, mut g) = f(&x);
    let mut mem: std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)> = Default::default();
    let mut it = 0;
    let amax = |v: &[f64]| v.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    while it < max_iter {
        if amax(&g) <= gtol {
            return LbfgsOut { x, iterations: it, converged: true };
        }
        // two-loop recursion
        let mut q = g.clone();
        let mut alphas = Vec::with_capacity(mem.len());
        for (s, y, rho) in mem.iter().rev() {
            let a = rho * dot(s, &q);
            q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
            alphas.push(a);
        }
        let h0 = match mem.back() {
            Some((s, y, _)) => dot(s, y) / dot(y, y),
            None => 1.0 / amax(&g).max(1.0),
        };
        q.iter_mut().for_each(|v| *v *= h0);
        for ((s, y, rho), a) in mem.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            q.iter_mut().zip(s).for_each(|(qi, si)| *qi += (a - b) * si);
        }
        let mut d: Vec<f64> = q.iter().map(|v| -v).collect();
        let mut slope = dot(&g, &d);
        if !(slope < 0.0) {
            mem.clear();
            d = g.iter().map(|v| -v / amax(&g).max(1.0)).collect();
            slope = dot(&g, &d);
        }
        let mut step = 1.0;
        let mut accepted = None;
        for _ in 0..50 {
            let xt: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + step * b).collect();
            let (ft, gt) = f(&xt);
            if ft.is_finite() && ft <= fx + 1e-4 * step * slope {
                accepted = Some((xt, ft, gt));
                break;
            }
            step *= 0.5;
        }
        it += 1;
        let Some((xn, fnew, gn)) = accepted else {
            return LbfgsOut { x, iterations: it, converged: false };
        };
        let s: Vec<f64> = xn.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = gn.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-300 {
            mem.push_back((s, y, 1.0 / sy));
            if mem.len() > memory {
                mem.pop_front();
            }
        }
        let stalled = fx - fnew <= 1e-15 * fx.abs().max(1e-300);
        x = xn;
        fx = fnew;
        g = gn;
        on_iter(&x);
        if stalled && amax(&g) <= gtol.max(1e-12) {
            return LbfgsOut { x, iterations: it, converged: true };
        }
    }
    let converged = amax(&g) <= gtol;
    LbfgsOut { x, iterations: it, converged }
}
