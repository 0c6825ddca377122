//! The RoDEM dataset manifest: scenes, perturbations, severities, frames (RGB, GT depth and
//! unit, optional ROI mask) and per-method prediction files (thesis §3.2.6–3.2.7, Table 3.2).
//!
//! A manifest is TOML (`.toml`) or JSON (`.json`); paths are relative to the manifest's folder.
//!
//! ```toml
//! version = 1
//! gt_unit = "mm"                 # unit of the GT depth files: "m" or "mm"
//! depth_min_m = 0.01             # optional clamp range of aligned depth (default 1 cm – 50 cm)
//! depth_max_m = 0.5
//! baseline = "AF-SfM"            # optional default baseline of mCE (eq. 3.3)
//! error_map_frames = ["liver/dark/s1/000012"]   # optional: frames drawn as error maps (Fig. C.1)
//!
//! [[methods]]
//! name = "DA2"
//! kind = "disparity"             # "disparity" (any scale/shift) or "depth" (any scale)
//! predictions = "predictions/DA2/{id}.npy"   # {id} {scene} {perturbation} {severity} {name}
//!
//! [[sequences]]                  # deformation / incision sequences (optional)
//! scene = "liver"
//! perturbation = "deformation"
//! name = "seq01"
//! gesture_start = "000120"       # first frame (by name) at or after the gesture; earlier = clean
//!
//! [[frames]]
//! id = "liver/smoke/s1/000123"   # unique; default key of the prediction files
//! scene = "liver"
//! perturbation = "smoke"
//! severity = 1                   # 0 = clean reference of this (scene, perturbation)
//! rgb = "liver/smoke/s1/rgb/000123.png"
//! gt = "liver/smoke/s1/depth/000123.png"
//! mask = "liver/smoke/s1/mask/000123.png"    # optional ROI (non-zero = evaluated)
//! # gt_unit = "m"                # optional per-frame override
//! # sequence = "seq01"           # instead of severity: member of a [[sequences]] entry
//! # name = "000123"              # frame name (default: last component of id)
//! ```
//!
//! Perturbation names are free; [`DEFAULT_PERTURBATIONS`] (the nine of the thesis) only sets
//! the display order and titles. A perturbation called `clean` is a scene-level clean set used
//! when a (scene, perturbation) cell has no severity-0 frames.
//!
//! Folder layout understood by [`scaffold`]:
//! `<root>/<scene>/<perturbation>/<level>/{rgb,depth,mask}/<name>.<ext>` and
//! `<root>/predictions/<method>/<scene>/<perturbation>/<level>/<name>.<ext>`, where `<level>`
//! is `s0`/`clean`/`0` (severity 0), `s<k>` or `<k>` (severity k), or any other name (a
//! sequence; an optional `<level>/gesture_start.txt` holds the first perturbed frame name).
//!
//! Length (~650 lines): ~50 lines of format documentation above, the manifest types, their
//! resolution/validation and the scaffolding from a folder layout, which must produce exactly what
//! the validation accepts.
use crate::align::{DepthRange, PredKind};
use crate::error::{DepthError, Result};
use crate::robustness::{Layout, CLEAN};
use laparo_core::DepthUnit;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// The thesis' nine perturbations (Table 3.2) as (key, title): the default vocabulary.
pub const DEFAULT_PERTURBATIONS: [(&str, &str); 9] = [
    ("smoke", "Smoke"),
    ("blood", "Blood"),
    ("dirt", "Lens Dirtiness"),
    ("defocus", "Defocus Blur"),
    ("bright", "Light (Bright)"),
    ("dark", "Light (Dark)"),
    ("motion", "Motion Blur"),
    ("deformation", "Deformation"),
    ("incision", "Incision"),
];

/// Display title of a perturbation key (the key itself when not in the vocabulary).
pub fn perturbation_title(key: &str) -> String {
    DEFAULT_PERTURBATIONS.iter().find(|(k, _)| *k == key).map(|(_, t)| t.to_string()).unwrap_or_else(|| key.to_string())
}

/// A benchmarked method.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodSpec {
    /// Method name (column / legend label).
    pub name: String,
    /// Whether predictions are depth or disparity.
    pub kind: PredKind,
    /// Path template of a frame's prediction, relative to the manifest folder.
    pub predictions: String,
}

/// A deformation/incision sequence: frames before `gesture_start` are the clean reference.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SequenceSpec {
    /// Scene the sequence belongs to.
    pub scene: String,
    /// Perturbation (gesture) the sequence shows.
    pub perturbation: String,
    /// Sequence name.
    pub name: String,
    /// Name of the first frame at or after the gesture (frames are ordered by name).
    #[serde(default)]
    pub gesture_start: String,
}

/// One image with its ground truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameSpec {
    /// Unique frame id.
    pub id: String,
    /// Scene name.
    pub scene: String,
    /// Perturbation name (`clean` for unperturbed frames).
    pub perturbation: String,
    /// Severity level 1..L (0 = clean); assigned for sequence frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub severity: Option<u32>,
    /// Sequence this frame belongs to, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence: Option<String>,
    /// Frame name (default: last `/` component of the id).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// RGB image, relative to the manifest folder.
    pub rgb: PathBuf,
    /// Ground-truth depth, relative to the manifest folder.
    pub gt: PathBuf,
    /// ROI mask, relative to the manifest folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<PathBuf>,
    /// Unit of this frame's GT (default: the manifest's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gt_unit: Option<DepthUnit>,
}

impl FrameSpec {
    /// Frame name (default: last `/` component of the id).
    pub fn frame_name(&self) -> &str {
        self.name.as_deref().unwrap_or_else(|| self.id.rsplit('/').next().unwrap_or(&self.id))
    }
}

fn default_version() -> u32 {
    1
}

/// A RoDEM evaluation manifest (see the module documentation for the format).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Manifest format version (1).
    #[serde(default = "default_version")]
    pub version: u32,
    /// Unit of the GT depth files.
    pub gt_unit: DepthUnit,
    /// Near clamp of aligned depth (m; default 0.01).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_min_m: Option<f64>,
    /// Far clamp of aligned depth (m; default 0.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_max_m: Option<f64>,
    /// Baseline method of mCE (default: the first method).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline: Option<String>,
    /// Frames (ids) drawn as colour error maps.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub error_map_frames: Vec<String>,
    /// The benchmarked methods.
    #[serde(default)]
    pub methods: Vec<MethodSpec>,
    /// Deformation/incision sequences.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sequences: Vec<SequenceSpec>,
    /// The frames with their ground truth.
    #[serde(default)]
    pub frames: Vec<FrameSpec>,
    /// Folder the relative paths are resolved against (the manifest's folder).
    #[serde(skip)]
    pub base_dir: PathBuf,
    /// Where the manifest was read from (for messages).
    #[serde(skip)]
    pub source: PathBuf,
}

/// A frame with its indices and resolved paths.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolvedFrame {
    /// Position in the manifest.
    pub index: usize,
    /// Unique frame id.
    pub id: String,
    /// Scene index into the layout.
    pub scene: usize,
    /// Perturbation index into the layout.
    pub perturbation: usize,
    /// Severity (0 = clean).
    pub severity: u32,
    /// RGB image (resolved path).
    pub rgb: PathBuf,
    /// Ground-truth depth (resolved path).
    pub gt: PathBuf,
    /// ROI mask (resolved path), if any.
    pub mask: Option<PathBuf>,
    /// Unit of the GT file.
    pub gt_unit: DepthUnit,
}

/// The manifest with names turned into indices and severities of sequence frames assigned.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    /// Names of scenes and perturbations.
    pub layout: Layout,
    /// The frames, in manifest order.
    pub frames: Vec<ResolvedFrame>,
    /// Depth clamp of aligned predictions.
    pub range: DepthRange,
}

/// Problems found by [`Manifest::validate`]; `problems` make the manifest unusable.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ValidationReport {
    /// Problems that make the manifest unusable.
    pub problems: Vec<String>,
    /// Suspicious but usable entries.
    pub warnings: Vec<String>,
    /// Number of frames.
    pub n_frames: usize,
    /// Number of methods.
    pub n_methods: usize,
    /// Number of files checked for existence.
    pub n_files_checked: usize,
}

impl ValidationReport {
    /// True when there is no problem.
    pub fn ok(&self) -> bool {
        self.problems.is_empty()
    }
}

const HEADER: &str = "# RoDEM evaluation manifest (laparo depth). Paths are relative to this file's folder.\n\
# gt_unit: unit of the GT depth files (m | mm). methods[].kind: disparity | depth.\n\
# methods[].predictions: path template with {id} {scene} {perturbation} {severity} {name}.\n\
# depth_min_m / depth_max_m: clamp range (m) of aligned predicted depth; set it to the scene's\n\
#   depth range (surgical default 0.01-0.5 m; e.g. 1.0-10.0 for Middlebury).\n\
# frames[].severity: 0 = clean reference; or frames[].sequence + [[sequences]].gesture_start.\n\
# Check with: laparo depth manifest validate <this file>\n\n";

impl Manifest {
    /// Read a TOML or JSON manifest; relative paths are resolved against its folder.
    pub fn read(path: impl AsRef<Path>) -> Result<Manifest> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| laparo_core::CoreError::io(path, e))?;
        let mut m: Manifest = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) {
            serde_json::from_str(&text).map_err(|e| DepthError::file(path, format!("invalid manifest JSON: {e}")))?
        } else {
            toml::from_str(&text).map_err(|e| DepthError::file(path, format!("invalid manifest TOML: {e}")))?
        };
        if m.version != 1 {
            return Err(DepthError::file(path, format!("unsupported manifest version {} (expected 1)", m.version)));
        }
        m.base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        m.source = path.to_path_buf();
        Ok(m)
    }

    /// Write as TOML (or JSON for a `.json` path), atomically.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let text = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) {
            serde_json::to_string_pretty(self).map_err(|e| DepthError::file(path, e.to_string()))?
        } else {
            let body = toml::to_string(self).map_err(|e| DepthError::file(path, e.to_string()))?;
            format!("{HEADER}{body}")
        };
        laparo_core::atomic::write_atomic(path, text.as_bytes())?;
        Ok(())
    }

    /// Resolve a relative manifest path.
    pub fn path(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }

    /// The method called `name`.
    pub fn method(&self, name: &str) -> Option<&MethodSpec> {
        self.methods.iter().find(|m| m.name == name)
    }

    /// Prediction file of `method` for `frame` (template substitution).
    pub fn prediction_path(&self, method: &MethodSpec, frame: &ResolvedFrame, spec: &FrameSpec) -> PathBuf {
        let s = method
            .predictions
            .replace("{id}", &spec.id)
            .replace("{scene}", &spec.scene)
            .replace("{perturbation}", &spec.perturbation)
            .replace("{severity}", &frame.severity.to_string())
            .replace("{name}", spec.frame_name());
        self.path(Path::new(&s))
    }

    /// Clamp range of aligned depth.
    pub fn range(&self) -> Result<DepthRange> {
        let d = DepthRange::default();
        DepthRange::new(self.depth_min_m.unwrap_or(d.min_m), self.depth_max_m.unwrap_or(d.max_m))
    }

    /// Structural checks and index resolution; every problem is collected.
    fn resolve_collect(&self, problems: &mut Vec<String>, warnings: &mut Vec<String>) -> Option<Resolved> {
        let range = match self.range() {
            Ok(r) => Some(r),
            Err(e) => {
                problems.push(e.to_string());
                None
            }
        };
        if self.frames.is_empty() {
            problems.push("no frames listed".into());
        }
        let mut names = BTreeSet::new();
        for m in &self.methods {
            if !names.insert(m.name.as_str()) {
                problems.push(format!("method '{}' listed twice", m.name));
            }
            if m.predictions.trim().is_empty() {
                problems.push(format!("method '{}': empty predictions template", m.name));
            }
        }
        // Scenes in order of appearance; perturbations in vocabulary order, then appearance.
        let mut scenes: Vec<String> = Vec::new();
        let mut perts_seen: Vec<String> = Vec::new();
        for f in &self.frames {
            if !scenes.contains(&f.scene) {
                scenes.push(f.scene.clone());
            }
            if !perts_seen.contains(&f.perturbation) {
                perts_seen.push(f.perturbation.clone());
            }
        }
        let mut perturbations: Vec<String> =
            DEFAULT_PERTURBATIONS.iter().map(|p| p.0.to_string()).filter(|p| perts_seen.contains(p)).collect();
        for p in &perts_seen {
            if !perturbations.contains(p) {
                if p != CLEAN {
                    warnings.push(format!(
                        "perturbation '{p}' is not in the default vocabulary ({}); it is evaluated like the others",
                        DEFAULT_PERTURBATIONS.map(|p| p.0).join(", ")
                    ));
                }
                perturbations.push(p.clone());
            }
        }
        // Sequences: severity by frame-name order.
        let mut seqs: HashMap<(&str, &str, &str), &SequenceSpec> = HashMap::new();
        for s in &self.sequences {
            if seqs.insert((&s.scene, &s.perturbation, &s.name), s).is_some() {
                problems.push(format!("sequence '{}' of {}/{} listed twice", s.name, s.scene, s.perturbation));
            }
            if s.gesture_start.trim().is_empty() {
                problems.push(format!(
                    "sequence '{}' of {}/{}: gesture_start is not set (name of the first frame at or after the gesture)",
                    s.name, s.scene, s.perturbation
                ));
            }
        }
        let mut ids = BTreeSet::new();
        let mut frames = Vec::with_capacity(self.frames.len());
        for (index, f) in self.frames.iter().enumerate() {
            if !ids.insert(f.id.as_str()) {
                problems.push(format!("frame id '{}' listed twice", f.id));
            }
            let severity = match (&f.sequence, f.severity) {
                (Some(_), Some(_)) => {
                    problems.push(format!("frame '{}': give either severity or sequence, not both", f.id));
                    0
                }
                (Some(sq), None) => match seqs.get(&(f.scene.as_str(), f.perturbation.as_str(), sq.as_str())) {
                    Some(s) => u32::from(f.frame_name() >= s.gesture_start.as_str()),
                    None => {
                        problems.push(format!(
                            "frame '{}': sequence '{sq}' of {}/{} is not listed in [[sequences]]",
                            f.id, f.scene, f.perturbation
                        ));
                        0
                    }
                },
                (None, Some(s)) => s,
                (None, None) => {
                    problems.push(format!("frame '{}': no severity (0 = clean) and no sequence", f.id));
                    0
                }
            };
            frames.push(ResolvedFrame {
                index,
                id: f.id.clone(),
                scene: scenes.iter().position(|s| *s == f.scene).unwrap(),
                perturbation: perturbations.iter().position(|p| *p == f.perturbation).unwrap(),
                severity,
                rgb: self.path(&f.rgb),
                gt: self.path(&f.gt),
                mask: f.mask.as_ref().map(|m| self.path(m)),
                gt_unit: f.gt_unit.unwrap_or(self.gt_unit),
            });
        }
        for s in &self.sequences {
            let members: Vec<&FrameSpec> = self
                .frames
                .iter()
                .filter(|f| {
                    f.scene == s.scene && f.perturbation == s.perturbation && f.sequence.as_deref() == Some(&s.name)
                })
                .collect();
            if members.is_empty() {
                warnings.push(format!("sequence '{}' of {}/{} has no frames", s.name, s.scene, s.perturbation));
            } else if !s.gesture_start.is_empty() {
                let before = members.iter().filter(|f| f.frame_name() < s.gesture_start.as_str()).count();
                if before == 0 {
                    warnings.push(format!(
                        "sequence '{}' of {}/{}: no frame before the gesture (no clean reference)",
                        s.name, s.scene, s.perturbation
                    ));
                }
                if before == members.len() {
                    warnings.push(format!(
                        "sequence '{}' of {}/{}: no frame at or after gesture_start '{}'",
                        s.name, s.scene, s.perturbation, s.gesture_start
                    ));
                }
            }
        }
        if let Some(b) = &self.baseline {
            if self.method(b).is_none() {
                problems.push(format!("baseline '{b}' is not a listed method"));
            }
        }
        for f in &self.error_map_frames {
            if !ids.contains(f.as_str()) {
                problems.push(format!("error_map_frames: '{f}' is not a frame id"));
            }
        }
        range.map(|range| Resolved { layout: Layout { scenes, perturbations }, frames, range })
    }

    /// Resolve indices and sequence severities (structural problems are an error listing all).
    pub fn resolve(&self) -> Result<Resolved> {
        let (mut p, mut w) = (Vec::new(), Vec::new());
        let r = self.resolve_collect(&mut p, &mut w);
        match r {
            Some(r) if p.is_empty() => Ok(r),
            _ => Err(DepthError::Manifest { path: self.source.clone(), problems: p }),
        }
    }

    /// Check the structure and that every listed file exists (RGB, GT, mask, and the
    /// predictions of `methods`, all methods when `None`); all problems at once.
    pub fn validate(&self, methods: Option<&[String]>) -> ValidationReport {
        let mut rep = ValidationReport::default();
        let resolved = self.resolve_collect(&mut rep.problems, &mut rep.warnings);
        let chosen: Vec<&MethodSpec> = match methods {
            None => self.methods.iter().collect(),
            Some(names) => names
                .iter()
                .filter_map(|n| {
                    let m = self.method(n);
                    if m.is_none() {
                        rep.problems.push(format!(
                            "method '{n}' is not in the manifest (listed: {})",
                            self.methods.iter().map(|m| m.name.as_str()).collect::<Vec<_>>().join(", ")
                        ));
                    }
                    m
                })
                .collect(),
        };
        if chosen.is_empty() {
            rep.problems.push("no method to evaluate ([[methods]] is empty)".into());
        }
        rep.n_frames = self.frames.len();
        rep.n_methods = chosen.len();
        let Some(res) = resolved else { return rep };
        let mut missing = Vec::new();
        let mut check = |p: &Path, what: &str, id: &str, rep: &mut ValidationReport| {
            rep.n_files_checked += 1;
            if !p.is_file() {
                missing.push(format!("missing {what} of frame '{id}': {}", p.display()));
            }
        };
        for (f, spec) in res.frames.iter().zip(&self.frames) {
            check(&f.rgb, "RGB", &f.id, &mut rep);
            check(&f.gt, "GT depth", &f.id, &mut rep);
            if let Some(m) = &f.mask {
                check(m, "mask", &f.id, &mut rep);
            }
            for m in &chosen {
                check(&self.prediction_path(m, f, spec), &format!("prediction of {}", m.name), &f.id, &mut rep);
            }
        }
        rep.problems.extend(missing);
        rep
    }
}

/// Options of [`scaffold`].
#[derive(Clone, Debug)]
pub struct ScaffoldOptions {
    /// Unit of the GT depth files.
    pub gt_unit: DepthUnit,
    /// Methods whose predictions are depth (the others are disparity).
    pub depth_methods: Vec<String>,
    /// Folder of the per-method predictions, relative to the root.
    pub predictions_dir: String,
}

const RGB_EXT: [&str; 5] = ["png", "jpg", "jpeg", "tif", "tiff"];
const MAP_EXT: [&str; 6] = ["npy", "npz", "pfm", "tif", "tiff", "png"];

fn sorted_dirs(p: &Path) -> Result<Vec<String>> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(p).map_err(|e| laparo_core::CoreError::io(p, e))? {
        let e = e.map_err(|e| laparo_core::CoreError::io(p, e))?;
        if e.path().is_dir() {
            v.push(e.file_name().to_string_lossy().into_owned());
        }
    }
    v.sort();
    Ok(v)
}

/// Files of `dir` by stem (sorted), keeping those with an extension in `exts`.
fn files_by_stem(dir: &Path, exts: &[&str]) -> Result<BTreeMap<String, PathBuf>> {
    let mut out = BTreeMap::new();
    if !dir.is_dir() {
        return Ok(out);
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| laparo_core::CoreError::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    entries.sort();
    for p in entries {
        let ext = laparo_core::io::extension(&p);
        if exts.contains(&ext.as_str()) {
            if let Some(stem) = p.file_stem() {
                out.entry(stem.to_string_lossy().into_owned()).or_insert(p);
            }
        }
    }
    Ok(out)
}

/// Severity of a level folder name: `s0`/`clean`/`0` → 0, `s<k>`/`<k>` → k, else None (sequence).
pub fn level_severity(name: &str) -> Option<u32> {
    let l = name.to_ascii_lowercase();
    if l == "clean" {
        return Some(0);
    }
    let digits = l.strip_prefix('s').unwrap_or(&l);
    digits.parse().ok()
}

/// Build a manifest from the folder layout described in the module documentation.
pub fn scaffold(root: &Path, opts: &ScaffoldOptions) -> Result<Manifest> {
    if !root.is_dir() {
        return Err(DepthError::file(root, "is not a folder"));
    }
    let rel = |p: &Path| p.strip_prefix(root).unwrap_or(p).to_path_buf();
    let mut frames = Vec::new();
    let mut sequences = Vec::new();
    for scene in sorted_dirs(root)? {
        if scene == opts.predictions_dir || scene.starts_with('.') {
            continue;
        }
        for pert in sorted_dirs(&root.join(&scene))? {
            for level in sorted_dirs(&root.join(&scene).join(&pert))? {
                let dir = root.join(&scene).join(&pert).join(&level);
                let rgbs = files_by_stem(&dir.join("rgb"), &RGB_EXT)?;
                let mut gts = files_by_stem(&dir.join("depth"), &MAP_EXT)?;
                if gts.is_empty() {
                    gts = files_by_stem(&dir.join("gt"), &MAP_EXT)?;
                }
                let masks = files_by_stem(&dir.join("mask"), &["png", "npy", "tif", "tiff"])?;
                if rgbs.is_empty() && gts.is_empty() {
                    continue;
                }
                let severity = level_severity(&level);
                if severity.is_none() {
                    let gs = std::fs::read_to_string(dir.join("gesture_start.txt")).unwrap_or_default();
                    sequences.push(SequenceSpec {
                        scene: scene.clone(),
                        perturbation: pert.clone(),
                        name: level.clone(),
                        gesture_start: gs.trim().to_string(),
                    });
                }
                let stems: BTreeSet<&String> = rgbs.keys().chain(gts.keys()).collect();
                for stem in stems {
                    let id = format!("{scene}/{pert}/{level}/{stem}");
                    frames.push(FrameSpec {
                        id,
                        scene: scene.clone(),
                        perturbation: pert.clone(),
                        severity,
                        sequence: severity.is_none().then(|| level.clone()),
                        name: None,
                        // A missing file keeps its expected name so that validation reports it.
                        rgb: rgbs
                            .get(stem)
                            .map(|p| rel(p))
                            .unwrap_or_else(|| rel(&dir.join("rgb").join(format!("{stem}.png")))),
                        gt: gts
                            .get(stem)
                            .map(|p| rel(p))
                            .unwrap_or_else(|| rel(&dir.join("depth").join(format!("{stem}.npy")))),
                        mask: masks.get(stem).map(|p| rel(p)),
                        gt_unit: None,
                    });
                }
            }
        }
    }
    let mut methods = Vec::new();
    let pred_root = root.join(&opts.predictions_dir);
    if pred_root.is_dir() {
        for name in sorted_dirs(&pred_root)? {
            let ext = first_map_ext(&pred_root.join(&name)).unwrap_or_else(|| "npy".into());
            let kind = if opts.depth_methods.contains(&name) { PredKind::Depth } else { PredKind::Disparity };
            methods.push(MethodSpec {
                predictions: format!("{}/{name}/{{id}}.{ext}", opts.predictions_dir),
                name,
                kind,
            });
        }
    }
    Ok(Manifest {
        version: 1,
        gt_unit: opts.gt_unit,
        // Written out so that a user sees (and can edit) the clamp range of aligned depth.
        depth_min_m: Some(crate::align::DEPTH_MIN_M),
        depth_max_m: Some(crate::align::DEPTH_MAX_M),
        baseline: methods.first().map(|m| m.name.clone()),
        error_map_frames: Vec::new(),
        methods,
        sequences,
        frames,
        base_dir: root.to_path_buf(),
        source: root.join("manifest.toml"),
    })
}

/// Extension of the first prediction file found under `dir` (depth-first, sorted).
fn first_map_ext(dir: &Path) -> Option<String> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).ok()?.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in &entries {
        if p.is_file() {
            let e = laparo_core::io::extension(p);
            if MAP_EXT.contains(&e.as_str()) {
                return Some(e);
            }
        }
    }
    entries.iter().filter(|p| p.is_dir()).find_map(|p| first_map_ext(p))
}
