//! Incisions on a meshed box: lips disconnected except at the crack front, a through-cut splits
//! the box in two, lip curves and landmarks, errors for blades that miss.
use laparo_core::mesh::TetMesh;
use laparo_fem::mesh::shapes::box_surface;
use laparo_fem::mesh::{cut, tetrahedralize_surface, Blade, CutMesh, TetraParams};
use nalgebra::{Rotation3, Vector3};
use std::collections::{BTreeMap, BTreeSet};

type V3 = Vector3<f64>;
const H: f64 = 2.0;

/// Box [0,40]×[0,20]×[0,20] mm meshed at 2 mm.
fn box_mesh() -> TetMesh {
    let s = box_surface(&V3::zeros(), &V3::new(40.0, 20.0, 20.0));
    tetrahedralize_surface(s, "box", &TetraParams { edge_mm: H, ..TetraParams::default() }).unwrap().0
}

/// A blade entering the top face z = 20 along x = 20.3 from y = y0 to y1, going down by `depth`.
fn blade(y0: f64, y1: f64, depth: f64) -> Blade {
    let mouth: Vec<V3> = (0..=20).map(|i| V3::new(20.3, y0 + (y1 - y0) * i as f64 / 20.0, 20.0)).collect();
    Blade::uniform(mouth, -V3::z(), depth, 3.0)
}

fn crack_nodes(c: &CutMesh, s: usize) -> BTreeSet<usize> {
    c.crack_faces[s].iter().flatten().copied().collect()
}

#[test]
fn partial_cut_lips_are_disconnected_except_at_the_front() {
    let m = box_mesh();
    let b = blade(5.0, 15.0, 10.0);
    let c = cut(&m, &b).unwrap();
    // volume unchanged up to the tangential moves of mouth nodes on the top face
    assert!((c.mesh.volume() - m.volume()).abs() < 1e-3 * m.volume());
    assert_eq!(c.mesh.tets.len(), m.tets.len());
    // only crack nodes move (onto the blade plane x = 20.3, by less than a cell)
    let moved: BTreeSet<usize> = (0..c.mesh.vertices.len())
        .filter(|&k| c.mesh.vertices[k] != m.vertices[c.original_node[k]])
        .map(|k| c.original_node[k])
        .collect();
    assert!(!moved.is_empty());
    let crack_orig: BTreeSet<usize> = c.crack_faces.iter().flatten().flatten().map(|&k| c.original_node[k]).collect();
    assert!(moved.is_subset(&crack_orig));
    for (k, &o) in c.original_node.iter().enumerate() {
        let d = c.mesh.vertices[k] - m.vertices[o];
        assert!(d.norm() < H, "node {k} moved by {d:?}");
        if d.norm() > 0.0 {
            assert!((c.mesh.vertices[k].x - 20.3).abs() < (m.vertices[o].x - 20.3).abs(), "moves towards the blade");
        }
    }
    assert!(c.mesh.vertices.len() > m.vertices.len(), "crack nodes were duplicated");
    // one crack face per side per cut pair; the crack covers ≈ 10 × 10 mm²
    assert_eq!(c.crack_faces[0].len(), c.crack_faces[1].len());
    let area = |s: usize| -> f64 {
        c.crack_faces[s]
            .iter()
            .map(|f| {
                (c.mesh.vertices[f[1]] - c.mesh.vertices[f[0]]).cross(&(c.mesh.vertices[f[2]] - c.mesh.vertices[f[0]]))
            })
            .sum::<V3>()
            .norm()
            / 2.0
    };
    // projected (vector) area ≈ blade area inside the box; side A's faces point towards −normal
    let normal = (b.mouth[1] - b.mouth[0]).cross(&b.directions[0]).normalize(); // +x·… side A normal
    let va: V3 = c.crack_faces[0]
        .iter()
        .map(|f| {
            (c.mesh.vertices[f[1]] - c.mesh.vertices[f[0]]).cross(&(c.mesh.vertices[f[2]] - c.mesh.vertices[f[0]]))
        })
        .sum::<V3>()
        / 2.0;
    assert!(va.dot(&normal) < 0.0, "side A crack faces point towards side B");
    assert!((area(0) - 100.0).abs() < 30.0, "projected crack area {} mm² vs 100", area(0));
    assert!((area(1) - area(0)).abs() < 1e-9);
    // Disconnected lips: a tet of side A shares no crack node of side B except front nodes.
    let front: BTreeSet<usize> = c.front_nodes.iter().copied().collect();
    let (na, nb) = (crack_nodes(&c, 0), crack_nodes(&c, 1));
    assert_eq!(na.intersection(&nb).copied().collect::<BTreeSet<_>>(), front);
    for (t, tet) in c.mesh.tets.iter().enumerate() {
        let other = match c.tet_side[t] {
            1 => &nb,
            2 => &na,
            _ => continue,
        };
        for k in tet {
            assert!(
                !other.contains(k) || front.contains(k),
                "tet {t} (side {}) touches the other lip at {k}",
                c.tet_side[t]
            );
        }
    }
    // Front nodes lie near the blade's free edges (bottom z = 10, ends y = 5, 15), not at its middle.
    assert!(!front.is_empty());
    for &k in &front {
        let p = c.mesh.vertices[k];
        let to_edge = (p.z - 10.0).abs().min((p.y - 5.0).abs()).min((p.y - 15.0).abs());
        assert!(to_edge < 1.5 * H, "front node {k} at {p:?}");
    }
    // Crack nodes off the front (the lips' interiors) were duplicated: two copies of one original.
    let mut copies: BTreeMap<usize, usize> = BTreeMap::new();
    for &k in na.union(&nb) {
        *copies.entry(c.original_node[k]).or_default() += 1;
    }
    for (&o, &n) in &copies {
        let is_front = front.iter().any(|&f| c.original_node[f] == o);
        assert_eq!(n, if is_front { 1 } else { 2 }, "original node {o}");
    }
    // The cut mesh is still one piece (the crack is partial).
    let comp = c.components();
    assert!(comp.iter().all(|&x| x == comp[0]));
    // Lips: on the top face near x = 20.3, from y ≈ 5 to 15, same direction as the blade.
    for s in 0..2 {
        let l = c.lip_positions(s, &c.mesh.vertices);
        // on the top face up to the boundary snapping tolerance, on the blade plane mostly
        assert!(l.iter().all(|p| (p.z - 20.0).abs() < 0.5 * H && (p.x - 20.3).abs() < H), "lip {s}: {l:?}");
        // the lip follows lattice faces: a staircase up to √2 longer than the 10 mm mouth
        let len = c.lip_length(s);
        assert!(len > 10.0 - H && len < 10.0 * 1.5 + H, "lip {s} length {len}");
        assert!(l[0].y < l[l.len() - 1].y, "lip {s} runs along the blade");
    }
}

#[test]
fn through_cut_splits_the_box_in_two() {
    let m = box_mesh();
    let c = cut(&m, &blade(-5.0, 25.0, 30.0)).unwrap();
    let comp = c.components();
    let roots: BTreeSet<usize> = comp.iter().copied().collect();
    assert_eq!(roots.len(), 2, "two pieces");
    let mut vol: BTreeMap<usize, (f64, f64)> = BTreeMap::new(); // root -> (volume, mean x · volume)
    for (t, &r) in comp.iter().enumerate() {
        let v = c.mesh.tet_volume(t);
        let cx = c.mesh.tets[t].iter().map(|&k| c.mesh.vertices[k].x).sum::<f64>() / 4.0;
        let e = vol.entry(r).or_default();
        e.0 += v;
        e.1 += v * cx;
    }
    let total = 40.0 * 20.0 * 20.0;
    for (v, mx) in vol.values() {
        let left = mx / v < 20.3;
        let want = if left { 20.3 / 40.0 * total } else { 19.7 / 40.0 * total };
        assert!((v - want).abs() < 0.05 * total, "piece volume {v} vs plane split {want}");
    }
    // No crack front: nothing is shared between the lips.
    assert!(c.front_nodes.is_empty());
}

#[test]
fn landmarks_are_equally_spaced_material_points() {
    let m = box_mesh();
    let c = cut(&m, &blade(5.0, 15.0, 10.0)).unwrap();
    for n in [20, 50, 250] {
        let l = c.landmarks(n).unwrap();
        assert_eq!(l.items.len(), n);
        let x = l.landmark_positions(&c.mesh.vertices);
        for s in 0..2 {
            // arc-length positions along the lip polyline: (k + ½) L / (n/2)
            let lip = c.lip_positions(s, &c.mesh.vertices);
            let len = c.lip_length(s);
            let per = n / 2;
            for k in 0..per {
                let lm = l.items[s * per + k];
                assert_eq!(lm.side as usize, s);
                let ia = c.lips[s].iter().position(|&q| q == lm.a).unwrap();
                assert_eq!(c.lips[s][ia + 1], lm.b);
                let arc: f64 = lip[..=ia].windows(2).map(|w| (w[1] - w[0]).norm()).sum::<f64>()
                    + lm.t * (lip[ia + 1] - lip[ia]).norm();
                let want = (k as f64 + 0.5) * len / per as f64;
                assert!((arc - want).abs() < 1e-9, "landmark {k} of side {s}: arc {arc} vs {want}");
                assert!((x[s * per + k] - (lip[ia] * (1.0 - lm.t) + lip[ia + 1] * lm.t)).norm() < 1e-12);
            }
        }
        // material points: a rigid motion of all nodes moves the landmarks rigidly
        let r = Rotation3::from_euler_angles(0.3, -0.2, 1.1);
        let tr = V3::new(4.0, -7.0, 1.5);
        let moved: Vec<V3> = c.mesh.vertices.iter().map(|p| r * p + tr).collect();
        for (p, q) in x.iter().zip(l.landmark_positions(&moved)) {
            assert!((r * p + tr - q).norm() < 1e-9);
        }
    }
    assert!(c.landmarks(3).is_err() && c.landmarks(0).is_err());
}

#[test]
fn blades_that_miss_or_stay_inside_fail_clearly() {
    let m = box_mesh();
    let away: Vec<V3> = (0..5).map(|i| V3::new(100.0 + i as f64, 50.0, 50.0)).collect();
    let e = cut(&m, &Blade::uniform(away, -V3::z(), 5.0, 1.0)).unwrap_err().to_string();
    assert!(e.contains("misses"), "{e}");
    // entirely inside: no mouth on the outer surface
    let inner: Vec<V3> = (0..=10).map(|i| V3::new(20.3, 6.0 + i as f64, 15.0)).collect();
    let e = cut(&m, &Blade::uniform(inner, -V3::z(), 6.0, 0.0)).unwrap_err().to_string();
    assert!(e.contains("does not reach the outer surface"), "{e}");
    let e = cut(&m, &Blade::uniform(vec![V3::zeros()], -V3::z(), 6.0, 0.0)).unwrap_err().to_string();
    assert!(e.contains("blade"), "{e}");
}
