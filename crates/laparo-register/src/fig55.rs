//! The 2D illustrations of Fig. 5.5 (§5.4.1) with the set-ups proposed in `register.md` §3 (the
//! thesis gives no shapes, targets or material for them): a unit square domain, n_grid 120, an 80 × 80
//! particle square (6,400 particles at Δx/2, centred), ρ 1, Δt 2e-4, T 200, sticky walls of 3 cells (the
//! units of the DiffTaichi script `mpm2d_rods.py`: length 144 mm, stress kPa).
//!
//! * (a) stretch and (b) curve: the DiffTaichi material, E 4.1, ν 0.49 (the thesis' liver), from v₀ = 0.
//! * (c) rupture: each lip is its top-edge half *and* its face of the cut, scored (closest point) against
//!   the same material curve moved by [`RUPTURE_OPENING`] (each half ±0.06 in x, top edge down 0.03).
//!   Scoring only the top-edge halves (`register.md`) is met by a fold without a tear. Three choices make
//!   the tear reachable, each measured (BENCHMARKS.md, Issue 12, "stop 24"):
//!   1. **Material [`RUPTURE_MATERIAL`]: E 1, ν 0.4** (a soft, compressible illustration material, not the
//!      liver). A forward velocity jump of k × the lips' opening speed tears the square at k = 1 for it,
//!      at k = 4 for the liver values (k = 12 with the old book opening): MLS-MPM has no damage model, so a
//!      separation is a band of material stretched until its particles are > 1.5 Δx apart, and with
//!      ν = 0.49 (λ ≈ 16 E) that band costs more elastic energy than an opening at the target speed carries.
//!   2. **Kerf of one column per side ([`KERF`])**: the two particle columns straddling x = 0.5 (±Δx/4)
//!      share every grid node, so P2G gives them one velocity and any velocity jump leaves them behind as a
//!      1–2-column sliver (≈ 2.5 % of the particles); the lips are the first columns that follow their side
//!      (x = 0.5 ± 0.75 Δx), so the incision is 1.5 Δx wide (`register.md` pitfall 5: < 2 Δx is unresolved).
//!   3. **Kinematic warm start** ([`WarmStart::Kinematic`]): v₀ = (target − source)/(T Δt) of the nearest
//!      lip landmark of the particle's own side, what a user with lip correspondences starts from; from
//!      v₀ = 0 the (Gaussian-preconditioned, side-blind) steps stretch the body and never tear it.
//!
//!   The opening is parallel (±0.06 at the bottom too, not the book's ±0.015: the bottom of a book opening
//!   is < 4 Δx and stays bridged).
//! * (d) rupture + large deformation ("stop 25"): **(a)'s material (E 4.1, ν 0.49, the thesis' liver)**,
//!   (a)'s two side points moved out by [`STRETCH_RUPTURE_SHIFT`] (±0.30), each outer edge scored against
//!   the vertical line through its point's target, each lip = its face of the cut only (kerf 1) scored
//!   against the vertical line [`STRETCH_RUPTURE_OPENING`] (±0.26) out: every target moves in x only, no
//!   target touches the top or bottom edge, so the height reduction at mid-width (≈ 0.82 × rest) is the
//!   material's response to each half being stretched 24 % (0.04 / 0.167), as in (a). Kinematic warm start.
//!   Why so large, measured: a tear needs a velocity jump across the cut of ≈ 1–2 × the P-wave speed c
//!   (whatever T: at a fixed opening, doubling T loses the tear), so a stiff, nearly incompressible material
//!   tears only under a large opening (the liver: ±0.26 tears, ±0.20 does not; E 1 / ν 0.4: ±0.06), and a
//!   soft compressible one (E 1, ν 0.4) does not thin within T: with (c)'s opening and the top edge free
//!   its mid-height stays 1.00, and stretching it harder opens holes (J up to 3–4) instead. With the side
//!   points alone (no edge lines) the optimiser reaches them by a local tent and the halves keep their
//!   height (0.958–0.987 where the width is met).
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
    /// (c) rupture: each lip (top-edge half + its face of the cut) against its own polyline, moved by
    /// [`RUPTURE_OPENING`].
    Rupture,
    /// (d) rupture + large deformation: (a)'s points at ±[`STRETCH_RUPTURE_SHIFT`] and the outer edges
    /// on their vertical lines, the cut faces on theirs ([`STRETCH_RUPTURE_OPENING`]); (a)'s material.
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

/// The opening of the lips' targets, linear in height (a book when `bottom` < `top`): the particle of side
/// sx (−1 left, +1 right) at height fraction s of the square moves by (sx (`bottom` + (`top` − `bottom`) s),
/// `up` s).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BookOpening {
    /// Outward x displacement of each lip at the top edge.
    pub top: f64,
    /// Outward x displacement of each lip at the bottom edge.
    pub bottom: f64,
    /// Rise of the top edge (negative: a drop).
    pub up: f64,
}

/// The book opening of the previous set-up: ±0.06 and up 0.04 at the top (`register.md` §3), ±0.015 at the
/// bottom (no material of the threshold table tears it at its own speed).
pub const BOOK_OPENING: BookOpening = BookOpening { top: 0.06, bottom: 0.015, up: 0.04 };

/// The opening (c)/(d) use: each half moves ±0.06 at the top and at the bottom (the lips' faces end
/// 2 × 0.06 + 1.5 Δx = 15.9 Δx apart), its top edge drops 0.03 (9 % of the height).
pub const RUPTURE_OPENING: BookOpening = BookOpening { top: 0.06, bottom: 0.06, up: -0.03 };

/// The opening (d) uses: each half moves ±0.26 in x, parallel, nothing vertical (the lips' faces end
/// 2 × 0.26 + 1.5 Δx = 63.9 Δx apart).
pub const STRETCH_RUPTURE_OPENING: BookOpening = BookOpening { top: 0.26, bottom: 0.26, up: 0.0 };

/// Outward x displacement of (d)'s side points and outer-edge lines: 0.04 beyond the lips' opening, a 24 %
/// stretch of each half (the left edge's target, x = 0.033, is 4 Δx from the domain side).
pub const STRETCH_RUPTURE_SHIFT: f64 = 0.30;

/// Two particles belong to the same body when closer than this (Δx): three rest spacings (Δx/2), so a
/// body stays connected under stretches up to 3× and a separation counts only once the lips are more
/// than 1.5 Δx apart (the radius of the quadratic B-spline's support).
pub const LINK_DX: f64 = 1.5;

/// Outward x displacement of the two side points' targets of (a).
pub const STRETCH_SHIFT: f64 = 0.08;

/// Particles per side of the square.
pub const SIDE: usize = 80;

/// The material of the DiffTaichi 2D script `mpm2d_rods.py` (E 4.1, ν 0.49, ρ 1): the thesis' liver values;
/// cases (a), (b).
pub const DIFFTAICHI_MATERIAL: Material =
    Material { model: Model::NeoHookean, youngs_modulus: 4.1, poisson_ratio: 0.49, density: 1.0 };

/// The illustration material of cases (c), (d): E 1, ν 0.4, ρ 1 (see the module doc).
pub const RUPTURE_MATERIAL: Material =
    Material { model: Model::NeoHookean, youngs_modulus: 1.0, poisson_ratio: 0.4, density: 1.0 };

/// Lattice columns per side between x = 0.5 and the lips' faces in cases (c), (d) (see the module doc).
pub const KERF: usize = 1;

/// The square scene with the DiffTaichi material (v₀ = 0).
pub fn square_scene() -> Scene<2> {
    square_scene_with(DIFFTAICHI_MATERIAL)
}

/// The square scene with another material (v₀ = 0; Δt 2e-4, T 200 whatever the material).
pub fn square_scene_with(material: Material) -> Scene<2> {
    let grid = GridSpec::unit(120);
    let s = grid.dx / 2.0;
    let half = SIDE as f64 * s / 2.0;
    let lo = Vector::<2>::new(0.5 - half, 0.5 - half);
    let hi = Vector::<2>::new(0.5 + half, 0.5 + half);
    let pos = box_lattice(lo, hi, s);
    let mut scene = Scene::new(pos, s * s, material, grid, 2e-4, 200);
    scene.mass_epsilon = 1e-10;
    scene
}

/// Lip side of particle `p` of [`square_scene`]: −1 left of the cut (x = 0.5), +1 right.
pub fn side(p: usize) -> f64 {
    if p / SIDE < SIDE / 2 {
        -1.0
    } else {
        1.0
    }
}

/// v₀ that carries every particle to its book-opened position ([`opened`], its own side) in T Δt if nothing
/// resisted, times `k`: a velocity jump across the cut (the forward tear probe).
pub fn book_opening_velocities(scene: &Scene<2>, opening: &BookOpening, k: f64) -> Vec<Vector<2>> {
    let t = scene.steps as f64 * scene.dt;
    (0..scene.n_particles()).map(|p| (opened(scene, p, side(p), opening) - scene.positions[p]) * (k / t)).collect()
}

/// Bodies of a final configuration of the square and the gap between the two largest along the cut.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Separation {
    /// Body fractions of the particles, largest first.
    pub bodies: Vec<f64>,
    /// Smallest distance (Δx) between particles of the two largest bodies whose rest positions lie within
    /// [`CUT_BAND_DX`] of the cut (x = 0.5), if there are two bodies.
    pub gap_dx: Option<f64>,
    /// Label of each particle: 0 = largest body, 1 = second, … (ties by first particle).
    #[serde(skip)]
    pub label: Vec<usize>,
}

/// Half-width (Δx, rest positions) of the band around the cut in which the gap is measured.
pub const CUT_BAND_DX: f64 = 3.0;

/// Bodies (flood fill at [`LINK_DX`]) of the final positions `x` of the square whose rest positions are `x0`.
pub fn separation(x0: &[Vector<2>], x: &[Vector<2>], dx: f64) -> Separation {
    let (raw, sizes) = components(x, LINK_DX * dx);
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by(|&a, &b| sizes[b].cmp(&sizes[a]).then(a.cmp(&b)));
    let mut rank = vec![0; sizes.len()];
    for (r, &c) in order.iter().enumerate() {
        rank[c] = r;
    }
    let label: Vec<usize> = raw.iter().map(|&c| rank[c]).collect();
    let n = x.len() as f64;
    let bodies = order.iter().map(|&c| sizes[c] as f64 / n).collect();
    let gap_dx = (order.len() >= 2).then(|| {
        let near = |b: usize| -> Vec<Vector<2>> {
            (0..x.len())
                .filter(|&p| label[p] == b && (x0[p][0] - 0.5).abs() <= CUT_BAND_DX * dx)
                .map(|p| x[p])
                .collect()
        };
        let (a, b) = (near(0), near(1));
        if a.is_empty() || b.is_empty() {
            return f64::INFINITY;
        }
        let tree = crate::distance::build_tree(&b);
        a.iter()
            .map(|p| tree.nearest_one::<kiddo::SquaredEuclidean>(&[p[0], p[1]]).distance.sqrt())
            .fold(f64::INFINITY, f64::min)
            / dx
    });
    Separation { bodies, gap_dx, label }
}

/// (c)'s rupture criterion: two bodies of > 40 % of the particles each, ≥ 2 Δx apart along the cut.
pub fn ruptured(s: &Separation) -> bool {
    s.bodies.len() >= 2 && s.bodies[1] > 0.4 && s.gap_dx.is_some_and(|g| g >= 2.0)
}

/// One forward tear probe: v₀ = [`book_opening_velocities`] × `k`, no optimisation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TearProbe {
    /// Opening speed factor.
    pub k: f64,
    /// Bodies and gap after T steps.
    pub separation: Separation,
    /// Gap between the two faces of the cut (the columns next to x = 0.5) at the top / bottom edge, Δx
    /// (at k = 1 without resistance: (2 top + Δx/2)/Δx and (2 bottom + Δx/2)/Δx, 14.9 and 4.1 for
    /// [`BOOK_OPENING`]).
    pub lip_gap_dx: [f64; 2],
    /// min J.
    pub min_j: f64,
}

/// Run the forward tear probe on the square made of `material`.
pub fn tear_probe(material: Material, opening: &BookOpening, k: f64) -> crate::Result<TearProbe> {
    let mut scene = square_scene_with(material);
    scene.velocities = book_opening_velocities(&scene, opening, k);
    let fin = laparo_mpm::simulate(&scene)?.final_state;
    let dx = scene.grid.dx;
    let (m, top) = (SIDE / 2, SIDE - 1);
    let gap = |j: usize| (fin.x[idx(m, j)][0] - fin.x[idx(m - 1, j)][0]) / dx;
    let min_j = fin.f.iter().map(laparo_mpm::det).fold(f64::INFINITY, f64::min);
    Ok(TearProbe { k, separation: separation(&scene.positions, &fin.x, dx), lip_gap_dx: [gap(top), gap(0)], min_j })
}

/// Particle index of lattice cell (i along x, j along y) (box_lattice: last axis fastest).
pub fn idx(i: usize, j: usize) -> usize {
    i * SIDE + j
}

/// Loss of a case on [`square_scene`].
pub fn case_loss(scene: &Scene<2>, case: Case, setup: &CaseSetup) -> crate::Result<RegistrationLoss<2>> {
    let x = &scene.positions;
    let mid = SIDE / 2;
    let top = SIDE - 1;
    let points = || {
        let (l, r) = (idx(0, mid), idx(SIDE - 1, mid));
        let shift = Vector::<2>::new(setup.side_shift, 0.0);
        let (tl, tr) = (x[l] - shift, x[r] + shift);
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
    let edges = || {
        // each outer edge (its whole particle column) against the vertical line through its side point's
        // target, over the rest height (closest point: free to slide, so its height is not prescribed)
        [("left edge", 0, -1.0), ("right edge", SIDE - 1, 1.0)]
            .into_iter()
            .map(|(name, i, sx)| {
                let parts: Vec<usize> = (0..SIDE).map(|j| idx(i, j)).collect();
                let shift = Vector::<2>::new(sx * setup.side_shift, 0.0);
                let verts = vec![x[idx(i, 0)] + shift, x[idx(i, top)] + shift];
                LandmarkGroup {
                    name: name.into(),
                    particles: parts,
                    target: GroupTarget::Shared(Arc::new(Polyline::open(verts))),
                    weight: 1.0,
                }
            })
            .collect::<Vec<_>>()
    };
    let halves = || {
        // each side: its top-edge half and its face of the cut (`kerf` columns out from x = 0.5), scored
        // (closest point) against its own polyline: the same material curve moved by `setup.opening`
        lips(setup.kerf, setup.lip_top_edge)
            .into_iter()
            .zip([-1.0, 1.0])
            .map(|((name, parts), sx)| {
                let open = |p: usize| opened(scene, p, sx, &setup.opening);
                // the curve is straight on the top edge and on the cut face: three vertices (two without
                // the top edge)
                let last = open(*parts.last().unwrap());
                let verts = if setup.lip_top_edge {
                    vec![open(parts[0]), open(parts[SIDE / 2 - setup.kerf - 1]), last]
                } else {
                    vec![open(parts[0]), last]
                };
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
            if setup.outer_edges {
                g.extend(edges());
            }
            g.extend(halves());
            g
        }
    };
    Ok(RegistrationLoss::new(groups))
}

/// Rest position of particle `p` moved by the book opening `o` of its lip (`sx` = −1 left, +1 right).
pub fn opened(scene: &Scene<2>, p: usize, sx: f64, o: &BookOpening) -> Vector<2> {
    let x = &scene.positions;
    let (yb, yt) = (x[idx(0, 0)][1], x[idx(0, SIDE - 1)][1]);
    let s = (x[p][1] - yb) / (yt - yb);
    x[p] + Vector::<2>::new(sx * (o.bottom + (o.top - o.bottom) * s), o.up * s)
}

/// The two lips of the cut along x = 0.5, each as an ordered material curve: its top-edge part (outer
/// corner → cut; only with `top_edge`) then its face of the cut (top → bottom): the lattice column next to
/// x = 0.5 for `kerf` = 0, `kerf` columns further out otherwise (the columns in between belong to no lip).
pub fn lips(kerf: usize, top_edge: bool) -> [(&'static str, Vec<usize>); 2] {
    let (mid, top) = (SIDE / 2, SIDE - 1);
    let side = |outer: usize, inner: usize| -> Vec<usize> {
        let mut v: Vec<usize> = if !top_edge {
            vec![idx(inner, top)]
        } else if outer < inner {
            (outer..=inner).map(|i| idx(i, top)).collect()
        } else {
            (inner..=outer).rev().map(|i| idx(i, top)).collect()
        };
        v.extend((0..top).rev().map(|j| idx(inner, j)));
        v
    };
    [("left lip", side(0, mid - 1 - kerf)), ("right lip", side(SIDE - 1, mid + kerf))]
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

/// Starting v₀ of a Fig. 5.5 registration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum WarmStart {
    /// v₀ = 0 (the thesis).
    Zero,
    /// Kinematic: each particle takes (target − source)/(T Δt) of the nearest landmark of its own side of the
    /// cut (x = 0.5), what a user with lip correspondences would start from ([`kinematic_warm_start`]).
    Kinematic,
}

/// Landmark correspondences of a case: (particle, its corresponding target point): paired targets, and for
/// the lips the book-opened rest position ([`opened`]) of each lip particle.
pub fn correspondences(scene: &Scene<2>, case: Case, setup: &CaseSetup) -> crate::Result<Vec<(usize, Vector<2>)>> {
    let loss = case_loss(scene, case, setup)?;
    let mut out = Vec::new();
    for g in &loss.groups {
        match &g.target {
            GroupTarget::Paired(t) => out.extend(g.particles.iter().copied().zip(t.iter().copied())),
            GroupTarget::Shared(s) => match g.name.as_str() {
                "left lip" => out.extend(g.particles.iter().map(|&p| (p, opened(scene, p, -1.0, &setup.opening)))),
                "right lip" => out.extend(g.particles.iter().map(|&p| (p, opened(scene, p, 1.0, &setup.opening)))),
                _ => out.extend(g.particles.iter().map(|&p| (p, s.closest(&scene.positions[p]).0))),
            },
        }
    }
    Ok(out)
}

/// The kinematic warm start of a case ([`WarmStart::Kinematic`]): each particle takes (y − x₀)/(T Δt) of the
/// nearest landmark (rest positions; ties: first in loss order) on its own side of the cut, y being that
/// landmark's corresponding target ([`correspondences`]).
pub fn kinematic_warm_start(scene: &Scene<2>, case: Case, setup: &CaseSetup) -> crate::Result<Vec<Vector<2>>> {
    let t = scene.steps as f64 * scene.dt;
    let x = &scene.positions;
    let lm = correspondences(scene, case, setup)?;
    Ok((0..x.len())
        .map(|p| {
            let mut best = (f64::INFINITY, Vector::<2>::zeros());
            for &(q, y) in lm.iter().filter(|(q, _)| side(*q) == side(p)) {
                let d = (x[q] - x[p]).norm_squared();
                if d < best.0 {
                    best = (d, (y - x[q]) / t);
                }
            }
            best.1
        })
        .collect())
}

/// Material, lips and starting point of a Fig. 5.5 run.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct CaseSetup {
    /// Material of the square.
    pub material: Material,
    /// Starting v₀.
    pub warm_start: WarmStart,
    /// Targets of the lips (cases c, d).
    pub opening: BookOpening,
    /// Lattice columns between each lip's cut face and x = 0.5 (cases c, d; see [`lips`]).
    pub kerf: usize,
    /// Whether each lip includes its top-edge half (cases c, d; see [`lips`]).
    pub lip_top_edge: bool,
    /// Outward x displacement of the two side points' targets (cases a, d).
    pub side_shift: f64,
    /// Time steps T (Δt 2e-4).
    pub steps: usize,
    /// (d): also score each outer edge against the vertical line through its side point's target.
    pub outer_edges: bool,
}

impl CaseSetup {
    /// The set-up of a case: (a), (b) the DiffTaichi material from v₀ = 0; (c) [`RUPTURE_MATERIAL`],
    /// [`RUPTURE_OPENING`], [`KERF`], kinematic warm start; (d) the DiffTaichi material,
    /// [`STRETCH_RUPTURE_OPENING`], [`STRETCH_RUPTURE_SHIFT`], outer edges, lips = cut faces, [`KERF`],
    /// kinematic warm start.
    pub fn for_case(case: Case) -> Self {
        match case {
            Case::Stretch | Case::Curve => CaseSetup {
                material: DIFFTAICHI_MATERIAL,
                warm_start: WarmStart::Zero,
                opening: RUPTURE_OPENING,
                kerf: KERF,
                lip_top_edge: true,
                side_shift: STRETCH_SHIFT,
                steps: 200,
                outer_edges: false,
            },
            Case::Rupture => CaseSetup {
                material: RUPTURE_MATERIAL,
                warm_start: WarmStart::Kinematic,
                opening: RUPTURE_OPENING,
                kerf: KERF,
                lip_top_edge: true,
                side_shift: STRETCH_SHIFT,
                steps: 200,
                outer_edges: false,
            },
            Case::RuptureStretch => CaseSetup {
                material: DIFFTAICHI_MATERIAL,
                warm_start: WarmStart::Kinematic,
                opening: STRETCH_RUPTURE_OPENING,
                kerf: KERF,
                lip_top_edge: false,
                side_shift: STRETCH_RUPTURE_SHIFT,
                steps: 200,
                outer_edges: true,
            },
        }
    }

    /// The square scene of this set-up ([`square_scene_with`] its material, T = `steps`).
    pub fn scene(&self) -> Scene<2> {
        let mut scene = square_scene_with(self.material);
        scene.steps = self.steps;
        scene
    }
}

/// Figures of one Fig. 5.5 case after registration.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaseMetrics {
    /// Case label.
    pub case: String,
    /// Material and warm start.
    pub setup: CaseSetup,
    /// Mean landmark distance before / after (Δx).
    pub residual_dx: [f64; 2],
    /// Distance between the two side landmarks / between their targets (cases a, d).
    pub width_ratio: Option<f64>,
    /// Height of the particle column at mid-width after / at rest (for two bodies: each body at its own
    /// mid-width, averaged).
    pub mid_height_ratio: f64,
    /// min det F over all particles.
    pub min_j: f64,
    /// min det F over the (up to two) largest bodies (slivers left in the kerf excluded).
    pub min_j_bodies: f64,
    /// Connected bodies (particles closer than [`LINK_DX`] Δx linked; flood fill over k-d tree radius
    /// queries), largest first: particle fractions.
    pub bodies: Vec<f64>,
    /// Smallest distance between particles of the two largest bodies within [`CUT_BAND_DX`] of the cut (Δx),
    /// if there are two.
    pub gap_dx: Option<f64>,
    /// Iterations.
    pub iterations: usize,
    /// Simulations.
    pub simulations: usize,
    /// Wall time (s).
    pub seconds: f64,
    /// Why the optimiser stopped.
    pub stop_reason: String,
    /// Loss (mean landmark distance, Δx) per iteration.
    pub curve_dx: Vec<f64>,
}

/// Register one case with its set-up ([`CaseSetup::for_case`]) and measure it. Returns the metrics and the
/// final positions and J.
pub fn run_case(
    case: Case,
    cfg: &crate::optimize::OptimizerConfig,
) -> crate::Result<(CaseMetrics, Vec<Vector<2>>, Vec<f64>)> {
    run_case_with(case, &CaseSetup::for_case(case), cfg)
}

/// Register one case with a material and warm start and measure it.
pub fn run_case_with(
    case: Case,
    setup: &CaseSetup,
    cfg: &crate::optimize::OptimizerConfig,
) -> crate::Result<(CaseMetrics, Vec<Vector<2>>, Vec<f64>)> {
    let scene = setup.scene();
    let loss = case_loss(&scene, case, setup)?;
    let warm = match setup.warm_start {
        WarmStart::Zero => None,
        WarmStart::Kinematic => Some(kinematic_warm_start(&scene, case, setup)?),
    };
    let r = crate::optimize::register(&scene, &loss, cfg, warm.as_deref(), &mut |_, _| true)?;
    let dx = scene.grid.dx;
    let x = r.final_state.x.clone();
    let j: Vec<f64> = r.final_state.f.iter().map(laparo_mpm::det).collect();
    let min_j = j.iter().cloned().fold(f64::INFINITY, f64::min);
    let width_ratio = width_ratio(case, setup, &scene.positions, &x);
    let sep = separation(&scene.positions, &x, dx);
    let mid_height_ratio = mid_height_ratio(&scene.positions, &x, &sep, dx);
    let min_j_bodies = (0..x.len()).filter(|&p| sep.label[p] < 2).map(|p| j[p]).fold(f64::INFINITY, f64::min);
    let last = r.history.last().cloned().unwrap_or_else(|| r.history[0].clone());
    let m = CaseMetrics {
        case: case.label().into(),
        setup: *setup,
        residual_dx: [r.history[0].mean_distance / dx, last.mean_distance / dx],
        width_ratio,
        mid_height_ratio,
        min_j,
        min_j_bodies,
        bodies: sep.bodies,
        gap_dx: sep.gap_dx,
        iterations: last.iteration,
        simulations: last.evaluations,
        seconds: last.seconds,
        stop_reason: r.stop_reason,
        curve_dx: r.history.iter().map(|h| h.mean_distance / dx).collect(),
    };
    Ok((m, x, j))
}

/// Distance between the two side landmarks (final `x`) over the distance between their targets (rest `x0`
/// moved by the set-up's `side_shift`); cases (a), (d) only.
pub fn width_ratio(case: Case, setup: &CaseSetup, x0: &[Vector<2>], x: &[Vector<2>]) -> Option<f64> {
    match case {
        Case::Stretch | Case::RuptureStretch => {
            let (l, r) = (idx(0, SIDE / 2), idx(SIDE - 1, SIDE / 2));
            let target = (x0[r][0] + setup.side_shift) - (x0[l][0] - setup.side_shift);
            Some((x[r][0] - x[l][0]) / target)
        }
        _ => None,
    }
}

/// Height of the particle column within Δx of the mid-width (centroid x) of each of the (up to two)
/// largest bodies of `sep`, final (`x`) over rest (`x0`), averaged.
pub fn mid_height_ratio(x0: &[Vector<2>], x: &[Vector<2>], sep: &Separation, dx: f64) -> f64 {
    let height = |pts: &[Vector<2>]| {
        let cx = pts.iter().map(|p| p[0]).sum::<f64>() / pts.len() as f64;
        let col: Vec<f64> = pts.iter().filter(|p| (p[0] - cx).abs() < dx).map(|p| p[1]).collect();
        if col.is_empty() {
            return 0.0;
        }
        col.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - col.iter().cloned().fold(f64::INFINITY, f64::min)
    };
    let body = |c: usize, pts: &[Vector<2>]| -> Vec<Vector<2>> {
        pts.iter().zip(&sep.label).filter(|(_, &l)| l == c).map(|(p, _)| *p).collect()
    };
    let k = sep.bodies.len().min(2);
    (0..k).map(|c| height(&body(c, x)) / height(&body(c, x0))).sum::<f64>() / k as f64
}

/// The kinematic warm start of a case simulated alone (no optimisation): what it leaves.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WarmStartProbe {
    /// Bodies and gap after T steps.
    pub separation: Separation,
    /// [`mid_height_ratio`] after T steps.
    pub mid_height_ratio: f64,
    /// Mean landmark distance after T steps (Δx).
    pub residual_dx: f64,
    /// [`width_ratio`] after T steps.
    pub width_ratio: Option<f64>,
    /// min J.
    pub min_j: f64,
}

/// Simulate the kinematic warm start of a case ([`kinematic_warm_start`]) with no optimisation and measure
/// bodies, gap, mid-width height and residual as [`run_case_with`] does.
pub fn warm_start_probe(case: Case, setup: &CaseSetup) -> crate::Result<WarmStartProbe> {
    let mut scene = setup.scene();
    let loss = case_loss(&scene, case, setup)?;
    scene.velocities = kinematic_warm_start(&scene, case, setup)?;
    let fin = laparo_mpm::simulate(&scene)?.final_state;
    let dx = scene.grid.dx;
    let sep = separation(&scene.positions, &fin.x, dx);
    let mid_height_ratio = mid_height_ratio(&scene.positions, &fin.x, &sep, dx);
    let residual_dx = loss.mean_distance(&fin.x) / dx;
    let min_j = fin.f.iter().map(laparo_mpm::det).fold(f64::INFINITY, f64::min);
    let width_ratio = width_ratio(case, setup, &scene.positions, &fin.x);
    Ok(WarmStartProbe { separation: sep, mid_height_ratio, residual_dx, width_ratio, min_j })
}

/// Target marks of a case (for drawing): paired target points, the opened lip curves (every other
/// landmark's target), or the curve target sampled at the landmarks' closest points at rest.
pub fn case_marks(scene: &Scene<2>, case: Case, setup: &CaseSetup) -> crate::Result<Vec<Vector<2>>> {
    let loss = case_loss(scene, case, setup)?;
    let mut out = Vec::new();
    for g in &loss.groups {
        match (&g.target, g.name.as_str()) {
            (GroupTarget::Paired(t), _) => out.extend(t.iter().copied()),
            (_, "left lip") => {
                out.extend(g.particles.iter().step_by(2).map(|&p| opened(scene, p, -1.0, &setup.opening)))
            }
            (_, "right lip") => {
                out.extend(g.particles.iter().step_by(2).map(|&p| opened(scene, p, 1.0, &setup.opening)))
            }
            (GroupTarget::Shared(s), _) => out.extend(g.particles.iter().map(|&p| s.closest(&scene.positions[p]).0)),
        }
    }
    Ok(out)
}

/// Picture of a case: particles coloured by J (Turbo, [0.5, 1.5]) in the view [0.2, 0.8]² (or
/// when a particle or mark lies outside it, (d): the whole domain [0, 1]²), target marks as crosses, with a
/// colour bar.
pub fn render_case(x: &[Vector<2>], j: &[f64], marks: &[Vector<2>], size: usize) -> laparo_core::image::Image<u8> {
    let inside = |p: &Vector<2>| (0..2).all(|d| (0.2..=0.8).contains(&p[d]));
    let (lo, extent) = if x.iter().chain(marks).all(inside) { (0.2, 0.6) } else { (0.0, 1.0) };
    let shift = |p: &Vector<2>| p - Vector::<2>::new(lo, lo);
    let xs: Vec<Vector<2>> = x.iter().map(shift).collect();
    let ms: Vec<Vector<2>> = marks.iter().map(shift).collect();
    let img = laparo_mpm::render::render_particles_2d(&xs, j, 0.5, 1.5, extent, size, 2, &ms);
    laparo_core::plot::with_colorbar(&img, 0.5, 1.5, laparo_core::colormap::Colormap::Turbo, "J = det F")
}
