//! COLMAP `database.db` export (thesis §4.5.5: SfM with CPC matches): cameras, images, keypoints,
//! descriptors, matches and two_view_geometries, exactly as COLMAP's `database_sqlite.cc`
//! (see `shared/spec/features.md` §4). Blobs are raw little-endian row-major arrays.
use std::path::{Path, PathBuf};

use rusqlite::{params, Connection};

use crate::error::{FeaturesError, Result};
use crate::keypoint::{Descriptors, Keypoint, Match};

/// COLMAP's pair-id base: `pair_id = min · 2147483647 + max`.
pub const MAX_NUM_IMAGES: u64 = 2_147_483_647;

/// COLMAP's pair id of two image ids (order-independent).
pub fn pair_id(id1: u32, id2: u32) -> u64 {
    let (a, b) = if id1 <= id2 { (id1, id2) } else { (id2, id1) };
    a as u64 * MAX_NUM_IMAGES + b as u64
}

/// The two image ids `(smaller, larger)` of a COLMAP pair id.
pub fn pair_id_to_image_ids(pair_id: u64) -> (u32, u32) {
    let id2 = pair_id % MAX_NUM_IMAGES;
    (((pair_id - id2) / MAX_NUM_IMAGES) as u32, id2 as u32)
}

/// COLMAP camera models laparo writes (id, parameter count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraModel {
    /// 0: f, cx, cy.
    SimplePinhole,
    /// 1: fx, fy, cx, cy.
    Pinhole,
    /// 2: f, cx, cy, k.
    SimpleRadial,
    /// 4: fx, fy, cx, cy, k1, k2, p1, p2.
    Opencv,
}

impl CameraModel {
    /// COLMAP's model id.
    pub fn id(self) -> i64 {
        match self {
            CameraModel::SimplePinhole => 0,
            CameraModel::Pinhole => 1,
            CameraModel::SimpleRadial => 2,
            CameraModel::Opencv => 4,
        }
    }

    /// Number of parameters COLMAP expects.
    pub fn n_params(self) -> usize {
        match self {
            CameraModel::SimplePinhole => 3,
            CameraModel::Pinhole => 4,
            CameraModel::SimpleRadial => 4,
            CameraModel::Opencv => 8,
        }
    }
}

/// A camera row (params in px, COLMAP's pixel convention: centre of top-left pixel = (0.5, 0.5)).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// Model.
    pub model: CameraModel,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Parameters in COLMAP's order for `model`.
    pub params: Vec<f64>,
    /// Whether the focal length is trusted (`prior_focal_length`).
    pub prior_focal_length: bool,
}

/// COLMAP's two-view configuration codes (`two_view_geometry.h`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(i64)]
pub enum TwoViewConfig {
    /// 0
    Undefined = 0,
    /// 1
    Degenerate = 1,
    /// 2: E known (calibrated).
    Calibrated = 2,
    /// 3: F only.
    Uncalibrated = 3,
    /// 4: planar scene, H.
    Planar = 4,
    /// 5: pure rotation, H.
    Panoramic = 5,
    /// 6
    PlanarOrPanoramic = 6,
}

/// A verified two-view geometry (image 1 → image 2 as passed to [`ColmapDatabase::add_two_view_geometry`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TwoViewGeometry {
    /// Configuration code.
    pub config: TwoViewConfig,
    /// Inlier matches.
    pub inliers: Vec<Match>,
    /// Fundamental matrix, row-major (zeros if unknown).
    pub f: [f64; 9],
    /// Essential matrix, row-major (zeros if unknown).
    pub e: [f64; 9],
    /// Homography image 1 → image 2, row-major (zeros if unknown).
    pub h: [f64; 9],
    /// Rotation cam2_from_cam1 as quaternion (w, x, y, z).
    pub qvec: [f64; 4],
    /// Translation cam2_from_cam1.
    pub tvec: [f64; 3],
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS cameras (camera_id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, model INTEGER NOT NULL, width INTEGER NOT NULL, height INTEGER NOT NULL, params BLOB, prior_focal_length INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS images (image_id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, name TEXT NOT NULL UNIQUE, camera_id INTEGER NOT NULL, prior_qw REAL, prior_qx REAL, prior_qy REAL, prior_qz REAL, prior_tx REAL, prior_ty REAL, prior_tz REAL, CONSTRAINT image_id_check CHECK(image_id >= 0 and image_id < 2147483647), FOREIGN KEY(camera_id) REFERENCES cameras(camera_id));
CREATE UNIQUE INDEX IF NOT EXISTS index_name ON images(name);
CREATE TABLE IF NOT EXISTS keypoints (image_id INTEGER PRIMARY KEY NOT NULL, rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB, FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS descriptors (image_id INTEGER PRIMARY KEY NOT NULL, rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB, FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS matches (pair_id INTEGER PRIMARY KEY NOT NULL, rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB);
CREATE TABLE IF NOT EXISTS two_view_geometries (pair_id INTEGER PRIMARY KEY NOT NULL, rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB, config INTEGER NOT NULL, F BLOB, E BLOB, H BLOB, qvec BLOB, tvec BLOB);
";

/// SIFT float descriptors → COLMAP uint8: L1-root normalisation (COLMAP's default
/// `normalization = L1_ROOT`), then `min(255, round(512 · v))` per value.
pub fn sift_to_colmap_u8(desc: &[f32]) -> Vec<u8> {
    let l1: f32 = desc.iter().map(|v| v.abs()).sum();
    desc.iter()
        .map(|&v| {
            let r = if l1 > 0.0 { (v.abs() / l1).sqrt() } else { 0.0 };
            (512.0 * r).round().min(255.0) as u8
        })
        .collect()
}

fn f32_blob(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn f64_blob(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
/// Match pairs as uint32 (i1, i2) rows; `swap` exchanges the columns.
fn match_blob(m: &[Match], swap: bool) -> Vec<u8> {
    m.iter()
        .flat_map(|m| {
            let (a, b) = if swap { (m.i2, m.i1) } else { (m.i1, m.i2) };
            a.to_le_bytes().into_iter().chain(b.to_le_bytes())
        })
        .collect()
}

/// A COLMAP database being written: built in a temporary sibling file and renamed onto `path`
/// by [`ColmapDatabase::finish`] (an interrupted export never leaves a half-written database).
pub struct ColmapDatabase {
    conn: Option<Connection>,
    tmp: PathBuf,
    path: PathBuf,
}

impl ColmapDatabase {
    /// Start a new database for `path` (an existing file there is replaced on `finish`).
    pub fn create(path: &Path) -> Result<Self> {
        if let Some(parent) = path.parent() {
            if !parent.as_os_str().is_empty() {
                std::fs::create_dir_all(parent).map_err(|e| laparo_core::error::CoreError::io(parent, e))?;
            }
        }
        let tmp = laparo_core::atomic::temp_path(path);
        let db = |e: rusqlite::Error| FeaturesError::Database { path: path.display().to_string(), msg: e.to_string() };
        let conn = Connection::open(&tmp).map_err(db)?;
        conn.execute_batch(SCHEMA).map_err(db)?;
        conn.execute_batch("BEGIN").map_err(db)?;
        Ok(ColmapDatabase { conn: Some(conn), tmp, path: path.to_path_buf() })
    }

    fn c(&self) -> &Connection {
        self.conn.as_ref().expect("connection is open until finish")
    }

    fn err(&self, e: rusqlite::Error) -> FeaturesError {
        FeaturesError::Database { path: self.path.display().to_string(), msg: e.to_string() }
    }

    /// Add a camera; returns its id (1, 2, …).
    pub fn add_camera(&mut self, cam: &ColmapCamera) -> Result<u32> {
        if cam.params.len() != cam.model.n_params() {
            return Err(FeaturesError::invalid(
                "camera params",
                format!("{:?} needs {} parameters, got {}", cam.model, cam.model.n_params(), cam.params.len()),
            ));
        }
        self.c()
            .execute(
                "INSERT INTO cameras (model, width, height, params, prior_focal_length) VALUES (?1, ?2, ?3, ?4, ?5)",
                params![cam.model.id(), cam.width, cam.height, f64_blob(&cam.params), cam.prior_focal_length as i64],
            )
            .map_err(|e| self.err(e))?;
        Ok(self.c().last_insert_rowid() as u32)
    }

    /// Add an image (file name relative to the image folder); returns its id (1, 2, …).
    pub fn add_image(&mut self, name: &str, camera_id: u32) -> Result<u32> {
        self.c()
            .execute("INSERT INTO images (name, camera_id) VALUES (?1, ?2)", params![name, camera_id])
            .map_err(|e| self.err(e))?;
        Ok(self.c().last_insert_rowid() as u32)
    }

    /// Keypoints as float32 rows (x + 0.5, y + 0.5, scale = size/2, orientation rad): laparo's
    /// pixel centres are integers, COLMAP's top-left pixel centre is (0.5, 0.5).
    pub fn add_keypoints(&mut self, image_id: u32, kps: &[Keypoint]) -> Result<()> {
        let blob = f32_blob(
            kps.iter()
                .flat_map(|k| [(k.x + 0.5) as f32, (k.y + 0.5) as f32, (0.5 * k.size_px) as f32, k.angle_rad as f32]),
        );
        self.c()
            .execute(
                "INSERT INTO keypoints (image_id, rows, cols, data) VALUES (?1, ?2, 4, ?3)",
                params![image_id, kps.len() as i64, blob],
            )
            .map_err(|e| self.err(e))?;
        Ok(())
    }

    /// Descriptors: SIFT → uint8 rows × 128 ([`sift_to_colmap_u8`]); binary descriptors
    /// (which COLMAP cannot match) are stored as their raw bytes with `cols` = bytes.
    pub fn add_descriptors(&mut self, image_id: u32, d: &Descriptors) -> Result<()> {
        let (rows, cols, blob) = match d {
            Descriptors::Float { dim, data } => {
                (d.len(), *dim, data.chunks_exact(*dim).flat_map(sift_to_colmap_u8).collect::<Vec<u8>>())
            }
            Descriptors::Binary { bytes, data } => (d.len(), *bytes, data.clone()),
        };
        self.c()
            .execute(
                "INSERT INTO descriptors (image_id, rows, cols, data) VALUES (?1, ?2, ?3, ?4)",
                params![image_id, rows as i64, cols as i64, blob],
            )
            .map_err(|e| self.err(e))?;
        Ok(())
    }

    /// Raw matches between images `id1` and `id2` (`m.i1` indexes `id1`'s keypoints).
    pub fn add_matches(&mut self, id1: u32, id2: u32, m: &[Match]) -> Result<()> {
        self.c()
            .execute(
                "INSERT INTO matches (pair_id, rows, cols, data) VALUES (?1, ?2, 2, ?3)",
                params![pair_id(id1, id2) as i64, m.len() as i64, match_blob(m, id1 > id2)],
            )
            .map_err(|e| self.err(e))?;
        Ok(())
    }

    /// A verified geometry between `id1` and `id2` (what the mapper reads). When `id1 > id2` the
    /// columns are swapped and F, H are inverted / transposed as COLMAP does.
    pub fn add_two_view_geometry(&mut self, id1: u32, id2: u32, g: &TwoViewGeometry) -> Result<()> {
        let swap = id1 > id2;
        let (f, e, h) = if swap {
            let t = |m: &[f64; 9]| [m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]];
            let hinv = nalgebra::Matrix3::from_row_slice(&g.h).try_inverse().map(|m| {
                let mut r = [0.0; 9];
                for i in 0..3 {
                    for j in 0..3 {
                        r[i * 3 + j] = m[(i, j)];
                    }
                }
                r
            });
            (t(&g.f), t(&g.e), hinv.unwrap_or([0.0; 9]))
        } else {
            (g.f, g.e, g.h)
        };
        self.c()
            .execute(
                "INSERT INTO two_view_geometries (pair_id, rows, cols, data, config, F, E, H, qvec, tvec) \
                 VALUES (?1, ?2, 2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
                params![
                    pair_id(id1, id2) as i64,
                    g.inliers.len() as i64,
                    match_blob(&g.inliers, swap),
                    g.config as i64,
                    f64_blob(&f),
                    f64_blob(&e),
                    f64_blob(&h),
                    f64_blob(&g.qvec),
                    f64_blob(&g.tvec)
                ],
            )
            .map_err(|e| self.err(e))?;
        Ok(())
    }

    /// Commit, close and move the database onto its final path.
    pub fn finish(mut self) -> Result<()> {
        self.c().execute_batch("COMMIT").map_err(|e| self.err(e))?;
        if let Some(conn) = self.conn.take() {
            conn.close().map_err(|(_, e)| self.err(e))?;
        }
        std::fs::rename(&self.tmp, &self.path).map_err(|e| laparo_core::error::CoreError::io(&self.path, e))?;
        Ok(())
    }
}

impl Drop for ColmapDatabase {
    fn drop(&mut self) {
        // Unfinished: close and remove the temporary file (after `finish` it no longer exists).
        drop(self.conn.take());
        let _ = std::fs::remove_file(&self.tmp);
    }
}
