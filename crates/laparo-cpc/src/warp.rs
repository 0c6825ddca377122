//! Step 5 of the CPC pipeline (§4.4.6): the input image is used as a texture and mapped onto the
//! flattened mesh by piecewise-affine interpolation. Every output pixel is inverse-mapped (the
//! affine map of the flattened triangle that contains it) to the original image and sampled
//! bilinearly. The output canvas is the bounding box of the flattened mesh; canvas pixel (i, j)
//! is the flattened point (i + origin_x, j + origin_y).
//!
//! Dense coordinate maps (canvas → original and original → canvas) let an external matcher run on
//! the warped image and bring its keypoints back; [`Warp::original_to_warped`] and
//! [`Warp::warped_to_original`] do the same for single points (barycentric coordinates).
use crate::error::{CpcError, Result};
use crate::mesh::{signed_area, CpcMesh};
use crate::metrics::{edge_map, largest_singular_value};
use laparo_core::image::{Image, Mask};
use laparo_core::remap::{remap_rows, Interp, Texel};
use rayon::prelude::*;

const NONE: u32 = u32::MAX;

/// Canvas pixel range (x0, y0, x1, y1) of a face, inclusive.
type PixelBox = (usize, usize, usize, usize);

/// Canvas rows per rasterisation band (unit of parallel work).
const RASTER_BAND_ROWS: usize = 32;

/// Largest canvas accepted, as a multiple of the input image area (guards against exploded solutions).
pub const MAX_CANVAS_FACTOR: usize = 16;

/// A piecewise-affine warp from the initial grid to its flattened counterpart.
#[derive(Clone, Debug)]
pub struct Warp {
    mesh: CpcMesh,
    /// Flattened vertex positions (px, solver frame).
    pub p_flat: Vec<[f64; 2]>,
    /// Canvas origin in the flattened frame (integer).
    pub origin: [f64; 2],
    /// Canvas width (px).
    pub width: usize,
    /// Canvas height (px).
    pub height: usize,
    /// Original image width (px).
    pub src_width: usize,
    /// Original image height (px).
    pub src_height: usize,
    /// Per face: affine map canvas → original, [A_x, A_y, a_x, a_y, l00, l01, l10, l11]: original
    /// anchor A, canvas anchor a and linear part (q ↦ A + L (q − a)); one cache line per face.
    inv_aff: Vec<[f64; 8]>,
    /// Per face: affine map original → canvas (linear part), computed on the first point query.
    fwd_lin: std::sync::OnceLock<Vec<[f64; 4]>>,
    /// Triangle covering every canvas pixel (or NONE).
    face_id: Vec<u32>,
    /// Bucket grid over the canvas for point location.
    /// Bucket grid over the canvas for point location, built on first use.
    buckets: std::sync::OnceLock<Buckets>,
}

/// Bucket grid over the canvas: the faces whose bounding box meets each cell.
#[derive(Clone, Debug)]
struct Buckets {
    px: f64,
    cols: usize,
    rows: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Buckets {
    fn build(
        faces: &[[usize; 3]],
        canvas: impl Fn(usize) -> [f64; 2],
        grid_step_px: usize,
        width: usize,
        height: usize,
    ) -> Buckets {
        let bucket_px = (2 * grid_step_px).max(4) as f64;
        let bucket_cols = (width as f64 / bucket_px).ceil() as usize + 1;
        let bucket_rows = (height as f64 / bucket_px).ceil() as usize + 1;
        let mut counts = vec![0u32; bucket_cols * bucket_rows + 1];
        let brange = |f: &[usize; 3]| {
            let (a, b, c) = (canvas(f[0]), canvas(f[1]), canvas(f[2]));
            let bx0 = (a[0].min(b[0]).min(c[0]) / bucket_px).floor().max(0.0) as usize;
            let by0 = (a[1].min(b[1]).min(c[1]) / bucket_px).floor().max(0.0) as usize;
            let bx1 = ((a[0].max(b[0]).max(c[0]) / bucket_px).floor() as usize).min(bucket_cols - 1);
            let by1 = ((a[1].max(b[1]).max(c[1]) / bucket_px).floor() as usize).min(bucket_rows - 1);
            (bx0, by0, bx1, by1)
        };
        for f in faces {
            let (bx0, by0, bx1, by1) = brange(f);
            for by in by0..=by1 {
                for bx in bx0..=bx1 {
                    counts[by * bucket_cols + bx + 1] += 1;
                }
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let bucket_start = counts.clone();
        let mut fill = counts;
        let mut bucket_items = vec![0u32; *bucket_start.last().unwrap() as usize];
        for (t, f) in faces.iter().enumerate() {
            let (bx0, by0, bx1, by1) = brange(f);
            for by in by0..=by1 {
                for bx in bx0..=bx1 {
                    let b = by * bucket_cols + bx;
                    bucket_items[fill[b] as usize] = t as u32;
                    fill[b] += 1;
                }
            }
        }
        Buckets { px: bucket_px, cols: bucket_cols, rows: bucket_rows, start: bucket_start, items: bucket_items }
    }
}

/// Dense coordinate maps of a warp.
pub struct WarpMaps {
    /// Canvas-sized, 2 channels: original (x, y) of every warped pixel (NaN where invalid).
    pub backward: Image<f64>,
    /// Original-sized, 2 channels: canvas (x, y) of every original pixel (NaN outside the mesh).
    pub forward: Image<f64>,
}

#[inline]
fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// Barycentric coordinates of `q` in triangle (a, b, c).
#[inline]
fn barycentric(q: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> [f64; 3] {
    let d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let wb = ((q[0] - a[0]) * (c[1] - a[1]) - (q[1] - a[1]) * (c[0] - a[0])) / d;
    let wc = ((b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])) / d;
    [1.0 - wb - wc, wb, wc]
}

/// ⌈v⌉ for v ≥ 0 (0 for negative or NaN v) without a libm call. (Through i64: one instruction
/// plus a range check, where f64 → usize needs a multi-instruction sequence for the upper half of
/// the u64 range; canvas coordinates are far below 2⁶³.)
#[inline(always)]
fn ceil_nonneg(v: f64) -> usize {
    let t = v.max(0.0) as i64 as usize;
    if (t as f64) < v {
        t + 1
    } else {
        t
    }
}

/// q ↦ A + L (q − a) with `af` = [A_x, A_y, a_x, a_y, l00, l01, l10, l11].
#[inline(always)]
fn inv_apply(af: &[f64; 8], q: [f64; 2]) -> [f64; 2] {
    let d = [q[0] - af[2], q[1] - af[3]];
    [af[0] + (af[4] * d[0] + af[5] * d[1]), af[1] + (af[6] * d[0] + af[7] * d[1])]
}

/// AVX2 rasterisation (x86-64): the inside test of [`RowTest`] on 4 pixels at once.
#[cfg(target_arch = "x86_64")]
mod simd {
    use std::arch::x86_64::*;

    /// Whether the CPU has AVX2.
    pub fn available() -> bool {
        std::is_x86_feature_detected!("avx2")
    }

    /// [`super::RasterBand::raster`] with AVX2 rows.
    ///
    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub unsafe fn raster_band(band: super::RasterBand<'_>) {
        band.raster::<true>();
    }

    /// Pixels `x0..=x1` of `row` covered by `test` are set to `t`, 4 at a time: the same inside
    /// test as [`super::RowTest::inside`], lane by lane; the pixels beyond the row's last full
    /// vector take the scalar path.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub unsafe fn fill_row(test: &super::RowTest, row: &mut [u32], x0: usize, x1: usize, t: u32) {
        let (ax, cb, cc) = (_mm256_set1_pd(test.ax), _mm256_set1_pd(test.cb), _mm256_set1_pd(test.cc));
        let (tb, tc, sd, tol) =
            (_mm256_set1_pd(test.tb), _mm256_set1_pd(test.tc), _mm256_set1_pd(test.sd), _mm256_set1_pd(test.tol));
        let tv = _mm_set1_epi32(t as i32);
        let lanes = _mm_set_epi32(3, 2, 1, 0);
        let last = _mm_set1_epi32(x1 as i32);
        let mut x = x0;
        while x <= x1 && x + 4 <= row.len() {
            let xi = _mm_add_epi32(_mm_set1_epi32(x as i32), lanes);
            let qx = _mm256_sub_pd(_mm256_cvtepi32_pd(xi), ax);
            let nb = _mm256_sub_pd(_mm256_mul_pd(qx, cb), tb);
            let nc = _mm256_sub_pd(tc, _mm256_mul_pd(cc, qx));
            let na = _mm256_sub_pd(_mm256_sub_pd(sd, nb), nc);
            let ok = _mm256_and_pd(
                _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(na, tol), _mm256_cmp_pd::<_CMP_GE_OQ>(nb, tol)),
                _mm256_cmp_pd::<_CMP_GE_OQ>(nc, tol),
            );
            // 4 × 64-bit lane masks → 4 × 32-bit, restricted to x ≤ x1.
            let ok32 = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(
                _mm256_castpd_si256(ok),
                _mm256_set_epi32(7, 5, 3, 1, 6, 4, 2, 0),
            ));
            let keep = _mm_andnot_si128(_mm_cmpgt_epi32(xi, last), ok32);
            let dst = row[x..x + 4].as_mut_ptr() as *mut __m128i;
            // SAFETY: `row[x..x + 4]` is in bounds (checked by the slice index), unaligned access.
            let old = _mm_loadu_si128(dst);
            _mm_storeu_si128(dst, _mm_blendv_epi8(old, tv, keep));
            x += 4;
        }
        if x <= x1 {
            test.fill_scalar(row, x, x1, t);
        }
    }
}

/// Tolerance of the rasterisation's inside test (barycentric coordinates ≥ −`RASTER_EPS`).
const RASTER_EPS: f64 = 1e-9;

/// One band of canvas rows to rasterise: the faces meeting it, in index order (the last face in
/// index order wins on shared edges).
struct RasterBand<'a> {
    /// The band's rows of the face-id raster (`width` per row).
    chunk: &'a mut [u32],
    width: usize,
    /// Canvas row of the band's first row.
    y0: usize,
    faces: &'a [u32],
    mesh_faces: &'a [[usize; 3]],
    canvas: &'a [[f64; 2]],
    boxes: &'a [Option<PixelBox>],
}

/// Inside test of one face on one canvas row: pixel x is inside when
/// na, nb, nc ≥ tol with qx = x − ax, nb = qx·cb − tb, nc = tc − cc·qx, na = sd − nb − nc.
#[derive(Clone, Copy)]
struct RowTest {
    ax: f64,
    cb: f64,
    cc: f64,
    tb: f64,
    tc: f64,
    sd: f64,
    tol: f64,
}

impl RowTest {
    #[inline(always)]
    fn inside(&self, x: usize) -> bool {
        let qx = x as i32 as f64 - self.ax;
        let nb = qx * self.cb - self.tb;
        let nc = self.tc - self.cc * qx;
        let na = self.sd - nb - nc;
        na >= self.tol && nb >= self.tol && nc >= self.tol
    }

    /// Scalar rasterisation of pixels `x0..=x1` of `row`.
    #[inline(always)]
    fn fill_scalar(&self, row: &mut [u32], x0: usize, x1: usize, t: u32) {
        for (x, id) in row.iter_mut().enumerate().take(x1 + 1).skip(x0) {
            if self.inside(x) {
                *id = t;
            }
        }
    }
}

impl RasterBand<'_> {
    /// Rasterise every listed face into the band (`SIMD`: rows by 4-pixel AVX2 vectors; only
    /// instantiated as `true` inside an AVX2 function).
    #[inline(always)]
    fn raster<const SIMD: bool>(self) {
        let width = self.width;
        let by0 = self.y0;
        let by1 = (by0 + self.chunk.len() / width).saturating_sub(1);
        for &t in self.faces {
            let f = self.mesh_faces[t as usize];
            let (a, b, c) = (self.canvas[f[0]], self.canvas[f[1]], self.canvas[f[2]]);
            let (x0, y0, x1, y1) = self.boxes[t as usize].expect("listed faces have a row range");
            // Barycentric test w_k ≥ −eps without divisions: w_b = nb / d, w_c = nc / d,
            // w_a = (d − nb − nc) / d, so w ≥ −eps ⇔ s·num ≥ −eps·|d| with s = sign(d). The sign
            // is folded into the edge coefficients (exact) and the row terms are hoisted.
            let (e1x, e1y) = (b[0] - a[0], b[1] - a[1]);
            let (e2x, e2y) = (c[0] - a[0], c[1] - a[1]);
            let d = e1x * e2y - e1y * e2x;
            let sg = if d > 0.0 { 1.0 } else { -1.0 };
            let (cb, rb, cc, rc) = (sg * e2y, sg * e2x, sg * e1y, sg * e1x);
            let sd = d.abs();
            let tol = -RASTER_EPS * sd;
            for y in y0.max(by0)..=y1.min(by1) {
                let row = &mut self.chunk[(y - by0) * width..(y - by0 + 1) * width];
                let qy = y as i32 as f64 - a[1];
                let test = RowTest { ax: a[0], cb, cc, tb: qy * rb, tc: rc * qy, sd, tol };
                #[cfg(target_arch = "x86_64")]
                if SIMD {
                    // SAFETY: `SIMD` is only true inside `simd::raster_band`, an AVX2 function.
                    unsafe { simd::fill_row(&test, row, x0, x1, t) };
                    continue;
                }
                test.fill_scalar(row, x0, x1, t);
            }
        }
    }
}

/// Whether the AVX2 paths can be used on this CPU.
fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    return simd::available();
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// The face-id raster of the canvas (`width` × `height`): every pixel gets the covering face (or
/// `NONE`). `avx2` (only honoured when the CPU has it) picks the vectorised rows; both paths give
/// the same raster.
fn rasterise(
    mesh_faces: &[[usize; 3]],
    canvas: &[[f64; 2]],
    boxes: &[Option<PixelBox>],
    width: usize,
    height: usize,
    avx2: bool,
) -> Vec<u32> {
    #[cfg(target_arch = "x86_64")]
    let avx2 = avx2 && simd::available();
    #[cfg(not(target_arch = "x86_64"))]
    let _ = avx2;
    // Rasterise: canvas pixel → covering triangle (the last face in index order wins on shared
    // edges). Parallel over bands of rows: each band visits, in index order, the faces whose
    // row range meets it, so the result does not depend on the thread count.
    let mut face_id = vec![NONE; width * height];
    let band = RASTER_BAND_ROWS;
    let n_bands = height.div_ceil(band);
    let mut band_count = vec![0usize; n_bands + 1];
    for &(_, y0, _, y1) in boxes.iter().flatten() {
        for bi in y0 / band..=y1 / band {
            band_count[bi + 1] += 1;
        }
    }
    for i in 1..band_count.len() {
        band_count[i] += band_count[i - 1];
    }
    let mut band_faces = vec![0u32; band_count[n_bands]];
    let mut fill = band_count.clone();
    for (t, r) in boxes.iter().enumerate() {
        if let Some((_, y0, _, y1)) = *r {
            for bi in y0 / band..=y1 / band {
                band_faces[fill[bi]] = t as u32;
                fill[bi] += 1;
            }
        }
    }
    face_id.par_chunks_mut(band * width).enumerate().for_each(|(bi, chunk)| {
        let band = RasterBand {
            chunk,
            width,
            y0: bi * band,
            faces: &band_faces[band_count[bi]..band_count[bi + 1]],
            mesh_faces,
            canvas,
            boxes,
        };
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: `avx2` is only true when the CPU supports AVX2.
            return unsafe { simd::raster_band(band) };
        }
        band.raster::<false>();
    });
    face_id
}

impl Warp {
    /// Build the warp of `mesh` to the flattened positions `p_flat` (one per vertex).
    pub fn new(mesh: &CpcMesh, p_flat: Vec<[f64; 2]>, src_width: usize, src_height: usize) -> Result<Warp> {
        if p_flat.len() != mesh.n_vertices() {
            return Err(CpcError::SizeMismatch(format!(
                "{} flattened positions for {} vertices",
                p_flat.len(),
                mesh.n_vertices()
            )));
        }
        if p_flat.iter().any(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(CpcError::invalid("flattened mesh", "has non-finite vertex positions"));
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &p_flat {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let origin = [lo[0].floor(), lo[1].floor()];
        let width = (hi[0] - origin[0]).floor() as usize + 1;
        let height = (hi[1] - origin[1]).floor() as usize + 1;
        if width.saturating_mul(height) > MAX_CANVAS_FACTOR * src_width.max(1) * src_height.max(1) {
            return Err(CpcError::invalid(
                "flattened mesh",
                format!("canvas {width}x{height} is more than {MAX_CANVAS_FACTOR}x the input image"),
            ));
        }
        let canvas: Vec<[f64; 2]> = p_flat.iter().map(|p| sub(*p, origin)).collect();
        // Per face (in parallel, each face independently): the affine map canvas → original and
        // the canvas pixel range to rasterise.
        let face_map = |f: &[usize; 3]| -> ([f64; 8], Option<PixelBox>) {
            let (a, b, c) = (canvas[f[0]], canvas[f[1]], canvas[f[2]]);
            let (pa, pb, pc) = (mesh.p_init[f[0]], mesh.p_init[f[1]], mesh.p_init[f[2]]);
            let inv = edge_map(sub(pb, pa), sub(pc, pa), sub(b, a), sub(c, a)).unwrap_or([f64::NAN; 4]);
            let af = [pa[0], pa[1], a[0], a[1], inv[0], inv[1], inv[2], inv[3]];
            if signed_area(a, b, c) == 0.0 || inv[0].is_nan() {
                return (af, None);
            }
            // Canvas coordinates are ≥ 0 (origin = floor of the minimum): truncation is floor,
            // and avoids a libm call per bound.
            let x0 = ceil_nonneg(a[0].min(b[0]).min(c[0]));
            let y0 = ceil_nonneg(a[1].min(b[1]).min(c[1]));
            let x1 = (a[0].max(b[0]).max(c[0]).max(0.0) as i64 as usize).min(width - 1);
            let y1 = (a[1].max(b[1]).max(c[1]).max(0.0) as i64 as usize).min(height - 1);
            (af, (y0 <= y1 && x0 <= x1).then_some((x0, y0, x1, y1)))
        };
        // Written in place (`unzip_into_vecs` of an indexed iterator; a plain parallel `unzip`
        // concatenates per-thread lists, which costs more than the maps themselves).
        let (mut inv_aff, mut rows_of): (Vec<[f64; 8]>, Vec<Option<PixelBox>>) = (Vec::new(), Vec::new());
        mesh.faces.par_iter().with_min_len(1024).map(face_map).unzip_into_vecs(&mut inv_aff, &mut rows_of);
        let face_id = rasterise(&mesh.faces, &canvas, &rows_of, width, height, simd_available());
        Ok(Warp {
            mesh: mesh.clone(),
            p_flat,
            origin,
            width,
            height,
            src_width,
            src_height,
            inv_aff,
            fwd_lin: std::sync::OnceLock::new(),
            face_id,
            buckets: std::sync::OnceLock::new(),
        })
    }

    /// The mesh this warp was built on.
    pub fn mesh(&self) -> &CpcMesh {
        &self.mesh
    }

    /// Canvas position of vertex `v`.
    #[inline]
    fn canvas_vertex(&self, v: usize) -> [f64; 2] {
        sub(self.p_flat[v], self.origin)
    }

    /// Original coordinates of canvas point `q` through the affine map of face `t`.
    #[inline]
    fn inv_affine(&self, t: usize, q: [f64; 2]) -> [f64; 2] {
        inv_apply(&self.inv_aff[t], q)
    }

    /// Canvas coordinates of original point `q` through the affine map of face `t`.
    #[inline]
    fn fwd_affine(&self, t: usize, q: [f64; 2]) -> [f64; 2] {
        let f = self.mesh.faces[t];
        let a = self.canvas_vertex(f[0]);
        let pa = self.mesh.p_init[f[0]];
        let l = self.fwd_lin.get_or_init(|| {
            self.mesh
                .faces
                .iter()
                .map(|f| {
                    let (a, b, c) = (self.canvas_vertex(f[0]), self.canvas_vertex(f[1]), self.canvas_vertex(f[2]));
                    let (pa, pb, pc) = (self.mesh.p_init[f[0]], self.mesh.p_init[f[1]], self.mesh.p_init[f[2]]);
                    edge_map(sub(b, a), sub(c, a), sub(pb, pa), sub(pc, pa)).unwrap_or([f64::NAN; 4])
                })
                .collect::<Vec<_>>()
        })[t];
        let d = sub(q, pa);
        [a[0] + (l[0] * d[0] + l[1] * d[1]), a[1] + (l[2] * d[0] + l[3] * d[1])]
    }

    /// Local magnification of every face: the largest singular value of its original → canvas
    /// affine map (px of output per px of input along the most stretched direction); NaN for
    /// degenerate faces.
    pub fn face_magnification(&self) -> Vec<f64> {
        self.mesh
            .faces
            .par_iter()
            .map(|f| {
                let (a, b, c) = (self.canvas_vertex(f[0]), self.canvas_vertex(f[1]), self.canvas_vertex(f[2]));
                let (pa, pb, pc) = (self.mesh.p_init[f[0]], self.mesh.p_init[f[1]], self.mesh.p_init[f[2]]);
                match edge_map(sub(b, a), sub(c, a), sub(pb, pa), sub(pc, pa)) {
                    Some(l) => largest_singular_value(l),
                    None => f64::NAN,
                }
            })
            .collect()
    }

    /// Near-grazing guard: remove from the raster (so from the warped image, its validity mask and
    /// the backward map) every face whose [`Warp::face_magnification`] exceeds `limit` times the
    /// median over the faces. Returns the number of faces removed.
    pub fn mask_magnified(&mut self, limit: f64) -> Result<usize> {
        if !(limit.is_finite() && limit >= 1.0) {
            return Err(CpcError::invalid("max_rel_magnification", format!("{limit} must be a finite number >= 1")));
        }
        let mag = self.face_magnification();
        let mut finite: Vec<f64> = mag.iter().copied().filter(|m| m.is_finite() && *m > 0.0).collect();
        if finite.is_empty() {
            return Ok(0);
        }
        let med = laparo_core::stats::median(&mut finite);
        let cut = limit * med;
        let drop: Vec<bool> = mag.iter().map(|&m| m.is_nan() || m > cut).collect();
        let n = drop.iter().filter(|&&d| d).count();
        if n > 0 {
            self.face_id.par_iter_mut().for_each(|t| {
                if *t != NONE && drop[*t as usize] {
                    *t = NONE;
                }
            });
        }
        Ok(n)
    }

    /// Whether canvas pixel (x, y) is covered by a (kept) face of the warp.
    pub fn covers_pixel(&self, x: usize, y: usize) -> bool {
        x < self.width && y < self.height && self.face_id[y * self.width + x] != NONE
    }

    /// Original image coordinates of canvas pixel (x, y), if it is covered by the mesh.
    pub fn backward_pixel(&self, x: usize, y: usize) -> Option<[f64; 2]> {
        let t = *self.face_id.get(y * self.width + x)?;
        if t == NONE {
            return None;
        }
        Some(self.inv_affine(t as usize, [x as f64, y as f64]))
    }

    /// Warp `image` (any number of channels and texel type, same size as the depth/ROI):
    /// piecewise-affine inverse mapping, bilinear sampling by [`laparo_core::remap`] (source
    /// positions in f32, clamped to the pixel-centre hull against round-off). Returns the warped
    /// image and its validity mask (uncovered canvas pixels are 0 / false).
    pub fn warp_image<T: Texel + Default>(&self, image: &Image<T>) -> Result<(Image<T>, Mask)> {
        self.warp_image_with(image, Interp::Bilinear)
    }

    /// [`Warp::warp_image`] with a chosen interpolation (bicubic keeps the fine texture that
    /// bilinear averaging blurs at sub-pixel offsets; see [`laparo_core::remap`]).
    pub fn warp_image_with<T: Texel + Default>(&self, image: &Image<T>, interp: Interp) -> Result<(Image<T>, Mask)> {
        if image.width != self.src_width || image.height != self.src_height {
            return Err(CpcError::SizeMismatch(format!(
                "image is {}x{}, the mesh was built on {}x{}",
                image.width, image.height, self.src_width, self.src_height
            )));
        }
        let (width, wmax, hmax) = (self.width, (image.width - 1) as f64, (image.height - 1) as f64);
        let coords = |y: usize, sx: &mut [f32], sy: &mut [f32]| {
            let fid = &self.face_id[y * width..(y + 1) * width];
            let yf = y as i32 as f64;
            for (x, ((&t, a), b)) in fid.iter().zip(sx.iter_mut()).zip(sy.iter_mut()).enumerate() {
                if t == NONE {
                    (*a, *b) = (f32::NAN, f32::NAN);
                } else {
                    let q = inv_apply(&self.inv_aff[t as usize], [x as i32 as f64, yf]);
                    (*a, *b) = (q[0].clamp(0.0, wmax) as f32, q[1].clamp(0.0, hmax) as f32);
                }
            }
        };
        remap_rows(image, self.width, self.height, interp, T::default(), coords)
            .map_err(|e| CpcError::SizeMismatch(e.to_string()))
    }

    /// Dense coordinate maps (see [`WarpMaps`]).
    pub fn maps(&self) -> WarpMaps {
        let mut backward = Image::filled(self.width, self.height, 2, f64::NAN);
        backward.data.par_chunks_mut(self.width * 2).enumerate().for_each(|(y, row)| {
            for x in 0..self.width {
                if let Some(q) = self.backward_pixel(x, y) {
                    row[2 * x] = q[0];
                    row[2 * x + 1] = q[1];
                }
            }
        });
        let mut forward = Image::filled(self.src_width, self.src_height, 2, f64::NAN);
        forward.data.par_chunks_mut(self.src_width * 2).enumerate().for_each(|(y, row)| {
            for x in 0..self.src_width {
                if let Some(q) = self.original_to_warped(x as f64, y as f64) {
                    row[2 * x] = q[0];
                    row[2 * x + 1] = q[1];
                }
            }
        });
        WarpMaps { backward, forward }
    }

    /// Canvas coordinates of original image point (u, v), or `None` outside the mesh.
    pub fn original_to_warped(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let (t, w) = self.mesh.locate_initial(u, v)?;
        let f = self.mesh.faces[t];
        let (a, b, c) = (self.canvas_vertex(f[0]), self.canvas_vertex(f[1]), self.canvas_vertex(f[2]));
        Some([w[0] * a[0] + w[1] * b[0] + w[2] * c[0], w[0] * a[1] + w[1] * b[1] + w[2] * c[1]])
    }

    /// The flattened triangle containing canvas point (x, y) and its barycentric coordinates.
    pub fn locate_warped(&self, x: f64, y: f64) -> Option<(usize, [f64; 3])> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        // Buckets for point location (cell ≈ 2 grid steps), built on the first query.
        let bk = self.buckets.get_or_init(|| {
            Buckets::build(&self.mesh.faces, |v| self.canvas_vertex(v), self.mesh.grid_step_px, self.width, self.height)
        });
        let bx = (x / bk.px).floor();
        let by = (y / bk.px).floor();
        if bx < 0.0 || by < 0.0 || bx as usize >= bk.cols || by as usize >= bk.rows {
            return None;
        }
        let b = by as usize * bk.cols + bx as usize;
        let mut best: Option<(usize, [f64; 3], f64)> = None;
        for &t in &bk.items[bk.start[b] as usize..bk.start[b + 1] as usize] {
            let f = self.mesh.faces[t as usize];
            let (a, bb, c) = (self.canvas_vertex(f[0]), self.canvas_vertex(f[1]), self.canvas_vertex(f[2]));
            if signed_area(a, bb, c) == 0.0 {
                continue;
            }
            let w = barycentric([x, y], a, bb, c);
            let mn = w[0].min(w[1]).min(w[2]);
            if mn >= -1e-9 && best.as_ref().is_none_or(|bst| mn > bst.2) {
                best = Some((t as usize, w, mn));
            }
        }
        best.map(|(t, w, _)| (t, w))
    }

    /// Original image coordinates of canvas point (x, y), or `None` outside the flattened mesh.
    pub fn warped_to_original(&self, x: f64, y: f64) -> Option<[f64; 2]> {
        let (t, w) = self.locate_warped(x, y)?;
        let f = self.mesh.faces[t];
        let (a, b, c) = (self.mesh.p_init[f[0]], self.mesh.p_init[f[1]], self.mesh.p_init[f[2]]);
        Some([w[0] * a[0] + w[1] * b[0] + w[2] * c[0], w[0] * a[1] + w[1] * b[1] + w[2] * c[1]])
    }

    /// Canvas coordinates of original point `q` by the affine map of the initial triangle
    /// containing it (same as [`Warp::original_to_warped`], via the per-face affine maps).
    pub fn original_to_warped_affine(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let (t, _) = self.mesh.locate_initial(u, v)?;
        Some(self.fwd_affine(t, [u, v]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{cpc_warp, CpcParams};
    use crate::scene::bumpy_bowl_spec;

    /// Deterministic pseudo-random numbers in [0, 1) (xorshift).
    fn rng(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The warp samples exactly what the contract of `laparo_core::remap` gives at the affine
    /// source position of every covered canvas pixel (f32, clamped to the pixel-centre hull).
    #[test]
    fn warp_samples_the_shared_kernel_at_the_affine_source_positions() {
        let sc = bumpy_bowl_spec().render().unwrap();
        let r = cpc_warp(&sc.image, &sc.depth, &sc.intrinsics, &sc.roi, &CpcParams::default()).unwrap();
        let w = &r.warp;
        let (out, mask) = w.warp_image(&sc.image).unwrap();
        let (wmax, hmax) = ((sc.image.width - 1) as f64, (sc.image.height - 1) as f64);
        let mut checked = 0;
        for y in (0..w.height).step_by(7) {
            for x in (0..w.width).step_by(5) {
                match w.backward_pixel(x, y) {
                    None => assert!(!mask.get(x, y, 0) && out.pixel(x, y).iter().all(|&v| v == 0)),
                    Some(q) => {
                        let (qx, qy) = (q[0].clamp(0.0, wmax), q[1].clamp(0.0, hmax));
                        let one =
                            laparo_core::remap::CoordMap { width: 1, height: 1, xy: vec![[qx as f32, qy as f32]] };
                        let (v, m) = laparo_core::remap::remap(&sc.image, &one, Interp::Bilinear, 0).unwrap();
                        assert!(m.data[0] && mask.get(x, y, 0));
                        assert_eq!(out.pixel(x, y), &v.data[..], "pixel ({x}, {y})");
                        // And within half a grey level (+ f32 rounding) of the f64 bilinear value.
                        for c in 0..sc.image.channels {
                            let exact = sc.image.sample_bilinear(qx, qy, c).unwrap();
                            assert!((out.get(x, y, c) as f64 - exact).abs() <= 0.51, "{exact}");
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked}");
    }

    /// Random triangles (rows whose length is not a multiple of 4, faces overlapping, slivers):
    /// the AVX2 rasterisation gives the scalar raster.
    #[test]
    fn simd_raster_matches_the_scalar_code_on_random_triangles() {
        let mut seed = 0x2545f4914f6cdd1du64;
        let (width, height) = (37, 29);
        let canvas: Vec<[f64; 2]> = (0..300).map(|_| [rng(&mut seed) * 36.9, rng(&mut seed) * 28.9]).collect();
        let faces: Vec<[usize; 3]> = (0..100).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let boxes: Vec<Option<PixelBox>> = faces
            .iter()
            .map(|f| {
                let (a, b, c) = (canvas[f[0]], canvas[f[1]], canvas[f[2]]);
                let x0 = ceil_nonneg(a[0].min(b[0]).min(c[0]));
                let y0 = ceil_nonneg(a[1].min(b[1]).min(c[1]));
                let x1 = (a[0].max(b[0]).max(c[0]) as usize).min(width - 1);
                let y1 = (a[1].max(b[1]).max(c[1]) as usize).min(height - 1);
                (y0 <= y1 && x0 <= x1).then_some((x0, y0, x1, y1))
            })
            .collect();
        let scalar = rasterise(&faces, &canvas, &boxes, width, height, false);
        assert_eq!(scalar, rasterise(&faces, &canvas, &boxes, width, height, true));
        assert!(scalar.iter().filter(|&&t| t != NONE).count() > width * height / 2);
    }

    /// The AVX2 rasterisation gives bitwise the same raster as the scalar code (on a CPU without
    /// AVX2 both calls take the scalar path).
    #[test]
    fn simd_paths_match_the_scalar_code() {
        let sc = bumpy_bowl_spec().render().unwrap();
        // Without the magnification guard, which removes faces from the raster afterwards.
        let p = CpcParams { max_rel_magnification: None, ..CpcParams::default() };
        let r = cpc_warp(&sc.image, &sc.depth, &sc.intrinsics, &sc.roi, &p).unwrap();
        let w = &r.warp;
        let canvas: Vec<[f64; 2]> = w.p_flat.iter().map(|p| sub(*p, w.origin)).collect();
        let boxes: Vec<Option<PixelBox>> = w
            .mesh
            .faces
            .iter()
            .map(|f| {
                let (a, b, c) = (canvas[f[0]], canvas[f[1]], canvas[f[2]]);
                if signed_area(a, b, c) == 0.0 {
                    return None;
                }
                let x0 = ceil_nonneg(a[0].min(b[0]).min(c[0]));
                let y0 = ceil_nonneg(a[1].min(b[1]).min(c[1]));
                let x1 = (a[0].max(b[0]).max(c[0]).max(0.0) as usize).min(w.width - 1);
                let y1 = (a[1].max(b[1]).max(c[1]).max(0.0) as usize).min(w.height - 1);
                (y0 <= y1 && x0 <= x1).then_some((x0, y0, x1, y1))
            })
            .collect();
        let scalar = rasterise(&w.mesh.faces, &canvas, &boxes, w.width, w.height, false);
        let vector = rasterise(&w.mesh.faces, &canvas, &boxes, w.width, w.height, true);
        assert_eq!(scalar, vector);
        assert_eq!(scalar, w.face_id);
        assert!(scalar.iter().filter(|&&t| t != NONE).count() > 100_000);
    }
}
