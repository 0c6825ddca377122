//! The FileStorage YAML parser: logical lines (comments stripped, multi-line flow collections
//! joined), a block parser driven by indentation and a flow parser for `[...]` / `{...}`, both
//! with nesting bounded by [`MAX_DEPTH`].
use super::{FsMatrix, FsNode};
use crate::error::{CoreError, Result};
use std::collections::HashSet;
use std::path::Path;

/// Deepest nesting of collections (flow `[`/`{` or block indentation) the reader accepts; real
/// calibration files nest 2-3 levels. Bounds the recursion so hostile input cannot overflow the stack.
pub const MAX_DEPTH: usize = 64;

pub(super) struct Line {
    pub(super) no: usize,
    pub(super) indent: usize,
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
pub(super) fn logical_lines(text: &str, path: &Path) -> Result<Vec<Line>> {
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
pub(super) fn scalar(s: &str) -> FsNode {
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
    pub(super) depth: usize,
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

pub(super) struct BlockParser<'a> {
    pub(super) lines: Vec<Line>,
    pub(super) i: usize,
    pub(super) path: &'a Path,
    /// Current nesting of block collections (bounded by [`MAX_DEPTH`]).
    pub(super) depth: usize,
}

impl BlockParser<'_> {
    fn err(&self, no: usize, msg: impl std::fmt::Display) -> CoreError {
        CoreError::format(self.path, format!("line {no}: {msg}"))
    }

    fn is_seq_item(text: &str) -> bool {
        text == "-" || text.starts_with("- ")
    }

    pub(super) fn parse_map(&mut self, indent: usize) -> Result<Vec<(String, FsNode)>> {
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
