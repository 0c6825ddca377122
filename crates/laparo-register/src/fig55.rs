//! The 2D illustrations of Fig. 5.5 (§5.4.1) with the set-ups proposed in `register.md` §3 (the
//! thesis gives no shapes or targets): a unit square domain, n_grid 120, an 80 × 80 particle square
//! (6,400 particles at Δx/2, centred), E 4.1, ν 0.49, ρ 1, Δt 2e-4, T 200, sticky walls of 3 cells
//! (the units of the DiffTaichi script `mpm2d_rods.py`: length 144 mm, stress kPa).
use crate::distance::Polyline;
use crate::loss::{GroupTarget, LandmarkGroup, RegistrationLoss};
use laparo_mpm::{box_lattice, GridSpec, Material, Model, Scene, Vector};
use std::sync::Arc;

/// The four cases of Fig. 5.5.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Case {
    /// (a) stretch from two point landmarks (±0.08 in x).
    Stretch,
    /// (b) 20 top-edge landmarks onto a circular arc of sagitta 0.08.
    Curve,
    /// (c) rupture: top-edge halves against their own polylines moved apart ±0.06 and up 0.04.
    Rupture,
    /// (d) (a)'s points plus (c)'s polylines.
    RuptureStretch,
}

impl Case {
    /// All four, in figure order.
    pub const ALL: [Case; 4] = [Case::Stretch, Case::Curve, Case::Rupture, Case::RuptureStretch];
    /// Panel letter and name.
    pub fn label(self) -> &'static str {
        match self {
            Case::Stretch => "a_stretch",
            Case::Curve => "b_curve",
            Case::Rupture => "c_rupture",
            Case::RuptureStretch => "d_rupture_stretch",
        }
    }
}

/// Particles per side of the square.
pub const SIDE: usize = 80;

/// The square scene (v₀ = 0).
pub fn square_scene() -> Scene<2> {
    let grid = GridSpec::unit(120);
    let s = grid.dx / 2.0;
    let half = SIDE as f64 * s / 2.0;
    let lo = Vector::<2>::new(0.5 - half, 0.5 - half);
    let hi = Vector::<2>::new(0.5 + half, 0.5 + half);
    let pos = box_lattice(lo, hi, s);
    let material = Material { model: Model::NeoHookean, youngs_modulus: 4.1, poisson_ratio: 0.49, density: 1.0 };
    let mut scene = Scene::new(pos, s * s, material, grid, 2e-4, 200);
    scene.mass_epsilon = 1e-10;
    scene
}

/// Particle index of lattice cell (i along x, j along y) (box_lattice: last axis fastest).
pub fn idx(i: usize, j: usize) -> usize {
    i * SIDE + j
}

/// Loss of a case on [`square_scene`].
pub fn case_loss(scene: &Scene<2>, case: Case) -> RegistrationLoss<2> {
    let x = &scene.positions;
    let mid = SIDE / 2;
    let top = SIDE - 1;
    let points = || {
        let (l, r) = (idx(0, mid), idx(SIDE - 1, mid));
        vec![
            LandmarkGroup {
                name: "left point".into(),
                particles: vec![l],
                target: GroupTarget::Paired(vec![x[l] - Vector::<2>::new(0.08, 0.0)]),
                weight: 1.0,
            },
            LandmarkGroup {
                name: "right point".into(),
                particles: vec![r],
                target: GroupTarget::Paired(vec![x[r] + Vector::<2>::new(0.08, 0.0)]),
                weight: 1.0,
            },
        ]
    };
    let halves = || {
        let mut out = Vec::new();
        for (name, range, sx) in [("left lip", 0..mid, -0.06), ("right lip", mid..SIDE, 0.06)] {
            let parts: Vec<usize> = range.map(|i| idx(i, top)).collect();
            let verts: Vec<Vector<2>> =
                [parts[0], *parts.last().unwrap()].iter().map(|&p| x[p] + Vector::<2>::new(sx, 0.04)).collect();
            out.push(LandmarkGroup {
                name: name.into(),
                particles: parts,
                target: GroupTarget::Shared(Arc::new(Polyline::open(verts))),
                weight: 1.0,
            });
        }
        out
    };
    let groups = match case {
        Case::Stretch => points(),
        Case::Curve => {
            // 20 landmarks evenly along the top edge; the arc through the top corners, sagitta 0.08
            let parts: Vec<usize> = (0..20).map(|k| idx(k * (SIDE - 1) / 19, top)).collect();
            let (a, b) = (x[idx(0, top)], x[idx(SIDE - 1, top)]);
            let half = (b[0] - a[0]) / 2.0;
            let sag = 0.08;
            let r = (half * half + sag * sag) / (2.0 * sag);
            let cy = a[1] + sag - r;
            let cx = (a[0] + b[0]) / 2.0;
            let th = (half / r).asin();
            let arc: Vec<Vector<2>> = (0..=64)
                .map(|k| {
                    let t = -th + 2.0 * th * k as f64 / 64.0;
                    Vector::<2>::new(cx + r * t.sin(), cy + r * t.cos())
                })
                .collect();
            vec![LandmarkGroup {
                name: "top curve".into(),
                particles: parts,
                target: GroupTarget::Shared(Arc::new(Polyline::open(arc))),
                weight: 1.0,
            }]
        }
        Case::Rupture => halves(),
        Case::RuptureStretch => {
            let mut g = points();
            g.extend(halves());
            g
        }
    };
    RegistrationLoss::new(groups)
}

/// Connected bodies of particles: union of particles closer than `link` (length units); returns the
/// component label per particle and the component sizes (largest first order not guaranteed).
pub fn components<const D: usize>(x: &[Vector<D>], link: f64) -> (Vec<usize>, Vec<usize>) {
    use kiddo::SquaredEuclidean;
    let tree = crate::distance::build_tree(x);
    let mut label = vec![usize::MAX; x.len()];
    let mut sizes = Vec::new();
    for s in 0..x.len() {
        if label[s] != usize::MAX {
            continue;
        }
        let c = sizes.len();
        let mut stack = vec![s];
        label[s] = c;
        let mut size = 0;
        while let Some(p) = stack.pop() {
            size += 1;
            let q: [f64; D] = std::array::from_fn(|d| x[p][d]);
            for nb in tree.within_unsorted::<SquaredEuclidean>(&q, link * link) {
                let o = nb.item as usize;
                if label[o] == usize::MAX {
                    label[o] = c;
                    stack.push(o);
                }
            }
        }
        sizes.push(size);
    }
    (label, sizes)
}

/// Figures of one Fig. 5.5 case after registration.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaseMetrics {
    /// Case label.
    pub case: String,
    /// Mean landmark distance before / after (Δx).
    pub residual_dx: [f64; 2],
    /// Distance between the two side landmarks / between their targets (cases a, d).
    pub width_ratio: Option<f64>,
    /// Height at mid-width after / before.
    pub mid_height_ratio: f64,
    /// min det F.
    pub min_j: f64,
    /// Connected bodies (particles closer than Δx linked), largest first: particle fractions.
    pub bodies: Vec<f64>,
    /// Smallest distance between the two largest bodies (Δx), if there are two.
    pub gap_dx: Option<f64>,
    /// Iterations, simulations, wall time (s).
    pub iterations: usize,
    /// Simulations.
    pub simulations: usize,
    /// Wall time (s).
    pub seconds: f64,
    /// Loss (mean landmark distance, Δx) per iteration.
    pub curve_dx: Vec<f64>,
}

/// Register one case and measure it. Returns the metrics and the final positions and J.
pub fn run_case(
    case: Case,
    cfg: &crate::optimize::OptimizerConfig,
) -> crate::Result<(CaseMetrics, Vec<Vector<2>>, Vec<f64>)> {
    let scene = square_scene();
    let loss = case_loss(&scene, case);
    let r = crate::optimize::register(&scene, &loss, cfg, None, &mut |_, _| true)?;
    let dx = scene.grid.dx;
    let x = r.final_state.x.clone();
    let j: Vec<f64> = r.final_state.f.iter().map(laparo_mpm::det).collect();
    let min_j = j.iter().cloned().fold(f64::INFINITY, f64::min);
    let width_ratio = match case {
        Case::Stretch | Case::RuptureStretch => {
            let (l, rr) = (idx(0, SIDE / 2), idx(SIDE - 1, SIDE / 2));
            let target = (scene.positions[rr][0] + 0.08) - (scene.positions[l][0] - 0.08);
            Some((x[rr][0] - x[l][0]) / target)
        }
        _ => None,
    };
    let height = |pts: &[Vector<2>]| {
        let cx = pts.iter().map(|p| p[0]).sum::<f64>() / pts.len() as f64;
        let col: Vec<f64> = pts.iter().filter(|p| (p[0] - cx).abs() < dx).map(|p| p[1]).collect();
        if col.is_empty() {
            return 0.0;
        }
        col.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - col.iter().cloned().fold(f64::INFINITY, f64::min)
    };
    let (label, mut sizes) = components(&x, dx);
    let n = x.len() as f64;
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by(|&a, &b| sizes[b].cmp(&sizes[a]));
    let gap_dx = if order.len() >= 2 {
        let (a, b) = (order[0], order[1]);
        let pb: Vec<Vector<2>> = x.iter().zip(&label).filter(|(_, &l)| l == b).map(|(p, _)| *p).collect();
        let tree = crate::distance::build_tree(&pb);
        let g = x
            .iter()
            .zip(&label)
            .filter(|(_, &l)| l == a)
            .map(|(p, _)| tree.nearest_one::<kiddo::SquaredEuclidean>(&[p[0], p[1]]).distance.sqrt())
            .fold(f64::INFINITY, f64::min);
        Some(g / dx)
    } else {
        None
    };
    sizes.sort_by(|a, b| b.cmp(a));
    let last = r.history.last().cloned().unwrap_or_else(|| r.history[0].clone());
    let m = CaseMetrics {
        case: case.label().into(),
        residual_dx: [r.history[0].mean_distance / dx, last.mean_distance / dx],
        width_ratio,
        mid_height_ratio: height(&x) / height(&scene.positions),
        min_j,
        bodies: sizes.iter().map(|&s| s as f64 / n).collect(),
        gap_dx,
        iterations: last.iteration,
        simulations: last.evaluations,
        seconds: last.seconds,
        curve_dx: r.history.iter().map(|h| h.mean_distance / dx).collect(),
    };
    Ok((m, x, j))
}

/// Target marks of a case (for drawing): paired points and polyline vertices.
pub fn case_marks(scene: &Scene<2>, case: Case) -> Vec<Vector<2>> {
    let loss = case_loss(scene, case);
    let mut out = Vec::new();
    for g in &loss.groups {
        match &g.target {
            GroupTarget::Paired(t) => out.extend(t.iter().copied()),
            GroupTarget::Shared(s) => {
                // sample the target near each landmark (closest points at rest)
                for &p in &g.particles {
                    out.push(s.closest(&scene.positions[p]).0);
                }
            }
        }
    }
    out
}

/// Picture of a case: particles coloured by J (Turbo, [0.5, 1.5]) in the view [0.2, 0.8]², target marks
/// as crosses, with a colour bar.
pub fn render_case(x: &[Vector<2>], j: &[f64], marks: &[Vector<2>], size: usize) -> laparo_core::image::Image<u8> {
    let shift = |p: &Vector<2>| p - Vector::<2>::new(0.2, 0.2);
    let xs: Vec<Vector<2>> = x.iter().map(shift).collect();
    let ms: Vec<Vector<2>> = marks.iter().map(shift).collect();
    let img = laparo_mpm::render::render_particles_2d(&xs, j, 0.5, 1.5, 0.6, size, 2, &ms);
    laparo_core::plot::with_colorbar(&img, 0.5, 1.5, laparo_core::colormap::Colormap::Turbo, "J = det F")
}
