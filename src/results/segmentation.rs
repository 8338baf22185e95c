//! `probecal segment`'s outcome: which frames of a PLUS sequence gave the
//! N-wire dots (and why the others did not), the settings read, and how it
//! compares with PLUS's own segmentation of the same frames.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::io::fs::display_path;
use crate::io::plus::config::ConfigError;
use crate::io::plus::segmentation::{score, FrameResults, PlusSegmentation, SegmentationScore};
use crate::pipeline::tracked::segment::SegmentRun;
use crate::results::ReadError;

/// `summary.json` of `probecal segment`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SegmentationSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub approximate_spacing_mm_per_px: f64,
    /// Left, top, width, height (px).
    pub clip_rectangle_px: [usize; 4],
    pub config: String,
    /// Frames whose dots were found, and all frames.
    pub found: usize,
    pub frames: usize,
    pub image_size_px: [usize; 2],
    /// Every frame not segmented, with its reason.
    pub not_found: Vec<FrameNotFound>,
    pub not_found_by_check: Vec<CheckCount>,
    pub opening_radius_px: u32,
    /// The sequence's image orientation (`MF`, `UF`, …).
    pub orientation: String,
    /// The screen's overlay left out, when the device set gives no clip rectangle.
    pub overlay: Option<OverlaySummary>,
    pub plus_baseline: Option<PlusBaseline>,
    pub sequence: String,
    pub threshold_percent: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameNotFound {
    pub frame: usize,
    pub reason: String,
}

/// How many frames one check refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckCount {
    pub check: String,
    pub frames: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OverlaySummary {
    pub pixels: usize,
    pub threshold_grey: u8,
    pub frames: usize,
}

/// PLUS's segmentation of the same sequence, and how probecal's compares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlusBaseline {
    pub file: String,
    pub section: String,
    pub score: SegmentationScore,
}

/// PLUS's segmentation file could not be read or holds no section for the sequence.
#[derive(Debug, thiserror::Error)]
pub enum BaselineError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Read(#[from] ReadError),
}

impl SegmentationSummary {
    pub fn of(run: &SegmentRun, plus_baseline: Option<PlusBaseline>) -> SegmentationSummary {
        SegmentationSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            approximate_spacing_mm_per_px: run.spacing_guess_mm_per_px,
            clip_rectangle_px: run.clip_rectangle_px,
            config: display_path(&run.config),
            found: run.frames.iter().filter(|f| f.rejected.is_none()).count(),
            frames: run.frames.len(),
            image_size_px: run.image_size_px,
            not_found: run
                .frames
                .iter()
                .filter_map(|f| {
                    f.rejected.as_ref().map(|r| FrameNotFound {
                        frame: f.index,
                        reason: r.to_string(),
                    })
                })
                .collect(),
            not_found_by_check: crate::pipeline::sequence_frames::rejections_by_check(&run.frames)
                .into_iter()
                .map(|(check, frames)| CheckCount { check, frames })
                .collect(),
            opening_radius_px: run.segmentation.opening_radius_for(run.spacing_guess_mm_per_px),
            orientation: format!("{:?}", run.orientation).to_uppercase(),
            overlay: run.overlay.as_ref().map(|o| OverlaySummary {
                pixels: o.pixels(),
                threshold_grey: o.threshold_grey,
                frames: o.frames,
            }),
            plus_baseline,
            sequence: display_path(&run.sequence),
            threshold_percent: run.segmentation.threshold_percent,
        }
    }
}

/// The section of `file` that is `run`'s sequence: its only one, or the one
/// listing as many frames as the sequence has.
fn baseline_section<'a>(
    file: &'a PlusSegmentation,
    frames: usize,
    path: &Path,
) -> Result<(&'a str, &'a FrameResults), ReadError> {
    let fits: Vec<&(String, FrameResults)> = if file.sections.len() == 1 {
        file.sections.iter().collect()
    } else {
        file.sections.iter().filter(|(_, f)| f.len() == frames).collect()
    };
    match fits.as_slice() {
        [(name, f)] => Ok((name.as_str(), f)),
        _ => Err(ReadError::new(
            path,
            format!(
                "no single section lists the sequence's {frames} frames (sections: {})",
                file.sections
                    .iter()
                    .map(|(n, f)| format!("{n} with {} frames", f.len()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// Scores `run` against PLUS's segmentation in `path`.
pub fn against_plus(run: &SegmentRun, path: &Path) -> Result<PlusBaseline, BaselineError> {
    let file = PlusSegmentation::read(path)?;
    let (section, plus) = baseline_section(&file, run.frames.len(), path)?;
    let ours = run
        .frames
        .iter()
        .map(|f| {
            let points = f
                .rejected
                .is_none()
                .then(|| f.dots_px.iter().flatten().copied().collect::<Vec<_>>());
            (f.index, points)
        })
        .collect();
    Ok(PlusBaseline {
        file: display_path(path),
        section: section.to_string(),
        score: score(&ours, plus),
    })
}
