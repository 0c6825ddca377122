//! OpenCV FileStorage YAML (`%YAML:1.0`, `!!opencv-matrix`): a value tree, a reader and a writer.
//!
//! The reader is hand-written: no maintained crate parses OpenCV's YAML dialect (`%YAML:1.0`
//! header, `!!opencv-matrix` tags); generic YAML crates reject the header. It is bounded against
//! malformed input: collections nest at most [`MAX_DEPTH`] levels, duplicate keys are found with a
//! hash set (linear time), and matrix sizes are checked against the data before use.
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::{Matrix3, Vector3};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// FileStorage value tree
// ---------------------------------------------------------------------------------------------

/// A dense matrix from a `!!opencv-matrix` node (row-major, `channels` interleaved).
#[derive(Clone, Debug, PartialEq)]
pub struct FsMatrix {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Interleaved channels per element.
    pub channels: usize,
    /// OpenCV element type code as written (`d`, `f`, `i`, `u`, `3d`, ...).
    pub dt: String,
    /// Row-major values (channels interleaved), as f64.
    pub data: Vec<f64>,
}

impl FsMatrix {
    /// A single-channel f64 matrix (`dt: d`).
    pub fn new(rows: usize, cols: usize, data: Vec<f64>) -> Result<Self> {
        if rows.checked_mul(cols) != Some(data.len()) {
            return Err(CoreError::SizeMismatch(format!(
                "matrix {rows}x{cols} needs {} values, got {}",
                rows as u128 * cols as u128,
                data.len()
            )));
        }
        Ok(FsMatrix { rows, cols, channels: 1, dt: "d".into(), data })
    }

    /// Element (r, c) of a single-channel matrix.
    pub fn get(&self, r: usize, c: usize) -> f64 {
        self.data[(r * self.cols + c) * self.channels]
    }

    /// As a 3×3 matrix, if it is one: 3×3, or a flat list of 9 values (row-major).
    pub fn to_matrix3(&self) -> Option<Matrix3<f64>> {
        let shape_ok = (self.rows == 3 && self.cols == 3) || self.rows == 1 || self.cols == 1;
        (shape_ok && self.channels == 1 && self.data.len() == 9).then(|| Matrix3::from_row_slice(&self.data))
    }

    /// As a 3-vector if it is 3×1 or 1×3.
    pub fn to_vector3(&self) -> Option<Vector3<f64>> {
        (self.rows * self.cols * self.channels == 3).then(|| Vector3::new(self.data[0], self.data[1], self.data[2]))
    }
}

/// One node of an OpenCV FileStorage document.
#[derive(Clone, Debug, PartialEq)]
pub enum FsNode {
    /// An integer scalar.
    Int(i64),
    /// A real scalar.
    Real(f64),
    /// A string scalar.
    Str(String),
    /// A sequence `[ ... ]` or `- ...` items.
    Seq(Vec<FsNode>),
    /// A mapping, keys in file order.
    Map(Vec<(String, FsNode)>),
    /// An `!!opencv-matrix`.
    Mat(FsMatrix),
    /// `key:` with nothing after it.
    Empty,
}

impl FsNode {
    /// Numeric value of an Int or Real node.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            FsNode::Int(i) => Some(*i as f64),
            FsNode::Real(r) => Some(*r),
            _ => None,
        }
    }
    /// Non-negative integer value (a Real with an integral value is accepted).
    pub fn as_usize(&self) -> Option<usize> {
        match self {
            FsNode::Int(i) if *i >= 0 => Some(*i as usize),
            FsNode::Real(r) if *r >= 0.0 && r.fract() == 0.0 && *r < 1e15 => Some(*r as usize),
            _ => None,
        }
    }
    /// String value.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            FsNode::Str(s) => Some(s),
            _ => None,
        }
    }
    /// Value of `key` in a Map node.
    pub fn get(&self, key: &str) -> Option<&FsNode> {
        match self {
            FsNode::Map(m) => m.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }
    /// All numbers of a Mat, or of a Seq of numbers.
    pub fn numbers(&self) -> Option<Vec<f64>> {
        match self {
            FsNode::Mat(m) => Some(m.data.clone()),
            FsNode::Seq(s) => s.iter().map(|v| v.as_f64()).collect(),
            _ => None,
        }
    }
}

/// A parsed OpenCV FileStorage YAML document: its top-level mapping, keys in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct FileStorage {
    /// The file it was read from (used in error messages; empty for in-memory documents).
    pub path: PathBuf,
    /// Top-level key/value pairs in file order.
    pub entries: Vec<(String, FsNode)>,
}

impl FileStorage {
    /// Value of a top-level key.
    pub fn get(&self, key: &str) -> Option<&FsNode> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }

    /// The first of `keys` present at the top level, with its name.
    pub fn get_any<'a>(&'a self, keys: &[&'a str]) -> Option<(&'a str, &'a FsNode)> {
        keys.iter().find_map(|k| self.get(k).map(|v| (*k, v)))
    }

    /// Top-level keys in file order.
    pub fn keys(&self) -> Vec<&str> {
        self.entries.iter().map(|(k, _)| k.as_str()).collect()
    }

    /// The top-level keys for an error message: at most 12, then "... and N more".
    pub fn keys_summary(&self) -> String {
        let k = self.keys();
        if k.len() <= 12 {
            format!("{k:?}")
        } else {
            format!("{:?} ... and {} more", &k[..12], k.len() - 12)
        }
    }

    /// The matrix stored under `key` (an `!!opencv-matrix`, or a flow sequence of numbers read as
    /// a column); an error naming the file when the key is missing or holds something else.
    pub fn matrix(&self, key: &str) -> Result<FsMatrix> {
        match self.get(key) {
            Some(FsNode::Mat(m)) => Ok(m.clone()),
            Some(n @ FsNode::Seq(_)) => match n.numbers() {
                Some(v) => Ok(FsMatrix { rows: v.len(), cols: 1, channels: 1, dt: "d".into(), data: v }),
                None => Err(CoreError::format(&self.path, format!("'{key}' is a sequence but not of numbers"))),
            },
            Some(_) => Err(CoreError::format(&self.path, format!("'{key}' is not a matrix"))),
            None => Err(CoreError::format(&self.path, format!("no '{key}' entry (keys: {})", self.keys_summary()))),
        }
    }

    /// Parse FileStorage YAML text; `path` only names the source in errors.
    pub fn parse(text: &str, path: impl Into<PathBuf>) -> Result<Self> {
        let path = path.into();
        let lines = logical_lines(text, &path)?;
        let mut p = BlockParser { lines, i: 0, path: &path, depth: 0 };
        if p.lines.is_empty() {
            return Err(CoreError::format(&path, "no entries in the FileStorage document"));
        }
        let indent = p.lines[0].indent;
        let entries = p.parse_map(indent)?;
        if p.i < p.lines.len() {
            let l = &p.lines[p.i];
            return Err(CoreError::format(&path, format!("line {}: unexpected indentation", l.no)));
        }
        Ok(FileStorage { path, entries })
    }

    /// Serialise as OpenCV FileStorage YAML (readable by `cv::FileStorage` and [`read_filestorage`]).
    pub fn to_yaml(&self) -> String {
        let mut s = String::from("%YAML:1.0\n---\n");
        for (k, v) in &self.entries {
            emit(&mut s, k, v, 0);
        }
        s
    }

    /// Write the document to `path` atomically.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        write_atomic(path.as_ref(), self.to_yaml().as_bytes())
    }
}

/// Read an OpenCV FileStorage YAML file (`%YAML:1.0` header optional).
pub fn read_filestorage(path: impl AsRef<Path>) -> Result<FileStorage> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| CoreError::io(path, e))?;
    let text = String::from_utf8(bytes).map_err(|_| CoreError::format(path, "not UTF-8 text"))?;
    let first = text.lines().map(str::trim).find(|l| !l.is_empty() && !l.starts_with('#'));
    match first {
        None => return Err(CoreError::format(path, "empty file")),
        Some(l) if l.starts_with('<') => {
            return Err(CoreError::format(path, "XML FileStorage is not supported; save it as YAML"))
        }
        Some(l) if l.starts_with('{') => {
            return Err(CoreError::format(path, "looks like JSON, not OpenCV FileStorage YAML"))
        }
        _ => {}
    }
    FileStorage::parse(&text, path)
}

mod parse;
mod write;
pub use parse::MAX_DEPTH;
use parse::{logical_lines, BlockParser};
use write::emit;

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "%YAML:1.0\n---\n# comment line\nimage_width: 640\nimage_height: 480 # trailing\n\
name: \"left cam: a\"\nM1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 500., 0., 320.5,\n       0., 510.,\n       240., 0., 0., 1. ]\n\
vals: [ 1, -2.5e-3, .Inf ]\nnested:\n   a: 1\n   b: [ x, \"y z\" ]\nitems:\n   - 1\n   - two\n   - { k: 3 }\ncolor: !!opencv-matrix\n   rows: 1\n   cols: 1\n   dt: 3u\n   data: [ 1, 2, 3 ]\n";

    #[test]
    fn filestorage_parses_matrices_scalars_sequences() {
        let fs = FileStorage::parse(SAMPLE, "sample.yml").unwrap();
        assert_eq!(fs.keys(), vec!["image_width", "image_height", "name", "M1", "vals", "nested", "items", "color"]);
        assert_eq!(fs.get("image_width"), Some(&FsNode::Int(640)));
        assert_eq!(fs.get("name").unwrap().as_str(), Some("left cam: a"));
        let m = fs.matrix("M1").unwrap();
        assert_eq!((m.rows, m.cols), (3, 3));
        assert_eq!(m.get(0, 2), 320.5);
        assert_eq!(m.get(1, 1), 510.0);
        let v = fs.get("vals").unwrap().numbers().unwrap();
        assert_eq!(v[0], 1.0);
        assert_eq!(v[1], -2.5e-3);
        assert!(v[2].is_infinite());
        let n = fs.get("nested").unwrap();
        assert_eq!(n.get("a"), Some(&FsNode::Int(1)));
        assert_eq!(n.get("b"), Some(&FsNode::Seq(vec![FsNode::Str("x".into()), FsNode::Str("y z".into())])));
        match fs.get("items").unwrap() {
            FsNode::Seq(s) => {
                assert_eq!(s.len(), 3);
                assert_eq!(s[1], FsNode::Str("two".into()));
                assert_eq!(s[2].get("k"), Some(&FsNode::Int(3)));
            }
            other => panic!("{other:?}"),
        }
        let c = fs.matrix("color").unwrap();
        assert_eq!((c.channels, c.data.len()), (3, 3));
    }

    #[test]
    fn filestorage_writer_round_trip() {
        let fs = FileStorage::parse(SAMPLE, "sample.yml").unwrap();
        let text = fs.to_yaml();
        let back = FileStorage::parse(&text, "back.yml").unwrap();
        assert_eq!(back.keys(), fs.keys());
        for (k, v) in &fs.entries {
            if k == "vals" {
                continue; // contains inf; compared below
            }
            assert_eq!(back.get(k), Some(v), "{k}\n{text}");
        }
        assert!(back.get("vals").unwrap().numbers().unwrap()[2].is_infinite());
        // nested collections inside sequences
        let nested = FsNode::Seq(vec![
            FsNode::Seq(vec![FsNode::Int(1), FsNode::Seq(vec![FsNode::Str("a b".into())])]),
            FsNode::Mat(FsMatrix::new(1, 2, vec![0.5, -1.0]).unwrap()),
            FsNode::Map(vec![("k".into(), FsNode::Real(2.5)), ("e".into(), FsNode::Empty)]),
            FsNode::Str("-starts with dash".into()),
            FsNode::Str("123".into()),
        ]);
        let fs = FileStorage { path: PathBuf::new(), entries: vec![("n".into(), nested.clone())] };
        let text = fs.to_yaml();
        assert_eq!(FileStorage::parse(&text, "n").unwrap().get("n"), Some(&nested), "{text}");
        // bit-exact reals with many digits and a long wrapped data list
        let data: Vec<f64> = (0..40).map(|i| (i as f64 * 0.731).sin() * 1e-7 + 1.0 / 3.0).collect();
        let fs = FileStorage {
            path: PathBuf::new(),
            entries: vec![("A".into(), FsNode::Mat(FsMatrix::new(5, 8, data.clone()).unwrap()))],
        };
        let back = FileStorage::parse(&fs.to_yaml(), "x").unwrap();
        assert_eq!(back.matrix("A").unwrap().data, data);
    }

    #[test]
    fn filestorage_errors_name_the_file_and_line() {
        let cases = [
            "%YAML:1.0\nM: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 2.,\n",
            "%YAML:1.0\nM: !!opencv-matrix\n   rows: 2\n   cols: 2\n   dt: d\n   data: [ 1., 2., 3. ]\n",
            "%YAML:1.0\njust some words\n",
            "%YAML:1.0\na: 1\na: 2\n",
            "%YAML:1.0\na: [ 1, 2 ] ]\n",
        ];
        for c in cases {
            let e = FileStorage::parse(c, "broken.yml").unwrap_err().to_string();
            assert!(e.contains("broken.yml") && e.contains("line"), "{e}");
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("empty.yml");
        std::fs::write(&p, "%YAML:1.0\n").unwrap();
        assert!(read_filestorage(&p).unwrap_err().to_string().contains("empty.yml"));
        assert!(read_filestorage(dir.path().join("nope.yml")).unwrap_err().to_string().contains("nope.yml"));
    }

    /// Regression (issue 10): ~30,000 nested `[` overflowed the stack and aborted the process.
    #[test]
    fn deep_nesting_is_an_error_not_a_stack_overflow() {
        let text = format!("%YAML:1.0\na: {}1{}\n", "[".repeat(30_000), "]".repeat(30_000));
        let e = FileStorage::parse(&text, "deep.yml").unwrap_err().to_string();
        assert!(e.contains("deep.yml") && e.contains("nested deeper than 64"), "{e}");
        let text = format!("%YAML:1.0\na: {}1{}\n", "{k: ".repeat(100), "}".repeat(100));
        assert!(FileStorage::parse(&text, "deep.yml").unwrap_err().to_string().contains("nested deeper"));
        // 64 levels are accepted.
        let text = format!("%YAML:1.0\na: {}1{}\n", "[".repeat(64), "]".repeat(64));
        assert!(FileStorage::parse(&text, "ok.yml").is_ok());
        // Block nesting by indentation is bounded the same way.
        let mut text = String::from("%YAML:1.0\n");
        for i in 0..200 {
            text += &format!("{}k{i}:\n", " ".repeat(i));
        }
        let e = FileStorage::parse(&text, "block.yml").unwrap_err().to_string();
        assert!(e.contains("block.yml") && e.contains("nested deeper"), "{e}");
    }

    /// Regression (issue 10): 100k distinct keys took ~50 s (quadratic duplicate check).
    #[test]
    fn many_distinct_keys_parse_and_duplicates_are_still_found() {
        let mut text = String::from("%YAML:1.0\n");
        for i in 0..100_000 {
            text += &format!("key{i}: {i}\n");
        }
        let fs = FileStorage::parse(&text, "many.yml").unwrap();
        assert_eq!(fs.entries.len(), 100_000);
        assert_eq!(fs.get("key99999"), Some(&FsNode::Int(99_999)));
        text += "key5: 1\n";
        let e = FileStorage::parse(&text, "many.yml").unwrap_err().to_string();
        assert!(e.contains("duplicate key 'key5'") && e.contains("line 100002"), "{e}");
    }

    #[test]
    fn nd_matrix_with_huge_sizes_is_an_error() {
        let text = "%YAML:1.0\nm: !!opencv-nd-matrix\n   sizes: [ 4294967296, 4294967296, 4294967296 ]\n   dt: d\n   data: [ 1. ]\n";
        assert!(FileStorage::parse(text, "nd.yml").unwrap_err().to_string().contains("nd.yml"));
    }
}
