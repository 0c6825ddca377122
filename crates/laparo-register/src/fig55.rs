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
