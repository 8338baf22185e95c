//! Why a dataset's run stopped: the one error type of the camera pipeline's
//! stages, a leaf every stage and the runner import.

use crate::detect::camera_calibration;
use crate::estimate::horn::HornError;
use crate::synth;

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("dataset `{dataset}`: {source}")]
    Dataset {
        dataset: String,
        source: crate::io::dataset::DatasetError,
    },
    #[error("dataset `{dataset}`: rendering failed: {source}")]
    Synth { dataset: String, source: synth::SynthError },
    #[error("dataset `{dataset}`: camera calibration failed: {source}")]
    Calibration {
        dataset: String,
        source: camera_calibration::CalibrationError,
    },
    #[error("dataset `{dataset}`: {source}")]
    Intrinsics {
        dataset: String,
        source: crate::io::camera_model::IntrinsicsError,
    },
    #[error("dataset `{dataset}`: only {used} of {total} frames are usable, at least {needed} are needed. Rejections:\n{reasons}")]
    TooFewFrames {
        dataset: String,
        used: usize,
        total: usize,
        needed: usize,
        reasons: String,
    },
    #[error("dataset `{dataset}`: the calibration cannot be solved: {source}")]
    Solve { dataset: String, source: HornError },
    #[error("dataset `{dataset}`: no calibration at the calibration cut-off {cutoff} mm ({kept} frames left): {source}; lower thresholds.min_frames or raise thresholds.calibration_cutoff_mm")]
    Cutoff {
        dataset: String,
        cutoff: String,
        kept: usize,
        source: HornError,
    },
    #[error("dataset `{dataset}`: {source}")]
    Truth {
        dataset: String,
        source: crate::io::truth::TruthError,
    },
    #[error("dataset `{dataset}`: {source}")]
    TrackerPoses {
        dataset: String,
        source: crate::io::tracker_poses::TrackerPosesError,
    },
    #[error("{0}")]
    Unsupported(String),
    #[error("opencv: {0}")]
    OpenCv(#[from] opencv::Error),
    #[error("polars: {0}")]
    Polars(#[from] polars::error::PolarsError),
}

/// Why a reporter could not write a finished run: the writer's own error, boxed
/// (the writers live above the pipeline).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ReporterError(pub Box<dyn std::error::Error + Send + Sync>);
