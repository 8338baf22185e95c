//! The run page's context: everything the HTML and LaTeX pages show, prepared
//! (numbers formatted, mm with 3 decimals as in the thesis). It is also written
//! as `report_context.json`, a stable target for tests.

use serde::Serialize;

use crate::core::geometry::to_rows;
use crate::evaluate::cutoff_label;
use crate::pipeline::record::DatasetRun;
use crate::report::page::context_rows::{
    calibration_rows, camera_rows, method_rows, mm, setup_rows, start_basin_rows, stat_rows, threshold_blocks,
    truth_by_cutoff, truth_rows, validation_rows,
};
pub use crate::report::page::context_rows::{AxisBlock, KeyValue, StatRow};

#[derive(Debug, Serialize, PartialEq)]
pub struct CutoffColumn {
    pub label: String,
    pub frames: usize,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Rejected {
    pub frame: usize,
    pub stage: String,
    pub reason: String,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Gate {
    pub name: String,
    pub limit: String,
    pub value: String,
    pub passed: bool,
}

/// Everything the page shows, formatted.
#[derive(Debug, Serialize, PartialEq)]
pub struct RunContext {
    pub experiment: String,
    pub dataset: String,
    pub description: String,
    pub manifest: String,
    pub manifest_sha256: String,
    pub probecal_version: String,
    pub frames_total: usize,
    pub frames_used: usize,
    pub frames_rejected: usize,
    pub camera: Vec<KeyValue>,
    pub calibration_matrix: Vec<Vec<String>>,
    pub calibration: Vec<KeyValue>,
    /// The thesis's BRE table at the calibration cut-off: rows Std./Mean/Min/Max, columns x, y, z.
    pub bre_caption: String,
    pub bre_table: Vec<StatRow>,
    /// The thesis's threshold table: one column per cut-off.
    pub threshold_columns: Vec<CutoffColumn>,
    pub threshold_blocks: Vec<AxisBlock>,
    pub truth: Vec<KeyValue>,
    pub truth_by_cutoff: Vec<StatRow>,
    pub gates: Vec<Gate>,
    pub rejected: Vec<Rejected>,
    /// The BRE figure's SVG, or why it was not drawn.
    pub bre_figure: Figure,
    /// Other estimators on the same frames: name, description, frames, truth errors.
    pub methods: Vec<StatRow>,
    /// Why two estimators give the same calibration, when they do.
    pub methods_agree: Vec<String>,
    /// Wire phantoms: the start guess's offset from where it converged.
    pub start_offset: String,
    /// Wire phantoms: per offset, the random starts that converged.
    pub start_basin: Vec<StatRow>,
    pub validation: Vec<KeyValue>,
    /// Manifest summary, software versions, inputs.
    pub setup: Vec<KeyValue>,
    /// B-scans with their detections: file beside the report (LaTeX), caption.
    pub gallery: Vec<GalleryEntry>,
    /// Further figures: PNG file beside the report (LaTeX), caption.
    pub figures: Vec<GalleryEntry>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct GalleryEntry {
    pub file: String,
    pub caption: String,
}

/// Prepares the page's context.
pub fn context(run: &DatasetRun, labels: &crate::pipeline::labels::RunLabels) -> RunContext {
    let fit = run.primary_fit();
    let primary = &run.thresholds[run.primary];
    let camera = camera_rows(run);
    let calibration = calibration_rows(run, labels);
    let threshold_blocks = threshold_blocks(run);
    let (truth, truth_by_cutoff) = match &run.truth {
        Some(tr) => (truth_rows(tr), truth_by_cutoff(run)),
        None => (Vec::new(), Vec::new()),
    };
    let used = run.used_frames();
    RunContext {
        experiment: run.experiment.clone(),
        dataset: run.dataset.clone(),
        description: labels.description.clone(),
        manifest: labels
            .manifest_path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        manifest_sha256: labels.manifest_sha256.clone(),
        probecal_version: env!("CARGO_PKG_VERSION").into(),
        frames_total: run.frames.len(),
        frames_used: used,
        frames_rejected: run.frames.len() - used,
        camera,
        calibration_matrix: to_rows(&fit.target_T_source)
            .iter()
            .map(|r| r.iter().map(|v| format!("{v:.4}")).collect())
            .collect(),
        calibration,
        bre_caption: format!(
            "BRE along axes for dataset {} ({} frames, cut-off {} mm)",
            run.dataset,
            primary.frames.len(),
            cutoff_label(primary.cutoff_mm)
        ),
        bre_table: primary.stats.as_ref().map(stat_rows).unwrap_or_default(),
        threshold_columns: run
            .thresholds
            .iter()
            .map(|r| CutoffColumn {
                label: cutoff_label(r.cutoff_mm),
                frames: r.frames.len(),
            })
            .collect(),
        threshold_blocks,
        truth,
        truth_by_cutoff,
        gates: run
            .gates
            .iter()
            .map(|g| Gate {
                name: g.name.clone(),
                limit: mm(g.limit),
                value: g.value.map(mm).unwrap_or_else(|| "—".into()),
                passed: g.passed,
            })
            .collect(),
        rejected: run
            .frames
            .iter()
            .filter_map(|f| {
                f.rejection.as_ref().map(|r| Rejected {
                    frame: f.files.frame,
                    stage: r.stage().label().into(),
                    reason: r.to_string(),
                })
            })
            .collect(),
        bre_figure: match crate::report::page::figures::bre_figure(run) {
            Ok(svg) => Figure::Svg(svg),
            Err(e) => Figure::NotDrawn(format!("figure not drawn: {e}")),
        },
        methods: method_rows(run),
        methods_agree: agreements(&run.methods),
        start_offset: run
            .start_guess
            .as_ref()
            .map(|g| {
                format!(
                    "The manifest's start guess (solve.initial_marker_T_image) is {:.1} mm and {:.1}° from the calibration it converged to.",
                    g.offset_translation_mm, g.offset_rotation_deg
                )
            })
            .unwrap_or_default(),
        start_basin: start_basin_rows(run),
        validation: validation_rows(run),
        setup: setup_rows(run, labels),
        gallery: Vec::new(),
        figures: Vec::new(),
    }
}

/// One sentence per pair of estimators that ended on the same calibration: the
/// same frames were left out, so the same final fit was solved.
fn agreements(methods: &[crate::pipeline::record::MethodResult]) -> Vec<String> {
    let mut out = Vec::new();
    for (i, a) in methods.iter().enumerate() {
        for b in &methods[i + 1..] {
            let same_fit = a.marker_T_image.to_homogeneous() == b.marker_T_image.to_homogeneous()
                && a.spacing_mm_per_px == b.spacing_mm_per_px;
            if same_fit && a.frames_left_out == b.frames_left_out {
                let left_out = if a.frames_left_out.is_empty() {
                    "no frame".to_string()
                } else {
                    format!(
                        "the same frames ({})",
                        a.frames_left_out
                            .iter()
                            .map(|f| f.to_string())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                out.push(format!(
                    "{} and {} agree: each left out {left_out} and solved the rest with the same fit, so their calibrations are identical.",
                    a.method.name(),
                    b.method.name()
                ));
            }
        }
    }
    out
}

/// A page's figure: its SVG (`{"svg": …}` in the context), or why it was not
/// drawn (`{"not_drawn": …}`).
#[derive(Debug, Serialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum Figure {
    Svg(String),
    NotDrawn(String),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::Rigid;
    use crate::pipeline::record::{Method, MethodResult};

    fn result(method: Method, left_out: Vec<usize>, shift_mm: f64) -> MethodResult {
        MethodResult {
            method,
            frames_used: 10 - left_out.len(),
            frames_left_out: left_out,
            marker_T_image: Rigid::translation(shift_mm, 0.0, 0.0),
            spacing_mm_per_px: [0.2, 0.2],
            truth: None,
        }
    }

    #[test]
    fn estimators_that_end_on_one_fit_are_explained_and_others_are_not() {
        let methods = [
            result(
                Method::Ransac {
                    threshold_mm: 1.3,
                    noise_sd_mm: Some(0.4),
                },
                vec![3, 7],
                0.0,
            ),
            result(Method::Lmeds { threshold_mm: 1.9 }, vec![3, 7], 0.0),
            result(Method::CutoffWorstFirst { cutoff_mm: 2.0 }, vec![3], 0.1),
        ];
        let said = agreements(&methods);
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(
            said[0].starts_with("ransac and lmeds agree: each left out the same frames (3, 7)"),
            "{said:?}"
        );
    }
}
