//! The scenario generator (issue 16 deliverable 1): the patient liver with a virtual tumour, before
//! ("past") and after ("present") an incision, rendered as a textured stereo laparoscope pair.
//!
//! - Organ: a closed surface (the P2ILF patient liver, mm) meshed into tetrahedra
//!   ([`crate::tetmesh`]); the ground-truth deformation is read from a laparo-fem folder
//!   (`rest.vtk` + `deformation.json`) or, until that lands, made by the stand-in
//!   [`crate::deformation::synthetic_incision`].
//! - Cameras: the P2ILF acquisition camera (1920×1080, f = 952.07 px) scaled to the render size,
//!   without lens distortion. The right camera is `baseline_mm` to the right, with a small relative
//!   rotation (Z-Y-X Euler angles, CATS eq. 3.7) and a principal-point offset: an uncalibrated pair
//!   in CATS' sense. Its exact calibration is written too (`calibration.json`, laparo's JSON).
//! - Texture: the real P2ILF frame projected onto the rest organ from the left camera (each rest
//!   vertex gets the frame pixel at its projection in the left image, the frame scaled to the image
//!   size), so the texture moves with the tissue in the present pair; exposed
//!   crack faces are tinted dark red. A background plane 40 mm behind the organ carries the same
//!   frame mirrored in both directions and darkened.
//! - Ground truth: depth (mm) and raw disparity `d = x_L − x_R` (px) of every left pixel, liver
//!   masks, the organ pose, the deformed organ and tumour, lips in 3D and on the images.
use crate::deformation::{synthetic_incision, Deformation, IncisionSpec};
use crate::error::{GuideError, Result};
use crate::render::{render, Rendered, Textured, View};
use crate::tetmesh::grid_tet_mesh;
use laparo_core::atomic::write_atomic;
use laparo_core::image::Image;
use laparo_core::mesh::TriMesh;
use laparo_core::{Intrinsics, StereoCalibration};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Scenario settings.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ScenarioConfig {
    /// Render width (px); the camera is the 1920×1080 acquisition camera scaled.
    pub width: usize,
    /// Render height (px).
    pub height: usize,
    /// Tetrahedral grid cell (mm).
    pub grid_mm: f64,
    /// Stereo baseline (mm).
    pub baseline_mm: f64,
    /// Right camera rotation w.r.t. the left, Z-Y-X Euler angles [x, y, z] (degrees).
    pub right_euler_deg: [f64; 3],
    /// Right principal-point offset (px at 1920×1080).
    pub right_pp_shift_px: [f64; 2],
    /// Viewpoint tilt about the camera x and y axes (degrees).
    pub tilt_deg: [f64; 2],
    /// Distance from the camera to the middle of the incision (mm).
    pub distance_mm: f64,
    /// Rough initial pose given to the pipeline: rotation (degrees) and translation (mm) away from
    /// the true pose.
    pub initial_error: [f64; 2],
}

impl ScenarioConfig {
    /// The full-size scenario (1920×1080, 4 mm grid).
    pub fn full() -> Self {
        ScenarioConfig {
            width: 1920,
            height: 1080,
            grid_mm: 4.0,
            baseline_mm: 5.0,
            right_euler_deg: [0.3, -0.5, 0.4],
            right_pp_shift_px: [12.0, 3.0],
            tilt_deg: [25.0, 10.0],
            distance_mm: 90.0,
            initial_error: [6.0, 8.0],
        }
    }
    /// The quick scenario (960×540, 6 mm grid) for tests and `laparo demo`.
    pub fn quick() -> Self {
        ScenarioConfig { width: 960, height: 540, grid_mm: 6.0, ..Self::full() }
    }
}

/// A rigid pose `X_cam = R X_model + t` (mm). In JSON it is laparo's one transform form
/// (`laparo_core::se3::transform_json`: `{"R": 3 rows, "t_mm", "scale": 1, "T": 4x4 rows}`), under a key
/// that names the direction (`model_to_camera`); it is read back by `laparo_core::se3::transform_from_json`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "serde_json::Value", into = "serde_json::Value")]
pub struct Pose {
    /// Rotation (rows).
    pub rotation: [[f64; 3]; 3],
    /// Translation (mm).
    pub translation_mm: [f64; 3],
}

impl Pose {
    /// From R, t.
    pub fn new(r: &Matrix3<f64>, t: &Vector3<f64>) -> Self {
        Pose {
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation_mm: [t[0], t[1], t[2]],
        }
    }
    /// R.
    pub fn r(&self) -> Matrix3<f64> {
        let m = &self.rotation;
        Matrix3::new(m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2])
    }
    /// t (mm).
    pub fn t(&self) -> Vector3<f64> {
        Vector3::new(self.translation_mm[0], self.translation_mm[1], self.translation_mm[2])
    }
    /// Apply to a model point.
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.r() * p + self.t()
    }
}

impl From<Pose> for serde_json::Value {
    fn from(p: Pose) -> Self {
        laparo_core::se3::transform_json(&p.r(), &p.t(), 1.0)
    }
}

impl TryFrom<serde_json::Value> for Pose {
    type Error = laparo_core::CoreError;
    fn try_from(v: serde_json::Value) -> std::result::Result<Self, Self::Error> {
        let rec = laparo_core::se3::transform_from_json(&v, "model_to_camera", "pose")?;
        let se3 = rec.to_se3_mm(laparo_core::DepthUnit::Mm, "pose (model_to_camera)")?;
        Ok(Pose::new(se3.rotation.to_rotation_matrix().matrix(), &se3.translation.vector))
    }
}

/// Whether `p` lies inside the closed triangle surface `m`: the parity of the crossings of a ray from
/// `p`, in three oblique directions, by majority (a ray through an edge or a vertex can miscount once).
pub fn point_inside_closed_surface(p: &Vector3<f64>, m: &TriMesh) -> bool {
    let dirs = [
        Vector3::new(0.5377, 0.8622, 0.3188),
        Vector3::new(-0.6917, 0.1234, 0.7116),
        Vector3::new(0.2113, -0.9012, -0.3784),
    ];
    let odd = dirs
        .iter()
        .filter(|d| {
            let d = d.normalize();
            let hits = m
                .faces
                .iter()
                .filter(|f| {
                    laparo_core::geometry::ray_triangle(p, &d, &m.vertices[f[0]], &m.vertices[f[1]], &m.vertices[f[2]])
                        .is_some_and(|t| t > 0.0)
                })
                .count();
            hits % 2 == 1
        })
        .count();
    odd >= 2
}

/// `scenario.json`: what the pipeline reads (inputs) and where the ground truth is.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    /// Settings used.
    pub config: ScenarioConfig,
    /// Left camera (render size).
    pub left: Intrinsics,
    /// Right camera (render size).
    pub right: Intrinsics,
    /// Depth range the surgeon expects (mm): a prior for the disparity search, not ground truth.
    pub depth_prior_mm: [f64; 2],
    /// Ground-truth organ pose (model → left camera).
    #[serde(rename = "gt_model_to_camera", alias = "gt_pose")]
    pub gt_pose: Pose,
    /// Tumour centre at rest, model frame (mm).
    pub tumour_centre_model_mm: [f64; 3],
    /// Tumour centre after the incision, camera frame (mm).
    pub tumour_centre_present_mm: [f64; 3],
    /// Tumour radius (mm).
    pub tumour_radius_mm: f64,
    /// Where the deformation came from.
    pub deformation_source: String,
    /// Organ surface file used.
    pub organ: String,
    /// Texture frame used.
    pub frame: String,
    /// Tetrahedra, nodes of the ground-truth mesh.
    pub tet_mesh: [usize; 2],
    /// Mean / max node displacement of the deformation (mm).
    pub displacement_mm: [f64; 2],
}

/// A 2D polyline file (`incision_past.json`): points in px.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Polyline2 {
    /// Image the points refer to.
    pub image: String,
    /// Points (px).
    pub points_px: Vec<[f64; 2]>,
}

/// `lips_present.json`: one polyline per lip (px, present left image).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Lips2 {
    /// Image the points refer to.
    pub image: String,
    /// Lip 0 and lip 1 (px): the longest run of lip vertices the present left camera sees (a surgeon cannot
    /// draw a lip where nearer tissue hides it).
    pub lips_px: [Vec<[f64; 2]>; 2],
    /// Lip vertices left out of `lips_px`: hidden by nearer tissue in the present left image, or beyond such a
    /// gap (each lip is drawn as one stroke, its longest visible run).
    #[serde(default)]
    pub hidden: [usize; 2],
}

fn json_write<T: Serialize>(path: &Path, v: &T) -> Result<()> {
    let s = serde_json::to_string_pretty(v)
        .map_err(|e| GuideError::stage("io", path.display().to_string(), e.to_string()))?;
    Ok(write_atomic(path, (s + "\n").as_bytes())?)
}

/// Read a JSON file, naming it on error.
pub fn json_read<T: for<'de> Deserialize<'de>>(path: &Path, stage: &str) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| laparo_core::CoreError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| GuideError::stage(stage, path.display().to_string(), e.to_string()))
}

/// Crack faces of a rest boundary: boundary faces whose vertices coincide with another boundary
/// face's (the two sides of a closed cut).
pub fn crack_faces(rest_vertices: &[Vector3<f64>], faces: &[[usize; 3]]) -> Vec<bool> {
    let key = |p: &Vector3<f64>| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
    let mut rep: HashMap<[u64; 3], usize> = HashMap::new();
    let merged: Vec<usize> = rest_vertices.iter().enumerate().map(|(i, p)| *rep.entry(key(p)).or_insert(i)).collect();
    let keys: Vec<[usize; 3]> = faces
        .iter()
        .map(|f| {
            let mut k = [merged[f[0]], merged[f[1]], merged[f[2]]];
            k.sort_unstable();
            k
        })
        .collect();
    let mut count: HashMap<[usize; 3], usize> = HashMap::new();
    for k in &keys {
        *count.entry(*k).or_insert(0) += 1;
    }
    keys.iter().map(|k| count[k] > 1).collect()
}

/// Default stand-in incision for an organ bounding box: crack normal along the longest axis, the
/// camera above the thinnest axis, the incision along the remaining axis (half its extent).
pub fn default_incision(lo: &Vector3<f64>, hi: &Vector3<f64>) -> IncisionSpec {
    let ext = hi - lo;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| ext[a].total_cmp(&ext[b]));
    let (up, span, normal) = (axes[0], axes[1], axes[2]);
    let c = (lo + hi) / 2.0;
    IncisionSpec {
        normal_axis: normal,
        span_axis: span,
        up_axis: up,
        plane_mm: c[normal] - 0.1 * ext[normal],
        span_mm: [c[span] - 0.25 * ext[span], c[span] + 0.2 * ext[span]],
        depth_mm: 0.35 * ext[up],
        opening_mm: 5.0,
        decay_mm: 20.0,
        tumour_depth_mm: 0.12 * ext[up],
        tumour_offset_mm: 10.0,
        tumour_radius_mm: 8.0,
    }
}

/// Summary returned by [`generate`].
#[derive(Clone, Debug, Serialize)]
pub struct GenerateSummary {
    /// Manifest written.
    pub manifest: Manifest,
    /// Liver pixels in the past / present left image.
    pub liver_pixels: [usize; 2],
    /// Seconds.
    pub seconds: f64,
}

fn write_depth_and_disparity(dir: &Path, name: &str, l: &Rendered, r: &Rendered, vl: &View, vr: &View) -> Result<()> {
    let (w, h) = (vl.k.width, vl.k.height);
    let mut disp = Image::filled(w, h, 1, f32::INFINITY);
    for y in 0..h {
        for x in 0..w {
            let z = l.depth_mm.get(x, y, 0);
            if !z.is_finite() {
                continue;
            }
            let p = vl.backproject(x as f64, y as f64, z);
            let Some((u, v, zr)) = vr.project(&p) else { continue };
            let Some(zz) = r.depth_mm.sample_nearest(u, v, 0) else { continue };
            if (zz - zr).abs() < 0.01 * zr + 0.5 {
                disp.set(x, y, 0, (x as f64 - u) as f32);
            }
        }
    }
    laparo_core::io::write_float_map(dir.join(format!("{name}_depth_gt_mm.npy")), &l.depth_mm)?;
    laparo_core::io::write_pfm(dir.join(format!("{name}_disparity_gt.pfm")), &disp)?;
    let mask = l.label.map(|v| v == 1);
    laparo_core::io::write_mask_png(dir.join(format!("{name}_liver_mask.png")), &mask)?;
    Ok(())
}

/// Generate the scenario into `out`: organ surface `organ` (closed, mm), texture `frame`, camera
/// file `camera` (the acquisition camera, any laparo camera format), optional laparo-fem
/// deformation folder.
pub fn generate(
    organ: &Path,
    frame: &Path,
    camera: &Path,
    deformation: Option<&Path>,
    cfg: &ScenarioConfig,
    out: &Path,
) -> Result<GenerateSummary> {
    let t0 = std::time::Instant::now();
    let bad = |input: &Path, m: String| GuideError::stage("scenario", input.display().to_string(), m);
    if cfg.width < 64 || cfg.height < 36 {
        return Err(GuideError::stage("scenario", "size", format!("{}x{} px is too small", cfg.width, cfg.height)));
    }
    std::fs::create_dir_all(out.join("gt")).map_err(|e| laparo_core::CoreError::io(out, e))?;
    let surface = laparo_core::mesh::read_mesh(organ)?;
    if !surface.is_closed() {
        return Err(bad(organ, "the organ surface is not closed".into()));
    }
    let texture = laparo_core::io::read_rgb8(frame)?;
    let cam = laparo_core::io::read_camera(camera)?;
    let k_full = cam.intrinsics(Some((1920, 1080)))?;
    // deformation
    let (def, source) = match deformation {
        Some(d) => (Deformation::read(d)?, d.display().to_string()),
        None => {
            let g = grid_tet_mesh(&surface, cfg.grid_mm)?;
            let (lo, hi) = surface.bounding_box().ok_or_else(|| bad(organ, "empty".into()))?;
            let spec = default_incision(&lo, &hi);
            (
                synthetic_incision(&g, &spec)?,
                format!("stand-in planar incision (analytic opening field), grid {} mm — not laparo-fem", cfg.grid_mm),
            )
        }
    };
    def.write(&out.join("gt").join("deformation"))?;
    let (lo, hi) = surface.bounding_box().ok_or_else(|| bad(organ, "empty".into()))?;
    let ext = hi - lo;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| ext[a].total_cmp(&ext[b]));
    let (up, normal) = (axes[0], axes[2]);
    // camera axes in model coordinates: x = crack normal, z = −up, y = z × x; then the tilt
    let ex = Vector3::ith(normal, 1.0);
    let ez = -Vector3::ith(up, 1.0);
    let ey = ez.cross(&ex);
    let r0 = Matrix3::from_rows(&[ex.transpose(), ey.transpose(), ez.transpose()]);
    let tilt = Rotation3::from_axis_angle(&Vector3::x_axis(), cfg.tilt_deg[0].to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), cfg.tilt_deg[1].to_radians());
    let r = tilt.into_inner() * r0;
    let s = cfg.width as f64 / 1920.0;
    let k = Intrinsics::new(
        k_full.fx * s,
        k_full.fy * s,
        (k_full.cx + 0.5) * s - 0.5,
        (k_full.cy + 0.5) * s - 0.5,
        cfg.width,
        cfg.height,
    )?;
    let rv: Vec<Vector3<f64>> = surface.vertices.iter().map(|p| r * p).collect();
    let (mut clo, mut chi) = (rv[0], rv[0]);
    for p in &rv {
        clo = clo.inf(p);
        chi = chi.sup(p);
    }
    // the laparoscope looks at the middle of the incision from `distance_mm`
    let lip_mid = def.lips[1].iter().map(|&n| def.rest.vertices[n]).sum::<Vector3<f64>>() / def.lips[1].len() as f64;
    let cc = r * lip_mid;
    let dist = cfg.distance_mm;
    let t = Vector3::new(-cc[0], -cc[1], dist - cc[2]);
    let gt_pose = Pose::new(&r, &t);
    let vl = View { k, r, t };
    // a camera inside the organ sees nothing but liver (every pixel) and no incision: refuse it
    for (name, centre_cam) in [("left", Vector3::zeros()), ("right", Vector3::new(cfg.baseline_mm, 0.0, 0.0))] {
        let c = r.transpose() * (centre_cam - t);
        if point_inside_closed_surface(&c, &surface) {
            return Err(bad(
                organ,
                format!(
                    "the virtual {name} camera is inside the organ: its centre ({:.1}, {:.1}, {:.1}) mm (model frame),                      {dist} mm from the incision's middle, lies within the surface (bounding box {:.0} x {:.0} x {:.0} mm),                      so every pixel would be liver. The organ is too large for the scenario's {dist} mm viewing                      distance, or not in millimetres",
                    c[0], c[1], c[2], ext[0], ext[1], ext[2]
                ),
            ));
        }
    }
    // right camera: X_right = R_rl X_left + T, centre at (b, 0, 0) in the left frame
    let e = cfg.right_euler_deg;
    let r_rl = laparo_core::se3::rotation_zyx(e[0].to_radians(), e[1].to_radians(), e[2].to_radians());
    let t_rl = -(r_rl * Vector3::new(cfg.baseline_mm, 0.0, 0.0));
    let kr = Intrinsics::new(
        k.fx,
        k.fy,
        k.cx + cfg.right_pp_shift_px[0] * s,
        k.cy + cfg.right_pp_shift_px[1] * s,
        cfg.width,
        cfg.height,
    )?;
    let vr = View { k: kr, r: r_rl * r, t: r_rl * t + t_rl };
    let calib = StereoCalibration {
        width: cfg.width,
        height: cfg.height,
        left: k,
        left_dist: Default::default(),
        right: kr,
        right_dist: Default::default(),
        r: r_rl,
        t_mm: t_rl,
    };
    calib.write_json(out.join("calibration.json"))?;
    // texture coordinates: the frame seen from the left camera with the frame's intrinsics
    let (tw, th) = (texture.width as f64, texture.height as f64);
    // the frame as seen by the left camera: a rest vertex gets the frame pixel at its projection
    let _ = k_full;
    let uv_of = |p: &Vector3<f64>| -> [f64; 2] {
        let (u, v, _) = vl.project(p).unwrap_or((0.0, 0.0, 1.0));
        [(u + 0.5) / cfg.width as f64 * tw - 0.5, (v + 0.5) / cfg.height as f64 * th - 0.5]
    };
    let boundary = def.rest.boundary();
    let uv: Vec<[f64; 2]> = def.rest.vertices.iter().map(uv_of).collect();
    let crack = crack_faces(&def.rest.vertices, &boundary.faces);
    let tint: Vec<[f64; 3]> = crack.iter().map(|&c| if c { [0.85, 0.3, 0.3] } else { [1.0, 1.0, 1.0] }).collect();
    // background plane 40 mm behind the farthest organ point, over 140 % of the left view
    let zb = chi[2] - cc[2] + dist + 40.0; // behind the farthest organ point
    let (w, h) = (cfg.width as f64, cfg.height as f64);
    let corners = [(-0.2 * w, -0.2 * h), (1.2 * w, -0.2 * h), (1.2 * w, 1.2 * h), (-0.2 * w, 1.2 * h)];
    let bg_v: Vec<Vector3<f64>> = corners.iter().map(|&(u, v)| vl.backproject(u, v, zb)).collect();
    let bg_uv: Vec<[f64; 2]> = corners
        .iter()
        .map(|&(u, v)| [tw - 1.0 - ((u + 0.5) / w * tw - 0.5), th - 1.0 - ((v + 0.5) / h * th - 0.5)])
        .collect();
    let bg_f = [[0, 1, 2], [0, 2, 3]];
    let bg_tint = [[0.5, 0.45, 0.45]; 2];
    let bg = Textured { vertices: &bg_v, faces: &bg_f, uv: &bg_uv, tint: &bg_tint, label: 2 };
    let mut liver_pixels = [0usize; 2];
    let mut nearest_mm = f64::INFINITY;
    let mut left_depth: Vec<Image<f64>> = Vec::with_capacity(2);
    for (i, (name, verts)) in [("past", &def.rest.vertices), ("present", &def.deformed)].into_iter().enumerate() {
        let liver = Textured { vertices: verts, faces: &boundary.faces, uv: &uv, tint: &tint, label: 1 };
        let l = render(&vl, &[liver, bg], &texture);
        let liver = Textured { vertices: verts, faces: &boundary.faces, uv: &uv, tint: &tint, label: 1 };
        let rr = render(&vr, &[liver, bg], &texture);
        left_depth.push(l.depth_mm.clone());
        laparo_core::io::write_png(out.join(format!("{name}_left.png")), &l.rgb)?;
        laparo_core::io::write_png(out.join(format!("{name}_right.png")), &rr.rgb)?;
        write_depth_and_disparity(&out.join("gt"), name, &l, &rr, &vl, &vr)?;
        liver_pixels[i] = l.label.data.iter().filter(|&&v| v == 1).count();
        for (z, &lab) in l.depth_mm.data.iter().zip(&l.label.data) {
            if lab == 1 && z.is_finite() {
                nearest_mm = nearest_mm.min(*z);
            }
        }
        // the segmentation the pipeline is given (as a surgeon's annotation would be)
        laparo_core::io::write_mask_png(out.join(format!("{name}_liver_mask.png")), &l.label.map(|v| v == 1))?;
    }
    // preoperative model and tumour (model frame)
    let (pre, _node, copies) = def.preoperative_surface();
    laparo_core::mesh::write_obj(out.join("model.obj"), &pre)?;
    laparo_core::mesh::write_vtk(out.join("model_tets.vtk"), &def.uncut_tets())?;
    let tum = laparo_fem::mesh::shapes::icosphere(&def.tumour_centre_mm, def.tumour_radius_mm, 2);
    laparo_core::mesh::write_obj(out.join("tumour.obj"), &tum)?;
    // ground truth: tumour and model vertices after the incision (camera frame)
    let tum_present = TriMesh {
        vertices: def.map_points(&tum.vertices).iter().map(|p| r * p + t).collect(),
        faces: tum.faces.clone(),
    };
    laparo_core::mesh::write_obj(out.join("gt").join("tumour_present.obj"), &tum_present)?;
    let centre_present = r * def.map_points(&[def.tumour_centre_mm])[0] + t;
    let present_copies: Vec<Vec<[f64; 3]>> = copies
        .iter()
        .map(|c| {
            c.iter()
                .map(|&n| {
                    let p = r * def.deformed[n] + t;
                    [p[0], p[1], p[2]]
                })
                .collect()
        })
        .collect();
    json_write(
        &out.join("gt").join("model_present.json"),
        &serde_json::json!({
            "about": "for every vertex of model.obj: its position(s) after the incision, left camera frame (mm); vertices on the cut have one position per lip",
            "positions_mm": present_copies,
        }),
    )?;
    let present_surface =
        TriMesh { vertices: def.deformed.iter().map(|p| r * p + t).collect(), faces: boundary.faces.clone() };
    laparo_core::mesh::write_ply(out.join("gt").join("liver_present.ply"), &present_surface)?;
    // incision (past left image) and lips (present left image), from the ground truth
    let proj = |p: &Vector3<f64>| -> [f64; 2] {
        let (u, v, _) = vl.project(p).unwrap_or((f64::NAN, f64::NAN, 0.0));
        [u, v]
    };
    // a point is drawn only where the left camera sees it: hidden when every pixel around its projection
    // shows a surface more than 2 mm nearer (the lip behind a nearer lobe)
    let visible = |depth: &Image<f64>, p: &Vector3<f64>| -> bool {
        let Some((u, v, z)) = vl.project(p) else { return false };
        let (x0, y0) = (u.round() as i64, v.round() as i64);
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (x, y) = (x0 + dx, y0 + dy);
                x >= 0
                    && y >= 0
                    && (x as usize) < depth.width
                    && (y as usize) < depth.height
                    && !(depth.get(x as usize, y as usize, 0) < z - 2.0)
            })
        })
    };
    // one stroke: the longest run of consecutive visible vertices (a stroke joining two runs would cross the
    // tissue that hides the gap)
    let drawn = |nodes: &[usize], verts: &[Vector3<f64>], depth: &Image<f64>| -> (Vec<[f64; 2]>, usize) {
        let (mut best, mut run) = (0..0, 0..0);
        for (k, &n) in nodes.iter().enumerate() {
            if visible(depth, &verts[n]) {
                run.end = k + 1; // the current run: from just after the last hidden vertex to k
                if run.len() > best.len() {
                    best = run.clone();
                }
            } else {
                run = k + 1..k + 1;
            }
        }
        let seen: Vec<[f64; 2]> = nodes[best].iter().map(|&n| proj(&verts[n])).collect();
        let hidden = nodes.len() - seen.len();
        (seen, hidden)
    };
    let (points_px, _) = drawn(&def.lips[1], &def.rest.vertices, &left_depth[0]);
    let incision = Polyline2 { image: "past_left.png".into(), points_px };
    json_write(&out.join("incision_past.json"), &incision)?;
    let (lip0, hidden0) = drawn(&def.lips[0], &def.deformed, &left_depth[1]);
    let (lip1, hidden1) = drawn(&def.lips[1], &def.deformed, &left_depth[1]);
    let lips = Lips2 { image: "present_left.png".into(), lips_px: [lip0, lip1], hidden: [hidden0, hidden1] };
    json_write(&out.join("lips_present.json"), &lips)?;
    let lips3: Vec<Vec<[f64; 3]>> = def
        .lips
        .iter()
        .map(|l| {
            l.iter()
                .map(|&n| {
                    let p = r * def.deformed[n] + t;
                    [p[0], p[1], p[2]]
                })
                .collect()
        })
        .collect();
    json_write(&out.join("gt").join("lips_present_3d.json"), &serde_json::json!({"lips_mm": lips3}))?;
    // the rough initial pose: the true pose moved by initial_error (rotation about a fixed oblique axis)
    let axis = Unit::new_normalize(Vector3::new(0.6, -0.48, 0.64));
    let dr = Rotation3::from_axis_angle(&axis, cfg.initial_error[0].to_radians()).into_inner();
    let c_model = surface.vertices.iter().sum::<Vector3<f64>>() / surface.vertices.len() as f64;
    // rotate about the organ centre, then translate
    let c_cam = r * c_model + t;
    let r_init = dr * r;
    let t_init = c_cam - r_init * c_model + Vector3::new(0.48, 0.6, -0.64) * cfg.initial_error[1];
    json_write(&out.join("initial_pose.json"), &serde_json::json!({"model_to_camera": Pose::new(&r_init, &t_init)}))?;
    // manifest
    let disp: Vec<f64> = def.deformed.iter().zip(&def.rest.vertices).map(|(a, b)| (a - b).norm()).collect();
    let manifest = Manifest {
        config: cfg.clone(),
        left: k,
        right: kr,
        // the working range a user would set: from 80 % of the nearest organ point (the organ may bulge
        // towards the laparoscope closer than the incision) to behind the background
        depth_prior_mm: [(0.5 * dist).min(0.8 * nearest_mm), zb + 20.0],
        gt_pose,
        tumour_centre_model_mm: [def.tumour_centre_mm[0], def.tumour_centre_mm[1], def.tumour_centre_mm[2]],
        tumour_centre_present_mm: [centre_present[0], centre_present[1], centre_present[2]],
        tumour_radius_mm: def.tumour_radius_mm,
        deformation_source: source,
        organ: organ.display().to_string(),
        frame: frame.display().to_string(),
        tet_mesh: [def.rest.tets.len(), def.rest.vertices.len()],
        displacement_mm: [disp.iter().sum::<f64>() / disp.len() as f64, disp.iter().cloned().fold(0.0, f64::max)],
    };
    json_write(&out.join("scenario.json"), &manifest)?;
    Ok(GenerateSummary { manifest, liver_pixels, seconds: t0.elapsed().as_secs_f64() })
}

/// The files of a scenario folder.
pub struct ScenarioFiles {
    /// Folder.
    pub dir: PathBuf,
}

impl ScenarioFiles {
    /// A path inside the scenario.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }
}
