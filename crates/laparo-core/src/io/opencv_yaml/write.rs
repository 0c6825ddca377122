//! The FileStorage YAML writer (shortest round-trip reals, `!!opencv-matrix` blocks).
use super::parse::scalar;
use super::FsNode;
use std::fmt::Write as _;

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

pub(super) fn emit(s: &mut String, key: &str, v: &FsNode, indent: usize) {
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
