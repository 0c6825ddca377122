//! Ground-truth preparation of thesis §3.2.6: depth-sensor (DS) depth → laparoscope (L) view.
//!
//! Every sensor pixel is back-projected with the sensor intrinsics, moved to the laparoscope
//! frame with `P_L = T_DS→L(P_DS)` and projected with the laparoscope intrinsics. Instead of
//! splatting *points* (which leaves holes wherever the warp magnifies the surface — any oblique
//! or nearer view at equal resolution), the sensor depth map is treated as a triangulated
//! surface: each 2×2 block of valid sensor pixels gives two triangles, which are rasterised
//! into the laparoscope image. Every laparoscope pixel centre inside the projection of the
//! surface is therefore covered. Depth inside a triangle is interpolated perspective-correctly
//! (1/z is affine in screen coordinates for a planar facet, so planes are reproduced exactly).
//! A per-pixel z-buffer keeps the nearest surface (occlusion handling of §3.2.6). Triangles whose
//! corners span a depth discontinuity (relative jump above `max_rel_jump`) are dropped so that
//! foreground and background are not bridged by "rubber sheets"; disoccluded regions stay
//! invalid (NaN). Backward warping was not used because the inverse map does not exist where
//! the two views see different surfaces (occlusion) — it would need exactly this z-buffer.
//! The sensor depth is taken as undistorted (depth cameras such as the RealSense D435i deliver
//! rectified depth); the laparoscope may have Brown–Conrady distortion ([`TargetCamera`]), in
//! which case projected vertices are distorted and triangles stay straight between them.
//! Finally an optional tool mask is removed and depth is clamped to `[min_depth_m, max_depth_m]`
//! (1 cm – 50 cm by default, §3.2.6).
//!
//! Length: ~360 lines of code; the rest (~260) are its tests.
use laparo_core::{CoreError, DepthMap, DepthUnit, Distortion, Image, Intrinsics, Result, Se3};
#[cfg(test)]
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// What happens to reprojected depth outside `[min_depth_m, max_depth_m]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ClampMode {
    /// Out-of-range depth becomes invalid (NaN): a sensor value outside the working range is
    /// treated as an artefact rather than moved to the range bound (default).
    Invalidate,
    /// Out-of-range depth is saturated to the nearest bound.
    Saturate,
}

/// Parameters of [`reproject_depth`].
#[derive(Clone, Debug, PartialEq)]
pub struct ReprojectParams {
    /// Lower bound of valid output depth, m (thesis: 1 cm).
    pub min_depth_m: f64,
    /// Upper bound of valid output depth, m (thesis: 50 cm).
    pub max_depth_m: f64,
    /// A sensor triangle is dropped when `max(z)/min(z) − 1` over its corners exceeds this.
    pub max_rel_jump: f64,
    /// How out-of-range depths are handled.
    pub clamp: ClampMode,
}

impl Default for ReprojectParams {
    fn default() -> Self {
        ReprojectParams { min_depth_m: 0.01, max_depth_m: 0.5, max_rel_jump: 0.05, clamp: ClampMode::Invalidate }
    }
}

impl ReprojectParams {
    fn validate(&self) -> Result<()> {
        if !(self.min_depth_m.is_finite() && self.max_depth_m.is_finite() && self.min_depth_m < self.max_depth_m) {
            return Err(CoreError::invalid(
                "depth range",
                format!(
                    "min_depth_m = {}, max_depth_m = {} (need finite min < max)",
                    self.min_depth_m, self.max_depth_m
                ),
            ));
        }
        if self.max_rel_jump.is_nan() || self.max_rel_jump <= 0.0 {
            return Err(CoreError::invalid("max_rel_jump", format!("{} (must be > 0)", self.max_rel_jump)));
        }
        Ok(())
    }
}

/// The laparoscope camera the depth is reprojected into.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetCamera {
    /// Pinhole intrinsics (px); output size is `width × height` of these intrinsics.
    pub intrinsics: Intrinsics,
    /// Lens distortion of the laparoscope image (None = depth for the undistorted/rectified image).
    pub distortion: Option<Distortion>,
}

/// Statistics of one reprojection.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ReprojectStats {
    /// Valid sensor pixels.
    pub sensor_valid: usize,
    /// Triangles rasterised.
    pub triangles: usize,
    /// Triangles dropped because they span a depth discontinuity.
    pub triangles_dropped_jump: usize,
    /// Output pixels covered before tool-mask removal and clamping.
    pub covered: usize,
    /// Output pixels removed by the tool mask.
    pub removed_tool: usize,
    /// Output pixels invalidated (or saturated) by the depth range.
    pub out_of_range: usize,
    /// Valid output pixels.
    pub valid: usize,
}

/// A projected sensor vertex: laparoscope pixel (u, v), depth z_L in m, sensor depth in m.
#[derive(Clone, Copy)]
struct Vert {
    u: f64,
    v: f64,
    z: f64,
    zs: f64,
}

/// Reproject sensor depth into the laparoscope view (thesis §3.2.6).
///
/// `t_ds_to_l` maps DS coordinates to L coordinates with its translation in **metres**
/// (`P_L = R P_DS + t`). `tool_mask` (laparoscope size, `true` = tool) removes tool pixels.
/// Returns depth in metres (NaN = invalid) of size `target.intrinsics.width × height`.
pub fn reproject_depth(
    depth: &DepthMap,
    sensor: &Intrinsics,
    t_ds_to_l: &Se3,
    target: &TargetCamera,
    tool_mask: Option<&Image<bool>>,
    params: &ReprojectParams,
) -> Result<(DepthMap, ReprojectStats)> {
    params.validate()?;
    sensor.validate()?;
    target.intrinsics.validate()?;
    if depth.width != sensor.width || depth.height != sensor.height {
        return Err(CoreError::SizeMismatch(format!(
            "sensor depth is {}x{} but sensor intrinsics are for {}x{}",
            depth.width, depth.height, sensor.width, sensor.height
        )));
    }
    let (ow, oh) = (target.intrinsics.width, target.intrinsics.height);
    if let Some(m) = tool_mask {
        if m.width != ow || m.height != oh || m.channels != 1 {
            return Err(CoreError::SizeMismatch(format!(
                "tool mask is {}x{}x{} but the laparoscope image is {ow}x{oh}x1",
                m.width, m.height, m.channels
            )));
        }
    }
    let t = t_ds_to_l.translation.vector;
    if !t.iter().all(|v| v.is_finite()) || !t_ds_to_l.rotation.coords.iter().all(|v| v.is_finite()) {
        return Err(CoreError::invalid("T_DS→L", "non-finite rotation or translation"));
    }
    let to_m = depth.unit.to_metres();
    let (sw, sh) = (depth.width, depth.height);
    // 1. Project every valid sensor pixel.
    let verts: Vec<Option<Vert>> = (0..sw * sh)
        .into_par_iter()
        .map(|i| {
            let zs = depth.data[i] * to_m;
            if !DepthMap::is_valid(zs) {
                return None;
            }
            let (x, y) = ((i % sw) as f64, (i / sw) as f64);
            let p = t_ds_to_l * nalgebra::Point3::from(sensor.backproject(x, y, zs));
            if p.z.is_nan() || p.z <= 0.0 {
                return None;
            }
            let (mut xn, mut yn) = (p.x / p.z, p.y / p.z);
            if let Some(d) = &target.distortion {
                (xn, yn) = d.distort_normalized(xn, yn);
            }
            let (u, v) = target.intrinsics.normalized_to_pixel(xn, yn);
            Some(Vert { u, v, z: p.z, zs })
        })
        .collect();
    let sensor_valid = verts.iter().filter(|v| v.is_some()).count();

    // 2. Rasterise the two triangles of every 2×2 block into per-band z-buffers, then take the
    //    element-wise minimum (order-independent, hence deterministic).
    let n_bands = (rayon::current_num_threads() * 2).clamp(1, sh.max(1));
    let band_rows = sh.saturating_sub(1).div_ceil(n_bands).max(1);
    let partial: Vec<(Vec<f64>, usize, usize)> = (0..n_bands)
        .into_par_iter()
        .map(|b| {
            let mut zbuf = vec![f64::INFINITY; ow * oh];
            let (mut n_tri, mut n_drop) = (0usize, 0usize);
            let y_end = ((b + 1) * band_rows).min(sh.saturating_sub(1));
            for y in b * band_rows..y_end {
                for x in 0..sw - 1 {
                    let q = [
                        verts[y * sw + x],
                        verts[y * sw + x + 1],
                        verts[(y + 1) * sw + x + 1],
                        verts[(y + 1) * sw + x],
                    ];
                    for tri in [[0usize, 1, 2], [0, 2, 3]] {
                        let (Some(a), Some(bv), Some(c)) = (q[tri[0]], q[tri[1]], q[tri[2]]) else { continue };
                        let zmin = a.zs.min(bv.zs).min(c.zs);
                        let zmax = a.zs.max(bv.zs).max(c.zs);
                        if zmax / zmin - 1.0 > params.max_rel_jump {
                            n_drop += 1;
                            continue;
                        }
                        n_tri += 1;
                        raster_triangle(&mut zbuf, ow, oh, &a, &bv, &c);
                    }
                }
            }
            (zbuf, n_tri, n_drop)
        })
        .collect();
    let mut zbuf = vec![f64::INFINITY; ow * oh];
    let (mut triangles, mut dropped) = (0, 0);
    for (p, nt, nd) in partial {
        triangles += nt;
        dropped += nd;
        zbuf.iter_mut().zip(p).for_each(|(z, q)| *z = z.min(q));
    }

    // 3. Tool mask, clamping.
    let mut stats = ReprojectStats { sensor_valid, triangles, triangles_dropped_jump: dropped, ..Default::default() };
    let mut out = vec![f64::NAN; ow * oh];
    for (i, (&z, o)) in zbuf.iter().zip(out.iter_mut()).enumerate() {
        if !z.is_finite() {
            continue;
        }
        stats.covered += 1;
        if tool_mask.is_some_and(|m| m.data[i]) {
            stats.removed_tool += 1;
            continue;
        }
        if z < params.min_depth_m || z > params.max_depth_m {
            stats.out_of_range += 1;
            if params.clamp == ClampMode::Invalidate {
                continue;
            }
            *o = z.clamp(params.min_depth_m, params.max_depth_m);
        } else {
            *o = z;
        }
        stats.valid += 1;
    }
    Ok((DepthMap::new(ow, oh, DepthUnit::M, out)?, stats))
}

#[inline]
fn edge(ax: f64, ay: f64, bx: f64, by: f64, px: f64, py: f64) -> f64 {
    (bx - ax) * (py - ay) - (by - ay) * (px - ax)
}

/// Rasterise one triangle into `zbuf` at integer pixel centres (inclusive edges, so shared
/// edges and vertices are covered by both neighbours; the z-buffer makes that harmless).
fn raster_triangle(zbuf: &mut [f64], w: usize, h: usize, a: &Vert, b: &Vert, c: &Vert) {
    let area = edge(a.u, a.v, b.u, b.v, c.u, c.v);
    if area.is_nan() || area.abs() <= 1e-12 {
        return;
    }
    const EPS: f64 = 1e-9;
    let umin = a.u.min(b.u).min(c.u) - EPS;
    let umax = a.u.max(b.u).max(c.u) + EPS;
    let vmin = a.v.min(b.v).min(c.v) - EPS;
    let vmax = a.v.max(b.v).max(c.v) + EPS;
    if umax < 0.0 || vmax < 0.0 || umin > (w - 1) as f64 || vmin > (h - 1) as f64 {
        return;
    }
    let x0 = umin.ceil().max(0.0) as usize;
    let x1 = (umax.floor() as usize).min(w - 1);
    let y0 = vmin.ceil().max(0.0) as usize;
    let y1 = (vmax.floor() as usize).min(h - 1);
    let inv_area = 1.0 / area;
    let (iza, izb, izc) = (1.0 / a.z, 1.0 / b.z, 1.0 / c.z);
    for py in y0..=y1 {
        let pyf = py as f64;
        for px in x0..=x1 {
            let pxf = px as f64;
            let wa = edge(b.u, b.v, c.u, c.v, pxf, pyf) * inv_area;
            let wb = edge(c.u, c.v, a.u, a.v, pxf, pyf) * inv_area;
            let wc = 1.0 - wa - wb;
            if wa < -EPS || wb < -EPS || wc < -EPS {
                continue;
            }
            // Perspective-correct: 1/z is affine in screen space on a planar facet.
            let z = 1.0 / (wa * iza + wb * izb + wc * izc);
            let i = py * w + px;
            if z < zbuf[i] {
                zbuf[i] = z;
            }
        }
    }
}

/// Parse pinhole intrinsics (px) from JSON with the shared camera reader
/// ([`laparo_core::io::camera_io::camera_from_json`]): `{"fx","fy","cx","cy","width","height"[,"skew"]}`
/// or `{"K": [[..],[..],[..]] (or 9 numbers), "width", "height"}`, numbers or numeric strings.
/// The size is required here; distortion, if any, is the caller's to apply
/// (see [`laparo_core::io::read_camera`]). `what` names the source in errors.
pub fn intrinsics_from_json(v: &serde_json::Value, what: &str) -> Result<Intrinsics> {
    let cam = laparo_core::io::camera_io::camera_from_json(v, std::path::Path::new(what))?;
    cam.intrinsics(None)
}

/// Parse T_DS→L from JSON with laparo's one transform reader ([`laparo_core::se3::transform_from_json`]):
/// `{"depth_sensor_to_laparoscope": {"R": 3 rows, "t_mm": [x, y, z]}}` (the form laparo writes), or at
/// the top level `{"T": 4×4}` or `{"R": 3×3, "t": [x,y,z]}` (rows, nested or flat), with an optional
/// `"unit": "m"|"mm"` for a bare `t`/`T` (else `default_unit`); the older key names `t_ds_to_l` (for
/// `T`) and `T_vec` (for `t`) are still read. Returns the transform with its translation in **metres**.
pub fn extrinsics_from_json(v: &serde_json::Value, default_unit: DepthUnit, what: &str) -> Result<Se3> {
    let mut v = v.clone();
    if let Some(o) = v.as_object_mut() {
        for (old, new) in [("t_ds_to_l", "T"), ("T_vec", "t")] {
            if !o.contains_key(new) {
                if let Some(x) = o.remove(old) {
                    o.insert(new.into(), x);
                }
            }
        }
    }
    let rec = laparo_core::se3::transform_from_json(&v, "depth_sensor_to_laparoscope", what)?;
    let t_mm = rec.translation_mm(default_unit);
    let se3 = rec.to_se3_mm(DepthUnit::Mm, what)?;
    Ok(laparo_core::se3::se3_from_rt(se3.rotation.to_rotation_matrix().matrix(), &(t_mm * 1e-3)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use laparo_core::se3::{rotation_zyx, se3_from_rt};

    fn cam(f: f64, w: usize, h: usize) -> Intrinsics {
        Intrinsics::new(f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0, w, h).unwrap()
    }

    fn target(k: Intrinsics) -> TargetCamera {
        TargetCamera { intrinsics: k, distortion: None }
    }

    /// Depth map of an analytic surface z = f(X, Y) seen by camera `k`, solved per pixel by
    /// fixed-point iteration z ← f(xn z, yn z) (converges for gentle surfaces).
    fn surface_depth(k: &Intrinsics, f: impl Fn(f64, f64) -> f64) -> DepthMap {
        let mut d = vec![0.0; k.width * k.height];
        for y in 0..k.height {
            for x in 0..k.width {
                let (xn, yn) = k.pixel_to_normalized(x as f64, y as f64);
                let mut z = 0.1;
                for _ in 0..200 {
                    z = f(xn * z, yn * z);
                }
                d[y * k.width + x] = z;
            }
        }
        DepthMap::new(k.width, k.height, DepthUnit::M, d).unwrap()
    }

    #[test]
    fn identity_returns_input() {
        let k = cam(300.0, 64, 48);
        let d = surface_depth(&k, |x, y| 0.12 + 0.2 * x - 0.1 * y + 0.01 * (40.0 * x).sin());
        let mm = d.to_unit(DepthUnit::Mm);
        let (out, st) =
            reproject_depth(&mm, &k, &Se3::identity(), &target(k), None, &ReprojectParams::default()).unwrap();
        assert_eq!(st.valid, 64 * 48);
        for y in 1..47 {
            for x in 1..63 {
                let (a, b) = (out.get(x, y), d.get(x, y));
                assert!((a - b).abs() < 1e-9, "({x},{y}): {a} vs {b}");
            }
        }
    }

    #[test]
    fn translated_plane_matches_closed_form() {
        // DS sees the tilted plane Z = a + b X. With P_L = P_DS + t the plane in L is
        // Z − tz = a + b (X − tx), so along the ray (xn, yn): z = (a + tz − b tx) / (1 − b xn).
        let (a, b) = (0.15, 0.3);
        let t = Vector3::new(0.01, -0.005, 0.02);
        let ks = cam(250.0, 80, 60);
        let kl = cam(280.0, 80, 60);
        let d = surface_depth(&ks, |x, _| a + b * x);
        let tf = se3_from_rt(&Matrix3::identity(), &t);
        let (out, st) = reproject_depth(&d, &ks, &tf, &target(kl), None, &ReprojectParams::default()).unwrap();
        assert!(st.valid > 60 * 80 / 2);
        let mut n = 0;
        for y in 0..60 {
            for x in 0..80 {
                let z = out.get(x, y);
                if z.is_nan() {
                    continue;
                }
                let (xn, _) = kl.pixel_to_normalized(x as f64, y as f64);
                let expect = (a + t.z - b * t.x) / (1.0 - b * xn);
                assert!((z - expect).abs() < 1e-9, "({x},{y}): {z} vs {expect}");
                n += 1;
            }
        }
        assert_eq!(n, st.valid);
        // Fronto-parallel plane: pure translation changes depth by tz everywhere.
        let d = DepthMap::new(80, 60, DepthUnit::Mm, vec![100.0; 80 * 60]).unwrap();
        let (out, _) = reproject_depth(&d, &ks, &tf, &target(ks), None, &ReprojectParams::default()).unwrap();
        let valid: Vec<f64> = out.data.iter().copied().filter(|z| z.is_finite()).collect();
        assert!(valid.len() > 1500, "{}", valid.len());
        assert!(valid.iter().all(|z| (z - 0.12).abs() < 1e-12));
    }

    #[test]
    fn nearer_surface_wins_and_shadow_stays_empty() {
        // Background plane at 0.30 m, a square occluder at 0.10 m covering X, Y in [-1, 1] cm.
        let k = cam(200.0, 120, 100);
        let (zb, zo, half) = (0.30, 0.10, 0.01);
        let mut d = vec![zb; 120 * 100];
        for y in 0..100 {
            for x in 0..120 {
                let p = k.backproject(x as f64, y as f64, zo);
                if p.x.abs() <= half && p.y.abs() <= half {
                    d[y * 120 + x] = zo;
                }
            }
        }
        let d = DepthMap::new(120, 100, DepthUnit::M, d).unwrap();
        let t = Vector3::new(-0.02, 0.0, 0.0); // L sits 2 cm to the right of DS: X_L = X_DS − 2 cm
        let tf = se3_from_rt(&Matrix3::identity(), &t);
        let (out, st) = reproject_depth(&d, &k, &tf, &target(k), None, &ReprojectParams::default()).unwrap();
        assert!(st.triangles_dropped_jump > 0);
        let (mut n_obj, mut n_shadow) = (0, 0);
        for y in 0..100 {
            for x in 0..120 {
                let (xn, yn) = k.pixel_to_normalized(x as f64, y as f64);
                let z = out.get(x, y);
                // Ray hits the occluder plane (in DS coordinates) at X_DS = xn zo − t.x.
                let (xo, yo) = (xn * zo - t.x, yn * zo);
                if xo.abs() < half - 0.001 && yo.abs() < half - 0.001 {
                    assert!((z - zo).abs() < 1e-9, "occluder pixel ({x},{y}) = {z}");
                    n_obj += 1;
                    continue;
                }
                // Background point seen by L; is it hidden from DS by the occluder?
                let (xb, yb) = (xn * zb - t.x, yn * zb);
                let (xs, ys) = (xb * zo / zb, yb * zo / zb); // DS ray meets the occluder plane here
                let in_frame = k
                    .project(&Vector3::new(xb, yb, zb))
                    .is_some_and(|(u, v)| u > 1.0 && v > 1.0 && u < 118.0 && v < 98.0);
                if xs.abs() < half - 0.001
                    && ys.abs() < half - 0.001
                    && (xo.abs() > half + 0.001 || yo.abs() > half + 0.001)
                {
                    assert!(z.is_nan(), "shadow pixel ({x},{y}) got {z}");
                    n_shadow += 1;
                } else if in_frame
                    && (xs.abs() > half + 0.001 || ys.abs() > half + 0.001)
                    && (xo.abs() > half + 0.001 || yo.abs() > half + 0.001)
                {
                    assert!((z - zb).abs() < 1e-9, "background pixel ({x},{y}) = {z}");
                }
            }
        }
        assert!(n_obj > 50 && n_shadow > 20, "n_obj {n_obj} n_shadow {n_shadow}");
    }

    #[test]
    fn smooth_surface_has_no_holes_unlike_point_splatting() {
        // Wider-FOV sensor at equal resolution, laparoscope rotated and closer: the warp
        // magnifies the surface, so naive point splatting leaves holes; triangles must not.
        let ks = cam(180.0, 96, 72);
        let kl = cam(260.0, 96, 72);
        let d = surface_depth(&ks, |x, y| 0.12 + 0.004 * (60.0 * x).sin() * (50.0 * y).cos());
        let r = rotation_zyx(0.05, -0.08, 0.1);
        let tf = se3_from_rt(&r, &Vector3::new(0.003, -0.002, -0.03));
        let (out, st) = reproject_depth(&d, &ks, &tf, &target(kl), None, &ReprojectParams::default()).unwrap();
        assert_eq!(st.triangles_dropped_jump, 0);
        assert_eq!(st.valid, 96 * 72, "holes: {}", 96 * 72 - st.valid);
        let mut hit = vec![false; 96 * 72];
        for y in 0..72 {
            for x in 0..96 {
                let p = tf * nalgebra::Point3::from(ks.backproject(x as f64, y as f64, d.get(x, y)));
                if let Some((u, v)) = kl.project(&p.coords) {
                    let (u, v) = (u.round(), v.round());
                    if u >= 0.0 && v >= 0.0 && u < 96.0 && v < 72.0 {
                        hit[v as usize * 96 + u as usize] = true;
                    }
                }
            }
        }
        let holes = hit.iter().filter(|h| !**h).count();
        assert!(holes > 500, "point splatting should leave holes here, got {holes}");
        // Sanity: depths are those of the surface (range of the analytic function + motion).
        assert!(out.data.iter().all(|z| *z > 0.08 && *z < 0.11));
    }

    #[test]
    fn round_trip_with_rotation_recovers_plane() {
        // DS → L with a general rigid motion, then L → DS with the inverse: a plane is
        // reproduced exactly (perspective-correct interpolation) wherever both views see it.
        let k = cam(220.0, 90, 70);
        let d = surface_depth(&k, |x, y| 0.14 + 0.25 * x + 0.1 * y);
        let tf = se3_from_rt(&rotation_zyx(0.04, -0.06, 0.2), &Vector3::new(0.004, 0.003, 0.01));
        let p = ReprojectParams::default();
        let (l, _) = reproject_depth(&d, &k, &tf, &target(k), None, &p).unwrap();
        let (back, st) = reproject_depth(&l, &k, &tf.inverse(), &target(k), None, &p).unwrap();
        assert!(st.valid > 90 * 70 / 2, "{}", st.valid);
        let mut n = 0;
        for (a, b) in back.data.iter().zip(&d.data) {
            if a.is_finite() {
                assert!((a - b).abs() < 1e-9, "{a} vs {b}");
                n += 1;
            }
        }
        assert_eq!(n, st.valid);
    }

    #[test]
    fn distortion_moves_depth_to_distorted_pixels() {
        // With barrel distortion (k1 < 0) the value at distorted pixel u_d is the depth of the
        // undistorted ray; checked on a tilted plane against the closed form at the distorted position.
        let k = cam(200.0, 80, 60);
        let (a, b) = (0.12, 0.3);
        let d = surface_depth(&k, |x, _| a + b * x);
        let dist = Distortion::brown_conrady(-0.2, 0.0, 0.0, 0.0, 0.0);
        let t = TargetCamera { intrinsics: k, distortion: Some(dist) };
        let (out, _) = reproject_depth(&d, &k, &Se3::identity(), &t, None, &ReprojectParams::default()).unwrap();
        let mut n = 0;
        for y in 5..55 {
            for x in 5..75 {
                let z = out.get(x, y);
                if z.is_nan() {
                    continue;
                }
                let (xn, _) =
                    dist.undistort_pixel(&k, x as f64, y as f64).map(|(u, v)| k.pixel_to_normalized(u, v)).unwrap();
                let expect = a / (1.0 - b * xn);
                // Triangles are straight in the distorted image: small linearisation error only.
                assert!((z - expect).abs() < 2e-4 * expect, "({x},{y}) {z} vs {expect}");
                n += 1;
            }
        }
        assert!(n > 2000, "{n}");
    }

    #[test]
    fn tool_mask_and_clamp() {
        let k = cam(100.0, 20, 10);
        let mut v = vec![0.2; 200];
        v[0..20].iter_mut().for_each(|z| *z = 0.6); // first row beyond 50 cm
        let d = DepthMap::new(20, 10, DepthUnit::M, v).unwrap();
        let mut mask = Image::filled(20, 10, 1, false);
        mask.set(5, 5, 0, true);
        let p = ReprojectParams { max_rel_jump: 10.0, ..Default::default() };
        let (out, st) = reproject_depth(&d, &k, &Se3::identity(), &target(k), Some(&mask), &p).unwrap();
        assert!(out.get(5, 5).is_nan());
        assert_eq!(st.removed_tool, 1);
        assert!(out.get(3, 0).is_nan());
        assert_eq!(st.out_of_range, 20);
        let p = ReprojectParams { clamp: ClampMode::Saturate, max_rel_jump: 10.0, ..Default::default() };
        let (out, _) = reproject_depth(&d, &k, &Se3::identity(), &target(k), None, &p).unwrap();
        assert_eq!(out.get(3, 0), 0.5);
        // Bad inputs are errors, not panics.
        let bad = Image::filled(19, 10, 1, false);
        assert!(reproject_depth(&d, &k, &Se3::identity(), &target(k), Some(&bad), &p).is_err());
        let p = ReprojectParams { min_depth_m: 0.6, max_depth_m: 0.5, ..Default::default() };
        assert!(reproject_depth(&d, &k, &Se3::identity(), &target(k), None, &p).is_err());
        let k2 = cam(100.0, 21, 10);
        assert!(reproject_depth(&d, &k2, &Se3::identity(), &target(k), None, &ReprojectParams::default()).is_err());
    }

    #[test]
    fn json_parsers() {
        let v: serde_json::Value =
            serde_json::from_str(r#"{"K": [[500,0,320],[0,510,240],[0,0,1]], "width": 640, "height": 480}"#).unwrap();
        let k = intrinsics_from_json(&v, "k.json").unwrap();
        assert_eq!((k.fx, k.fy, k.cx, k.cy, k.width), (500.0, 510.0, 320.0, 240.0, 640));
        let v: serde_json::Value =
            serde_json::from_str(r#"{"T": [[0,-1,0,10],[1,0,0,-20],[0,0,1,5],[0,0,0,1]], "unit": "mm"}"#).unwrap();
        let t = extrinsics_from_json(&v, DepthUnit::M, "t.json").unwrap();
        let p = t * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((p.coords - Vector3::new(0.01, 0.98, 0.005)).norm() < 1e-12);
        let v: serde_json::Value = serde_json::from_str(r#"{"R": [1,0,0,0,1,0,0,0,1], "t": [1, 2, 3]}"#).unwrap();
        let t = extrinsics_from_json(&v, DepthUnit::M, "t.json").unwrap();
        assert_eq!(t.translation.vector, Vector3::new(1.0, 2.0, 3.0));
        let v: serde_json::Value = serde_json::from_str(r#"{"R": [2,0,0,0,1,0,0,0,1], "t": [1, 2, 3]}"#).unwrap();
        assert!(extrinsics_from_json(&v, DepthUnit::M, "t.json").is_err());
        let v: serde_json::Value = serde_json::from_str(r#"{"fx": 1}"#).unwrap();
        let e = intrinsics_from_json(&v, "cam.json").unwrap_err().to_string();
        assert!(e.contains("cam.json"), "{e}");
    }
}
