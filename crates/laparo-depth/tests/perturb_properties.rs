//! Properties of the synthetic perturbations on realistic (rendered organ) images and several
//! seeds: strict severity ordering for every kind, output size and channels.
use laparo_depth::perturb::{apply, item_seed, mean_abs_diff, Perturbation};
use laparo_depth::synthetic::organ_scene;

#[test]
fn severity_ordering_holds_across_scenes_and_seeds() {
    for scene_seed in [1u64, 2, 3] {
        let sc = organ_scene(160, 120, scene_seed).unwrap();
        for kind in Perturbation::ALL {
            for base in [0u64, 42] {
                let seed = item_seed(base, &format!("frame{scene_seed}"), kind);
                let d: Vec<f64> =
                    (1..=3).map(|s| mean_abs_diff(&sc.rgb, &apply(&sc.rgb, kind, s, seed).unwrap()).unwrap()).collect();
                assert!(d[0] > 0.0 && d[0] < d[1] && d[1] < d[2], "scene {scene_seed} {kind} seed {base}: {d:?}");
            }
        }
    }
}

#[test]
fn outputs_keep_size_and_are_rgb() {
    let sc = organ_scene(97, 61, 5).unwrap();
    // A gray input is accepted and expanded to RGB.
    let gray = laparo_core::Image {
        width: 97,
        height: 61,
        channels: 1,
        data: sc.rgb.to_gray_f32().data.iter().map(|v| *v as u8).collect(),
    };
    for kind in Perturbation::ALL {
        for img in [&sc.rgb, &gray] {
            let o = apply(img, kind, 2, 1).unwrap();
            assert_eq!((o.width, o.height, o.channels), (97, 61, 3));
        }
    }
}
