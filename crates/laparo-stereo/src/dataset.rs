//! Stereo dataset layouts (SceneFlow, Middlebury, generic), per-sample CATS augmentation with
//! atomic outputs and a JSON sidecar, and parsing of hand-written augmentation parameters.
//!
//! Outputs mirror the input tree: every input file `ROOT/rel` becomes `OUT/rel` (augmented);
//! the sidecar `OUT/<id>.cats.json` (id = left image path without extension) is written last,
//! so a sample is finished iff its sidecar exists. Validity masks (PNG, 255 = valid) and, for
//! the exact rule, the vertical residual (PFM, px) go to `OUT/cats_aux/<id>_*.{png,pfm}`.
//! Unknown disparities are written as +inf (Middlebury's convention; CATS disparities can be
//! negative, so 0 cannot mark them).
use crate::augment::{
    augment_stereo, AugmentError, AugmentedDisparity, CameraAugmentation, GtRule, Mat3Rows, StereoAugmentation,
    StereoSample,
};
use crate::cats_params::{sample_rng, sample_seed, CatsConfig, ConfigError, SourceCamera};
use laparo_core::image::Mask;
use laparo_core::{io, CoreError, Distortion, Image, Intrinsics};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Errors of dataset conversion.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error(transparent)]
    Core(#[from] CoreError),
    #[error(transparent)]
    Augment(#[from] AugmentError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Layout or file problem (the message names the file).
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
}

fn ferr(path: &Path, msg: impl Into<String>) -> DatasetError {
    DatasetError::File { path: path.to_path_buf(), msg: msg.into() }
}

/// Dataset layouts understood by `laparo cats augment`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// `frames_*pass/.../left/NNNN.png`, `.../right/NNNN.png`, `disparity/.../left|right/NNNN.pfm`.
    SceneFlow,
    /// One folder per scene: `im0.png`, `im1.png`, `disp0.pfm` (or `disp0GT.pfm`), optional
    /// `disp1.pfm`, `calib.txt` (cam0, cam1).
    Middlebury,
    /// `left/*.png`, `right/*.png` (same names), optional `disp/<stem>.{pfm,npy,npz,tif,tiff}`
    /// (or `disp_left/`), `disp_right/<stem>.*`; the camera comes from the config's `[camera]`.
    Generic,
}

impl std::str::FromStr for Layout {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "sceneflow" => Ok(Layout::SceneFlow),
            "middlebury" => Ok(Layout::Middlebury),
            "generic" => Ok(Layout::Generic),
            _ => Err(format!("unknown layout '{s}' (sceneflow|middlebury|generic)")),
        }
    }
}

/// The files of one stereo sample (paths absolute or relative to the working directory).
#[derive(Clone, Debug, PartialEq)]
pub struct SampleFiles {
    /// Left image path relative to the root, without extension, `/`-separated.
    pub id: String,
    pub left: PathBuf,
    pub right: PathBuf,
    pub disp_left: Option<PathBuf>,
    pub disp_right: Option<PathBuf>,
    /// Middlebury `calib.txt`.
    pub calib: Option<PathBuf>,
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), DatasetError> {
    let rd = std::fs::read_dir(dir).map_err(|e| CoreError::io(dir, e))?;
    let mut entries: Vec<_> = rd.filter_map(|e| e.ok()).map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            walk(&p, out)?;
        } else {
            out.push(p);
        }
    }
    Ok(())
}

fn is_image(p: &Path) -> bool {
    matches!(io::extension(p).as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff")
}

fn rel_id(root: &Path, p: &Path) -> String {
    let rel = p.strip_prefix(root).unwrap_or(p).with_extension("");
    rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect::<Vec<_>>().join("/")
}

fn existing(p: PathBuf) -> Option<PathBuf> {
    p.is_file().then_some(p)
}

/// Find every sample of `root` in `layout`, sorted by id. Errors when the root is missing or
/// no sample is found, or when a left image has no right partner.
pub fn discover(root: &Path, layout: Layout) -> Result<Vec<SampleFiles>, DatasetError> {
    if !root.is_dir() {
        return Err(ferr(root, "input folder does not exist"));
    }
    let mut files = Vec::new();
    walk(root, &mut files)?;
    let mut out = Vec::new();
    match layout {
        Layout::SceneFlow => {
            for p in &files {
                let rel = p.strip_prefix(root).unwrap_or(p);
                let comps: Vec<String> =
                    rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
                let n = comps.len();
                if !is_image(p) || n < 2 || comps[n - 2] != "left" {
                    continue;
                }
                let Some(fi) = comps.iter().position(|c| c.starts_with("frames_")) else { continue };
                let mut rc = comps.clone();
                rc[n - 2] = "right".into();
                let right = root.join(rc.iter().collect::<PathBuf>());
                if !right.is_file() {
                    return Err(ferr(p, format!("no right image {}", right.display())));
                }
                let disp = |side: &str| {
                    let mut dc = comps.clone();
                    dc[fi] = "disparity".into();
                    dc[n - 2] = side.into();
                    existing(root.join(dc.iter().collect::<PathBuf>()).with_extension("pfm"))
                };
                out.push(SampleFiles {
                    id: rel_id(root, p),
                    left: p.clone(),
                    right,
                    disp_left: disp("left"),
                    disp_right: disp("right"),
                    calib: None,
                });
            }
        }
        Layout::Middlebury => {
            for p in &files {
                if p.file_name().and_then(|n| n.to_str()) != Some("im0.png") {
                    continue;
                }
                let d = p.parent().unwrap_or(root);
                let right = d.join("im1.png");
                if !right.is_file() {
                    return Err(ferr(p, format!("no right image {}", right.display())));
                }
                let calib = d.join("calib.txt");
                if !calib.is_file() {
                    return Err(ferr(&calib, "missing (Middlebury layout needs cam0/cam1 from calib.txt)"));
                }
                out.push(SampleFiles {
                    id: rel_id(root, p),
                    left: p.clone(),
                    right,
                    disp_left: existing(d.join("disp0.pfm")).or_else(|| existing(d.join("disp0GT.pfm"))),
                    disp_right: existing(d.join("disp1.pfm")).or_else(|| existing(d.join("disp1GT.pfm"))),
                    calib: Some(calib),
                });
            }
        }
        Layout::Generic => {
            let ldir = root.join("left");
            if !ldir.is_dir() {
                return Err(ferr(&ldir, "missing (generic layout: left/, right/, optional disp/, disp_right/)"));
            }
            for p in &files {
                if !is_image(p) || p.parent() != Some(ldir.as_path()) {
                    continue;
                }
                let name = p.file_name().expect("file has a name");
                let stem = p.file_stem().expect("file has a stem");
                let right = root.join("right").join(name);
                if !right.is_file() {
                    return Err(ferr(p, format!("no right image {}", right.display())));
                }
                // Disparities in any format `read_disparity` reads (outputs are PFM).
                let pfm = |dir: &str| {
                    ["pfm", "npy", "npz", "tif", "tiff"]
                        .iter()
                        .find_map(|e| existing(root.join(dir).join(stem).with_extension(e)))
                };
                out.push(SampleFiles {
                    id: rel_id(root, p),
                    left: p.clone(),
                    right,
                    disp_left: pfm("disp").or_else(|| pfm("disp_left")),
                    disp_right: pfm("disp_right"),
                    calib: None,
                });
            }
        }
    }
    if out.is_empty() {
        return Err(ferr(root, format!("no stereo samples found for layout {layout:?}")));
    }
    out.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(out)
}

/// Middlebury `calib.txt`: (left K, right K) from `cam0`, `cam1` (the size is the image's).
pub fn read_middlebury_calib(
    path: &Path,
    width: usize,
    height: usize,
) -> Result<(Intrinsics, Intrinsics), DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| CoreError::io(path, e))?;
    let cam = |key: &str| -> Result<Intrinsics, DatasetError> {
        let line = text
            .lines()
            .find_map(|l| l.trim().strip_prefix(key).and_then(|r| r.trim_start().strip_prefix('=')))
            .ok_or_else(|| ferr(path, format!("missing key '{key}'")))?;
        let nums: Vec<f64> = line
            .replace(['[', ']', ';'], " ")
            .split_whitespace()
            .map(|t| t.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| ferr(path, format!("'{key}': {e}")))?;
        if nums.len() != 9 {
            return Err(ferr(path, format!("'{key}' must have 9 numbers, found {}", nums.len())));
        }
        let m = Matrix3::from_row_slice(&nums);
        Intrinsics::from_matrix(&m, width, height).map_err(|e| ferr(path, format!("'{key}': {e}")))
    };
    Ok((cam("cam0")?, cam("cam1")?))
}

/// Read a disparity map (PFM, npy, npz, TIFF) as one-channel f32; non-finite = unknown.
pub fn read_disparity(path: &Path) -> Result<Image<f32>, DatasetError> {
    let d =
        if io::extension(path) == "pfm" { io::read_pfm(path)? } else { io::read_float_map(path)?.map(|v| v as f32) };
    if d.channels != 1 {
        // SceneFlow's disparity PFMs are 1-channel; a 3-channel PFM keeps its first channel only
        // when the others are copies, otherwise it is refused.
        return Err(ferr(path, format!("disparity has {} channels, expected 1", d.channels)));
    }
    Ok(d)
}

/// Read a stereo sample's images and disparities, checking sizes (errors name the files).
pub fn load_sample(f: &SampleFiles) -> Result<StereoSample, DatasetError> {
    let mut left = io::read_image(&f.left)?;
    let mut right = io::read_image(&f.right)?;
    if left.size() != right.size() {
        return Err(ferr(
            &f.right,
            format!(
                "right image is {}x{}, left {} is {}x{}",
                right.width,
                right.height,
                f.left.display(),
                left.width,
                left.height
            ),
        ));
    }
    if left.channels != right.channels {
        left = left.to_rgb();
        right = right.to_rgb();
    }
    let disp = |p: &Option<PathBuf>| -> Result<Option<Image<f32>>, DatasetError> {
        let Some(p) = p else { return Ok(None) };
        let d = read_disparity(p)?;
        if d.size() != left.size() {
            return Err(ferr(
                p,
                format!("disparity is {}x{}, images are {}x{}", d.width, d.height, left.width, left.height),
            ));
        }
        Ok(Some(d))
    };
    Ok(StereoSample {
        disp_left: disp(&f.disp_left)?,
        disp_right: disp(&f.disp_right)?,
        left,
        right,
        occ_left: None,
        occ_right: None,
    })
}

/// Source cameras of a sample: Middlebury calib.txt, else the config's `[camera]`, else
/// SceneFlow's default for the SceneFlow layout; the generic layout requires `[camera]`.
pub fn source_cameras(
    f: &SampleFiles,
    layout: Layout,
    config: &CatsConfig,
    width: usize,
    height: usize,
) -> Result<(Intrinsics, Intrinsics), DatasetError> {
    if let Some(c) = &f.calib {
        return read_middlebury_calib(c, width, height);
    }
    let cam = match (config.camera, layout) {
        (Some(c), _) => c,
        (None, Layout::SceneFlow) => SourceCamera::SCENEFLOW,
        (None, _) => {
            return Err(ConfigError::Invalid(
                "the generic layout needs the source camera: add [camera] fx, fy (and cx, cy) to the config".into(),
            )
            .into())
        }
    };
    Ok(cam.intrinsics(width, height)?)
}

/// Summary numbers of one augmented sample (stored in the sidecar).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SampleStats {
    pub valid_fraction_left: f64,
    pub valid_fraction_right: f64,
    /// Fraction of augmented left pixels with a known disparity.
    pub disparity_valid_fraction: Option<f64>,
    pub disparity_min_px: Option<f64>,
    pub disparity_max_px: Option<f64>,
    /// Exact rule: mean and max |vertical residual| (px).
    pub vertical_residual_mean_abs_px: Option<f64>,
    pub vertical_residual_max_abs_px: Option<f64>,
}

/// The JSON sidecar of an augmented sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    pub laparo_version: String,
    pub sample_id: String,
    pub seed: u64,
    /// The ChaCha8 seed derived from (seed, sample_id).
    pub sample_seed: u64,
    pub gt_rule: GtRule,
    pub config_source: String,
    /// The sampled parameters (re-apply with `laparo cats apply --params`).
    pub params: StereoAugmentation,
    /// H = K_rel K R K⁻¹ of each camera, row-major.
    pub homography_left: Mat3Rows,
    pub homography_right: Mat3Rows,
    pub stats: SampleStats,
    /// [`run_params_hash`] of the run that wrote this sample (resume check); empty in sidecars
    /// of older versions.
    #[serde(default)]
    pub params_hash: String,
}

/// Hash of everything an augmented sample depends on besides its input files: seed, GT rule,
/// layout and the CATS configuration (its TOML form). Stored in each sidecar.
pub fn run_params_hash(config: &CatsConfig, seed: u64, rule: GtRule, layout: Layout) -> String {
    let text = format!("v1;seed={seed};gt_rule={rule:?};layout={layout:?};config={}", config.to_toml_string());
    laparo_core::atomic::fnv1a64_hex(text.as_bytes())
}

/// Resume state of one sample of an output folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResumeState {
    /// Not (completely) written yet.
    Todo,
    /// Complete, written with the same parameters.
    Done,
    /// Complete, but written with other parameters (or by a version without a parameter hash).
    Stale,
}

/// [`is_done`], distinguishing outputs written with other parameters (`hash` from
/// [`run_params_hash`]).
pub fn resume_state(f: &SampleFiles, root: &Path, out: &Path, hash: &str) -> ResumeState {
    if !is_done(f, root, out) {
        return ResumeState::Todo;
    }
    let o = output_paths(f, root, out);
    let same = std::fs::read_to_string(&o.sidecar)
        .ok()
        .and_then(|t| serde_json::from_str::<Sidecar>(&t).ok())
        .is_some_and(|sc| sc.params_hash == hash);
    if same {
        ResumeState::Done
    } else {
        ResumeState::Stale
    }
}

fn rows(m: &Matrix3<f64>) -> Mat3Rows {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

fn mask_png(m: &Mask) -> Image<u8> {
    m.map(|b| if b { 255 } else { 0 })
}

fn disp_stats(d: &AugmentedDisparity, st: &mut SampleStats) {
    let n = d.valid.data.len().max(1);
    let vals: Vec<f64> =
        d.disparity.data.iter().zip(&d.valid.data).filter(|(_, &v)| v).map(|(&x, _)| x as f64).collect();
    st.disparity_valid_fraction = Some(vals.len() as f64 / n as f64);
    st.disparity_min_px = vals.iter().cloned().reduce(f64::min);
    st.disparity_max_px = vals.iter().cloned().reduce(f64::max);
    if let Some(r) = &d.vertical_residual {
        let a: Vec<f64> = r.data.iter().filter(|v| v.is_finite()).map(|v| v.abs() as f64).collect();
        if !a.is_empty() {
            st.vertical_residual_mean_abs_px = Some(a.iter().sum::<f64>() / a.len() as f64);
            st.vertical_residual_max_abs_px = a.iter().cloned().reduce(f64::max);
        }
    }
}

/// Output locations of one sample.
pub struct OutputPaths {
    pub left: PathBuf,
    pub right: PathBuf,
    pub disp_left: Option<PathBuf>,
    pub disp_right: Option<PathBuf>,
    pub sidecar: PathBuf,
    pub aux_dir: PathBuf,
}

/// Where the outputs of sample `f` (from `root`) go under `out`.
pub fn output_paths(f: &SampleFiles, root: &Path, out: &Path) -> OutputPaths {
    let m = |p: &Path| out.join(p.strip_prefix(root).unwrap_or(p));
    let png = |p: &Path| m(p).with_extension("png");
    OutputPaths {
        left: png(&f.left),
        right: png(&f.right),
        disp_left: f.disp_left.as_ref().map(|p| m(p).with_extension("pfm")),
        disp_right: f.disp_right.as_ref().map(|p| m(p).with_extension("pfm")),
        sidecar: out.join(format!("{}.cats.json", f.id)),
        aux_dir: out.join("cats_aux"),
    }
}

/// True when sample `f` already has a readable sidecar and all its outputs (resumability).
pub fn is_done(f: &SampleFiles, root: &Path, out: &Path) -> bool {
    let o = output_paths(f, root, out);
    let Ok(text) = std::fs::read_to_string(&o.sidecar) else { return false };
    serde_json::from_str::<Sidecar>(&text).is_ok()
        && o.left.is_file()
        && o.right.is_file()
        && o.disp_left.as_ref().is_none_or(|p| p.is_file())
        && o.disp_right.as_ref().is_none_or(|p| p.is_file())
}

/// Write an augmented sample (images, disparities, masks) and, last, its sidecar; atomic writes.
pub fn write_augmented(
    f: &SampleFiles,
    root: &Path,
    out: &Path,
    a: &crate::augment::AugmentedStereo,
    mut sidecar: Sidecar,
) -> Result<Sidecar, DatasetError> {
    let o = output_paths(f, root, out);
    io::write_png(&o.left, &a.left.image)?;
    io::write_png(&o.right, &a.right.image)?;
    let aux = |suffix: &str| o.aux_dir.join(format!("{}_{suffix}", f.id));
    io::write_png(aux("valid_left.png"), &mask_png(&a.left.valid))?;
    io::write_png(aux("valid_right.png"), &mask_png(&a.right.valid))?;
    let mut st = SampleStats {
        valid_fraction_left: a.left.valid.count() as f64 / a.left.valid.data.len().max(1) as f64,
        valid_fraction_right: a.right.valid.count() as f64 / a.right.valid.data.len().max(1) as f64,
        ..Default::default()
    };
    for (d, p, side) in [(&a.disp_left, &o.disp_left, "left"), (&a.disp_right, &o.disp_right, "right")] {
        if let (Some(d), Some(p)) = (d, p) {
            io::write_pfm(p, &d.disparity)?;
            if let Some(r) = &d.vertical_residual {
                io::write_pfm(aux(&format!("vres_{side}.pfm")), r)?;
            }
            if side == "left" {
                disp_stats(d, &mut st);
            }
        }
    }
    sidecar.stats = st;
    let text = serde_json::to_string_pretty(&sidecar).expect("sidecar serialises");
    laparo_core::atomic::write_atomic(&o.sidecar, text.as_bytes())?;
    Ok(sidecar)
}

/// Augment one sample of a dataset with parameters drawn from `config` (seeded by
/// (`seed`, sample id)) and write it. Returns the sidecar.
pub fn augment_sample(
    f: &SampleFiles,
    root: &Path,
    out: &Path,
    layout: Layout,
    config: &CatsConfig,
    seed: u64,
    rule: GtRule,
) -> Result<Sidecar, DatasetError> {
    let s = load_sample(f)?;
    let (kl, kr) = source_cameras(f, layout, config, s.left.width, s.left.height)?;
    let mut rng = sample_rng(seed, &f.id);
    let p = config.sample(&mut rng, &kl, &Distortion::default(), &kr, &Distortion::default());
    check_homographies(&p).map_err(|e| ferr(&f.left, format!("sampled parameters: {e}")))?;
    let a = augment_stereo(&s, &p, rule)?;
    let sidecar = Sidecar {
        laparo_version: env!("CARGO_PKG_VERSION").into(),
        sample_id: f.id.clone(),
        seed,
        sample_seed: sample_seed(seed, &f.id),
        gt_rule: rule,
        config_source: config.source.clone(),
        homography_left: rows(&p.left.homography()),
        homography_right: rows(&p.right.homography()),
        params: p,
        stats: SampleStats::default(),
        params_hash: run_params_hash(config, seed, rule, layout),
    };
    write_augmented(f, root, out, &a, sidecar)
}

// ---------------------------------------------------------------------------------------------
// Hand-written parameters (`laparo cats apply --params`).

#[derive(Deserialize)]
struct KObj {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    skew: f64,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum KInput {
    Obj(KObj),
    Rows(Mat3Rows),
}

#[derive(Deserialize)]
#[serde(untagged)]
enum DistInput {
    Coeffs(Vec<f64>),
    Obj(Distortion),
}

#[derive(Deserialize, Default)]
struct CameraInput {
    k: Option<KInput>,
    distortion: Option<DistInput>,
    euler_deg: Option<[f64; 3]>,
    rotation: Option<Mat3Rows>,
    k_rel: Option<Mat3Rows>,
    distortion_out: Option<DistInput>,
}

#[derive(Deserialize)]
struct ParamsInput {
    k: Option<KInput>,
    #[serde(default)]
    left: Option<CameraInput>,
    #[serde(default)]
    right: Option<CameraInput>,
    dx_right_px: Option<f64>,
}

fn k_of(k: &KInput, w: usize, h: usize, what: &str) -> Result<Intrinsics, ConfigError> {
    let m = match k {
        KInput::Obj(o) => Matrix3::new(o.fx, o.skew, o.cx, 0.0, o.fy, o.cy, 0.0, 0.0, 1.0),
        KInput::Rows(r) => Matrix3::from_row_slice(&r.concat()),
    };
    Intrinsics::from_matrix(&m, w, h).map_err(|e| ConfigError::Invalid(format!("{what}: {e}")))
}

fn dist_of(d: &Option<DistInput>, what: &str) -> Result<Distortion, ConfigError> {
    match d {
        None => Ok(Distortion::default()),
        Some(DistInput::Obj(o)) => Ok(*o),
        Some(DistInput::Coeffs(c)) => {
            Distortion::from_opencv(c).map_err(|e| ConfigError::Invalid(format!("{what}: {e}")))
        }
    }
}

/// Parse augmentation parameters from JSON: a sidecar of `cats augment` (its `params`), or a
/// hand-written object `{ "k": K (3×3 rows or {fx, fy, cx, cy}), "left": {...}, "right": {...},
/// "dx_right_px": Δx }` where each camera may give `k`, `euler_deg` `[x, y, z]` or `rotation`
/// (3×3 rows), `k_rel` (3×3 rows), `distortion` / `distortion_out` (OpenCV vector or object).
/// Missing rotation = identity; missing K_rel = identity (left) or [[1, 0, t_L − Δx], ...] (right);
/// missing Δx_right = t_L − t_R. `width`, `height` are the images'.
pub fn parse_params(text: &str, width: usize, height: usize) -> Result<StereoAugmentation, ConfigError> {
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| ConfigError::Invalid(format!("parameters are not valid JSON: {e}")))?;
    let v = v.get("params").cloned().unwrap_or(v);
    let p: ParamsInput = serde_json::from_value(v).map_err(|e| ConfigError::Invalid(format!("parameters: {e}")))?;
    let left = p.left.unwrap_or_default();
    let right = p.right.unwrap_or_default();
    /// K, input distortion, rotation R, optional K_rel, output distortion of one camera.
    type CameraParams = (Intrinsics, Distortion, Matrix3<f64>, Option<Matrix3<f64>>, Distortion);
    let cam = |c: &CameraInput, side: &str| -> Result<CameraParams, ConfigError> {
        let k = c.k.as_ref().or(p.k.as_ref()).ok_or_else(|| {
            ConfigError::Invalid(format!(
                "parameters: no intrinsics for the {side} camera (give \"k\" or \"{side}.k\")"
            ))
        })?;
        let k = k_of(k, width, height, &format!("{side}.k"))?;
        let r = match (&c.rotation, &c.euler_deg) {
            (Some(r), _) => Matrix3::from_row_slice(&r.concat()),
            (None, Some(e)) => laparo_core::se3::rotation_zyx(e[0].to_radians(), e[1].to_radians(), e[2].to_radians()),
            (None, None) => Matrix3::identity(),
        };
        let kr = c.k_rel.map(|r| Matrix3::from_row_slice(&r.concat()));
        Ok((
            k,
            dist_of(&c.distortion, &format!("{side}.distortion"))?,
            r,
            kr,
            dist_of(&c.distortion_out, &format!("{side}.distortion_out"))?,
        ))
    };
    let (kl, dl, rl, krl, dol) = cam(&left, "left")?;
    let (kr_, dr, rr, krr, dor) = cam(&right, "right")?;
    let krl = krl.unwrap_or_else(Matrix3::identity);
    let t_l = krl[(0, 2)];
    let (krr, dx) = match (krr, p.dx_right_px) {
        (Some(m), Some(dx)) => {
            let pure = m[(0, 0)] == 1.0 && krl[(0, 0)] == 1.0;
            if pure && (t_l - m[(0, 2)] - dx).abs() > 1e-6 {
                return Err(ConfigError::Invalid(format!(
                    "dx_right_px = {dx} disagrees with K_rel: t_x,left − t_x,right = {} (Δx_right is added to disparities, \
                     so the right principal point moves by −Δx_right)",
                    t_l - m[(0, 2)]
                )));
            }
            (m, dx)
        }
        (Some(m), None) => (m, t_l - m[(0, 2)]),
        (None, dx) => {
            let dx = dx.unwrap_or(0.0);
            (Matrix3::new(1.0, 0.0, t_l - dx, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), dx)
        }
    };
    let a = StereoAugmentation {
        left: CameraAugmentation::from_rotation(kl, dl, rl, krl, dol),
        right: CameraAugmentation::from_rotation(kr_, dr, rr, krr, dor),
        dx_right_px: dx,
    };
    a.validate().map_err(|e| ConfigError::Invalid(format!("parameters: {e}")))?;
    check_homographies(&a).map_err(|e| ConfigError::Invalid(format!("parameters: {e}")))?;
    Ok(a)
}

/// Check that both cameras' K are numerically invertible and that the homographies
/// H = K_rel K R K⁻¹ (eq. 3.6) and their inverses are finite and non-singular. A tiny or huge
/// focal length passes [`Intrinsics::validate`] but makes K⁻¹ overflow or K singular in f64.
pub fn check_homographies(a: &StereoAugmentation) -> Result<(), String> {
    for (side, c) in [("left", &a.left), ("right", &a.right)] {
        let k = c.k.matrix();
        let ki = k.try_inverse().filter(|m| m.iter().all(|v| v.is_finite()));
        if ki.is_none() || k.determinant().abs() < 1e-12 {
            return Err(format!(
                "{side}.k (fx = {}, fy = {}) is not numerically invertible; focal lengths are in px",
                c.k.fx, c.k.fy
            ));
        }
        let h = c.homography();
        let hi = c.homography_inverse().map_err(|e| format!("{side}: {e}"))?;
        let det = h.determinant();
        if h.iter().chain(hi.iter()).any(|v| !v.is_finite()) || !det.is_finite() || det == 0.0 {
            return Err(format!("{side}: the homography H = K_rel K R K⁻¹ is not finite and invertible: {h:?}"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_hand_written_params() {
        let t = r#"{"k": [[500, 0, 320], [0, 500, 240], [0, 0, 1]],
                    "left": {"euler_deg": [0.0, 0.1, 0.2]},
                    "right": {"rotation": [[1,0,0],[0,1,0],[0,0,1]]},
                    "dx_right_px": -40}"#;
        let p = parse_params(t, 640, 480).unwrap();
        assert_eq!(p.right.k_rel[0][2], 40.0);
        assert_eq!(p.dx_right_px, -40.0);
        assert!((p.left.euler_deg[2] - 0.2).abs() < 1e-12);
        let bad = t.replace("[[1,0,0],[0,1,0],[0,0,1]]", "[[1,0,0],[0,2,0],[0,0,1]]");
        let e = parse_params(&bad, 640, 480).unwrap_err().to_string();
        assert!(e.contains("right.rotation"), "{e}");
        let nok = parse_params(r#"{"left": {}}"#, 640, 480).unwrap_err().to_string();
        assert!(nok.contains("no intrinsics"), "{nok}");
        let inc = r#"{"k": {"fx": 500, "fy": 500, "cx": 320, "cy": 240},
                     "right": {"k_rel": [[1,0,-40],[0,1,0],[0,0,1]]}, "dx_right_px": -40}"#;
        assert!(parse_params(inc, 640, 480).unwrap_err().to_string().contains("disagrees"));
    }

    #[test]
    fn middlebury_calib_parsing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("calib.txt");
        std::fs::write(&p, "cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\ncam1=[3979.911 0 1369.115; 0 3979.911 1019.507; 0 0 1]\ndoffs=124.343\n").unwrap();
        let (l, r) = read_middlebury_calib(&p, 2964, 2000).unwrap();
        assert_eq!(l.cx, 1244.772);
        assert!((r.cx - l.cx - 124.343).abs() < 1e-9);
        std::fs::write(&p, "cam0=[1 0 0; 0 1 0]\n").unwrap();
        let e = read_middlebury_calib(&p, 10, 10).unwrap_err().to_string();
        assert!(e.contains("calib.txt") && e.contains("cam0"), "{e}");
    }

    #[test]
    fn discover_layouts() {
        let dir = tempfile::tempdir().unwrap();
        let r = dir.path();
        let touch = |p: &str| {
            let p = r.join(p);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        };
        for f in [
            "frames_cleanpass/TRAIN/A/0000/left/0006.png",
            "frames_cleanpass/TRAIN/A/0000/right/0006.png",
            "disparity/TRAIN/A/0000/left/0006.pfm",
            "frames_cleanpass/TRAIN/A/0000/left/0007.png",
            "frames_cleanpass/TRAIN/A/0000/right/0007.png",
        ] {
            touch(f);
        }
        let s = discover(r, Layout::SceneFlow).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].id, "frames_cleanpass/TRAIN/A/0000/left/0006");
        assert_eq!(s[0].disp_left.as_deref(), Some(r.join("disparity/TRAIN/A/0000/left/0006.pfm").as_path()));
        assert!(s[0].disp_right.is_none() && s[1].disp_left.is_none());
        let o = output_paths(&s[0], r, Path::new("/out"));
        assert_eq!(o.disp_left.unwrap(), Path::new("/out/disparity/TRAIN/A/0000/left/0006.pfm"));
        assert_eq!(o.sidecar, Path::new("/out/frames_cleanpass/TRAIN/A/0000/left/0006.cats.json"));
        // A left image without its right partner is an error naming the file.
        touch("frames_cleanpass/TRAIN/A/0000/left/0008.png");
        let e = discover(r, Layout::SceneFlow).unwrap_err().to_string();
        assert!(e.contains("0008.png") && e.contains("right"), "{e}");

        let m = tempfile::tempdir().unwrap();
        for f in ["Piano/im0.png", "Piano/im1.png", "Piano/disp0GT.pfm", "Piano/calib.txt"] {
            let p = m.path().join(f);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        }
        let s = discover(m.path(), Layout::Middlebury).unwrap();
        assert_eq!((s.len(), s[0].id.as_str()), (1, "Piano/im0"));
        assert!(s[0].disp_left.as_ref().unwrap().ends_with("disp0GT.pfm") && s[0].calib.is_some());
        assert!(discover(m.path(), Layout::Generic).unwrap_err().to_string().contains("left"));
    }
}
