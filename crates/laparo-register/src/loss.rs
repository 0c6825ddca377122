//! The registration loss of eq. 5.10, L = (1/|𝒦|) Σ_k dist(x_T^k, y^k), per landmark group, plus a
//! one-sided target→source region term for partially visible intraoperative point clouds.
use crate::distance::{build_tree, smoothed_distance, ClosestPoint};
use kiddo::SquaredEuclidean;
use laparo_mpm::{Loss, Vector};
use std::sync::Arc;

/// What the landmarks of a group are scored against.
#[derive(Clone)]
pub enum GroupTarget<const D: usize> {
    /// One target point per landmark (point → point).
    Paired(Vec<Vector<D>>),
    /// A shared target (polyline, triangle surface, point cloud): the closest point, recomputed at
    /// every evaluation.
    Shared(Arc<dyn ClosestPoint<D>>),
}

/// A landmark group: source particles and their target (e.g. one lip of an incision against its own
/// side's polyline, so that lips cannot swap).
#[derive(Clone)]
pub struct LandmarkGroup<const D: usize> {
    /// Name (report).
    pub name: String,
    /// Source landmark particle indices.
    pub particles: Vec<usize>,
    /// Target.
    pub target: GroupTarget<D>,
    /// Weight of each landmark of this group (default 1).
    pub weight: f64,
}

impl<const D: usize> LandmarkGroup<D> {
    /// Closest target point of landmark `k` at position x.
    pub fn closest(&self, k: usize, x: &Vector<D>) -> Vector<D> {
        match &self.target {
            GroupTarget::Paired(t) => t[k],
            GroupTarget::Shared(s) => s.closest(x).0,
        }
    }
}

/// One-sided target→source term: every target point y_j is scored against its nearest source particle
/// (among `particles`, at their current positions): (w / J) Σ_j dist(y_j, x_nn(j)).
#[derive(Clone)]
pub struct RegionTerm<const D: usize> {
    /// Target points (the visible intraoperative surface).
    pub targets: Vec<Vector<D>>,
    /// Candidate source particles (e.g. the surface particles).
    pub particles: Vec<usize>,
    /// Weight relative to the landmark mean.
    pub weight: f64,
}

/// The full registration loss: Σ_g w_g Σ_{k∈g} d_ε(x_k − c_k) / Σ_g w_g |g| (+ region term).
/// With all weights 1 and ε = 0 this is eq. 5.10.
#[derive(Clone)]
pub struct RegistrationLoss<const D: usize> {
    /// Landmark groups.
    pub groups: Vec<LandmarkGroup<D>>,
    /// Optional region term.
    pub region: Option<RegionTerm<D>>,
    /// Smoothing length ε of the distance (length units; 0 = the thesis' unsquared distance).
    pub epsilon: f64,
    /// Rest offsets of the landmarks from the particles that carry them, per group and landmark (empty, or a
    /// group's list empty = none: the thesis scores the nearest particle itself). With offsets a landmark is
    /// scored at x_p + o, its own material point carried rigidly by its particle, so that a particle a few
    /// mm under the surface is not pulled onto a surface target (the ground truth itself would otherwise
    /// score the particle's depth).
    pub offsets: Vec<Vec<Vector<D>>>,
}

/// Per-group residuals: mean and max distance of the landmarks to their targets.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GroupResidual {
    /// Group name.
    pub name: String,
    /// Landmarks.
    pub count: usize,
    /// Mean distance (length units).
    pub mean: f64,
    /// Max distance.
    pub max: f64,
}

impl<const D: usize> RegistrationLoss<D> {
    /// Loss without a region term, ε = 0.
    pub fn new(groups: Vec<LandmarkGroup<D>>) -> Self {
        RegistrationLoss { groups, region: None, epsilon: 0.0, offsets: Vec::new() }
    }
    /// Where landmark `k` of group `gi` is scored at positions x: its particle, plus its rest offset if any.
    fn at(&self, gi: usize, k: usize, x: &[Vector<D>]) -> Vector<D> {
        let p = self.groups[gi].particles[k];
        match self.offsets.get(gi).and_then(|o| o.get(k)) {
            Some(o) => x[p] + o,
            None => x[p],
        }
    }
    /// All landmark particle indices.
    pub fn landmark_particles(&self) -> Vec<usize> {
        self.groups.iter().flat_map(|g| g.particles.iter().copied()).collect()
    }
    /// Unsmoothed mean landmark distance (eq. 5.10, all landmarks equally weighted) at positions x.
    pub fn mean_distance(&self, x: &[Vector<D>]) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for (gi, g) in self.groups.iter().enumerate() {
            for k in 0..g.particles.len() {
                let y = self.at(gi, k, x);
                s += (y - g.closest(k, &y)).norm();
                n += 1;
            }
        }
        if n == 0 {
            0.0
        } else {
            s / n as f64
        }
    }
    /// Residual per group at positions x.
    pub fn residuals(&self, x: &[Vector<D>]) -> Vec<GroupResidual> {
        self.groups
            .iter()
            .enumerate()
            .map(|(gi, g)| {
                let d: Vec<f64> = (0..g.particles.len())
                    .map(|k| {
                        let y = self.at(gi, k, x);
                        (y - g.closest(k, &y)).norm()
                    })
                    .collect();
                GroupResidual {
                    name: g.name.clone(),
                    count: d.len(),
                    mean: d.iter().sum::<f64>() / d.len().max(1) as f64,
                    max: d.iter().cloned().fold(0.0, f64::max),
                }
            })
            .collect()
    }
    /// Loss value at positions x, adding ∂L/∂x into `grad`.
    pub fn value_and_gradient(&self, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        use rayon::prelude::*;
        let wsum: f64 = self.groups.iter().map(|g| g.weight * g.particles.len() as f64).sum();
        let mut total = 0.0;
        if wsum > 0.0 {
            for (gi, g) in self.groups.iter().enumerate() {
                // closest points in parallel, accumulated in landmark order (deterministic)
                let terms: Vec<(f64, Vector<D>)> = (0..g.particles.len())
                    .into_par_iter()
                    .map(|k| {
                        let y = self.at(gi, k, x);
                        smoothed_distance(&(y - g.closest(k, &y)), self.epsilon)
                    })
                    .collect();
                let w = g.weight / wsum;
                for (&p, (d, dg)) in g.particles.iter().zip(terms) {
                    total += w * d;
                    grad[p] += dg * w;
                }
            }
        }
        if let Some(r) = &self.region {
            if !r.targets.is_empty() && !r.particles.is_empty() {
                let src: Vec<Vector<D>> = r.particles.iter().map(|&p| x[p]).collect();
                let tree = build_tree(&src);
                let terms: Vec<(usize, f64, Vector<D>)> = r
                    .targets
                    .par_iter()
                    .map(|y| {
                        let q: [f64; D] = std::array::from_fn(|d| y[d]);
                        let i = tree.nearest_one::<SquaredEuclidean>(&q).item as usize;
                        let (d, dg) = smoothed_distance(&(src[i] - y), self.epsilon);
                        (i, d, dg)
                    })
                    .collect();
                let w = r.weight / r.targets.len() as f64;
                for (i, d, dg) in terms {
                    total += w * d;
                    grad[r.particles[i]] += dg * w;
                }
            }
        }
        total
    }
}

impl<const D: usize> Loss<D> for RegistrationLoss<D> {
    fn evaluate(&self, _step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        self.value_and_gradient(x, grad)
    }
}
