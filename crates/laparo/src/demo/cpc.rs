//! Demo section: cpc (being written).
use super::DemoSection;
use anyhow::Result;
use std::path::Path;

pub fn section(_out: &Path) -> Result<DemoSection> {
    Ok(DemoSection { title: "cpc".into(), html: "<p>This section is being written.</p>".into(), summary: serde_json::Value::Null })
}
