//! The YAML of a tracker-sequence manifest as written: the serde types that
//! the tracked manifest's `from_text` reads and checks.

use serde::{Deserialize, Serialize};

use crate::detect::nwire::SegmentationOverrides;
use crate::estimate::image_to_probe::{ConstraintModel, PixelModel};

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTrackedManifest {
    pub(super) experiment: String,
    #[serde(default)]
    pub(super) description: String,
    #[serde(with = "serde_yaml::with::singleton_map")]
    pub(super) tracking: Tracking,
    #[serde(with = "serde_yaml::with::singleton_map")]
    pub(super) phantom: TrackedPhantom,
    #[serde(default)]
    pub(super) bscan: TrackedBscan,
    #[serde(default)]
    pub(super) solve: TrackedSolve,
    #[serde(default)]
    pub(super) thresholds: TrackedThresholds,
    /// `probecal live --igtl`: the stream's device names and its end.
    #[serde(default)]
    pub(super) live: LiveStream,
    /// PLUS's own result file (`ProbeCalibrationResult` XML), for comparison only.
    #[serde(default)]
    pub(super) compare_with_plus_result: Option<String>,
    /// A sweep reconstructed with the calibration, shown on the run's page.
    #[serde(default)]
    pub(super) reconstruct: Option<RawReconstruct>,
}

/// `reconstruct:`: which sweep, and the device set whose `<VolumeReconstruction>` builds it.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawReconstruct {
    /// `validation`, `calibration`, or a sequence file.
    pub(super) sweep: String,
    /// A PLUS device set with a `<VolumeReconstruction>` element.
    pub(super) config: String,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Tracking {
    PlusSequence(PlusSequence),
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlusSequence {
    /// Names the run's subfolder.
    pub(super) dataset: String,
    /// Sequence file (`.mha` / `.igs.mha`) of the calibration frames.
    pub(super) calibration: String,
    /// Sequence file of held-out validation frames (PRE3D is reported on them).
    #[serde(default)]
    pub(super) validation: Option<String>,
    #[serde(default = "default_probe")]
    pub(super) probe_transform: String,
    #[serde(default = "default_reference")]
    pub(super) reference_transform: String,
    /// The tracker's lag behind the images: seconds, or `estimate` (from the calibration frames).
    #[serde(default = "default_offset")]
    pub(super) time_offset_s: OffsetSetting,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub(super) enum OffsetSetting {
    Seconds(f64),
    Word(String),
    /// `{temporal: {tracker: ..., video: ...}}`: a recording of the probe moved
    /// over a flat reflector (`probecal temporal`'s inputs).
    Temporal {
        temporal: TemporalRecording,
    },
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TemporalRecording {
    pub(super) tracker: String,
    pub(super) video: String,
}

pub(super) fn default_probe() -> String {
    "ProbeToTracker".into()
}
pub(super) fn default_reference() -> String {
    "ReferenceToTracker".into()
}
pub(super) fn default_offset() -> OffsetSetting {
    OffsetSetting::Word("estimate".into())
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum TrackedPhantom {
    /// N-wire patterns and `PhantomToReference` from a PLUS device-set
    /// configuration (`plus_config`), or written out here (`patterns` and
    /// `reference_T_phantom`).
    Nwire {
        #[serde(default)]
        plus_config: Option<String>,
        /// Each N: three wires (side, diagonal, side) in the phantom frame, mm.
        #[serde(default)]
        patterns: Option<Vec<RawNWirePattern>>,
        /// `reference_T_phantom` (PLUS's `PhantomToReference`), a 4x4 row-major matrix.
        #[serde(default)]
        reference_T_phantom: Option<[[f64; 4]; 4]>,
        /// Approximate pixel size the segmentation starts from.
        #[serde(default)]
        approximate_spacing_mm_per_px: Option<f64>,
        /// Name of the phantom frame and the reference (the tracked marker on the phantom).
        #[serde(default = "default_phantom_frame")]
        phantom_frame: String,
        #[serde(default = "default_reference_frame")]
        reference_frame: String,
    },
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawNWirePattern {
    pub(super) wires: [RawNWireWire; 3],
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawNWireWire {
    pub(super) name: String,
    pub(super) front_in_phantom_mm: [f64; 3],
    pub(super) back_in_phantom_mm: [f64; 3],
}

pub(super) fn default_phantom_frame() -> String {
    "Phantom".into()
}
pub(super) fn default_reference_frame() -> String {
    "Reference".into()
}

#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct TrackedBscan {
    /// Approximate pixel size for the segmentation; absent: the configuration's
    /// `ApproximateSpacingMmPerPixel`.
    pub(super) approximate_spacing_mm_per_px: Option<f64>,
    /// Each key replaces the device set's setting (PLUS's default where it gives
    /// none); absent: the device set's.
    pub(super) segmentation: SegmentationOverrides,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct TrackedSolve {
    /// Which constraints the dots give; absent: chosen by cross-validation on
    /// the calibration frames.
    pub(super) constraints: Option<ConstraintModel>,
    /// How pixels map onto the image plane; absent: chosen by cross-validation
    /// on the calibration frames.
    pub(super) pixel_model: Option<PixelModel>,
    /// Folds of the calibration frames' cross-validation (contiguous blocks).
    pub(super) folds: usize,
    /// Drop constraints above mean + k SD and refit; absent: keep all.
    pub(super) reject_sd: Option<f64>,
    /// Also correct the phantom's registration from the calibration frames.
    pub(super) refine_phantom_registration: bool,
}

impl Default for TrackedSolve {
    fn default() -> Self {
        // PLUS's outlier rule (mean + 3 SD); the model chosen on the calibration frames.
        TrackedSolve {
            constraints: None,
            pixel_model: None,
            folds: 5,
            reject_sd: Some(3.0),
            refine_phantom_registration: false,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct TrackedThresholds {
    pub(super) min_frames: usize,
    pub(super) gates: TrackedGates,
    pub(super) regression: TrackedRegression,
}

impl Default for TrackedThresholds {
    fn default() -> Self {
        TrackedThresholds {
            min_frames: 10,
            gates: TrackedGates::default(),
            regression: TrackedRegression::default(),
        }
    }
}

/// Accuracy gates of a tracked run.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrackedGates {
    /// Validation PRE3D (PLUS convention: mean of the best 95 %), mm.
    pub pre3d_mm: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackedRegression {
    pub pre3d_mm: f64,
    pub frames_rejected: f64,
}

impl Default for TrackedRegression {
    fn default() -> Self {
        // Runs are deterministic; 0.02 mm is well below what a worse segmentation does.
        TrackedRegression {
            pre3d_mm: 0.02,
            frames_rejected: 2.0,
        }
    }
}

/// What `probecal live --igtl` listens for and sends (OpenIGTLink device names
/// are at most 20 bytes).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LiveStream {
    /// The IMAGE messages' device.
    pub image_device: String,
    /// A STRING message from this device ends the acquisition.
    pub end_device: String,
    /// No message for this long ends the acquisition, s.
    pub silence_s: f64,
    /// A pose is interpolated between two transform samples no further apart
    /// than this, s; a wider gap leaves the image without a pose.
    pub max_transform_gap_s: f64,
    /// The TRANSFORM sent back with the calibration.
    pub send_device: String,
}

impl Default for LiveStream {
    fn default() -> Self {
        // PlusServer's and fCal's names. At 0.1 s a hand sweeping at 50 mm/s
        // moves 5 mm between the samples: interpolating over more is a guess.
        LiveStream {
            image_device: "Image".into(),
            end_device: "SequenceEnd".into(),
            silence_s: 5.0,
            max_transform_gap_s: 0.1,
            send_device: "ImageToProbe".into(),
        }
    }
}
