//! Outputs of `probecal selfcal`: `summary.json`, `ImageToProbe.xml` (PLUS's
//! Transform element, as `run` writes it) and `report.html` (the correction and
//! which directions were refined).

use std::path::Path;

use crate::io::fs::write_all_atomic;
use crate::pipeline::selfcal::SelfcalRun;
use crate::report::error::OutputError;
use crate::report::tracked::transform_files::plus_xml;
use crate::results::selfcal::SelfcalSummary;

const TEMPLATE: &str = include_str!("../../../templates/selfcal.html.tera");

fn html(summary: &SelfcalSummary) -> Result<String, OutputError> {
    let mut ctx = tera::Context::new();
    ctx.insert("sweeps", &summary.sweeps);
    ctx.insert("start_source", &summary.start_source);
    ctx.insert("lag_ms", &format!("{:.1}", summary.tracker_lag_s * 1e3));
    ctx.insert("correlation_start", &format!("{:.4}", summary.correlation_start));
    ctx.insert("correlation_end", &format!("{:.4}", summary.correlation_end));
    ctx.insert("voxels", &summary.voxels_compared);
    ctx.insert("voxel_mm", &summary.settings.comparison.voxel_mm);
    ctx.insert("corner_mm", &format!("{:.2}", summary.corner_change_mm));
    ctx.insert("move_mm", &summary.move_mm.map(|v| format!("{v:+.2}")));
    ctx.insert("turn_deg", &summary.turn_deg.map(|v| format!("{v:+.2}")));
    ctx.insert("radius_mm", &format!("{:.1}", summary.radius_mm));
    ctx.insert("ratio", &summary.settings.min_curvature_ratio);
    ctx.insert("resamples", &summary.settings.resamples);
    ctx.insert("max_se", &summary.settings.max_standard_error_mm);
    let directions: Vec<serde_json::Value> = summary
        .directions
        .iter()
        .map(|d| {
            serde_json::json!({
                "mostly": d.mostly,
                "curvature": format!("{:.4}", d.curvature_per_mm2),
                "standard_error": d.standard_error_mm.map_or("—".to_string(), |se| format!("{se:.2}")),
                "held": d.held,
            })
        })
        .collect();
    ctx.insert("directions", &directions);
    Ok(tera::Tera::one_off(TEMPLATE, &ctx, true)?)
}

/// Writes `summary.json`, `ImageToProbe.xml` and `report.html` into `out` (whole, or nothing).
pub fn write(run: &SelfcalRun, out: &Path) -> Result<SelfcalSummary, OutputError> {
    let summary = SelfcalSummary::of(run);
    let text = crate::results::summary::to_text(&summary)?;
    let files = [
        ("summary.json".to_string(), text.into_bytes()),
        (
            "ImageToProbe.xml".to_string(),
            plus_xml(&run.image_to_probe()).into_bytes(),
        ),
        ("report.html".to_string(), html(&summary)?.into_bytes()),
    ];
    write_all_atomic(out, &files)?;
    Ok(summary)
}
