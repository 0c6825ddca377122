//! The scenario's stand-in incision on a 60 × 40 × 20 mm box: grid tetrahedra, a crack across the
//! longest axis, its lips opened by the analytic field of `synthetic_incision` — by exactly
//! 2 × `opening_mm` where the weights are 1 (mid-span, at the surface, on the crack plane).
//! `cargo run -p laparo-guide --example incision`
use laparo_core::mesh::TriMesh;
use laparo_guide::prelude::*;
use nalgebra::Vector3;

pub fn main() -> Result<()> {
    let (lo, hi) = (Vector3::zeros(), Vector3::new(60.0, 40.0, 20.0));
    let corner = |i: usize| Vector3::from_fn(|d, _| if (i >> d) & 1 == 0 { lo[d] } else { hi[d] });
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let faces = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    let surface = TriMesh { vertices: (0..8).map(corner).collect(), faces };
    let grid = grid_tet_mesh(&surface, 2.5)?;
    let spec = default_incision(&lo, &hi); // crack normal x, incision along y, camera above z
    let d = synthetic_incision(&grid, &spec)?;
    let gap = |(&v0, &v1): (&usize, &usize)| (d.deformed[v1] - d.deformed[v0])[spec.normal_axis];
    let gaps: Vec<f64> = d.lips[0].iter().zip(&d.lips[1]).map(gap).collect();
    let widest = gaps.iter().copied().fold(0.0, f64::max);
    println!("{} tets, {} lip node pairs, widest gap {widest:.3} mm", d.rest.tets.len(), gaps.len());
    assert!(gaps.iter().all(|&g| g > 0.0 && g <= widest), "the lips part everywhere: {gaps:?}");
    assert!((widest - 2.0 * spec.opening_mm).abs() < 1e-9, "widest gap {widest} mm");
    Ok(())
}
