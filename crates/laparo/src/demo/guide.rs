//! Demo section "guide" (thesis §5.4.3, Fig. 5.10): the whole guidance chain on the quick in-silico scenario
//! (P2ILF liver, rendered stereo pair before and after an incision): stereo → depth → ICP → landmarks →
//! RODS-MPM → overlay, errors per stage against the ground truth. Needs the P2ILF data of ../shared/data.
use super::DemoSection;
use anyhow::Result;
use laparo_guide::pipeline::{GuideConfig, Route};
use laparo_guide::scenario::{self, ScenarioConfig};
use std::path::Path;

pub fn section(out: &Path) -> Result<DemoSection> {
    let (Some(organ), Some(frame), Some(camera)) = (
        super::shared_data("meshes/p2ilf/patient2_1_3d-liver-model.obj"),
        super::shared_data("surgical/p2ilf_frame/P2ILF22_patient1_12.jpg"),
        super::shared_data("meshes/p2ilf/acquisition-camera-metadata.json"),
    ) else {
        return Ok(DemoSection {
            title: "Guidance pipeline (§5.4.3)".into(),
            html: "<p>SKIP: the P2ILF liver, frame and camera of <code>../shared/data</code> are absent \
                   (set <code>LAPARO_SHARED_DATA</code>).</p>"
                .into(),
            summary: serde_json::Value::Null,
        });
    };
    let scn = out.join("guide/scenario");
    let run = out.join("guide/run");
    scenario::generate(&organ, &frame, &camera, None, &ScenarioConfig::quick(), &scn)?;
    let rep = laparo_guide::pipeline::run(&scn, &run, &GuideConfig::quick(Route::Calibrated), &mut |_| {})?;
    let html = format!(
        "<p>The guidance chain in silico on the real P2ILF liver (quick scenario, 960×540, the small stand-in \
         incision; <code>laparo guide scenario --deformation</code> takes the FEM ground truth of \
         <code>laparo register benchmark</code>): the past stereo pair → SGM → depth → ICP of the preoperative model \
         from a rough pose → the incision polyline back-projected to landmarks; the present pair → lips and visible \
         surface → RODS-MPM → deformed liver and tumour drawn on the present left image. \
         <a href=\"guide/run/report.html\">The full stage report</a> (every intermediate, errors and times).</p>\n\
         <figure><img src=\"guide/run/overlay.png\" width=\"640\"><figcaption>overlay on the present left image \
         (errors per stage in the report)</figcaption></figure>\n<pre>{}</pre>\n",
        serde_json::to_string_pretty(&rep.summary)?
    );
    Ok(DemoSection {
        title: "Guidance pipeline end to end (§5.4.3, Fig. 5.10)".into(),
        html,
        summary: rep.summary.clone(),
    })
}
