//! Closest points and distances to the target types of eq. 5.10 (point, polyline, triangle surface,
//! point cloud), exact, accelerated with kiddo k-d trees.
//!
//! Every query is exact (not approximate): a k-d tree over primitive centroids gives a first
//! candidate at distance d₀; every primitive whose closest point can be nearer than d₀ has its
//! centroid within d₀ + r_max (r_max = the largest centroid-to-vertex distance), and all of those are
//! tested. Ties go to the smallest primitive index.
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use laparo_mpm::Vector;

/// A k-d tree over points (item = index into the slice it was built from).
pub type Tree<const D: usize> = ImmutableKdTree<f64, u64, D, 32>;

/// Build a [`Tree`] over `points`.
pub fn build_tree<const D: usize>(points: &[Vector<D>]) -> Tree<D> {
    let arr: Vec<[f64; D]> = points.iter().map(|p| std::array::from_fn(|d| p[d])).collect();
    ImmutableKdTree::new_from_slice(&arr)
}

fn arr<const D: usize>(p: &Vector<D>) -> [f64; D] {
    std::array::from_fn(|d| p[d])
}

/// Closest point to `x` on the segment [a, b].
pub fn closest_on_segment<const D: usize>(x: &Vector<D>, a: &Vector<D>, b: &Vector<D>) -> Vector<D> {
    let ab = b - a;
    let l2 = ab.norm_squared();
    if l2 == 0.0 {
        return *a;
    }
    let t = ((x - a).dot(&ab) / l2).clamp(0.0, 1.0);
    a + ab * t
}

/// Closest point to `p` on the triangle (a, b, c) (laparo-core's, Ericson §5.1.5).
pub use laparo_core::geometry::closest_point_on_triangle as closest_on_triangle;

/// Something a landmark can be scored against: the closest point of the target to `x`.
pub trait ClosestPoint<const D: usize>: Sync + Send {
    /// Closest target point to `x` and the index of the primitive it lies on.
    fn closest(&self, x: &Vector<D>) -> (Vector<D>, usize);
    /// Number of primitives.
    fn len(&self) -> usize;
    /// True when there is no primitive.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Distance to the target.
    fn distance(&self, x: &Vector<D>) -> f64 {
        (x - self.closest(x).0).norm()
    }
}

/// Generic primitive set (points, segments, triangles or tetrahedra) with the exact centroid-tree query.
pub(crate) struct Accel<const D: usize> {
    tree: Tree<D>,
    r_max: f64,
}

impl<const D: usize> Accel<D> {
    /// Primitives with these centroids, none of whose points is farther than `r_max` from its centroid.
    pub(crate) fn new(centroids: &[Vector<D>], r_max: f64) -> Self {
        Accel { tree: build_tree(centroids), r_max }
    }
    /// The closest point to `x` over the primitives (`closest(i)`: primitive i's closest point) and its
    /// primitive; ties → the smallest index.
    pub(crate) fn query(&self, x: &Vector<D>, closest: impl Fn(usize) -> Vector<D>) -> (Vector<D>, usize) {
        let q = arr(x);
        let first = self.tree.nearest_one::<SquaredEuclidean>(&q).item as usize;
        let mut best = (closest(first), first);
        let mut best_d2 = (x - best.0).norm_squared();
        let r = best_d2.sqrt() + self.r_max;
        // small relative slack: the centroid bound must not lose a candidate to round-off
        let r2 = r * r * (1.0 + 1e-12) + 1e-300;
        for nb in self.tree.within_unsorted::<SquaredEuclidean>(&q, r2) {
            let i = nb.item as usize;
            let c = closest(i);
            let d2 = (x - c).norm_squared();
            if d2 < best_d2 || (d2 == best_d2 && i < best.1) {
                best = (c, i);
                best_d2 = d2;
            }
        }
        best
    }
}

/// A point cloud target (region, eq. 5.10): the closest cloud point.
pub struct PointCloud<const D: usize> {
    /// The points.
    pub points: Vec<Vector<D>>,
    accel: Accel<D>,
}

impl<const D: usize> PointCloud<D> {
    /// Build the k-d tree.
    pub fn new(points: Vec<Vector<D>>) -> Self {
        let accel = Accel::new(&points, 0.0);
        PointCloud { points, accel }
    }
}

impl<const D: usize> ClosestPoint<D> for PointCloud<D> {
    fn closest(&self, x: &Vector<D>) -> (Vector<D>, usize) {
        self.accel.query(x, |i| self.points[i])
    }
    fn len(&self) -> usize {
        self.points.len()
    }
}

/// A polyline target (curve landmarks, eq. 5.10): the closest point on any of its segments.
pub struct Polyline<const D: usize> {
    /// Vertices.
    pub vertices: Vec<Vector<D>>,
    /// Segments (vertex index pairs).
    pub segments: Vec<[usize; 2]>,
    accel: Accel<D>,
}

impl<const D: usize> Polyline<D> {
    /// An open polyline through `vertices` in order (one vertex = a point target).
    pub fn open(vertices: Vec<Vector<D>>) -> Self {
        let segments =
            if vertices.len() == 1 { vec![[0, 0]] } else { (1..vertices.len()).map(|i| [i - 1, i]).collect() };
        Self::from_segments(vertices, segments)
    }
    /// Any set of segments.
    pub fn from_segments(vertices: Vec<Vector<D>>, segments: Vec<[usize; 2]>) -> Self {
        let mut r_max: f64 = 0.0;
        let centroids: Vec<Vector<D>> = segments
            .iter()
            .map(|s| {
                let c = (vertices[s[0]] + vertices[s[1]]) * 0.5;
                r_max = r_max.max((vertices[s[0]] - c).norm()).max((vertices[s[1]] - c).norm());
                c
            })
            .collect();
        let accel = Accel::new(&centroids, r_max);
        Polyline { vertices, segments, accel }
    }
}

impl<const D: usize> ClosestPoint<D> for Polyline<D> {
    fn closest(&self, x: &Vector<D>) -> (Vector<D>, usize) {
        self.accel.query(x, |i| {
            let s = self.segments[i];
            closest_on_segment(x, &self.vertices[s[0]], &self.vertices[s[1]])
        })
    }
    fn len(&self) -> usize {
        self.segments.len()
    }
}

/// A triangle surface target (region, eq. 5.10): the closest point on any triangle.
pub struct TriangleSurface {
    /// Vertices (mm).
    pub vertices: Vec<Vector<3>>,
    /// Triangles.
    pub faces: Vec<[usize; 3]>,
    accel: Accel<3>,
}

impl TriangleSurface {
    /// Build the k-d tree over triangle centroids.
    pub fn new(vertices: Vec<Vector<3>>, faces: Vec<[usize; 3]>) -> Self {
        let mut r_max: f64 = 0.0;
        let centroids: Vec<Vector<3>> = faces
            .iter()
            .map(|f| {
                let c = (vertices[f[0]] + vertices[f[1]] + vertices[f[2]]) / 3.0;
                for &v in f {
                    r_max = r_max.max((vertices[v] - c).norm());
                }
                c
            })
            .collect();
        let accel = Accel::new(&centroids, r_max);
        TriangleSurface { vertices, faces, accel }
    }
}

impl ClosestPoint<3> for TriangleSurface {
    fn closest(&self, x: &Vector<3>) -> (Vector<3>, usize) {
        self.accel.query(x, |i| {
            let f = self.faces[i];
            closest_on_triangle(x, &self.vertices[f[0]], &self.vertices[f[1]], &self.vertices[f[2]])
        })
    }
    fn len(&self) -> usize {
        self.faces.len()
    }
}

/// Brute-force closest point over `n` primitives (`closest(i)`), ties to the smallest index; the
/// reference of the tests.
pub fn brute_force<const D: usize>(
    x: &Vector<D>,
    n: usize,
    closest: impl Fn(usize) -> Vector<D>,
) -> (Vector<D>, usize) {
    let mut best = (closest(0), 0);
    let mut bd = (x - best.0).norm_squared();
    for i in 1..n {
        let c = closest(i);
        let d = (x - c).norm_squared();
        if d < bd {
            best = (c, i);
            bd = d;
        }
    }
    best
}

/// Unsquared distance of eq. 5.10 with a smoothing length ε ≥ 0: d_ε(r) = √(|r|² + ε²) − ε, and its
/// gradient r / √(|r|² + ε²) with respect to x (closest point c held fixed, r = x − c).
pub fn smoothed_distance<const D: usize>(r: &Vector<D>, eps: f64) -> (f64, Vector<D>) {
    let s = (r.norm_squared() + eps * eps).sqrt();
    if s == 0.0 {
        return (0.0, Vector::<D>::zeros());
    }
    (s - eps, r / s)
}
