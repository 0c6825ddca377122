//! Tables as data: one [`Table`] rendered to markdown (reports, terminals) and to HTML (the demo
//! report), so that no output has to be parsed back from another.

/// A table of text cells: one header row and body rows (cells already formatted).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Table {
    /// Header cells.
    pub header: Vec<String>,
    /// Body rows (each as long as the header).
    pub rows: Vec<Vec<String>>,
}

fn md_row(cells: &[String]) -> String {
    let mut s = String::from("|");
    for c in cells {
        if c.is_empty() {
            s.push_str(" |");
        } else {
            s.push(' ');
            s.push_str(&c.replace('|', "\\|"));
            s.push_str(" |");
        }
    }
    s
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

impl Table {
    /// A table with this header and no rows.
    pub fn new<S: Into<String>>(header: impl IntoIterator<Item = S>) -> Table {
        Table { header: header.into_iter().map(Into::into).collect(), rows: Vec::new() }
    }

    /// Append a body row.
    pub fn push_row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) {
        self.rows.push(cells.into_iter().map(Into::into).collect());
    }

    /// GitHub-flavoured markdown: `| a | b |`, a `|---|` separator, one line per row (`|` in a
    /// cell escaped, an empty cell written `| |`).
    pub fn to_markdown(&self) -> String {
        let mut s = md_row(&self.header);
        s.push('\n');
        s.push('|');
        s.push_str(&"---|".repeat(self.header.len()));
        s.push('\n');
        for r in &self.rows {
            s.push_str(&md_row(r));
            s.push('\n');
        }
        s
    }

    /// An HTML `<table>` (header cells `<th>`, body cells `<td>`, text escaped).
    pub fn to_html(&self) -> String {
        let mut h = String::from("<table>\n<tr>");
        for c in &self.header {
            h.push_str(&format!("<th>{}</th>", html_escape(c)));
        }
        h.push_str("</tr>\n");
        for r in &self.rows {
            h.push_str("<tr>");
            for c in r {
                h.push_str(&format!("<td>{}</td>", html_escape(c)));
            }
            h.push_str("</tr>\n");
        }
        h.push_str("</table>\n");
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_table_two_renderings() {
        let mut t = Table::new(["", "n", "a<b"]);
        t.push_row(["row 1", "40", "1.5"]);
        t.push_row(["x|y", "", "&"]);
        assert_eq!(t.to_markdown(), "| | n | a<b |\n|---|---|---|\n| row 1 | 40 | 1.5 |\n| x\\|y | | & |\n");
        assert_eq!(
            t.to_html(),
            "<table>\n<tr><th></th><th>n</th><th>a&lt;b</th></tr>\n\
             <tr><td>row 1</td><td>40</td><td>1.5</td></tr>\n<tr><td>x|y</td><td></td><td>&amp;</td></tr>\n</table>\n"
        );
    }
}
