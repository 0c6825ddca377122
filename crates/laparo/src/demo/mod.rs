//! `laparo demo`: every module on built-in data, one report section each, written to
//! `<out>/index.html` (figures as PNG beside it) and `<out>/summary.json`.
//!
//! Each module's section lives in its own file and returns a [`DemoSection`]; figures go
//! under `<out>/<module>/`. The report is assembled and written atomically at the end.
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod cpc;
mod depth;
mod guide;
mod mpm;
mod register;
mod stereo;

/// Arguments of `laparo demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// Output folder of the report.
    #[arg(long, default_value = "demo-report")]
    pub out: PathBuf,
    /// Only these sections (depth, stereo, cpc, mpm, register, guide); all by default.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
}

/// One module's part of the report.
pub struct DemoSection {
    /// Section heading.
    pub title: String,
    /// HTML fragment (figures referenced relative to the report folder).
    pub html: String,
    /// Machine-readable figures of the section, merged into summary.json.
    pub summary: serde_json::Value,
}

type SectionFn = fn(&Path) -> Result<DemoSection>;

/// `<shared>/data/<rel>`, if present, where `<shared>` is `$LAPARO_SHARED_DATA`, else
/// `../shared/data` from the working directory, else `../shared/data` beside the repository the
/// executable was built in (`<repo>/target/<profile>/laparo`). Looked up at run time (no
/// compile-time source paths). Demo sections use real data from there when they can and fall back
/// to built-in data otherwise.
pub(crate) fn shared_data(rel: &str) -> Option<PathBuf> {
    let env = std::env::var_os("LAPARO_SHARED_DATA").map(PathBuf::from);
    let beside_exe = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent()?.parent()?.parent()?.parent().map(|r| r.join("shared/data")));
    env.into_iter().chain([PathBuf::from("../shared/data")]).chain(beside_exe).map(|d| d.join(rel)).find(|p| p.exists())
}

/// Run the demo.
pub fn run(args: DemoArgs) -> Result<()> {
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let sections: [(&str, SectionFn); 6] = [
        ("depth", depth::section),
        ("stereo", stereo::section),
        ("cpc", cpc::section),
        ("mpm", mpm::section),
        ("register", register::section),
        ("guide", guide::section),
    ];
    let mut html = String::new();
    let mut summary = serde_json::Map::new();
    let mut toc = String::new();
    for (name, f) in sections {
        if !args.only.is_empty() && !args.only.iter().any(|o| o == name) {
            continue;
        }
        eprintln!("[demo] {name} ...");
        let t0 = Instant::now();
        let dir = out.join(name);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let s = f(out).with_context(|| format!("demo section '{name}'"))?;
        let secs = t0.elapsed().as_secs_f64();
        eprintln!("[demo] {name} done in {secs:.1} s");
        toc.push_str(&format!("<li><a href=\"#{name}\">{}</a></li>\n", s.title));
        html.push_str(&format!(
            "<section id=\"{name}\"><h2>{}</h2>\n{}\n<p class=\"t\">section computed in {secs:.2} s</p></section>\n",
            s.title, s.html
        ));
        summary.insert(name.to_string(), s.summary);
    }
    let page = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>laparo demo report</title>\n<style>\
body{{font-family:sans-serif;max-width:1200px;margin:2em auto;line-height:1.4}}img{{max-width:100%}}\
table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:2px 8px;text-align:right}}td:first-child{{text-align:left}}\
.t{{color:#777;font-size:small}}figure{{display:inline-block;margin:4px}}</style></head><body>\n\
<h1>laparo demo report</h1><p>laparo {} — every module run on built-in data.</p><ul>{toc}</ul>\n{html}</body></html>\n",
        env!("CARGO_PKG_VERSION")
    );
    laparo_core::atomic::write_atomic(&out.join("summary.json"), serde_json::to_string_pretty(&summary)?.as_bytes())?;
    laparo_core::atomic::write_atomic(&out.join("index.html"), page.as_bytes())?;
    println!("report written to {}", out.join("index.html").display());
    Ok(())
}
