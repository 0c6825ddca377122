//! Invariance properties of the alignments (thesis §2.3.3): s-aligned metrics do not change
//! when the prediction is scaled; s&t-aligned metrics do not change under an affine change of
//! the predicted disparity.
use laparo_depth::align::{Alignment, PredKind};
use laparo_depth::metrics::{evaluate_pair, Metrics, PairOptions};
use proptest::prelude::*;

fn close(a: &Metrics, b: &Metrics, tol: f64) -> Result<(), TestCaseError> {
    let (va, vb) = (a.values(), b.values());
    // Compare the 10 metrics (not the fitted scale/shift, which change by design).
    for k in 0..10 {
        prop_assert!((va[k] - vb[k]).abs() <= tol * (1.0 + vb[k].abs()), "metric {k}: {} vs {}", va[k], vb[k]);
    }
    Ok(())
}

/// GT depth in [2 cm, 40 cm] with holes, and a noisy prediction related to it.
fn scene() -> impl Strategy<Value = (Vec<f64>, Vec<f64>)> {
    (8usize..200).prop_flat_map(|n| {
        (
            prop::collection::vec(prop_oneof![9 => 0.02f64..0.4, 1 => Just(0.0)], n),
            prop::collection::vec(0.5f64..1.5, n),
        )
            .prop_filter("some valid GT", |(z, _)| z.iter().filter(|v| **v > 0.0).count() >= 4)
            .prop_map(|(z, noise)| {
                let d: Vec<f64> = z.iter().zip(&noise).map(|(z, e)| if *z > 0.0 { e / z } else { 3.0 }).collect();
                (z, d)
            })
    })
}

fn only(a: Alignment) -> PairOptions {
    PairOptions { alignments: vec![a], ..Default::default() }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn scale_alignment_invariant_to_scaling((z, d) in scene(), k in 1e-3f64..1e3) {
        let o = only(Alignment::Scale);
        let a = evaluate_pair(&d, PredKind::Disparity, &z, None, &o).unwrap().scale.unwrap();
        let dk: Vec<f64> = d.iter().map(|v| v * k).collect();
        let b = evaluate_pair(&dk, PredKind::Disparity, &z, None, &o).unwrap().scale.unwrap();
        close(&b, &a, 1e-9)?;
        prop_assert!((b.scale * k - a.scale).abs() <= 1e-9 * a.scale.abs());
        // A depth prediction 1/d scaled by k is the same disparity scaled by 1/k.
        let zp: Vec<f64> = d.iter().map(|v| k / v).collect();
        let c = evaluate_pair(&zp, PredKind::Depth, &z, None, &o).unwrap().scale.unwrap();
        close(&c, &a, 1e-9)?;
    }

    #[test]
    fn scale_shift_alignment_invariant_to_affine_disparity((z, d) in scene(), s in prop_oneof![-50.0f64..-0.02, 0.02f64..50.0], t in -20.0f64..20.0) {
        let o = only(Alignment::ScaleShift);
        let a = evaluate_pair(&d, PredKind::Disparity, &z, None, &o).unwrap().scale_shift.unwrap();
        let da: Vec<f64> = d.iter().map(|v| s * v + t).collect();
        let b = evaluate_pair(&da, PredKind::Disparity, &z, None, &o).unwrap().scale_shift.unwrap();
        close(&b, &a, 1e-7)?;
    }

    #[test]
    fn perfect_prediction_is_perfect_under_every_alignment((z, _d) in scene(), k in 0.1f64..10.0) {
        // d = k / z: exact up to scale (inside the clamp range [1 cm, 50 cm] by construction).
        let d: Vec<f64> = z.iter().map(|z| if *z > 0.0 { k / z } else { 1.0 }).collect();
        let r = evaluate_pair(&d, PredKind::Disparity, &z, None, &PairOptions::default()).unwrap();
        for m in [r.scale.unwrap(), r.scale_shift.unwrap()] {
            prop_assert!(m.abs_rel < 1e-9 && m.rmse < 1e-9 && m.silog < 1e-4);
            prop_assert_eq!(m.delta_0_25, 1.0);
        }
    }
}
