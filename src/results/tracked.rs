//! `summary.json` of a tracked-sequence run (PLUS sequence files), typed: what
//! the tracked run's writer writes and the regression gate reads back.

use serde::{Deserialize, Serialize};

use crate::core::stats::MeanSd;
use crate::estimate::image_to_probe::{ConstraintModel, PixelModel};
use crate::pipeline::record::GateResult;
use crate::pipeline::tracked::resolution::ValidationResolution;

/// `summary.json` of a tracked-sequence run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub experiment: String,
    pub dataset: String,
    /// Always `tracked_sequence`.
    pub kind: String,
    pub frames: TrackedFrameCounts,
    pub constraints: ConstraintCounts,
    /// The tracker's lag behind the images applied, s.
    pub time_offset_s: f64,
    /// When the manifest asks for the lag to be estimated: the spatio-temporal
    /// estimate (`lag_s` null where the calibration frames cannot tell it), the
    /// motion estimate beside it, and which is applied and why.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_offset_estimate: Option<crate::pipeline::tracked::time::lag_joint::LagEstimate>,
    pub image_to_probe: ImageToProbeSummary,
    /// How the model was chosen: cross-validation on the calibration frames.
    pub model_selection: ModelSelectionSummary,
    pub validation: Pre3d,
    /// How far the validation score can tell calibrations apart (block bootstrap
    /// of the calibration frames, the model's floor on the validation frames, the
    /// sweeps' tilts).
    #[serde(default)]
    pub resolution: ValidationResolution,
    pub calibration: Pre3d,
    pub gates: Vec<GateResult>,
    pub regression_tolerances: TrackedTolerances,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_result: Option<PlusResultSummary>,
    /// The sweep the manifest names, reconstructed with this calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reconstruction: Option<crate::results::volume::TrackedVolume>,
}

/// One candidate model's cross-validated PRE3D (or why it has none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateScore {
    pub constraints: ConstraintModel,
    pub pixel_model: PixelModel,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cv_pre3d_mm: Option<MeanSd>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
}

/// The model family scored on the calibration frames and the model chosen.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelSelectionSummary {
    /// Contiguous blocks of calibration frames.
    pub folds: usize,
    /// Calibration frames cross-validated.
    pub frames: usize,
    pub candidates: Vec<CandidateScore>,
    pub chosen_constraints: ConstraintModel,
    pub chosen_pixel_model: PixelModel,
}

/// What `kind` says of a tracked run.
pub const TRACKED_KIND: &str = "tracked_sequence";

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Segmented {
    pub segmented: usize,
    pub total: usize,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedFrameCounts {
    pub calibration: Segmented,
    pub validation: Segmented,
    pub rejected: usize,
    /// How many frames each check rejected, most first.
    #[serde(default)]
    pub rejected_by_check: Vec<(String, usize)>,
    /// Pixels of a screen grab's overlay left out (bright in every calibration
    /// frame), when no clip rectangle was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub overlay_px: Option<usize>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ConstraintCounts {
    pub model: ConstraintModel,
    pub count: usize,
    pub kept: usize,
}

/// SDs of the fitted parameters.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ParameterSd {
    pub rotation_mrad: Vec<f64>,
    pub translation_mm: Vec<f64>,
    pub spacing_mm_per_px: Vec<f64>,
    pub shear_mm_per_px: f64,
}

/// PLUS's `Calibration`: `marker_T_image` after the pixel size.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ImageToProbeSummary {
    pub matrix: Vec<Vec<f64>>,
    pub pixel_model: PixelModel,
    pub spacing_mm_per_px: [f64; 2],
    /// mm along the image's x axis per pixel row (0 but for the affine model).
    pub shear_mm_per_px: f64,
    pub rotation_zyx_deg: [f64; 3],
    pub translation_mm: [f64; 3],
    pub sd: ParameterSd,
}

/// PRE3D in PLUS's convention (best 95 %) and over all points.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Pre3d {
    pub pre3d_mm: Option<MeanSd>,
    pub pre3d_all_mm: Option<MeanSd>,
    /// PLUS's `ImageToProbe` (its result file) on the same dots, poses and
    /// frames (those both segmented, where the file lists PLUS's), same
    /// convention: the like-for-like comparison.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_matrix_pre3d_mm: Option<MeanSd>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_matrix_pre3d_all_mm: Option<MeanSd>,
    /// Ours on exactly the frames of `plus_matrix_pre3d_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub same_frames_pre3d_mm: Option<MeanSd>,
    /// How many frames each used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames_compared: Option<FramesCompared>,
    /// Ours less PLUS's matrix, paired frame by frame on the same frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ours_minus_plus_matrix_mm: Option<PairedDifference>,
    /// Where a lag is applied: the same frames and dots with no lag (each
    /// frame's own poses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_lag: Option<NoLagPre3d>,
    /// Where an estimated lag is applied: the calibration refitted at lags
    /// across the lag's 90 % interval (and at the lag applied), scored with
    /// the poses at each, on the frames posed at all of them, in lag order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub across_lag_interval: Vec<Pre3dAtLag>,
}

/// PRE3D with the calibration refitted at one lag, poses read at that lag.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pre3dAtLag {
    pub lag_s: f64,
    /// Whether this is the lag applied.
    pub applied: bool,
    /// Our model refitted on the calibration frames at this lag.
    pub pre3d_mm: Option<MeanSd>,
    /// PLUS's matrix at this lag, on the frames of `plus_matrix_pre3d_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_matrix_pre3d_mm: Option<MeanSd>,
}

/// PRE3D with no tracker lag, on the frames and dots of the lagged figures.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct NoLagPre3d {
    /// Our model fitted to the calibration frames with no lag.
    pub pre3d_mm: Option<MeanSd>,
    /// PLUS's matrix with no lag (as PLUS scores it), on the frames of
    /// `plus_matrix_pre3d_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_matrix_pre3d_mm: Option<MeanSd>,
}

/// Two calibrations on the same frames: each frame's mean PRE3D over all its
/// points under one less the other's, their mean over the frames, and its
/// moving-block bootstrap 90 % interval (blocks of `block_frames` consecutive
/// frames, since neighbouring frames of a sweep err alike).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PairedDifference {
    pub mean: f64,
    pub interval_90: Option<[f64; 2]>,
    pub frames: usize,
    pub block_frames: usize,
    /// Frames on which the first was the lower.
    pub frames_won: usize,
}

impl PairedDifference {
    /// In words, by its interval: lower, higher, or no difference told apart.
    pub fn verdict(&self) -> &'static str {
        match self.interval_90 {
            Some([_, hi]) if hi < 0.0 => "lower",
            Some([lo, _]) if lo > 0.0 => "higher",
            _ => "not told apart",
        }
    }

    /// One sentence: `first` less `second` on the paired frames, its interval,
    /// the frames won and the verdict.
    pub fn sentence(&self, first: &str, second: &str) -> String {
        let interval = self
            .interval_90
            .map(|[lo, hi]| {
                format!(
                    "90 % interval {lo:+.3} to {hi:+.3} mm, blocks of {} frames",
                    self.block_frames
                )
            })
            .unwrap_or_else(|| "too few frames for an interval".into());
        let verdict = match self.verdict() {
            "lower" => format!("{first} lower"),
            "higher" => format!("{second} lower"),
            other => other.to_string(),
        };
        format!(
            "{first} less {second}, frame by frame on {} frames: {:+.3} mm ({interval}; {first} lower on {} of them): {verdict}",
            self.frames, self.mean, self.frames_won
        )
    }
}

/// Frames of one sequence: used here, segmented by PLUS (when its file lists
/// them), and both.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FramesCompared {
    pub ours: usize,
    pub plus: Option<usize>,
    pub both: usize,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedTolerances {
    pub pre3d_mm: f64,
    pub frames_rejected: f64,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PublishedPre3d {
    pub mean: Option<f64>,
    pub std: Option<f64>,
}

/// PLUS's own result file, and its matrix scored on our dots.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlusResultSummary {
    pub matrix: Vec<Vec<f64>>,
    pub published_validation_pre3d_mm: PublishedPre3d,
    pub published_calibration_pre3d_mm: PublishedPre3d,
}
