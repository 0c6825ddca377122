//! The 2D illustrations of Fig. 5.5 (§5.4.1) with the set-ups proposed in `register.md` §3 (the
//! thesis gives no shapes or targets): a unit square domain, n_grid 120, an 80 × 80 particle square
//! (6,400 particles at Δx/2, centred), E 4.1, ν 0.49, ρ 1, Δt 2e-4, T 200, sticky walls of 3 cells
//! (the units of the DiffTaichi script `mpm2d_rods.py`: length 144 mm, stress kPa).
//!
//! Cases (c)/(d) differ from `register.md` §3 on purpose: scoring only the top-edge halves against their
//! moved copies is satisfied without a tear (unsmoothed L-BFGS reaches 0.09 Δx with one folded body), so
//! each lip is its top-edge half *and* its face of the cut (the lattice column next to x = 0.5), scored
//! against the same material curve opened like a book (±`LIP_TOP`, +`LIP_UP` at the top edge, ±`LIP_BOTTOM`
//! at the bottom edge): the targets now demand a separation along the whole cut.
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
    /// (c) rupture: each lip (top-edge half + its face of the cut) against its own polyline, opened like a
    /// book (±0.06 and up 0.04 at the top, ±0.015 at the bottom).
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

/// Opening of each lip at the top edge (x, outward) and its rise (y) (register.md §3: ±0.06, +0.04).
pub const LIP_TOP: f64 = 0.06;
/// Rise of the top edge of each lip.
pub const LIP_UP: f64 = 0.04;
/// Opening of each lip at the bottom edge (the cut opens like a book: linear in height in between).
pub const LIP_BOTTOM: f64 = 0.015;

/// Two particles belong to the same body when closer than this (Δx): three rest spacings (Δx/2), so a
/// body stays connected under stretches up to 3× and a separation counts only once the lips are more
/// than 1.5 Δx apart (the radius of the quadratic B-spline's support).
pub const LINK_DX: f64 = 1.5;

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
pub fn case_loss(scene: &Scene<2>, case: Case) -> crate::Result<RegistrationLoss<2>> {
    let x = &scene.positions;
    let mid = SIDE / 2;
    let top = SIDE - 1;
    let points = || {
        let (l, r) = (idx(0, mid), idx(SIDE - 1, mid));
        let (tl, tr) = (x[l] - Vector::<2>::new(0.08, 0.0), x[r] + Vector::<2>::new(0.08, 0.0));
        vec![
            LandmarkGroup {
                name: "left point".into(),
                particles: vec![l],
                target: GroupTarget::Paired(vec![tl]),
                weight: 1.0,
            },
            LandmarkGroup {
                name: "right point".into(),
                particles: vec![r],
                target: GroupTarget::Paired(vec![tr]),
                weight: 1.0,
            },
        ]
    };
    let halves = || {
        // each side: its top-edge half and its face of the cut (the lattice column next to x = 0.5),
        // scored (closest point) against its own polyline: the same material curve opened like a book
        lips()
            .into_iter()
            .zip([-1.0, 1.0])
            .map(|((name, parts), sx)| {
                let open = |p: usize| opened(scene, p, sx);
                // the curve is straight on the top edge and on the cut face: three vertices
                let corner = SIDE / 2;
                let verts = vec![open(parts[0]), open(parts[corner - 1]), open(*parts.last().unwrap())];
                LandmarkGroup {
                    name: name.into(),
                    particles: parts,
                    target: GroupTarget::Shared(Arc::new(Polyline::open(verts))),
                    weight: 1.0,
                }
            })
            .collect::<Vec<_>>()
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
    Ok(RegistrationLoss::new(groups))
}

/// Rest position of particle `p` moved by the book opening of its lip (`sx` = −1 left, +1 right): at
/// height fraction s, (sx (`LIP_BOTTOM` + (`LIP_TOP` − `LIP_BOTTOM`) s), `LIP_UP` s).
pub fn opened(scene: &Scene<2>, p: usize, sx: f64) -> Vector<2> {
    let x = &scene.positions;
    let (yb, yt) = (x[idx(0, 0)][1], x[idx(0, SIDE - 1)][1]);
    let s = (x[p][1] - yb) / (yt - yb);
    x[p] + Vector::<2>::new(sx * (LIP_BOTTOM + (LIP_TOP - LIP_BOTTOM) * s), LIP_UP * s)
}

/// The two lips of the cut along x = 0.5, each as an ordered material curve: its top-edge half (outer
/// corner → cut) then its face of the cut (the lattice column next to x = 0.5, top → bottom).
pub fn lips() -> [(&'static str, Vec<usize>); 2] {
    let (mid, top) = (SIDE / 2, SIDE - 1);
    let side = |outer: usize, inner: usize| -> Vec<usize> {
        let mut v: Vec<usize> = if outer < inner {
            (outer..=inner).map(|i| idx(i, top)).collect()
        } else {
            (inner..=outer).rev().map(|i| idx(i, top)).collect()
        };
        v.extend((0..top).rev().map(|j| idx(inner, j)));
        v
    };
    [("left lip", side(0, mid - 1)), ("right lip", side(SIDE - 1, mid))]
}

/// Connected bodies of particles: flood fill linking particles closer than `link` (length units, k-d tree
/// radius queries, deterministic order); returns the
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
    /// Height of the particle column at mid-width after / at rest (for two bodies: each body at its own
    /// mid-width, averaged).
    pub mid_height_ratio: f64,
    /// min det F.
    pub min_j: f64,
    /// Connected bodies (particles closer than [`LINK_DX`] Δx linked; flood fill over k-d tree radius queries), largest
    /// first: particle fractions.
    pub bodies: Vec<f64>,
    /// Smallest particle-to-particle distance between the two largest bodies (Δx), if there are two.
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
    let loss = case_loss(&scene, case)?;
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
    // height of the particle column within Δx of the mid-width (centroid x) of a set of particles
    let height = |pts: &[Vector<2>]| {
        let cx = pts.iter().map(|p| p[0]).sum::<f64>() / pts.len() as f64;
        let col: Vec<f64> = pts.iter().filter(|p| (p[0] - cx).abs() < dx).map(|p| p[1]).collect();
        if col.is_empty() {
            return 0.0;
        }
        col.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - col.iter().cloned().fold(f64::INFINITY, f64::min)
    };
    let (label, mut sizes) = components(&x, LINK_DX * dx);
    let n = x.len() as f64;
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by(|&a, &b| sizes[b].cmp(&sizes[a]).then(a.cmp(&b)));
    let body = |c: usize, pts: &[Vector<2>]| -> Vec<Vector<2>> {
        pts.iter().zip(&label).filter(|(_, &l)| l == c).map(|(p, _)| *p).collect()
    };
    let gap_dx = if order.len() >= 2 {
        let (a, b) = (order[0], order[1]);
        let pb = body(b, &x);
        let tree = crate::distance::build_tree(&pb);
        let g = body(a, &x)
            .iter()
            .map(|p| tree.nearest_one::<kiddo::SquaredEuclidean>(&[p[0], p[1]]).distance.sqrt())
            .fold(f64::INFINITY, f64::min);
        Some(g / dx)
    } else {
        None
    };
    // mid-width height of each of the (up to two) largest bodies, after / at rest, averaged
    let mid_height_ratio = {
        let k = order.len().min(2);
        order[..k].iter().map(|&c| height(&body(c, &x)) / height(&body(c, &scene.positions))).sum::<f64>() / k as f64
    };
    sizes.sort_by(|a, b| b.cmp(a));
    let last = r.history.last().cloned().unwrap_or_else(|| r.history[0].clone());
    let m = CaseMetrics {
        case: case.label().into(),
        residual_dx: [r.history[0].mean_distance / dx, last.mean_distance / dx],
        width_ratio,
        mid_height_ratio,
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

/// Target marks of a case (for drawing): paired target points, the opened lip curves (every other
/// landmark's target), or the curve target sampled at the landmarks' closest points at rest.
pub fn case_marks(scene: &Scene<2>, case: Case) -> crate::Result<Vec<Vector<2>>> {
    let loss = case_loss(scene, case)?;
    let mut out = Vec::new();
    for g in &loss.groups {
        match &g.target {
            GroupTarget::Paired(t) => out.extend(t.iter().copied()),
            GroupTarget::Shared(s) => match g.name.as_str() {
                "left lip" => out.extend(g.particles.iter().step_by(2).map(|&p| opened(scene, p, -1.0))),
                "right lip" => out.extend(g.particles.iter().step_by(2).map(|&p| opened(scene, p, 1.0))),
                _ => out.extend(g.particles.iter().map(|&p| s.closest(&scene.positions[p]).0)),
            },
        }
    }
    Ok(out)
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
