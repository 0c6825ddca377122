//! Radar charts (Fig. 3.4) stay readable whatever the CE: a handful of rings scaled to the data,
//! and bars when there are fewer than three perturbations (issue 10).
use laparo_depth::align::Alignment;
use laparo_depth::report::{radar_rings, write_radar, MAX_RINGS};
use laparo_depth::robustness::{ByError, MethodRobustness, PerturbationRobustness};

fn method(ce: &[f64]) -> MethodRobustness {
    let names = ["smoke", "blood", "dirt", "defocus", "bright"];
    MethodRobustness {
        method: "M".into(),
        baseline: "B".into(),
        clean_error: ByError { abs_rel: Some(0.1), one_minus_delta: Some(0.2) },
        n_clean_frames: 4,
        mce: ByError { abs_rel: Some(1.0), one_minus_delta: Some(1.0) },
        mrr: ByError { abs_rel: Some(0.9), one_minus_delta: Some(0.9) },
        cells: Vec::new(),
        perturbations: ce
            .iter()
            .zip(names)
            .map(|(&c, n)| PerturbationRobustness {
                perturbation: n.into(),
                ce: ByError { abs_rel: Some(c), one_minus_delta: Some(c / 2.0) },
                rr: ByError { abs_rel: Some(0.8), one_minus_delta: Some(0.95) },
                by_severity: Vec::new(),
            })
            .collect(),
    }
}

/// Fraction of dark pixels (luminance < 100) of an RGB PNG.
fn dark_fraction(p: &std::path::Path) -> f64 {
    let img = laparo_core::io::read_image(p).unwrap();
    let c = img.channels;
    let dark = img.data.chunks(c).filter(|px| (px[0] as u32 + px[1] as u32 + px[2] as u32) < 300).count();
    dark as f64 / (img.width * img.height) as f64
}

#[test]
fn rings_are_few_and_cover_the_data() {
    for vmax in [0.3, 1.2, 1.7, 3.0, 12.0, 980.0, 5000.0, 2.5e7] {
        let (rings, rmax) = radar_rings(vmax);
        assert!(!rings.is_empty() && rings.len() <= MAX_RINGS, "{vmax}: {rings:?}");
        assert!(rmax >= vmax && rmax <= 2.6 * vmax.max(1.0), "{vmax}: outer ring {rmax}");
        let step = rings[0];
        assert!(rings.windows(2).all(|w| ((w[1] - w[0]) - step).abs() < 1e-9 * step));
    }
    // The default scale of an ordinary chart: 0.25 steps up to 1.5.
    assert_eq!(radar_rings(1.2).0, vec![0.25, 0.5, 0.75, 1.0, 1.25, 1.5]);
    assert_eq!(radar_rings(5000.0).0, vec![1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 6000.0]);
}

#[test]
fn a_huge_ce_does_not_turn_the_radar_into_a_disc() {
    let dir = tempfile::tempdir().unwrap();
    let normal = write_radar(&dir.path().join("n"), &method(&[1.1, 0.9, 1.3, 0.8, 1.0]), Alignment::Scale).unwrap();
    let huge = write_radar(&dir.path().join("h"), &method(&[1.1, 5000.0, 1.3, 0.8, 1.0]), Alignment::Scale).unwrap();
    let (fn_, fh) = (dark_fraction(&normal[0]), dark_fraction(&huge[0]));
    if let Ok(keep) = std::env::var("LAPARO_KEEP_FIGURES") {
        std::fs::copy(&huge[0], std::path::Path::new(&keep).join("radar_huge.png")).unwrap();
        std::fs::copy(&normal[0], std::path::Path::new(&keep).join("radar_normal.png")).unwrap();
        let bars = write_radar(&dir.path().join("b"), &method(&[1.4, 0.7]), Alignment::Scale).unwrap();
        std::fs::copy(&bars[0], std::path::Path::new(&keep).join("radar_bars.png")).unwrap();
    }
    // Thousands of rings (one per 0.25) used to paint most of the panel dark.
    assert!(fh < 0.05 && fh < 2.0 * fn_ + 0.01, "dark fraction {fh} (ordinary chart: {fn_})");
}

#[test]
fn fewer_than_three_perturbations_draw_bars() {
    let dir = tempfile::tempdir().unwrap();
    for n in [1usize, 2] {
        let ce = [1.4, 0.7];
        let files = write_radar(&dir.path().join(format!("b{n}")), &method(&ce[..n]), Alignment::ScaleShift).unwrap();
        let img = laparo_core::io::read_image(&files[0]).unwrap();
        // Bars: a solid red (CE) block of at least 8x40 px somewhere in the first panel.
        let red = |x: usize, y: usize| {
            let p = img.pixel(x, y);
            p[0] > 200 && p[1] < 60 && p[2] < 60
        };
        let mut best = 0;
        for x in 0..img.width / 2 {
            let run = (0..img.height).filter(|&y| red(x, y)).count();
            best = best.max(run);
        }
        assert!(best >= 40, "{n} perturbation(s): no CE bar (longest red column {best} px)");
        let svg = std::fs::read_to_string(&files[1]).unwrap();
        assert!(svg.contains("Smoke"));
    }
}
