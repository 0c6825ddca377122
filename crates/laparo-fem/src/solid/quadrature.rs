//! Quadrature rules on the reference tetrahedron {ξ, η, ζ ≥ 0, ξ + η + ζ ≤ 1} (volume 1/6) and the
//! quadratic (TET10) shape functions.
use nalgebra::{SMatrix, Vector3};

/// Quadrature rule for the element integrals (stiffness, internal force, energy).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quadrature {
    /// 4 points, exact for degree 2 (the usual rule for TET10, e.g. Abaqus C3D10): exact linear stiffness.
    #[default]
    Degree2,
    /// 14 points, exact for degree 5 (all weights positive).
    Degree5,
}

/// One quadrature point: reference coordinates (ξ, η, ζ) and weight (sum of weights = 1/6).
#[derive(Clone, Copy, Debug)]
pub struct QuadPoint {
    /// Reference coordinates (ξ, η, ζ).
    pub xi: Vector3<f64>,
    /// Weight on the reference tetrahedron (the weights sum to 1/6).
    pub weight: f64,
}

impl Quadrature {
    /// The points and weights.
    pub fn points(self) -> Vec<QuadPoint> {
        let mut out = Vec::new();
        let mut push = |l: [f64; 4], w: f64| out.push(QuadPoint { xi: Vector3::new(l[1], l[2], l[3]), weight: w });
        match self {
            Quadrature::Degree2 => {
                let a = 0.585_410_196_624_968_5;
                let b = 0.138_196_601_125_010_5;
                for i in 0..4 {
                    let mut l = [b; 4];
                    l[i] = a;
                    push(l, 1.0 / 24.0);
                }
            }
            Quadrature::Degree5 => {
                // Walkington / Keast 14-point rule (degree 5, positive weights).
                for (a, w) in [
                    (0.310_885_919_263_300_6, 0.018_781_320_953_002_642),
                    (0.092_735_250_310_891_23, 0.012_248_840_519_393_658),
                ] {
                    let b = 1.0 - 3.0 * a;
                    for i in 0..4 {
                        let mut l = [a; 4];
                        l[i] = b;
                        push(l, w);
                    }
                }
                let a = 0.045_503_704_125_649_65;
                let b = 0.5 - a;
                for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    let mut l = [b; 4];
                    l[i] = a;
                    l[j] = a;
                    push(l, 0.007_091_003_462_846_911);
                }
            }
        }
        out
    }
}

/// TET10 node order (VTK_QUADRATIC_TETRA): vertices 0–3, then mid-edge nodes of the edges
/// (0,1), (1,2), (2,0), (0,3), (1,3), (2,3).
pub const TET10_EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)];

fn barycentric(xi: &Vector3<f64>) -> [f64; 4] {
    [1.0 - xi.x - xi.y - xi.z, xi.x, xi.y, xi.z]
}

const DL: [[f64; 3]; 4] = [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Quadratic shape functions N_a(ξ): vertices L_i (2 L_i − 1), edges 4 L_a L_b.
pub fn tet10_shape(xi: &Vector3<f64>) -> [f64; 10] {
    let l = barycentric(xi);
    let mut n = [0.0; 10];
    for i in 0..4 {
        n[i] = l[i] * (2.0 * l[i] - 1.0);
    }
    for (e, &(a, b)) in TET10_EDGES.iter().enumerate() {
        n[4 + e] = 4.0 * l[a] * l[b];
    }
    n
}

/// Reference gradients ∂N_a/∂ξ (row a).
pub fn tet10_shape_grad(xi: &Vector3<f64>) -> SMatrix<f64, 10, 3> {
    let l = barycentric(xi);
    let mut g = SMatrix::<f64, 10, 3>::zeros();
    for i in 0..4 {
        for c in 0..3 {
            g[(i, c)] = (4.0 * l[i] - 1.0) * DL[i][c];
        }
    }
    for (e, &(a, b)) in TET10_EDGES.iter().enumerate() {
        for c in 0..3 {
            g[(4 + e, c)] = 4.0 * (l[a] * DL[b][c] + l[b] * DL[a][c]);
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fact(n: u32) -> f64 {
        (1..=n).map(f64::from).product()
    }

    #[test]
    fn rules_integrate_monomials_exactly() {
        for (rule, deg) in [(Quadrature::Degree2, 2), (Quadrature::Degree5, 5)] {
            let pts = rule.points();
            for a in 0..=deg {
                for b in 0..=(deg - a) {
                    for c in 0..=(deg - a - b) {
                        let exact = fact(a) * fact(b) * fact(c) / fact(a + b + c + 3);
                        let q: f64 = pts
                            .iter()
                            .map(|p| p.weight * p.xi.x.powi(a as i32) * p.xi.y.powi(b as i32) * p.xi.z.powi(c as i32))
                            .sum();
                        assert!((q - exact).abs() < 1e-14, "{rule:?} x^{a} y^{b} z^{c}: {q} vs {exact}");
                    }
                }
            }
        }
    }

    #[test]
    fn shape_functions_partition_unity_and_gradients_match_fd() {
        let xi = Vector3::new(0.2, 0.15, 0.4);
        let n = tet10_shape(&xi);
        assert!((n.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        let g = tet10_shape_grad(&xi);
        let h = 1e-6;
        for c in 0..3 {
            let (mut p, mut m) = (xi, xi);
            p[c] += h;
            m[c] -= h;
            let (np, nm) = (tet10_shape(&p), tet10_shape(&m));
            for a in 0..10 {
                assert!(((np[a] - nm[a]) / (2.0 * h) - g[(a, c)]).abs() < 1e-8);
            }
        }
        // Kronecker property at the nodes.
        let mut nodes = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        for &(a, b) in &TET10_EDGES {
            nodes.push((nodes[a] + nodes[b]) * 0.5);
        }
        for (i, x) in nodes.iter().enumerate() {
            let n = tet10_shape(x);
            for (a, v) in n.iter().enumerate() {
                assert!((v - if a == i { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
    }
}
