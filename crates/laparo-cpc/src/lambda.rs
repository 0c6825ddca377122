//! Automatic selection of λ (thesis §4.5.4): sweep λ, measure δ_area(λ) (eq. 4.13), fit the
//! piecewise Gompertz/exponential model f (eq. 4.14) under the constraints 4.15–4.18, and return
//! its transition point ℓ.
//!
//! Parametrisation of the fit. With a1 = median(δ_area) (eq. 4.15) fixed, the exponential branch
//! a2·exp(b2(λ + c2)) + d2 depends on a2 and c2 only through K = a2·e^{b2 c2}; eq. 4.16 gives
//! d2 = 1 − K e^{b2}, eq. 4.18 gives K = G'(ℓ) e^{−b2 ℓ} / b2 (G the Gompertz branch) and eq. 4.17
//! then reduces to (e^{b2(1−ℓ)} − 1) / b2 = (1 − G(ℓ)) / G'(ℓ), solved for b2 by bisection.
//! The free parameters are thus (b1, c1, ℓ), fitted by least squares with Nelder–Mead from several
//! starts (hand-written: 3 unknowns, a few hundred evaluations; no optimisation crate needed).
//! The reported (a2, c2) use the convention c2 = 0 (a2 = K).
//!
//! Normalisation. Eq. 4.16 fixes f(1) = 1, but δ_area (eq. 4.13) is not bounded by 1: on a bumpy
//! surface seen beyond about 60° the near-conformal solutions enlarge some triangles more than
//! twofold and δ_area passes 1 well before λ = 1. The fit is therefore made on
//! δ̂(λ) = δ_area(λ) / δ_area(λ_max), λ_max the largest λ of the grid (our reading of eq. 4.16:
//! the curve is scaled so that its value as λ → 1 is 1). When the fit is still not possible
//! (a non-monotone curve whose median is ≥ 1, too few points, no feasible model) the sweep is kept,
//! λ falls back to [`FALLBACK_LAMBDA`] and [`LambdaSweep::warning`] says why.
use crate::error::{CpcError, Result};
use crate::mesh::CpcMesh;
use crate::metrics;
use crate::solve::CpcSystem;
use serde::Serialize;

/// The default λ grid of the sweep: 0 to 0.95 by 0.05, then denser towards 1, up to 1 − 10⁻⁵:
/// with the area-normalised cost of [`crate::solve`] the final rise of δ_area (eq. 4.14's
/// exponential branch) starts only beyond λ ≈ 0.99, and a grid ending at 0.999 put ℓ on the
/// [`MIN_ELL`] guard (measured on `laparo cpc pair --kind hard`: ℓ 0.50 → 0.99).
pub fn default_lambda_grid() -> Vec<f64> {
    let mut g: Vec<f64> = (0..20).map(|i| i as f64 * 0.05).collect();
    g.extend([0.96, 0.97, 0.98, 0.99, 0.995, 0.998, 0.999, 0.9995, 0.9999, 0.99995, 0.99999]);
    g
}

/// λ used when the Gompertz/exponential fit fails (documented fallback; the thesis calls
/// λ = 0.95 a good trade-off, Fig. 4.11).
pub const FALLBACK_LAMBDA: f64 = 0.95;

/// Lower bound of the transition point ℓ in the fit. On fine grids δ_area(λ) often rises
/// almost linearly from λ = 0; unconstrained, the fit then degenerates to a pure exponential with
/// ℓ ≈ 0 (no correction at all). The thesis' ℓ sits at the knee before the final rise (Fig. 4.12c).
pub const MIN_ELL: f64 = 0.5;

/// Largest RMS residual (of the normalised curve) for which a fit is accepted; above it the
/// model of eq. 4.14 does not describe the sweep and λ falls back to [`FALLBACK_LAMBDA`].
pub const MAX_FIT_RMSE: f64 = 0.15;

/// The fitted model of eq. 4.14.
#[derive(Clone, Debug, Serialize)]
pub struct GompertzExpFit {
    /// Gompertz branch (λ < ℓ): a1 · exp(−b1 · exp(−c1 λ)); a1 = median δ_area (eq. 4.15).
    pub a1: f64,
    /// Gompertz displacement b1 (> 0).
    pub b1: f64,
    /// Gompertz growth rate c1 (> 0).
    pub c1: f64,
    /// Exponential branch (λ ≥ ℓ): a2 · exp(b2 (λ + c2)) + d2; amplitude a2.
    pub a2: f64,
    /// Exponential rate b2.
    pub b2: f64,
    /// Exponential shift c2.
    pub c2: f64,
    /// Exponential offset d2.
    pub d2: f64,
    /// Transition point ℓ (the selected λ).
    pub ell: f64,
    /// RMS residual of the fit over the sweep.
    pub rmse: f64,
}

impl GompertzExpFit {
    /// f(λ) of eq. 4.14.
    pub fn eval(&self, lambda: f64) -> f64 {
        if lambda < self.ell {
            self.a1 * (-self.b1 * (-self.c1 * lambda).exp()).exp()
        } else {
            self.a2 * (self.b2 * (lambda + self.c2)).exp() + self.d2
        }
    }
}

/// One row of the sweep.
#[derive(Clone, Debug, Serialize)]
pub struct SweepPoint {
    /// λ of this solve.
    pub lambda: f64,
    /// δ_area (eq. 4.13) of the flattened mesh.
    pub delta_area: f64,
    /// δ_area / δ_area(λ_max): the normalised curve the model is fitted to (f(1) = 1, eq. 4.16).
    pub delta_area_norm: f64,
    /// Mean |2D − 3D| corner angle (deg) of the flattened mesh.
    pub angle_error_deg: f64,
    /// Number of flipped triangles.
    pub n_flipped: usize,
}

/// Result of the automatic λ selection.
#[derive(Clone, Debug, Serialize)]
pub struct LambdaSweep {
    /// One row per λ of the grid.
    pub points: Vec<SweepPoint>,
    /// δ_area at the largest λ of the grid: the curve is divided by it before the fit.
    pub normaliser: f64,
    /// The model of eq. 4.14 fitted to the normalised sweep (`None` when the fit failed).
    pub fit: Option<GompertzExpFit>,
    /// The selected λ: ℓ of the fit, or [`FALLBACK_LAMBDA`] when the fit failed.
    pub ell: f64,
    /// Why the fit failed and λ fell back to [`FALLBACK_LAMBDA`] (`None` when ℓ was fitted).
    pub warning: Option<String>,
}

/// Solve for every λ of `grid` and record δ_area (eq. 4.13), the angle error and the flips.
pub fn sweep(system: &CpcSystem, mesh: &CpcMesh, grid: &[f64]) -> Result<Vec<SweepPoint>> {
    let mut pts = grid
        .iter()
        .map(|&lambda| {
            let p = system.solve(lambda)?;
            Ok(SweepPoint {
                lambda,
                delta_area: metrics::delta_area(&p, &mesh.p_init, &mesh.faces),
                delta_area_norm: f64::NAN,
                angle_error_deg: metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces),
                n_flipped: metrics::n_flipped(&p, &mesh.faces),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    normalise(&mut pts);
    Ok(pts)
}

/// Fill [`SweepPoint::delta_area_norm`] = δ_area / δ_area(λ_max); returns the normaliser.
fn normalise(pts: &mut [SweepPoint]) -> f64 {
    let last = pts.iter().max_by(|a, b| a.lambda.total_cmp(&b.lambda)).map(|p| p.delta_area).unwrap_or(f64::NAN);
    for p in pts.iter_mut() {
        p.delta_area_norm = p.delta_area / last;
    }
    last
}

/// Build the constrained model from the free parameters (b1, c1, ℓ); `None` if infeasible.
fn model(a1: f64, b1: f64, c1: f64, ell: f64) -> Option<GompertzExpFit> {
    if !(b1 > 0.0 && c1 > 0.0 && ell > 0.0 && ell < 1.0) {
        return None;
    }
    let e = (-c1 * ell).exp();
    let g = a1 * (-b1 * e).exp();
    let dg = a1 * b1 * c1 * e * (-b1 * e).exp();
    if !(g < 1.0 && dg > 0.0) {
        return None;
    }
    let target = (1.0 - g) / dg;
    let span = 1.0 - ell;
    // h(b) = (e^{b·span} − 1)/b is increasing, h(0) = span.
    let h = |b: f64| if b.abs() < 1e-12 { span } else { (b * span).exp_m1() / b };
    let (mut lo, mut hi) = (-1e4_f64, 700.0 / span);
    if !(h(lo) <= target && h(hi) >= target) {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if h(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let b2 = 0.5 * (lo + hi);
    if b2.abs() < 1e-12 {
        return None;
    }
    let k = dg * (-b2 * ell).exp() / b2;
    let d2 = 1.0 - k * b2.exp();
    if !(k.is_finite() && d2.is_finite()) {
        return None;
    }
    Some(GompertzExpFit { a1, b1, c1, a2: k, b2, c2: 0.0, d2, ell, rmse: f64::NAN })
}

fn nelder_mead(f: &dyn Fn(&[f64; 3]) -> f64, x0: [f64; 3], step: [f64; 3], iters: usize) -> ([f64; 3], f64) {
    let mut s: Vec<([f64; 3], f64)> = vec![(x0, f(&x0))];
    for i in 0..3 {
        let mut x = x0;
        x[i] += step[i];
        s.push((x, f(&x)));
    }
    for _ in 0..iters {
        s.sort_by(|a, b| a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal));
        let mut c = [0.0; 3];
        for p in &s[..3] {
            for (ck, &pk) in c.iter_mut().zip(&p.0) {
                *ck += pk / 3.0;
            }
        }
        let worst = s[3];
        let lerp = |t: f64| {
            let mut x = [0.0; 3];
            for k in 0..3 {
                x[k] = c[k] + t * (worst.0[k] - c[k]);
            }
            x
        };
        let xr = lerp(-1.0);
        let fr = f(&xr);
        if fr < s[0].1 {
            let xe = lerp(-2.0);
            let fe = f(&xe);
            s[3] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < s[2].1 {
            s[3] = (xr, fr);
        } else {
            let xc = lerp(0.5);
            let fc = f(&xc);
            if fc < worst.1 {
                s[3] = (xc, fc);
            } else {
                let best = s[0].0;
                for p in s.iter_mut().skip(1) {
                    for (pk, &bk) in p.0.iter_mut().zip(&best) {
                        *pk = bk + 0.5 * (*pk - bk);
                    }
                    p.1 = f(&p.0);
                }
            }
        }
    }
    s.sort_by(|a, b| a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal));
    s[0]
}

/// Fit eq. 4.14 under constraints 4.15–4.18 to (λ_i, δ_i).
pub fn fit_gompertz_exp(lambdas: &[f64], delta: &[f64]) -> Result<GompertzExpFit> {
    if lambdas.len() != delta.len() || lambdas.len() < 5 {
        return Err(CpcError::invalid("lambda sweep", "needs at least 5 (lambda, delta_area) pairs"));
    }
    if lambdas.iter().chain(delta).any(|v| !v.is_finite()) {
        return Err(CpcError::invalid("lambda sweep", "contains non-finite values"));
    }
    let a1 = laparo_core::stats::median(&mut delta.to_vec());
    if !(a1 > 0.0 && a1 < 1.0) {
        return Err(CpcError::invalid("lambda sweep", format!("median delta_area {a1} is not in (0, 1)")));
    }
    let to_ell = |x: f64| MIN_ELL + (1.0 - MIN_ELL) / (1.0 + (-x).exp());
    let cost = |x: &[f64; 3]| -> f64 {
        let ell = to_ell(x[2]);
        match model(a1, x[0].exp(), x[1].exp(), ell) {
            Some(m) => lambdas.iter().zip(delta).map(|(&l, &d)| (m.eval(l) - d).powi(2)).sum(),
            None => f64::INFINITY,
        }
    };
    let logit = |l: f64| {
        let u = (l - MIN_ELL) / (1.0 - MIN_ELL);
        (u / (1.0 - u)).ln()
    };
    let mut best: Option<([f64; 3], f64)> = None;
    for &ell0 in &[0.6, 0.8, 0.9, 0.95, 0.98] {
        for &c0 in &[3.0_f64, 10.0, 30.0] {
            for &b0 in &[1.0_f64, 5.0, 30.0] {
                let x0 = [b0.ln(), c0.ln(), logit(ell0)];
                if !cost(&x0).is_finite() {
                    continue;
                }
                let r = nelder_mead(&cost, x0, [0.5, 0.5, 0.5], 400);
                if best.as_ref().is_none_or(|b| r.1 < b.1) {
                    best = Some(r);
                }
            }
        }
    }
    let (x, c) = best.ok_or_else(|| CpcError::invalid("lambda sweep", "no feasible Gompertz/exponential fit"))?;
    let ell = to_ell(x[2]);
    let mut m = model(a1, x[0].exp(), x[1].exp(), ell)
        .ok_or_else(|| CpcError::invalid("lambda sweep", "no feasible Gompertz/exponential fit"))?;
    m.rmse = (c / lambdas.len() as f64).sqrt();
    if m.rmse > MAX_FIT_RMSE {
        return Err(CpcError::invalid(
            "lambda sweep",
            format!("the Gompertz/exponential model does not describe the curve (RMSE {:.3} > {MAX_FIT_RMSE})", m.rmse),
        ));
    }
    Ok(m)
}

/// Sweep λ over `grid`, fit the model to the normalised δ_area and return ℓ (§4.5.4). A failed
/// fit is not an error: the result then carries [`FALLBACK_LAMBDA`] and a warning. Errors only
/// come from the solves themselves.
pub fn auto_lambda(system: &CpcSystem, mesh: &CpcMesh, grid: &[f64]) -> Result<LambdaSweep> {
    Ok(LambdaSweep::from_points(sweep(system, mesh, grid)?))
}

impl LambdaSweep {
    /// Fit eq. 4.14 to measured sweep points (normalising δ_area, see the module docs); on
    /// failure select [`FALLBACK_LAMBDA`] with a warning.
    pub fn from_points(mut points: Vec<SweepPoint>) -> LambdaSweep {
        let normaliser = normalise(&mut points);
        let l: Vec<f64> = points.iter().map(|p| p.lambda).collect();
        let d: Vec<f64> = points.iter().map(|p| p.delta_area_norm).collect();
        let fit = if normaliser.is_finite() && normaliser > 0.0 {
            fit_gompertz_exp(&l, &d)
        } else {
            Err(CpcError::invalid("lambda sweep", format!("delta_area at the largest lambda is {normaliser}")))
        };
        match fit {
            Ok(f) => LambdaSweep { ell: f.ell, points, normaliser, fit: Some(f), warning: None },
            Err(e) => LambdaSweep {
                ell: FALLBACK_LAMBDA,
                points,
                normaliser,
                fit: None,
                warning: Some(format!("automatic lambda failed ({e}); using the fallback lambda {FALLBACK_LAMBDA}")),
            },
        }
    }
}

impl LambdaSweep {
    /// CSV: `lambda,delta_area,delta_area_norm,fit,angle_error_deg,n_flipped` (fit: f(λ) of the
    /// normalised curve, NaN when the fit failed).
    pub fn to_csv(&self) -> String {
        let mut s = String::from("lambda,delta_area,delta_area_norm,fit,angle_error_deg,n_flipped\n");
        for p in &self.points {
            s.push_str(&format!(
                "{},{},{},{},{},{}\n",
                p.lambda,
                p.delta_area,
                p.delta_area_norm,
                self.fit.as_ref().map_or(f64::NAN, |f| f.eval(p.lambda)),
                p.angle_error_deg,
                p.n_flipped
            ));
        }
        s
    }
}

impl LambdaSweep {
    /// Plot the normalised δ_area(λ), the fitted model f(λ) and ℓ (like thesis Fig. 4.12c) as
    /// PNG; without a fit, the measured curve and the fallback λ.
    pub fn plot_png(&self, path: &std::path::Path) -> Result<()> {
        use plotters::prelude::*;
        let ymax =
            self.points.iter().map(|p| p.delta_area_norm).filter(|v| v.is_finite()).fold(1.0_f64, f64::max) * 1.08;
        let fit = self.fit.clone();
        let pts: Vec<(f64, f64)> = self
            .points
            .iter()
            .filter(|p| p.delta_area_norm.is_finite())
            .map(|p| (p.lambda, p.delta_area_norm))
            .collect();
        let ell = self.ell;
        let caption = if fit.is_some() {
            format!("automatic λ: δ_area(λ)/{:.3}, fit (eq. 4.14), ℓ = {ell:.3}", self.normaliser)
        } else {
            format!("automatic λ: fit FAILED, fallback λ = {ell:.3}")
        };
        laparo_core::plot::draw_png(path, 720, 460, move |root| {
            let mut chart = ChartBuilder::on(&root)
                .caption(caption, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(55)
                .build_cartesian_2d(0f64..1f64, 0f64..ymax)?;
            chart.configure_mesh().x_desc("λ").y_desc("δ_area / δ_area(λ_max) (eq. 4.13)").draw()?;
            if let Some(fit) = &fit {
                chart
                    .draw_series(LineSeries::new(
                        (0..=1000).map(|i| i as f64 / 1000.0).map(|l| (l, fit.eval(l).clamp(0.0, ymax))),
                        BLUE.stroke_width(2),
                    ))?
                    .label("fit f(λ)")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
            }
            chart
                .draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 4, BLACK.filled())))?
                .label("measured δ_area")
                .legend(|(x, y)| Circle::new((x + 10, y), 4, BLACK.filled()));
            chart
                .draw_series(LineSeries::new(vec![(ell, 0.0), (ell, ymax)], RED.stroke_width(2)))?
                .label(if fit.is_some() { "ℓ" } else { "fallback λ" })
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
            chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).border_style(BLACK).draw()?;
            Ok(())
        })?;
        Ok(())
    }
}
