//! `laparo depth perturb` (seeded synthetic perturbations, issue 2 item 7) and
//! `laparo depth reproject` (GT preparation of thesis §3.2.6, issue 2 item 6).
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::DepthUnit;
use laparo_depth::manifest::{FrameSpec, Manifest};
use laparo_depth::perturb::{self as pt, Perturbation};
use laparo_depth::reproject::{self as rp, ClampMode, ReprojectParams, TargetCamera};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Arguments of `laparo depth perturb`.
#[derive(Args, Debug, Clone)]
pub struct PerturbArgs {
    /// Clean RGB image (PNG/JPEG/TIFF) or a folder of them (processed in sorted order).
    #[arg(long)]
    pub input: PathBuf,
    /// Output folder: `<out>/<kind>/s<severity>/<stem>.png`, plus perturbations.json (and manifest.toml with --gt).
    #[arg(long)]
    pub out: PathBuf,
    /// Perturbation kinds: smoke, blood, bright, dark, defocus, motion, dirt (or all).
    #[arg(long, value_delimiter = ',', default_value = "smoke,blood,bright,dark,defocus,motion,dirt")]
    pub kinds: Vec<String>,
    /// Severity levels (1..=3).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub severities: Vec<u8>,
    /// Random seed; the output of one image depends only on (seed, image name, kind, severity).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Optional ground-truth depth file or folder (same stems as the inputs) to list in the manifest.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// Unit of the values in the `--gt` files (m or mm).
    #[arg(long, default_value = "mm")]
    pub gt_unit: String,
    /// Scene name used in the manifest (default: the input folder's name).
    #[arg(long)]
    pub scene: Option<String>,
    /// Recompute outputs that already exist. Without it an interrupted run resumes (outputs made
    /// with the same parameters are kept) and a run whose seed or perturbation parameters differ
    /// from those recorded in `<out>/perturb.resume.json` is refused.
    #[arg(long, alias = "overwrite")]
    pub force: bool,
    /// Process only shard I of N (input images whose position in the sorted input list is
    /// I mod N): N processes with 0/N .. N-1/N (same --out, or merged with `rsync -a`) write
    /// exactly the files of one unsharded run.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<laparo_core::shard::Shard>,
}

/// Arguments of `laparo depth reproject`.
#[derive(Args, Debug, Clone)]
pub struct ReprojectArgs {
    /// Depth-sensor depth map (npy/npz/pfm/tif/tiff/png16).
    #[arg(long)]
    pub depth: PathBuf,
    /// Unit of the values in `--depth` (m or mm).
    #[arg(long, default_value = "mm")]
    pub depth_unit: String,
    /// Depth-sensor intrinsics (px): JSON {"fx","fy","cx","cy"} or {"K": 3x3}, numbers or numeric strings, optional "width"/"height" and distortion; ROS camera_info / OpenCV YAML; COLMAP cameras.txt; the size defaults to --depth's; must be distortion-free.
    #[arg(long)]
    pub sensor_intrinsics: PathBuf,
    /// T_DS→L JSON (P_L = R P_DS + t): {"T": 4x4} or {"R": 3x3, "t": [x,y,z]}, optional "unit": "mm"|"m"
    /// for the translation (default given by --extrinsics-unit).
    #[arg(long)]
    pub extrinsics: PathBuf,
    /// Unit of the translation in `--extrinsics` when the file does not state it.
    #[arg(long, default_value = "mm")]
    pub extrinsics_unit: String,
    /// Laparoscope intrinsics (same formats as --sensor-intrinsics), px; its distortion
    /// ("dist": [k1, k2, p1, p2, k3, ...] in OpenCV order, or named k1..k3, p1, p2) is applied:
    /// the output is depth for the distorted image.
    #[arg(long)]
    pub intrinsics: PathBuf,
    /// Output width in px (default: from --intrinsics).
    #[arg(long)]
    pub width: Option<usize>,
    /// Output height in px (default: from --intrinsics).
    #[arg(long)]
    pub height: Option<usize>,
    /// Tool mask in the laparoscope view (PNG/JPEG/TIFF: channel 0 non-zero; npy/npz/PFM/EXR: finite and non-zero): removed from the output.
    #[arg(long)]
    pub tool_mask: Option<PathBuf>,
    /// Lower clamp of the output depth in m (values below become invalid).
    #[arg(long, default_value_t = 0.01, alias = "min-depth-m")]
    pub depth_min_m: f64,
    /// Upper clamp of the output depth in m (values above become invalid).
    #[arg(long, default_value_t = 0.5, alias = "max-depth-m")]
    pub depth_max_m: f64,
    /// Saturate out-of-range depth to the range bounds instead of invalidating it.
    #[arg(long)]
    pub saturate: bool,
    /// Drop sensor triangles whose depth jump (max/min − 1) exceeds this (depth discontinuities).
    #[arg(long, default_value_t = 0.05)]
    pub max_rel_jump: f64,
    /// Unit of the written depth (m or mm).
    #[arg(long, default_value = "mm")]
    pub out_unit: String,
    /// Output depth file (npy/npz/pfm/tif/tiff/png16 by extension).
    #[arg(long)]
    pub out: PathBuf,
}

const RGB_EXT: [&str; 5] = ["png", "jpg", "jpeg", "tif", "tiff"];
const MAP_EXT: [&str; 6] = ["npy", "npz", "pfm", "tif", "tiff", "png"];

fn has_ext(p: &Path, exts: &[&str]) -> bool {
    p.extension().and_then(|e| e.to_str()).is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

fn stem(p: &Path) -> String {
    p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The input images: one file, or the images of a folder in sorted order.
fn list_inputs(input: &Path) -> Result<Vec<PathBuf>> {
    if input.is_file() {
        return Ok(vec![input.to_path_buf()]);
    }
    if !input.is_dir() {
        bail!("--input {}: no such file or folder", input.display());
    }
    let mut v: Vec<PathBuf> = std::fs::read_dir(input)
        .with_context(|| format!("reading folder {}", input.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && has_ext(p, &RGB_EXT))
        .collect();
    v.sort();
    if v.is_empty() {
        bail!("--input {}: no PNG/JPEG/TIFF image in this folder", input.display());
    }
    let mut stems: Vec<String> = v.iter().map(|p| stem(p)).collect();
    stems.sort();
    if let Some(w) = stems.windows(2).find(|w| w[0] == w[1]) {
        bail!("--input {}: two images share the name '{}' (outputs are named by stem)", input.display(), w[0]);
    }
    Ok(v)
}

/// GT file of input `img`: `gt` itself if it is a file, else `<gt>/<stem>.<map ext>`.
fn find_gt(gt: &Path, img: &Path) -> Result<PathBuf> {
    if gt.is_file() {
        return Ok(gt.to_path_buf());
    }
    let s = stem(img);
    for e in MAP_EXT {
        let p = gt.join(format!("{s}.{e}"));
        if p.is_file() {
            return Ok(p);
        }
    }
    bail!("--gt {}: no depth file named '{s}.<npy|npz|pfm|tif|tiff|png>' for input {}", gt.display(), img.display())
}

fn absolute(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// Output file of one (input, kind, severity).
pub fn perturbed_path(out: &Path, kind: Perturbation, severity: u8, stem: &str) -> PathBuf {
    out.join(kind.name()).join(format!("s{severity}")).join(format!("{stem}.png"))
}

/// Resume record of `depth perturb`: one parameter hash per `<kind>/s<severity>` folder.
pub const PERTURB_RESUME_FILE: &str = "perturb.resume.json";

/// Hash of everything an output of (kind, severity) depends on besides the input image.
fn perturb_hash(seed: u64, kind: Perturbation, severity: u8) -> String {
    let v = serde_json::json!({
        "seed": seed,
        "seed_rule": "item_seed(seed, stem, kind) v1",
        "kind": kind.name(),
        "severity": severity,
        "parameters": kind.describe(severity),
    });
    laparo_core::atomic::fnv1a64_hex(v.to_string().as_bytes())
}

/// Check the outputs already in `out` against the parameters of this run and record the
/// parameters of this run. Outputs of a (kind, severity) made with other parameters (or with
/// no record at all) are refused unless `force`, in which case they are redone.
fn check_perturb_resume(out: &Path, seed: u64, kinds: &[Perturbation], sevs: &[u8], force: bool) -> Result<()> {
    let rp = out.join(PERTURB_RESUME_FILE);
    let mut rec: serde_json::Map<String, serde_json::Value> = match std::fs::read_to_string(&rp) {
        Ok(t) => serde_json::from_str::<serde_json::Value>(&t)
            .ok()
            .and_then(|v| v.get("entries").and_then(|e| e.as_object().cloned()))
            .with_context(|| format!("{}: unreadable resume record (delete it and use --force)", rp.display()))?,
        Err(_) => Default::default(),
    };
    let mut stale = Vec::new();
    for &k in kinds {
        for &s in sevs {
            let key = format!("{}/s{s}", k.name());
            let h = perturb_hash(seed, k, s);
            let dir = out.join(k.name()).join(format!("s{s}"));
            let has_outputs = std::fs::read_dir(&dir)
                .is_ok_and(|mut d| d.any(|e| e.is_ok_and(|e| !e.file_name().to_string_lossy().starts_with('.'))));
            let recorded = rec.get(&key).and_then(|v| v.as_str());
            if has_outputs && recorded != Some(h.as_str()) {
                stale.push(key.clone());
            }
            rec.insert(key, serde_json::Value::String(h));
        }
    }
    if !stale.is_empty() && !force {
        bail!(
            "{}: the outputs of {} were made with another seed or other perturbation parameters (or by an \
             older laparo without {PERTURB_RESUME_FILE}); re-run with --force to redo them, or choose another --out",
            out.display(),
            stale.join(", ")
        );
    }
    let v = serde_json::json!({"version": 1, "seed": seed, "entries": rec});
    laparo_core::atomic::write_atomic(&rp, serde_json::to_string_pretty(&v)?.as_bytes())?;
    Ok(())
}

/// Run `laparo depth perturb`.
pub fn perturb(a: PerturbArgs) -> Result<()> {
    let inputs = list_inputs(&a.input)?;
    let mut kinds: Vec<Perturbation> = Vec::new();
    for k in a.kinds.iter().map(|k| k.trim()).filter(|k| !k.is_empty()) {
        if k.eq_ignore_ascii_case("all") {
            kinds.extend(Perturbation::ALL);
        } else {
            kinds.push(k.parse::<Perturbation>().context("--kinds")?);
        }
    }
    kinds.sort();
    kinds.dedup();
    if kinds.is_empty() {
        bail!("--kinds: no perturbation given");
    }
    let mut sevs = a.severities.clone();
    sevs.sort();
    sevs.dedup();
    if sevs.is_empty() || sevs.iter().any(|s| !(1..=3).contains(s)) {
        bail!("--severities {:?}: each must be 1, 2 or 3", a.severities);
    }
    let gt_unit: DepthUnit = a.gt_unit.parse().context("--gt-unit")?;
    let gts: Option<Vec<PathBuf>> = match &a.gt {
        Some(g) => Some(inputs.iter().map(|i| find_gt(g, i)).collect::<Result<_>>()?),
        None => None,
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let shard = a.shard.unwrap_or(laparo_core::shard::Shard::ALL);
    // Concurrent shards may share --out: only an unsharded run removes other processes' temporaries.
    let n_tmp = if shard.count == 1 { laparo_core::atomic::remove_stale_temps(&a.out)? } else { 0 };
    if n_tmp > 0 {
        eprintln!("removed {n_tmp} temporary file(s) left by an interrupted run in {}", a.out.display());
    }
    check_perturb_resume(&a.out, a.seed, &kinds, &sevs, a.force)?;

    let jobs: Vec<(usize, Perturbation)> =
        (0..inputs.len()).filter(|&i| shard.contains(i)).flat_map(|i| kinds.iter().map(move |&k| (i, k))).collect();
    let n_total = jobs.len() * sevs.len();
    let pb = ProgressBar::new(n_total as u64);
    pb.set_style(
        ProgressStyle::with_template("perturb {bar:40} {pos}/{len} images  {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // One job = one (input, kind): read once, write each missing severity atomically.
    let results: Vec<Result<(usize, usize)>> = jobs
        .par_iter()
        .map(|&(i, kind)| -> Result<(usize, usize)> {
            let path = &inputs[i];
            let name = stem(path);
            let todo: Vec<u8> = sevs
                .iter()
                .copied()
                .filter(|&s| a.force || !perturbed_path(&a.out, kind, s, &name).is_file())
                .collect();
            let skipped = sevs.len() - todo.len();
            pb.inc(skipped as u64);
            if todo.is_empty() {
                return Ok((0, skipped));
            }
            let img = laparo_core::io::read_image(path)?;
            let seed = pt::item_seed(a.seed, &name, kind);
            for s in &todo {
                let out = pt::apply(&img, kind, *s, seed).with_context(|| format!("perturbing {}", path.display()))?;
                laparo_core::io::write_png(perturbed_path(&a.out, kind, *s, &name), &out)?;
                pb.inc(1);
            }
            Ok((todo.len(), skipped))
        })
        .collect();
    pb.finish_and_clear();
    let (mut written, mut skipped, mut errors) = (0, 0, Vec::new());
    for r in results {
        match r {
            Ok((w, s)) => {
                written += w;
                skipped += s;
            }
            Err(e) => errors.push(format!("{e:#}")),
        }
    }
    if !errors.is_empty() {
        bail!("{} of {} jobs failed:\n  {}", errors.len(), jobs.len(), errors.join("\n  "));
    }

    // Parameters, for reproducibility.
    let params = serde_json::json!({
        "seed": a.seed,
        "seed_rule": "per (image stem, kind): laparo_depth::perturb::item_seed(seed, stem, kind); same for all severities",
        "kinds": kinds.iter().map(|k| serde_json::json!({
            "kind": k.name(),
            "severities": sevs.iter().map(|&s| serde_json::json!({"severity": s, "parameters": k.describe(s)})).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "inputs": inputs.iter().map(|p| absolute(p).display().to_string()).collect::<Vec<_>>(),
    });
    laparo_core::atomic::write_atomic(
        &a.out.join("perturbations.json"),
        serde_json::to_string_pretty(&params)?.as_bytes(),
    )?;

    let mut manifest_note = String::new();
    if let Some(gts) = gts {
        let scene = a.scene.clone().unwrap_or_else(|| {
            let base = if a.input.is_dir() {
                a.input.clone()
            } else {
                a.input.parent().map(Path::to_path_buf).unwrap_or_default()
            };
            absolute(&base).file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into())
        });
        let m = perturb_manifest(&a.out, &scene, &inputs, &gts, gt_unit, &kinds, &sevs);
        let mp = a.out.join("manifest.toml");
        m.write(&mp)?;
        manifest_note = format!(
            "; manifest {} ({} frames; add [[methods]] with your predictions, then `laparo depth manifest validate`)",
            mp.display(),
            m.frames.len()
        );
    }
    println!(
        "perturb: {written} images written, {skipped} already present (skipped), {} inputs x {} kinds x {} severities -> {}{manifest_note}",
        inputs.len(),
        kinds.len(),
        sevs.len(),
        a.out.display()
    );
    Ok(())
}

/// A manifest listing the clean inputs (perturbation `clean`, severity 0) and every perturbed
/// image, all with the input's GT. Paths of perturbed images are relative to `out`.
pub fn perturb_manifest(
    out: &Path,
    scene: &str,
    inputs: &[PathBuf],
    gts: &[PathBuf],
    gt_unit: DepthUnit,
    kinds: &[Perturbation],
    sevs: &[u8],
) -> Manifest {
    let _ = out;
    let mut frames = Vec::new();
    for (img, gt) in inputs.iter().zip(gts) {
        let name = stem(img);
        let gt = absolute(gt);
        frames.push(FrameSpec {
            id: format!("{scene}/clean/s0/{name}"),
            scene: scene.to_string(),
            perturbation: "clean".into(),
            severity: Some(0),
            sequence: None,
            name: Some(name.clone()),
            rgb: absolute(img),
            gt: gt.clone(),
            mask: None,
            gt_unit: None,
        });
        for k in kinds {
            for &s in sevs {
                frames.push(FrameSpec {
                    id: format!("{scene}/{}/s{s}/{name}", k.name()),
                    scene: scene.to_string(),
                    perturbation: k.name().into(),
                    severity: Some(s as u32),
                    sequence: None,
                    name: Some(name.clone()),
                    rgb: Path::new(k.name()).join(format!("s{s}")).join(format!("{name}.png")),
                    gt: gt.clone(),
                    mask: None,
                    gt_unit: None,
                });
            }
        }
    }
    Manifest {
        version: 1,
        gt_unit,
        depth_min_m: None,
        depth_max_m: None,
        baseline: None,
        error_map_frames: Vec::new(),
        methods: Vec::new(),
        sequences: Vec::new(),
        frames,
        base_dir: out.to_path_buf(),
        source: out.join("manifest.toml"),
    }
}

fn read_json(p: &Path, what: &str) -> Result<serde_json::Value> {
    let t = std::fs::read_to_string(p).with_context(|| format!("{what} {}", p.display()))?;
    serde_json::from_str(&t).with_context(|| format!("{what} {}: invalid JSON", p.display()))
}

/// Run `laparo depth reproject`.
pub fn reproject(a: ReprojectArgs) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![&a.depth, &a.sensor_intrinsics, &a.extrinsics, &a.intrinsics];
    inputs.extend(a.tool_mask.as_deref());
    laparo_core::atomic::refuse_overwrite_files(&[&a.out], &inputs).context("--out")?;
    let depth_unit: DepthUnit = a.depth_unit.parse().context("--depth-unit")?;
    let ext_unit: DepthUnit = a.extrinsics_unit.parse().context("--extrinsics-unit")?;
    let out_unit: DepthUnit = a.out_unit.parse().context("--out-unit")?;
    let sp = a.sensor_intrinsics.display().to_string();
    let lp = a.intrinsics.display().to_string();
    let depth = laparo_core::io::read_depth(&a.depth, depth_unit)?;
    // One camera reader for every command: JSON (numbers or numeric strings, fx..cy or K, optional
    // size and distortion), ROS / OpenCV YAML, COLMAP cameras.txt, EndoVis txt.
    let sensor_cam = laparo_core::io::read_camera(&a.sensor_intrinsics).context("--sensor-intrinsics")?;
    let sensor = sensor_cam
        .intrinsics_undistorted(
            Some((depth.width, depth.height)),
            "the depth-sensor back-projection of depth reproject",
        )
        .with_context(|| format!("--sensor-intrinsics {sp} for --depth {}", a.depth.display()))?;
    let lap_cam = laparo_core::io::read_camera(&a.intrinsics).context("--intrinsics")?;
    let size = match (a.width, a.height) {
        (Some(w), Some(h)) => Some(laparo_core::io::check_image_size(w as u64, h as u64, "--width/--height")?),
        (None, None) => None,
        _ => bail!("give both --width and --height, or neither"),
    };
    // The laparoscope's distortion is applied: the output is depth for the distorted image.
    let lap = match (lap_cam.size, size) {
        (Some(_), Some(s)) => laparo_core::io::CameraFile { size: Some(s), ..lap_cam.clone() }.intrinsics(None),
        _ => lap_cam.intrinsics(size),
    }
    .with_context(|| format!("--intrinsics {lp} (give --width/--height when the file has no size)"))?;
    let distortion = lap_cam.has_distortion().then_some(lap_cam.distortion);
    let ep = a.extrinsics.display().to_string();
    let t = rp::extrinsics_from_json(&read_json(&a.extrinsics, "--extrinsics")?, ext_unit, &ep)?;
    let dm = depth.to_unit(DepthUnit::M);
    let check = laparo_depth::eval::GtRangeCheck::new(
        &dm.data,
        None,
        laparo_depth::align::DepthRange { min_m: a.depth_min_m, max_m: a.depth_max_m },
    );
    for w in check
        .warnings(&format!("--depth {} (--depth-unit {depth_unit})", a.depth.display()), "--depth-min-m/--depth-max-m")
    {
        eprintln!("warning: {w}");
    }
    let mask = match &a.tool_mask {
        Some(p) => {
            let m = laparo_core::io::read_mask(p).context("--tool-mask")?;
            if m.width != lap.width || m.height != lap.height {
                bail!(
                    "--tool-mask {} is {}x{}, the laparoscope image is {}x{}",
                    p.display(),
                    m.width,
                    m.height,
                    lap.width,
                    lap.height
                );
            }
            Some(m)
        }
        None => None,
    };
    let params = ReprojectParams {
        min_depth_m: a.depth_min_m,
        max_depth_m: a.depth_max_m,
        max_rel_jump: a.max_rel_jump,
        clamp: if a.saturate { ClampMode::Saturate } else { ClampMode::Invalidate },
    };
    let target = TargetCamera { intrinsics: lap, distortion };
    let (d, st) = rp::reproject_depth(&depth, &sensor, &t, &target, mask.as_ref(), &params)?;
    if st.valid == 0 {
        bail!(
            "reprojection of {} left no valid pixel ({} sensor pixels valid, {} covered, {} out of range): check units and T_DS->L",
            a.depth.display(),
            st.sensor_valid,
            st.covered,
            st.out_of_range
        );
    }
    laparo_core::io::write_depth(&a.out, &d.to_unit(out_unit))?;
    println!(
        "reproject: {} -> {} ({}x{}, {out_unit}): {} valid px ({:.1}%), {} triangles, {} dropped at discontinuities, {} tool px removed, {} out of [{}, {}] m",
        a.depth.display(),
        a.out.display(),
        lap.width,
        lap.height,
        st.valid,
        100.0 * st.valid as f64 / (lap.width * lap.height) as f64,
        st.triangles,
        st.triangles_dropped_jump,
        st.removed_tool,
        st.out_of_range,
        a.depth_min_m,
        a.depth_max_m
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use laparo_depth::synthetic::organ_scene;

    fn perturb_args(input: &Path, out: &Path, gt: Option<&Path>) -> PerturbArgs {
        PerturbArgs {
            input: input.to_path_buf(),
            out: out.to_path_buf(),
            kinds: vec!["smoke".into(), "lens_dirtiness".into()],
            severities: vec![3, 1],
            seed: 4,
            gt: gt.map(Path::to_path_buf),
            gt_unit: "m".into(),
            scene: Some("organ".into()),
            force: false,
            shard: None,
        }
    }

    #[test]
    fn perturb_writes_resumes_and_emits_a_valid_manifest() {
        let dir = tempfile::tempdir().unwrap();
        let (inp, gt, out) = (dir.path().join("rgb"), dir.path().join("gt"), dir.path().join("bench"));
        for (i, name) in ["a", "b"].iter().enumerate() {
            let sc = organ_scene(64, 48, i as u64).unwrap();
            laparo_core::io::write_png(inp.join(format!("{name}.png")), &sc.rgb).unwrap();
            laparo_core::io::write_depth(gt.join(format!("{name}.npy")), &sc.depth).unwrap();
        }
        perturb(perturb_args(&inp, &out, Some(&gt))).unwrap();
        let p = perturbed_path(&out, Perturbation::LensDirt, 3, "b");
        assert!(p.is_file());
        assert!(!perturbed_path(&out, Perturbation::Smoke, 2, "a").exists());
        // Same output as the library call with the documented seed rule.
        let img = laparo_core::io::read_image(inp.join("b.png")).unwrap();
        let want = pt::apply(&img, Perturbation::LensDirt, 3, pt::item_seed(4, "b", Perturbation::LensDirt)).unwrap();
        assert_eq!(laparo_core::io::read_image(&p).unwrap(), want);
        // Resume: an existing output is not rewritten.
        std::fs::write(&p, b"sentinel").unwrap();
        perturb(perturb_args(&inp, &out, Some(&gt))).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"sentinel");
        let mut a = perturb_args(&inp, &out, Some(&gt));
        a.force = true;
        perturb(a).unwrap();
        assert_eq!(laparo_core::io::read_image(&p).unwrap(), want);
        // Another seed: refused (the outputs were made with seed 4), nothing rewritten; with
        // --force everything is redone with the new seed. A stale temporary is removed.
        let tmp = out.join("smoke/s1/.a.png.4294967295.0.tmp");
        std::fs::write(&tmp, b"half").unwrap();
        let mut a = perturb_args(&inp, &out, Some(&gt));
        a.seed = 5;
        let err = format!("{:#}", perturb(a.clone()).unwrap_err());
        assert!(err.contains("--force") && err.contains("smoke/s1"), "{err}");
        assert!(!tmp.exists(), "stale temporary removed");
        assert_eq!(laparo_core::io::read_image(&p).unwrap(), want);
        a.force = true;
        perturb(a).unwrap();
        let want5 = pt::apply(&img, Perturbation::LensDirt, 3, pt::item_seed(5, "b", Perturbation::LensDirt)).unwrap();
        assert_ne!(want5, want);
        assert_eq!(laparo_core::io::read_image(&p).unwrap(), want5);
        // Adding a kind with the same seed resumes: the existing outputs match their record.
        let mut a = perturb_args(&inp, &out, Some(&gt));
        a.seed = 5;
        a.kinds.push("blood".into());
        perturb(a).unwrap();
        assert!(perturbed_path(&out, Perturbation::Blood, 1, "a").is_file());
        assert_eq!(laparo_core::io::read_image(&p).unwrap(), want5);
        let a = perturb_args(&inp, &out, Some(&gt));
        perturb(a).unwrap_err();
        let mut a = perturb_args(&inp, &out, Some(&gt));
        a.seed = 4;
        a.force = true;
        perturb(a).unwrap();
        // The manifest lists 2 clean + 2 x 2 x 2 perturbed frames and validates except for methods.
        let m = Manifest::read(out.join("manifest.toml")).unwrap();
        assert_eq!(m.frames.len(), 2 + 8);
        let rep = m.validate(None);
        assert_eq!(rep.problems, vec!["no method to evaluate ([[methods]] is empty)".to_string()], "{rep:?}");
        let r = m.resolve().unwrap();
        assert!(r.layout.perturbations.iter().any(|p| p == "clean"));
        assert!(out.join("perturbations.json").is_file());
    }

    #[test]
    fn perturb_rejects_bad_arguments() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("x.png");
        laparo_core::io::write_png(&inp, &organ_scene(32, 24, 0).unwrap().rgb).unwrap();
        let out = dir.path().join("o");
        let mut a = perturb_args(&inp, &out, None);
        a.kinds = vec!["fog".into()];
        assert!(format!("{:#}", perturb(a).unwrap_err()).contains("fog"));
        let mut a = perturb_args(&inp, &out, None);
        a.severities = vec![4];
        assert!(perturb(a).is_err());
        let a = perturb_args(&dir.path().join("missing"), &out, None);
        assert!(format!("{:#}", perturb(a).unwrap_err()).contains("missing"));
        let a = perturb_args(&inp, &out, Some(&dir.path().join("nogt")));
        assert!(perturb(a).is_err());
        assert!(!out.exists(), "no output folder is created for rejected arguments");
    }

    #[test]
    fn reproject_cli_round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // Sensor sees a wall at 150 mm; laparoscope 20 mm closer, same intrinsics.
        let depth = laparo_core::DepthMap::new(40, 30, DepthUnit::Mm, vec![150.0; 1200]).unwrap();
        laparo_core::io::write_depth(d.join("s.npy"), &depth).unwrap();
        std::fs::write(d.join("k.json"), r#"{"fx": 50, "fy": 50, "cx": 19.5, "cy": 14.5, "width": 40, "height": 30}"#)
            .unwrap();
        std::fs::write(d.join("t.json"), r#"{"T": [[1,0,0,0],[0,1,0,0],[0,0,1,-0.02],[0,0,0,1]], "unit": "m"}"#)
            .unwrap();
        let args = |out: &str| ReprojectArgs {
            depth: d.join("s.npy"),
            depth_unit: "mm".into(),
            sensor_intrinsics: d.join("k.json"),
            extrinsics: d.join("t.json"),
            extrinsics_unit: "mm".into(),
            intrinsics: d.join("k.json"),
            width: None,
            height: None,
            tool_mask: None,
            depth_min_m: 0.01,
            depth_max_m: 0.5,
            saturate: false,
            max_rel_jump: 0.05,
            out_unit: "mm".into(),
            out: d.join(out),
        };
        reproject(args("gt.npy")).unwrap();
        let g = laparo_core::io::read_depth(d.join("gt.npy"), DepthUnit::Mm).unwrap();
        assert!(g.data.iter().all(|v| (v - 130.0).abs() < 1e-9), "a closer view of a wall is hole-free");
        // Tool mask of the wrong size names the file; nothing is written.
        laparo_core::io::write_png(d.join("mask.png"), &laparo_core::Image::filled(10, 10, 1, 255u8)).unwrap();
        let mut a = args("bad.npy");
        a.tool_mask = Some(d.join("mask.png"));
        assert!(format!("{:#}", reproject(a).unwrap_err()).contains("mask.png"));
        assert!(!d.join("bad.npy").exists());
        // Depth in the wrong unit: everything out of range -> error, no output.
        let mut a = args("bad.npy");
        a.depth_unit = "m".into();
        assert!(reproject(a).is_err());
        assert!(!d.join("bad.npy").exists());
        std::fs::write(d.join("t.json"), r#"{"R": [[1,0,0],[0,1,0]], "t": [0,0,0]}"#).unwrap();
        assert!(format!("{:#}", reproject(args("bad.npy")).unwrap_err()).contains("t.json"));
    }
}
