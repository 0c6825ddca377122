//! OpenCV FileStorage YAML (`%YAML:1.0`, `!!opencv-matrix`): a value tree, a reader and a writer.
//!
//! The reader is hand-written: no maintained crate parses OpenCV's YAML dialect (`%YAML:1.0`
//! header, `!!opencv-matrix` tags); generic YAML crates reject the header. It is bounded against
//! malformed input: collections nest at most [`MAX_DEPTH`] levels, duplicate keys are found with a
//! hash set (linear time), and matrix sizes are checked against the data before use.
use crate::atomic::write_atomic;
use crate::error::{CoreError, Result};
use nalgebra::{Matrix3, Vector3};
use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// FileStorage value tree
// ---------------------------------------------------------------------------------------------

/// A dense matrix from a `!!opencv-matrix` node (row-major, `channels` interleaved).
#[derive(Clone, Debug, PartialEq)]
pub struct FsMatrix {
    pub rows: usize,
    pub cols: usize,
    pub channels: usize,
    /// OpenCV element type code as written (`d`, `f`, `i`, `u`, `3d`, ...).
    pub dt: String,
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

    /// As a 3×3 matrix, if it is one.
    pub fn to_matrix3(&self) -> Option<Matrix3<f64>> {
        (self.rows == 3 && self.cols == 3 && self.channels == 1).then(|| Matrix3::from_row_slice(&self.data))
    }

    /// As a 3-vector if it is 3×1 or 1×3.
    pub fn to_vector3(&self) -> Option<Vector3<f64>> {
        (self.rows * self.cols * self.channels == 3).then(|| Vector3::new(self.data[0], self.data[1], self.data[2]))
    }
}

/// One node of an OpenCV FileStorage document.
#[derive(Clone, Debug, PartialEq)]
pub enum FsNode {
    Int(i64),
    Real(f64),
    Str(String),
    Seq(Vec<FsNode>),
    /// A mapping, keys in file order.
    Map(Vec<(String, FsNode)>),
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
            None => Err(CoreError::format(&self.path, format!("no '{key}' entry (keys: {:?})", self.keys()))),
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

// ----- parsing -------------------------------------------------------------------------------

/// Deepest nesting of collections (flow `[`/`{` or block indentation) the reader accepts; real
/// calibration files nest 2-3 levels. Bounds the recursion so hostile input cannot overflow the stack.
pub const MAX_DEPTH: usize = 64;

struct Line {
    no: usize,
    indent: usize,
    text: String,
}

/// Quote state while scanning YAML text: handles `"..."` with backslash escapes and `'...'`.
#[derive(Default)]
struct QuoteScan {
    quote: Option<char>,
    escaped: bool,
}

impl QuoteScan {
    /// Feed one character; true if it is outside any quoted string (and not a quote itself).
    fn outside(&mut self, ch: char) -> bool {
        match self.quote {
            Some(_) if self.escaped => {
                self.escaped = false;
                false
            }
            Some('"') if ch == '\\' => {
                self.escaped = true;
                false
            }
            Some(q) if ch == q => {
                self.quote = None;
                false
            }
            Some(_) => false,
            None if ch == '"' || ch == '\'' => {
                self.quote = Some(ch);
                false
            }
            None => true,
        }
    }
}

/// Position of a YAML comment `#` (at the start or after whitespace, outside quotes).
fn comment_start(s: &str) -> Option<usize> {
    let mut q = QuoteScan::default();
    let mut prev_ws = true;
    for (i, ch) in s.char_indices() {
        if q.outside(ch) && ch == '#' && prev_ws {
            return Some(i);
        }
        prev_ws = ch.is_whitespace();
    }
    None
}

/// Bracket depth change of `s` outside quotes.
fn bracket_balance(s: &str) -> i64 {
    let mut q = QuoteScan::default();
    let mut depth = 0i64;
    for ch in s.chars() {
        if q.outside(ch) {
            match ch {
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                _ => {}
            }
        }
    }
    depth
}

/// Strip comments, directives and document markers; join flow collections spanning lines.
fn logical_lines(text: &str, path: &Path) -> Result<Vec<Line>> {
    let mut out: Vec<Line> = Vec::new();
    let mut pending: Option<(Line, i64)> = None;
    for (idx, raw) in text.lines().enumerate() {
        let no = idx + 1;
        let raw = raw.trim_end_matches('\r');
        let body = match comment_start(raw) {
            Some(c) => &raw[..c],
            None => raw,
        };
        let trimmed = body.trim();
        if let Some((mut l, depth)) = pending.take() {
            if trimmed.is_empty() {
                pending = Some((l, depth));
                continue;
            }
            l.text.push(' ');
            l.text.push_str(trimmed);
            let d = depth + bracket_balance(trimmed);
            if d > 0 {
                pending = Some((l, d));
            } else {
                out.push(l);
            }
            continue;
        }
        if trimmed.is_empty() {
            continue;
        }
        let indent = body.len() - body.trim_start().len();
        if indent == 0
            && (trimmed.starts_with('%') || trimmed == "---" || trimmed == "..." || trimmed.starts_with("--- "))
        {
            continue;
        }
        let l = Line { no, indent, text: trimmed.to_string() };
        let d = bracket_balance(trimmed);
        if d > 0 {
            pending = Some((l, d));
        } else if d < 0 {
            return Err(CoreError::format(path, format!("line {no}: unbalanced closing bracket")));
        } else {
            out.push(l);
        }
    }
    if let Some((l, _)) = pending {
        return Err(CoreError::format(path, format!("line {}: '[' or '{{' never closed (file truncated?)", l.no)));
    }
    Ok(out)
}

/// Split `key: rest` at the first `:` followed by whitespace or end of line, outside quotes.
fn split_key(s: &str) -> Option<(String, &str)> {
    let mut q = QuoteScan::default();
    let mut it = s.char_indices().peekable();
    while let Some((i, ch)) = it.next() {
        if !q.outside(ch) {
            continue;
        }
        match ch {
            '[' | '{' => return None,
            ':' if !matches!(it.peek(), Some((_, n)) if !n.is_whitespace()) => {
                let key = unquote(s[..i].trim());
                if key.is_empty() {
                    return None;
                }
                return Some((key, s[i + 1..].trim()));
            }
            _ => {}
        }
    }
    None
}

fn unquote(s: &str) -> String {
    let b = s.as_bytes();
    if b.len() >= 2 && b[0] == b'\'' && b[b.len() - 1] == b'\'' {
        return s[1..s.len() - 1].replace("''", "'");
    }
    if b.len() >= 2 && b[0] == b'"' && b[b.len() - 1] == b'"' {
        let mut out = String::with_capacity(s.len());
        let mut chars = s[1..s.len() - 1].chars();
        while let Some(c) = chars.next() {
            if c != '\\' {
                out.push(c);
                continue;
            }
            match chars.next() {
                Some('n') => out.push('\n'),
                Some('t') => out.push('\t'),
                Some('"') => out.push('"'),
                Some('\\') => out.push('\\'),
                Some(o) => {
                    out.push('\\');
                    out.push(o);
                }
                None => out.push('\\'),
            }
        }
        return out;
    }
    s.to_string()
}

/// A plain scalar: integer, real (including `.Inf`, `-.Inf`, `.NaN`) or string.
fn scalar(s: &str) -> FsNode {
    let s = s.trim();
    if s.starts_with('"') || s.starts_with('\'') {
        return FsNode::Str(unquote(s));
    }
    if let Ok(i) = s.parse::<i64>() {
        return FsNode::Int(i);
    }
    match s.to_ascii_lowercase().as_str() {
        ".inf" | "+.inf" => return FsNode::Real(f64::INFINITY),
        "-.inf" => return FsNode::Real(f64::NEG_INFINITY),
        ".nan" => return FsNode::Real(f64::NAN),
        _ => {}
    }
    let numeric = s.starts_with(|c: char| c.is_ascii_digit() || c == '-' || c == '+' || c == '.');
    if numeric {
        if let Ok(r) = s.parse::<f64>() {
            return FsNode::Real(r);
        }
    }
    FsNode::Str(s.to_string())
}

/// Parser for one flow collection `[ ... ]` / `{ ... }` (already joined onto one line).
struct FlowParser<'a> {
    s: &'a [u8],
    src: &'a str,
    pos: usize,
    depth: usize,
}

impl FlowParser<'_> {
    fn ws(&mut self) {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }
    fn value(&mut self) -> std::result::Result<FsNode, String> {
        self.ws();
        // Tags inside flow collections (rare) are skipped.
        if self.src[self.pos..].starts_with("!!") {
            while self.pos < self.s.len() && !self.s[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            self.ws();
        }
        let opened = matches!(self.s.get(self.pos), Some(b'[') | Some(b'{'));
        if opened {
            self.depth += 1;
            if self.depth > MAX_DEPTH {
                return Err(format!("collections nested deeper than {MAX_DEPTH} levels at column {}", self.pos + 1));
            }
        }
        let v = self.value_inner();
        if opened {
            self.depth -= 1;
        }
        v
    }
    fn value_inner(&mut self) -> std::result::Result<FsNode, String> {
        match self.s.get(self.pos) {
            Some(b'[') => {
                self.pos += 1;
                let mut items = Vec::new();
                loop {
                    self.ws();
                    match self.s.get(self.pos) {
                        Some(b']') => {
                            self.pos += 1;
                            return Ok(FsNode::Seq(items));
                        }
                        None => return Err("unterminated '['".into()),
                        _ => {}
                    }
                    items.push(self.value()?);
                    self.ws();
                    match self.s.get(self.pos) {
                        Some(b',') => self.pos += 1,
                        Some(b']') => {}
                        _ => return Err(format!("expected ',' or ']' at column {}", self.pos + 1)),
                    }
                }
            }
            Some(b'{') => {
                self.pos += 1;
                let mut items = Vec::new();
                loop {
                    self.ws();
                    match self.s.get(self.pos) {
                        Some(b'}') => {
                            self.pos += 1;
                            return Ok(FsNode::Map(items));
                        }
                        None => return Err("unterminated '{'".into()),
                        _ => {}
                    }
                    let start = self.pos;
                    while self.pos < self.s.len() && self.s[self.pos] != b':' {
                        self.pos += 1;
                    }
                    if self.pos >= self.s.len() {
                        return Err("expected 'key: value' inside '{ }'".into());
                    }
                    let key = unquote(self.src[start..self.pos].trim());
                    self.pos += 1;
                    let v = self.value()?;
                    items.push((key, v));
                    self.ws();
                    match self.s.get(self.pos) {
                        Some(b',') => self.pos += 1,
                        Some(b'}') => {}
                        _ => return Err(format!("expected ',' or '}}' at column {}", self.pos + 1)),
                    }
                }
            }
            Some(b'"') | Some(b'\'') => {
                let q = self.s[self.pos];
                let start = self.pos;
                self.pos += 1;
                while self.pos < self.s.len() && self.s[self.pos] != q {
                    // backslash escapes inside double quotes
                    self.pos += if q == b'"' && self.s[self.pos] == b'\\' { 2 } else { 1 };
                }
                if self.pos >= self.s.len() {
                    self.pos = self.s.len();
                    return Err("unterminated quoted string".into());
                }
                self.pos += 1;
                Ok(FsNode::Str(unquote(&self.src[start..self.pos])))
            }
            Some(_) => {
                let start = self.pos;
                while self.pos < self.s.len() && !matches!(self.s[self.pos], b',' | b']' | b'}') {
                    self.pos += 1;
                }
                let tok = self.src[start..self.pos].trim();
                if tok.is_empty() {
                    return Err(format!("empty value at column {}", start + 1));
                }
                Ok(scalar(tok))
            }
            None => Err("missing value".into()),
        }
    }
}

fn parse_flow(s: &str) -> std::result::Result<FsNode, String> {
    let mut p = FlowParser { s: s.as_bytes(), src: s, pos: 0, depth: 0 };
    let v = p.value()?;
    p.ws();
    if p.pos != s.len() {
        return Err(format!("unexpected text after the closing bracket: '{}'", &s[p.pos..]));
    }
    Ok(v)
}

struct BlockParser<'a> {
    lines: Vec<Line>,
    i: usize,
    path: &'a Path,
    /// Current nesting of block collections (bounded by [`MAX_DEPTH`]).
    depth: usize,
}

impl BlockParser<'_> {
    fn err(&self, no: usize, msg: impl std::fmt::Display) -> CoreError {
        CoreError::format(self.path, format!("line {no}: {msg}"))
    }

    fn is_seq_item(text: &str) -> bool {
        text == "-" || text.starts_with("- ")
    }

    fn parse_map(&mut self, indent: usize) -> Result<Vec<(String, FsNode)>> {
        let mut out: Vec<(String, FsNode)> = Vec::new();
        let mut seen: HashSet<String> = HashSet::new();
        while self.i < self.lines.len() && self.lines[self.i].indent == indent {
            let (no, text) = (self.lines[self.i].no, self.lines[self.i].text.clone());
            if Self::is_seq_item(&text) {
                return Err(self.err(no, "a sequence item where a 'key: value' was expected"));
            }
            let Some((key, rest)) = split_key(&text) else {
                return Err(self.err(no, format!("expected 'key: value', found '{text}'")));
            };
            if !seen.insert(key.clone()) {
                return Err(self.err(no, format!("duplicate key '{key}'")));
            }
            self.i += 1;
            let v = self.parse_value(rest, indent, no, true)?;
            out.push((key, v));
        }
        Ok(out)
    }

    fn parse_seq(&mut self, indent: usize) -> Result<Vec<FsNode>> {
        let mut out = Vec::new();
        while self.i < self.lines.len()
            && self.lines[self.i].indent == indent
            && Self::is_seq_item(&self.lines[self.i].text)
        {
            let (no, text) = (self.lines[self.i].no, self.lines[self.i].text.clone());
            let rest = text[1..].trim_start();
            let offset = text.len() - rest.len();
            if !rest.is_empty() && !rest.starts_with(['[', '{', '"', '\'', '!']) && split_key(rest).is_some() {
                // "- key: value" starts a mapping indented at the key's column.
                self.lines[self.i].indent = indent + offset;
                self.lines[self.i].text = rest.to_string();
                out.push(FsNode::Map(self.parse_map(indent + offset)?));
            } else {
                self.i += 1;
                out.push(self.parse_value(rest, indent, no, false)?);
            }
        }
        Ok(out)
    }

    /// The value after `key:` (or `-`) on line `no`, whose block children are indented more
    /// than `indent`.
    fn parse_value(&mut self, rest: &str, indent: usize, no: usize, in_map: bool) -> Result<FsNode> {
        let (tag, rest) = match rest.strip_prefix("!!") {
            Some(tagged) => match tagged.find(char::is_whitespace) {
                Some(p) => (Some(&tagged[..p]), tagged[p..].trim()),
                None => (Some(tagged), ""),
            },
            None => (None, rest),
        };
        let node = if rest.is_empty() {
            self.depth += 1;
            if self.depth > MAX_DEPTH {
                return Err(self.err(no, format!("collections nested deeper than {MAX_DEPTH} levels")));
            }
            let n = match self.lines.get(self.i) {
                Some(next) if next.indent > indent => {
                    let ind = next.indent;
                    if Self::is_seq_item(&next.text) {
                        FsNode::Seq(self.parse_seq(ind)?)
                    } else {
                        FsNode::Map(self.parse_map(ind)?)
                    }
                }
                // YAML allows "key:\n- a\n- b" with the items at the key's own indentation.
                Some(next) if in_map && next.indent == indent && Self::is_seq_item(&next.text) => {
                    FsNode::Seq(self.parse_seq(indent)?)
                }
                _ => FsNode::Empty,
            };
            self.depth -= 1;
            n
        } else if rest.starts_with('[') || rest.starts_with('{') {
            parse_flow(rest).map_err(|m| self.err(no, m))?
        } else {
            scalar(rest)
        };
        match tag {
            Some("opencv-matrix") => self.to_matrix(node, no),
            Some("opencv-nd-matrix") => self.nd_to_matrix(node, no),
            _ => Ok(node),
        }
    }

    fn to_matrix(&self, node: FsNode, no: usize) -> Result<FsNode> {
        let field = |k: &str| node.get(k).ok_or_else(|| self.err(no, format!("opencv-matrix without '{k}'")));
        let rows = field("rows")?.as_usize().ok_or_else(|| self.err(no, "opencv-matrix 'rows' is not an integer"))?;
        let cols = field("cols")?.as_usize().ok_or_else(|| self.err(no, "opencv-matrix 'cols' is not an integer"))?;
        let dt = match field("dt")? {
            FsNode::Str(s) => s.clone(),
            FsNode::Int(i) => i.to_string(),
            _ => return Err(self.err(no, "opencv-matrix 'dt' is not a type code")),
        };
        let data = match field("data")? {
            FsNode::Empty => Vec::new(),
            d => d.numbers().ok_or_else(|| self.err(no, "opencv-matrix 'data' is not a list of numbers"))?,
        };
        let channels = channels_of(&dt);
        let n = rows.checked_mul(cols).and_then(|v| v.checked_mul(channels));
        if n != Some(data.len()) {
            return Err(self.err(
                no,
                format!(
                    "opencv-matrix {rows}x{cols} ({dt}) needs {} values, 'data' has {}",
                    rows as u128 * cols as u128 * channels as u128,
                    data.len()
                ),
            ));
        }
        Ok(FsNode::Mat(FsMatrix { rows, cols, channels, dt, data }))
    }

    fn nd_to_matrix(&self, node: FsNode, no: usize) -> Result<FsNode> {
        let sizes: Vec<usize> = node
            .get("sizes")
            .and_then(|s| s.numbers())
            .map(|v| v.iter().map(|&x| x as usize).collect())
            .ok_or_else(|| self.err(no, "opencv-nd-matrix without 'sizes'"))?;
        let (rows, cols) = match sizes.as_slice() {
            [n] => (*n, 1),
            [r, c] => (*r, *c),
            [r, rest @ ..] => (*r, rest.iter().fold(1usize, |a, &b| a.saturating_mul(b))),
            [] => (0, 0),
        };
        let mut m = node.clone();
        if let FsNode::Map(ref mut kv) = m {
            kv.push(("rows".into(), FsNode::Int(rows as i64)));
            kv.push(("cols".into(), FsNode::Int(cols as i64)));
        }
        self.to_matrix(m, no)
    }
}

fn channels_of(dt: &str) -> usize {
    let digits: String = dt.chars().take_while(|c| c.is_ascii_digit()).collect();
    digits.parse().unwrap_or(1).max(1)
}

// ----- writing -------------------------------------------------------------------------------

fn fmt_real(v: f64) -> String {
    if v.is_nan() {
        ".Nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { ".Inf" } else { "-.Inf" }.into()
    } else {
        // Shortest representation that reads back to the same f64.
        let s = format!("{v:?}");
        if s.contains(['.', 'e', 'E']) {
            s
        } else {
            format!("{s}.")
        }
    }
}

fn fmt_scalar(n: &FsNode) -> Option<String> {
    Some(match n {
        FsNode::Int(i) => i.to_string(),
        FsNode::Real(r) => fmt_real(*r),
        FsNode::Str(s) => {
            let plain = !s.is_empty()
                && matches!(scalar(s), FsNode::Str(_))
                && !s.contains([':', '#', '[', ']', '{', '}', ',', '"', '\'', '\n'])
                && !s.starts_with(['!', '-', '%', '&', '*', ' '])
                && !s.ends_with(' ');
            if plain {
                s.clone()
            } else {
                format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\"").replace('\n', "\\n"))
            }
        }
        FsNode::Empty => String::new(),
        _ => return None,
    })
}

fn flow_list(items: &[String], indent: usize) -> String {
    // Wrap long lists like OpenCV does (a few values per line).
    let mut s = String::from("[ ");
    let mut line_len = 0;
    for (i, it) in items.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
            if line_len > 70 {
                s.push('\n');
                s.push_str(&" ".repeat(indent + 4));
                line_len = 0;
            }
        }
        s.push_str(it);
        line_len += it.len() + 2;
    }
    s.push_str(" ]");
    s
}

/// Block sequence items `- x` at `indent`; nested collections go on the following lines.
fn emit_items(s: &mut String, items: &[FsNode], indent: usize) {
    let pad = " ".repeat(indent);
    for it in items {
        match (fmt_scalar(it), it) {
            (Some(t), _) => {
                let _ = writeln!(s, "{pad}- {t}");
            }
            (None, FsNode::Map(kv)) => {
                let _ = writeln!(s, "{pad}-");
                for (k, x) in kv {
                    emit(s, k, x, indent + 3);
                }
            }
            (None, FsNode::Seq(inner)) => {
                let _ = writeln!(s, "{pad}-");
                emit_items(s, inner, indent + 3);
            }
            (None, FsNode::Mat(m)) => {
                // A matrix item: "- !!opencv-matrix" then its fields.
                let mut tmp = String::new();
                emit(&mut tmp, "x", &FsNode::Mat(m.clone()), indent + 2);
                let tmp = tmp.replacen(&format!("{}x: ", " ".repeat(indent + 2)), &format!("{pad}- "), 1);
                s.push_str(&tmp);
            }
            (None, _) => {}
        }
    }
}

fn emit(s: &mut String, key: &str, v: &FsNode, indent: usize) {
    let pad = " ".repeat(indent);
    let key = fmt_scalar(&FsNode::Str(key.to_string())).unwrap_or_default();
    match v {
        FsNode::Mat(m) => {
            let _ = writeln!(s, "{pad}{key}: !!opencv-matrix");
            let _ = writeln!(s, "{pad}   rows: {}", m.rows);
            let _ = writeln!(s, "{pad}   cols: {}", m.cols);
            let _ = writeln!(s, "{pad}   dt: {}", m.dt);
            let items: Vec<String> = m.data.iter().map(|&x| fmt_real(x)).collect();
            let _ = writeln!(s, "{pad}   data: {}", flow_list(&items, indent + 3));
        }
        FsNode::Map(kv) => {
            let _ = writeln!(s, "{pad}{key}:");
            for (k, x) in kv {
                emit(s, k, x, indent + 3);
            }
        }
        FsNode::Seq(items) => {
            let flat: Option<Vec<String>> = items.iter().map(fmt_scalar).collect();
            match flat {
                Some(f) => {
                    let _ = writeln!(s, "{pad}{key}: {}", flow_list(&f, indent));
                }
                None => {
                    let _ = writeln!(s, "{pad}{key}:");
                    emit_items(s, items, indent + 3);
                }
            }
        }
        other => {
            let _ = writeln!(s, "{pad}{key}: {}", fmt_scalar(other).unwrap_or_default());
        }
    }
}
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
