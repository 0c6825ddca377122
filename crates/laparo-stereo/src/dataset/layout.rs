//! Dataset layouts (SceneFlow, Middlebury, generic): discovery of the samples and loading of one.
use super::ferr;
use crate::augment::StereoSample;
use crate::cats_params::{CatsConfig, SourceCamera};
use crate::error::{Result, StereoError};
use laparo_core::{io, CoreError, Image, Intrinsics};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

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
    fn from_str(s: &str) -> std::result::Result<Self, String> {
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
    /// Left image.
    pub left: PathBuf,
    /// Right image.
    pub right: PathBuf,
    /// Left disparity GT, when the layout has one.
    pub disp_left: Option<PathBuf>,
    /// Right disparity GT, when the layout has one.
    pub disp_right: Option<PathBuf>,
    /// Middlebury `calib.txt`.
    pub calib: Option<PathBuf>,
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
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
pub fn discover(root: &Path, layout: Layout) -> Result<Vec<SampleFiles>> {
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
pub fn read_middlebury_calib(path: &Path, width: usize, height: usize) -> Result<(Intrinsics, Intrinsics)> {
    let text = std::fs::read_to_string(path).map_err(|e| CoreError::io(path, e))?;
    let cam = |key: &str| -> Result<Intrinsics> {
        let line = text
            .lines()
            .find_map(|l| l.trim().strip_prefix(key).and_then(|r| r.trim_start().strip_prefix('=')))
            .ok_or_else(|| ferr(path, format!("missing key '{key}'")))?;
        let nums: Vec<f64> = line
            .replace(['[', ']', ';'], " ")
            .split_whitespace()
            .map(|t| t.parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|source| StereoError::FileNumber { path: path.into(), what: format!("'{key}'"), source })?;
        if nums.len() != 9 {
            return Err(ferr(path, format!("'{key}' must have 9 numbers, found {}", nums.len())));
        }
        let m = Matrix3::from_row_slice(&nums);
        Intrinsics::from_matrix(&m, width, height).map_err(|source| StereoError::FileField {
            path: path.into(),
            what: format!("'{key}'"),
            source,
        })
    };
    Ok((cam("cam0")?, cam("cam1")?))
}

/// Read a disparity map (PFM, npy, npz, TIFF) as one-channel f32; non-finite = unknown.
pub fn read_disparity(path: &Path) -> Result<Image<f32>> {
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
pub fn load_sample(f: &SampleFiles) -> Result<StereoSample> {
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
    let disp = |p: &Option<PathBuf>| -> Result<Option<Image<f32>>> {
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
) -> Result<(Intrinsics, Intrinsics)> {
    if let Some(c) = &f.calib {
        return read_middlebury_calib(c, width, height);
    }
    let cam = match (config.camera, layout) {
        (Some(c), _) => c,
        (None, Layout::SceneFlow) => SourceCamera::SCENEFLOW,
        (None, _) => {
            return Err(StereoError::Config(
                "the generic layout needs the source camera: add [camera] fx, fy (and cx, cy) to the config".into(),
            ))
        }
    };
    cam.intrinsics(width, height)
}
