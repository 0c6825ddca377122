//! The CPC matching evaluation (issue 11, items 3–5) on the rendered hard pair: CPC raises the
//! number of correct matches, every match judged correct is confirmed by the renderer's own
//! surface coordinates (independent of the depth + pose transfer and of the warp inversion), and
//! bad inputs give errors naming the view.
use laparo_cpc::eval::{self, EvalSettings, View};
use laparo_cpc::scene::{self, PairKind, Texture};
use laparo_features::gt::MatchLabel;

fn texture() -> Texture {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/textures/retina.jpg");
    if !p.exists() {
        eprintln!("SKIP texture: {} absent, using the procedural texture", p.display());
    }
    scene::photo_or_procedural(&p, 1)
}

#[test]
fn cpc_raises_correct_matches_on_the_hard_pair_and_labels_agree_with_surface_coordinates() {
    let p = scene::render_pair(&scene::pair_spec(PairKind::Hard, texture())).unwrap();
    assert!(p.viewpoint_change_deg >= 50.0, "{}", p.viewpoint_change_deg);
    let (v1, v2) = (View::of_scene(&p.view1), View::of_scene(&p.view2));
    let e = eval::evaluate_pair(&v1, &v2, &EvalSettings::default()).unwrap();
    assert_eq!(e.runs.len(), 4);
    for run in &e.runs {
        let r = &run.row;
        eprintln!("{}: {} matches, {} correct", r.label(), r.n_matches, r.n_correct);
        assert_eq!(run.labels.len(), run.matches.len());
        assert_eq!(r.n_correct, run.labels.iter().filter(|l| **l == MatchLabel::Correct).count());
        // Independent check: a correct match joins image points whose rendered surface points
        // (mm, exact per pixel) are close; 3 px at ≈ 100 mm and f = 500 px is ≈ 0.6 mm (more on
        // the oblique view), so allow 3 mm.
        let sxy = |s: &scene::Scene, x: f64, y: f64| -> Option<[f64; 2]> {
            let (u, v) = (x.round() as usize, y.round() as usize);
            let a = s.surface_xy.get(u, v, 0);
            a.is_finite().then(|| [a, s.surface_xy.get(u, v, 1)])
        };
        for (m, l) in run.matches.iter().zip(&run.labels) {
            let (k1, k2) = (run.kp1[m.i1 as usize], run.kp2[m.i2 as usize]);
            assert!(p.view1.roi.get(k1.x.round() as usize, k1.y.round() as usize, 0));
            if *l == MatchLabel::Correct {
                let (a, b) = (sxy(&p.view1, k1.x, k1.y).unwrap(), sxy(&p.view2, k2.x, k2.y).unwrap());
                let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
                assert!(d < 3.0, "{}: correct match {:?} -> {:?} is {d} mm apart on the surface", r.label(), k1, k2);
            }
        }
    }
    // Issue 11 acceptance: on the hard pair CPC raises #correct by ≥ 30 % for SIFT and for ORB.
    for m in ["SIFT+UBCMatcher", "ORB+NN"] {
        let g = e.gain(m).unwrap();
        assert!(g >= 0.3, "{m}: CPC changes #correct by {:+.0} %", 100.0 * g);
    }
    let csv = eval::rows_csv(&e.rows());
    assert_eq!(csv.lines().count(), 5);
    assert!(eval::pair_table(&e.rows()).to_markdown().contains("CPC+SIFT+UBCMatcher"));
}

#[test]
fn nan_depth_inside_the_mask_is_an_error_naming_the_view() {
    let mut spec = scene::bumpy_bowl_spec();
    spec.intrinsics = laparo_core::camera::Intrinsics::new(120.0, 120.0, 80.0, 60.0, 160, 120).unwrap();
    spec.march_step_mm = 0.5;
    let a = spec.render().unwrap();
    let mut b = a.clone();
    let i = b.roi.data.iter().position(|&m| m).unwrap();
    b.depth.data[i] = f64::NAN;
    let e = eval::evaluate_pair(&View::of_scene(&a), &View::of_scene(&b), &EvalSettings::default()).err().unwrap();
    let msg = e.to_string();
    assert!(msg.contains("view 2 depth") && msg.contains("NaN"), "{msg}");
    // A keyframe index out of range names the parameter.
    let e = eval::evaluate_sequence(&[View::of_scene(&a)], 3, &EvalSettings::default()).err().unwrap();
    assert!(e.to_string().contains("keyframe"), "{e}");
}

/// Issue 11's easy-pair line (7.2° viewpoint change, default settings, automatic λ): CPC lowers
/// #correct by at most 5 % for SIFT and for ORB. Before the resolution scale
/// (`ScaleRestore::Resolution`) SIFT lost 5.5 % here (52 vs 55) and passes with it (59 vs 55,
/// retina; see the crate README for the margins).
#[test]
fn cpc_costs_at_most_five_percent_on_the_easy_pair() {
    let p = scene::render_pair(&scene::pair_spec(PairKind::Easy, texture())).unwrap();
    assert!(p.viewpoint_change_deg < 10.0, "{}", p.viewpoint_change_deg);
    let (v1, v2) = (View::of_scene(&p.view1), View::of_scene(&p.view2));
    let e = eval::evaluate_pair(&v1, &v2, &EvalSettings::default()).unwrap();
    for m in ["SIFT+UBCMatcher", "ORB+NN"] {
        let g = e.gain(m).unwrap();
        assert!(g >= -0.05, "{m}: CPC changes #correct by {:+.1} %", 100.0 * g);
    }
}
