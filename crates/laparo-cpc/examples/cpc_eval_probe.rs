//! The issue-11 acceptance table in one run: `laparo cpc pair --kind easy|hard` rendered in
//! process, `laparo cpc eval` with the default (automatic λ) settings, and the λ sweep of
//! `--lambda-sweep` (same grid), for one texture:
//! `cargo run --release -p laparo-cpc --example cpc_eval_probe -- [texture.png|procedural] [easy,hard]`.
//! Prints per pair and detector #correct with / without CPC, the change, ℓ of both views, the
//! sweep maximum and the share of it reached at ℓ. `PROBE_SCALE=raw|area` selects another
//! [`laparo_cpc::ScaleRestore`], `PROBE_NO_SWEEP=1` skips the sweep, `PROBE_CURVE=1` prints it.
use laparo_cpc::eval::{evaluate_pair, lambda_match_sweep, EvalSettings, View};
use laparo_cpc::lambda::default_lambda_grid;
use laparo_cpc::scene::{pair_spec, photo_or_procedural, render_pair, PairKind, Texture};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let tex_name = args.get(1).cloned().unwrap_or_else(|| "retina.jpg".into());
    let kinds = args.get(2).cloned().unwrap_or_else(|| "easy,hard".into());
    let sweep = std::env::var_os("PROBE_NO_SWEEP").is_none();
    let texture = |name: &str| -> Texture {
        match name {
            "procedural" => Texture::Procedural { seed: 1 },
            n if n.starts_with("procedural") => Texture::Procedural { seed: n[10..].parse().unwrap_or(1) },
            n => photo_or_procedural(&std::path::Path::new("/work/shared/data/textures").join(n), 1),
        }
    };
    let mut s = EvalSettings::default();
    s.cpc.scale = match std::env::var("PROBE_SCALE").as_deref() {
        Ok("raw") => laparo_cpc::ScaleRestore::Raw,
        Ok("area") => laparo_cpc::ScaleRestore::TotalArea,
        _ => laparo_cpc::ScaleRestore::Resolution,
    };
    let grid: Vec<f64> =
        default_lambda_grid().into_iter().filter(|&l| (l * 20.0).fract() == 0.0 || l >= 0.96).collect();
    for kind in kinds.split(',') {
        let k: PairKind = kind.parse()?;
        let p = render_pair(&pair_spec(k, texture(&tex_name)))?;
        let (v1, v2) = (View::of_scene(&p.view1), View::of_scene(&p.view2));
        let e = evaluate_pair(&v1, &v2, &s)?;
        let ls = if sweep { Some(lambda_match_sweep(&v1, &v2, &s, &grid)?) } else { None };
        for (i, m) in s.methods.iter().enumerate() {
            let get = |cpc: bool| e.runs.iter().find(|r| r.row.method == m.name && r.row.cpc == cpc).unwrap();
            let (a, b) = (get(false), get(true));
            let mut line = format!(
                "{tex_name} {kind} {:<16} kp {:?}/{:?} correct {:>3} / {:>3} ({:+.1} %) ℓ {:.4} {:.4}",
                m.name,
                b.row.n_keypoints,
                a.row.n_keypoints,
                b.row.n_correct,
                a.row.n_correct,
                100.0 * (b.row.n_correct as f64 - a.row.n_correct as f64) / a.row.n_correct.max(1) as f64,
                e.cpc_stats[0].lambda,
                e.cpc_stats[1].lambda,
            );
            if let Some(ls) = &ls {
                let mx = ls.max_correct(i);
                let arg = ls.points.iter().find(|q| q.n_correct[i] == mx).map_or(f64::NAN, |q| q.lambda);
                line.push_str(&format!(
                    " | sweep max {mx} at λ {arg} auto {} ({:.0} %)",
                    ls.n_correct_auto[i],
                    100.0 * ls.n_correct_auto[i] as f64 / mx.max(1) as f64
                ));
                if i == 0 && std::env::var_os("PROBE_CURVE").is_some() {
                    for q in &ls.points {
                        eprintln!(
                            "  λ {:.5} correct {:?} δ {:.3} {:.3}",
                            q.lambda, q.n_correct, q.delta_area[0], q.delta_area[1]
                        );
                    }
                }
            }
            println!("{line}");
        }
        for (v, st) in e.cpc_stats.iter().enumerate() {
            println!(
                "  view {}: λ {:.4} scale {:.3} canvas {}x{} masked {} angle {:.2}→{:.2} warnings {:?}",
                v + 1,
                st.lambda,
                st.scale_restored,
                st.canvas_width,
                st.canvas_height,
                st.n_magnified_masked,
                st.angle_error_deg_before,
                st.angle_error_deg_after,
                st.warnings
            );
        }
    }
    Ok(())
}
