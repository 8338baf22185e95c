//! The manifest exactly as written in YAML. Unknown keys are refused.
//! Defaults are the ones the default experiments are built around; each says why.

use serde::{Deserialize, Serialize};

use crate::estimate::edge_blur::SliceBlur;
use crate::estimate::edge_offset::EdgeOffset;
use crate::evaluate::CutoffRule;
use crate::spec::phantom::Phantom;
use crate::spec::render::{RenderSpec, TrueTransform};
use crate::spec::rig::{CameraCalibrationBoard, Rig};

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawManifest {
    /// Names the experiment and its run folder.
    pub experiment: String,
    #[serde(default)]
    pub description: String,
    #[serde(with = "serde_yaml::with::singleton_map")]
    pub phantom: Phantom,
    #[serde(with = "serde_yaml::with::singleton_map")]
    pub rig: Rig,
    /// The camera that photographs both boards; absent when `poses` come from a tracker.
    #[serde(default)]
    pub camera: Option<RawCamera>,
    /// Poses from a tracker instead of the camera stage.
    #[serde(default)]
    pub poses: Option<RawPoses>,
    pub bscan: RawBscan,
    #[serde(default)]
    pub thresholds: RawThresholds,
    #[serde(default)]
    pub solve: Solve,
    pub datasets: Vec<RawDataset>,
}

/// How `marker_T_image` is solved.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Solve {
    /// `rigid` trusts the B-scan pixel spacing; `similarity` also estimates an
    /// isotropic scale on it (Horn's variant with scale, the thesis's eq. 4).
    pub variant: SolveVariant,
    /// A rough `marker_T_image` (e.g. from the probe clip's drawing) that starts the
    /// wire fit: dots are matched to the wires it predicts, then refined. Needed by
    /// the 4-wire phantom; a few millimetres and degrees off is enough.
    pub initial_marker_T_image: Option<TrueTransform>,
    /// RANSAC / LMedS over frames, reported beside the thesis's cut-offs.
    pub robust: crate::estimate::robust::RobustSettings,
    /// The hemisphere's arc edge points fitted to the sphere (no elevation bias).
    pub sphere_fit: SphereFitOptions,
    /// Bootstrap resamples and CR half-splits of the validation metrics.
    pub validation: ValidationOptions,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SphereFitOptions {
    /// Prior spread of the plane's distance from the sphere centre (mm); absent: none.
    pub elevation_prior_sd_mm: Option<f64>,
    /// Replace the stated prior by the data's own: fit with it, take the RMS of
    /// the fitted elevations as the spread and fit again (empirical Bayes).
    pub elevation_prior_from_data: bool,
    /// Estimate a constant offset of the echo edge from the sphere surface.
    pub fit_radius_offset: bool,
    /// Multi-sphere phantoms: also estimate the B-scan's pixel size, across and
    /// along the beam, in the pairing and the sphere fits (a medium whose speed of
    /// sound is not the scanner's shows every echo at a scaled depth).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub fit_pixel_size: bool,
    /// Multi-sphere phantoms: the sphere fit again with every frame's pose free
    /// under the prior its boards' corners and the hand give (absent: not run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose_prior: Option<PosePrior>,
}

/// How far the probe moves between a frame's photo and its B-scan: the hand's
/// speed times the two grabs' asynchrony. Per axis, the SD is the RMS speed over
/// √3 times the asynchrony's SD.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PosePrior {
    pub hand: crate::spec::realism::Hand,
    /// SD of the time between the photo and the B-scan, s.
    pub asynchrony_sd_s: f64,
    /// The terms of the echo edge's offset outside its sphere that are solved
    /// with the calibration (`none`, the default; `constant`; `obliquity`, a
    /// term in `(d / R)²`; `constant_and_obliquity`): [`EdgeOffset`].
    #[serde(default, skip_serializing_if = "is_no_offset")]
    pub edge_offset: EdgeOffset,
    /// The scanner's pulse and slice, by which an arc's edge noise grows the
    /// farther from its dome's centre the plane cuts ([`SliceBlur`]; absent:
    /// every arc weighed alike).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slice_blur: Option<SliceBlur>,
}

fn is_no_offset(o: &EdgeOffset) -> bool {
    *o == EdgeOffset::None
}

impl PosePrior {
    /// SD of the marker's motion per axis: mm and degrees.
    pub fn tremor_sd(&self) -> (f64, f64) {
        let per_axis = self.asynchrony_sd_s / 3f64.sqrt();
        (
            self.hand.speed_mm_per_s * per_axis,
            self.hand.rotation_deg_per_s * per_axis,
        )
    }
}

impl Default for SphereFitOptions {
    fn default() -> Self {
        // A careful sweep keeps the plane within about a millimetre of the centre.
        SphereFitOptions {
            elevation_prior_sd_mm: Some(1.0),
            elevation_prior_from_data: false,
            fit_radius_offset: true,
            fit_pixel_size: false,
            pose_prior: None,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ValidationOptions {
    pub bootstrap_resamples: usize,
    pub cr_half_splits: usize,
    pub seed: u64,
}

impl Default for ValidationOptions {
    fn default() -> Self {
        ValidationOptions {
            bootstrap_resamples: 200,
            cr_half_splits: 10,
            seed: 7,
        }
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolveVariant {
    #[default]
    Rigid,
    Similarity,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCamera {
    /// OpenCV FileStorage file with `camera_matrix` and `distortion_coefficients`.
    pub intrinsics_file: Option<String>,
    pub calibrate: Option<CameraCalibrationBoard>,
}

/// Where the poses come from when not from the camera.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPoses {
    pub tracker_csv: TrackerCsv,
}

/// A plain CSV of 4x4 matrices per frame (see [`crate::io::tracker_poses`]).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerCsv {
    /// File name inside each dataset folder (rendered datasets write `tracker_poses.csv`).
    pub file: String,
    /// `tracker_T_marker`: the probe's marker.
    #[serde(default = "default_probe_transform")]
    pub probe_transform: String,
    /// `tracker_T_phantom`: the phantom's reference marker, the frame of the phantom geometry.
    #[serde(default = "default_reference_transform")]
    pub reference_transform: String,
}

fn default_probe_transform() -> String {
    "ProbeToTracker".into()
}
fn default_reference_transform() -> String {
    "ReferenceToTracker".into()
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBscan {
    /// Millimetres per pixel along u (columns) and v (rows).
    pub spacing_mm_per_px: [f64; 2],
    #[serde(default)]
    pub arc_detection: ArcDetection,
}

/// Settings of the hemisphere arc detector.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArcDetection {
    /// Arc radii searched, as fractions of the sphere radius: a plane at distance d
    /// from the centre cuts a circle of radius sqrt(R^2 - d^2), so the low end sets
    /// how far off-centre a plane may pass.
    pub radius_fraction: [f64; 2],
    /// Smallest angular span of the inlier arc; shorter arcs give unstable centres.
    pub min_span_deg: f64,
    /// Largest RMS distance of the inlier echoes to the fitted circle.
    pub max_rms_px: f64,
    /// Fewest inlier echo points.
    pub min_points: usize,
    /// Fit the arc with the sphere's radius (`known`) or with a free radius (`free`).
    /// A free radius lets the centre of a short arc slide along the arc's axis.
    pub fit_radius: FitRadius,
    /// Where an echo point is placed on its ridge: at the column's peak
    /// (`column`, the default) or at the ridge's centre along its normal
    /// (`normal`), which the echo's weakening towards an arc's ends does not move.
    #[serde(skip_serializing_if = "EchoPeak::is_column")]
    pub peak: EchoPeak,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FitRadius {
    Known,
    Free,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EchoPeak {
    #[default]
    Column,
    Normal,
}

impl EchoPeak {
    pub fn is_column(&self) -> bool {
        *self == EchoPeak::Column
    }
}

impl Default for ArcDetection {
    fn default() -> Self {
        // 0.55 R admits planes up to 0.83 R off-centre; 1.15 R allows for the
        // widening of the echo by the beam's slice thickness.
        ArcDetection {
            radius_fraction: [0.55, 1.15],
            min_span_deg: 40.0,
            max_rms_px: 2.5,
            min_points: 25,
            fit_radius: FitRadius::Known,
            peak: EchoPeak::Column,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawThresholds {
    /// The thesis's BRE cut-offs: all frames, then < 2, 1.5, 1 mm.
    #[serde(default = "default_cutoffs")]
    pub bre_cutoffs_mm: Vec<f64>,
    #[serde(default = "default_rule")]
    pub cutoff_rule: CutoffRule,
    /// Which cut-off's calibration is the result (default: all frames).
    #[serde(default)]
    pub calibration_cutoff_mm: Option<f64>,
    #[serde(default = "default_min_frames")]
    pub min_frames: usize,
    #[serde(default)]
    pub gates: Gates,
    #[serde(default)]
    pub regression: Regression,
}

/// How much a metric may grow over its baseline before `probecal check` calls it a
/// regression (written into the baseline by `probecal check --update`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Regression {
    pub bre_mean_mm: f64,
    pub truth_corner_error_mm: f64,
    pub truth_rotation_error_deg: f64,
    pub frames_rejected: f64,
    pub pre3d_mm: f64,
}

impl Default for Regression {
    fn default() -> Self {
        // Well above the run-to-run spread of a fixed seed (zero: runs are
        // deterministic) and of platform floating-point differences, well below what
        // a worse detector or a broken stage does.
        Regression {
            bre_mean_mm: 0.05,
            truth_corner_error_mm: 0.05,
            truth_rotation_error_deg: 0.05,
            frames_rejected: 2.0,
            pre3d_mm: 0.02,
        }
    }
}

fn default_cutoffs() -> Vec<f64> {
    vec![f64::INFINITY, 2.0, 1.5, 1.0]
}
fn default_rule() -> CutoffRule {
    CutoffRule::MaxAxis
}
fn default_min_frames() -> usize {
    3
}

impl Default for RawThresholds {
    fn default() -> Self {
        RawThresholds {
            bre_cutoffs_mm: default_cutoffs(),
            cutoff_rule: default_rule(),
            calibration_cutoff_mm: None,
            min_frames: default_min_frames(),
            gates: Gates::default(),
            regression: Regression::default(),
        }
    }
}

/// The estimators' names (`pipeline::record::Method::name`), as `gates.method` may name one.
pub const ESTIMATOR_NAMES: [&str; 8] = [
    "cutoff_worst_first",
    "thesis_one_shot",
    "ransac",
    "lmeds",
    "ransac_lm_scales",
    "ransac_sphere_fit",
    "sphere_fit",
    "sphere_fit_pose_prior",
];

/// Accuracy gates: a run that misses one reports it and exits non-zero.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Gates {
    /// Mean distance of the image corners and centre mapped by estimate vs truth (rendered data).
    pub truth_corner_error_mm: Option<f64>,
    /// Rotation between estimated and true marker_T_image (rendered data).
    pub truth_rotation_error_deg: Option<f64>,
    /// Mean BRE along any axis, at the calibration cut-off.
    pub bre_mean_mm: Option<f64>,
    /// The estimator the truth gates check, by its name in the methods table
    /// (e.g. `sphere_fit_pose_prior`); absent: the reported calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<String>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDataset {
    pub name: String,
    pub render: Option<RenderSpec>,
    pub folder: Option<String>,
}
