//! Geometric primitives shared by meshing, registration and rendering: closest points on segments and
//! triangles, and ray–triangle intersection.
use nalgebra::Vector3;

/// Closest point to `p` on the segment [a, b] (a for a zero-length segment).
pub fn closest_point_on_segment(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    let ab = b - a;
    let l2 = ab.norm_squared();
    if l2 == 0.0 {
        return *a;
    }
    a + ab * ((p - a).dot(&ab) / l2).clamp(0.0, 1.0)
}

/// Closest point to `p` on the triangle (a, b, c) (Ericson, Real-Time Collision Detection §5.1.5); a
/// zero-area triangle gives the closest point of its edges.
pub fn closest_point_on_triangle(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Vector3<f64> {
    let ab = b - a;
    let ac = c - a;
    if ab.cross(&ac).norm_squared() == 0.0 {
        let cands =
            [closest_point_on_segment(p, a, b), closest_point_on_segment(p, b, c), closest_point_on_segment(p, c, a)];
        return cands
            .into_iter()
            .min_by(|x, y| (p - x).norm_squared().total_cmp(&(p - y).norm_squared()))
            .unwrap_or(*a);
    }
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Parameter t (of either sign) where the line `o + t d` crosses the triangle (a, b, c) (Möller–Trumbore,
/// barycentric tolerance 1e-12), None when it misses or is parallel.
pub fn ray_triangle(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(&p) * inv;
    if !(-1e-12..=1.0 + 1e-12).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < -1e-12 || u + v > 1.0 + 1e-12 {
        return None;
    }
    Some(e2.dot(&q) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_by_hand() {
        let (a, b, c) = (Vector3::zeros(), Vector3::x(), Vector3::y());
        let q = closest_point_on_triangle(&Vector3::new(0.2, 0.2, 5.0), &a, &b, &c);
        assert!((q - Vector3::new(0.2, 0.2, 0.0)).norm() < 1e-15, "{q}");
        assert_eq!(closest_point_on_triangle(&Vector3::new(-1.0, -1.0, 0.0), &a, &b, &c), a);
        assert_eq!(closest_point_on_triangle(&Vector3::new(1.0, 1.0, 0.0), &a, &b, &c), Vector3::new(0.5, 0.5, 0.0));
        // degenerate triangle: its edges
        let q = closest_point_on_triangle(&Vector3::new(0.5, 1.0, 0.0), &a, &b, &(b * 2.0));
        assert_eq!(q, Vector3::new(0.5, 0.0, 0.0));
        assert_eq!(closest_point_on_segment(&Vector3::new(3.0, 1.0, 0.0), &a, &b), b);
    }

    #[test]
    fn ray_hits_by_hand() {
        let (a, b, c) = (Vector3::zeros(), Vector3::x(), Vector3::y());
        let t = ray_triangle(&Vector3::new(0.25, 0.25, 2.0), &Vector3::new(0.0, 0.0, -1.0), &a, &b, &c);
        assert_eq!(t, Some(2.0));
        assert_eq!(ray_triangle(&Vector3::new(0.25, 0.25, 2.0), &Vector3::new(0.0, 0.0, 1.0), &a, &b, &c), Some(-2.0));
        assert_eq!(ray_triangle(&Vector3::new(2.0, 2.0, 2.0), &Vector3::new(0.0, 0.0, -1.0), &a, &b, &c), None);
        assert_eq!(ray_triangle(&Vector3::new(0.2, 0.2, 1.0), &Vector3::x(), &a, &b, &c), None);
    }
}
