//! What a dataset's run produced: every frame's fate, the camera (or tracker)
//! stage, the calibrations, the truth and the gates. Built by the stages of
//! [`crate::pipeline`], read by the report layer.

use std::path::PathBuf;

use crate::core::geometry::Rigid;
use crate::detect::arc::{ArcFeature, ArcRejection};
use crate::detect::board_pose::{BoardRejection, FramePoses};
use crate::detect::camera_calibration::CameraCalibration;
use crate::detect::spot::Spot;
use crate::estimate::correspondence::Correspondence;
use crate::estimate::horn::HornFit;
use crate::estimate::wire_matching::WireRejection;
use crate::evaluate::resampling;
use crate::evaluate::{ThresholdRow, TruthComparison};
use crate::io::camera_model::CameraIntrinsics;
use crate::io::dataset::FrameFiles;
use crate::io::image::ImageError;
use crate::io::tracker_poses::{MissingPose, TrackedFrame, TrackerPoses};

/// Which stage rejected a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    CameraImage,
    BoardPose,
    BscanImage,
    Arc,
    /// The pin head of the point phantom.
    Spot,
    /// Wire dots, or their pairing with the wires.
    Wires,
    /// The tracker gave no pose.
    TrackerPose,
    /// A measurement that is not a finite, physically possible number.
    Plausibility,
}

impl Stage {
    pub fn label(self) -> &'static str {
        match self {
            Stage::CameraImage => "camera image",
            Stage::BoardPose => "board pose",
            Stage::BscanImage => "B-scan image",
            Stage::Arc => "arc detection",
            Stage::Spot => "pin-head detection",
            Stage::Wires => "wire dots",
            Stage::TrackerPose => "tracker pose",
            Stage::Plausibility => "plausibility",
        }
    }
}

/// Why a frame was not used: what the stage that refused it found. Written as
/// text only at the edge (its `Display`, in tables and pages).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Rejection {
    #[error("the frame list names no camera image")]
    NoCameraImage,
    #[error("{0}")]
    CameraImage(ImageError),
    #[error("{0}")]
    BoardPose(BoardRejection),
    #[error("{0}")]
    TrackerPose(MissingPose),
    #[error("{0}")]
    BscanImage(ImageError),
    #[error("{0}")]
    Arc(ArcRejection),
    #[error("no echo as wide as the pin head with a comet tail behind it ({compact} compact echoes, {surfaces} surface echoes)")]
    NoPinHead { compact: usize, surfaces: usize },
    /// Two compact echoes of similar strength: which is the pin head is a guess.
    #[error("ambiguous: compact echoes of similar strength at ({:.0}, {:.0}) and ({:.0}, {:.0}) px", .first_px[0], .first_px[1], .second_px[0], .second_px[1])]
    AmbiguousPinHead { first_px: [f64; 2], second_px: [f64; 2] },
    #[error("{compact} compact echoes, at least 2 wire dots are needed ({surfaces} surface echoes)")]
    TooFewWireDots { compact: usize, surfaces: usize },
    #[error("{0}")]
    Wires(WireRejection),
    #[error("{0}")]
    Spheres(crate::estimate::sphere_matching::SphereRejection),
    #[error("{0}")]
    Implausible(Implausible),
}

/// Poses farther than this from the camera or tracker are not measurements: no
/// camera sees a board, and no tracker a marker, 10 m away.
pub const MAX_POSE_DISTANCE_MM: f64 = 10_000.0;

/// A measurement a stage gave that is not a finite, physically possible number.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Implausible {
    #[error("{pose} is not finite")]
    PoseNotFinite { pose: &'static str },
    #[error("{pose} puts its board {distance_mm:.0} mm away (more than {limit_mm:.0} mm: no camera or tracker measures that far)")]
    PoseTooFar {
        pose: &'static str,
        distance_mm: f64,
        limit_mm: f64,
    },
    #[error("a feature pixel ({u}, {v}) is not finite")]
    FeatureNotFinite { u: f64, v: f64 },
}

impl Implausible {
    /// The first implausible value of a frame's poses (named `names`) and feature pixels.
    pub fn of(
        poses: Option<(Rigid, Rigid)>,
        names: [&'static str; 2],
        features_px: &[[f64; 2]],
    ) -> Option<Implausible> {
        if let Some((marker, phantom)) = poses {
            for (pose, t) in [(names[0], marker), (names[1], phantom)] {
                let finite = t.translation.vector.iter().all(|v| v.is_finite())
                    && t.rotation.coords.iter().all(|v| v.is_finite());
                if !finite {
                    return Some(Implausible::PoseNotFinite { pose });
                }
                let distance_mm = t.translation.vector.norm();
                if distance_mm > MAX_POSE_DISTANCE_MM {
                    return Some(Implausible::PoseTooFar {
                        pose,
                        distance_mm,
                        limit_mm: MAX_POSE_DISTANCE_MM,
                    });
                }
            }
        }
        features_px
            .iter()
            .find(|p| !(p[0].is_finite() && p[1].is_finite()))
            .map(|p| Implausible::FeatureNotFinite { u: p[0], v: p[1] })
    }
}

impl Rejection {
    /// The stage that rejected the frame.
    pub fn stage(&self) -> Stage {
        match self {
            Rejection::NoCameraImage | Rejection::CameraImage(_) => Stage::CameraImage,
            Rejection::BoardPose(_) => Stage::BoardPose,
            Rejection::TrackerPose(_) => Stage::TrackerPose,
            Rejection::BscanImage(_) => Stage::BscanImage,
            Rejection::Arc(_) | Rejection::Spheres(_) => Stage::Arc,
            Rejection::NoPinHead { .. } | Rejection::AmbiguousPinHead { .. } => Stage::Spot,
            Rejection::TooFewWireDots { .. } | Rejection::Wires(_) => Stage::Wires,
            Rejection::Implausible(_) => Stage::Plausibility,
        }
    }
}

/// What happened to one frame.
#[derive(Debug, Clone)]
pub struct FrameRecord {
    pub files: FrameFiles,
    pub rejection: Option<Rejection>,
    /// Board poses from the photo (camera stage).
    pub poses: Option<FramePoses>,
    /// Poses from a tracker instead (no camera).
    pub tracked: Option<TrackedFrame>,
    pub arc: Option<ArcFeature>,
    /// Multi-sphere phantoms: every arc found, strongest first (`arc` is the first).
    pub arcs: Vec<ArcFeature>,
    /// Compact echoes found (point and wire phantoms), strongest first.
    pub spots: Vec<Spot>,
    /// The feature pixels used: the arc's centre, the pin head, the wire dots.
    pub features_px: Vec<[f64; 2]>,
    /// Wire and multi-sphere phantoms: the wire or sphere of each feature.
    pub wire_labels: Vec<String>,
    /// All-frames BRE `[x, y, z]` and 3D distance, mm (used frames).
    pub bre_mm: Option<([f64; 3], f64)>,
    /// Size of the B-scan image, px (when it could be read).
    pub bscan_size_px: Option<[usize; 2]>,
}

impl FrameRecord {
    /// `(camera_T_marker, camera_T_phantom)`, from the photo or the tracker (whose
    /// frame takes the camera's place).
    pub fn pose_pair(&self) -> Option<(Rigid, Rigid)> {
        match (&self.poses, &self.tracked) {
            (Some(p), _) => Some((p.camera_T_marker.camera_T_board, p.camera_T_phantom.camera_T_board)),
            (None, Some(t)) => Some((t.tracker_T_marker, t.tracker_T_phantom)),
            (None, None) => None,
        }
    }
}

/// Camera intrinsics and, if calibrated here, the calibration; or the tracker
/// that replaces the camera.
#[derive(Debug, Clone)]
pub struct CameraStage {
    /// `None` when the poses come from a tracker.
    pub intrinsics: Option<CameraIntrinsics>,
    pub calibration: Option<CameraCalibration>,
    pub source: String,
    pub tracker: Option<TrackerSource>,
}

/// A tracker's poses and the names of the probe's and the phantom's transforms.
#[derive(Debug, Clone)]
pub struct TrackerSource {
    pub poses: TrackerPoses,
    pub probe_transform: String,
    pub reference_transform: String,
}

/// An accuracy gate's verdict.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GateResult {
    pub name: String,
    pub limit: f64,
    pub value: Option<f64>,
    pub passed: bool,
}

/// One frame against the rendered truth: its kind and the errors of its
/// detections. Kept apart from the frame's record, which the estimators read,
/// and made only after every estimate is.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameTruth {
    pub kind: String,
    pub elevation_offset_mm: f64,
    /// The feature pixels' distance from the truth's (mean over wire dots), px.
    pub arc_centre_error_px: Option<f64>,
    /// Probe board pose error (mm, degrees).
    pub probe_pose_error: Option<(f64, f64)>,
    /// Phantom board pose error (mm, degrees).
    pub phantom_pose_error: Option<(f64, f64)>,
    /// Probe board position error along the camera's viewing axis, mm.
    pub probe_depth_error_mm: Option<f64>,
}

/// Truth for the whole dataset.
#[derive(Debug, Clone)]
pub struct TruthSummary {
    pub calibration: TruthComparison,
    /// Each frame the truth describes, by frame number.
    pub frames: std::collections::BTreeMap<usize, FrameTruth>,
    /// `None` without a camera (tracker poses).
    pub camera_focal_error_px: Option<f64>,
    pub camera_principal_error_px: Option<f64>,
    /// The camera's nine intrinsics against the truth, weighed by what its
    /// calibration states it knows of them (see `truth::camera_nees`).
    pub camera_intrinsics_nees: Option<f64>,
    pub arc_centre_error_px: Option<(f64, f64)>,
    pub probe_pose_translation_error_mm: Option<(f64, f64)>,
    pub probe_pose_rotation_error_deg: Option<(f64, f64)>,
    pub phantom_pose_translation_error_mm: Option<(f64, f64)>,
    /// Dome phantoms: the arcs' errors against their true cuts, set against the
    /// bound's noise model.
    pub arc_noise: Option<crate::evaluate::arc_noise::ArcNoiseCheck>,
}

/// An estimator and the parameters it ran with; the report writes the words.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// The reported calibration: Horn on the feature centres, frames above the
    /// cut-off removed worst first, re-solving after each.
    CutoffWorstFirst { cutoff_mm: f64 },
    /// The thesis's procedure: Horn on all frames, every frame above the cut-off
    /// dropped at once, Horn again.
    ThesisOneShot { cutoff_mm: f64 },
    /// RANSAC (MSAC) over frames (samples of 3, Horn inside).
    Ransac {
        threshold_mm: f64,
        /// The stated noise SD the threshold came from (`None`: the manifest
        /// gave the threshold itself).
        noise_sd_mm: Option<f64>,
    },
    /// LMedS over frames (samples of 3, Horn inside); its threshold from the data.
    Lmeds { threshold_mm: f64 },
    /// RANSAC's frames, Levenberg–Marquardt with the pixel size as two more unknowns.
    RansacLmScales,
    /// RANSAC's frames, every arc edge point on the sphere of known radius.
    RansacSphereFit {
        elevation_prior_sd_mm: Option<f64>,
        /// The echo edge's fitted offset from the sphere's surface.
        edge_offset_mm: f64,
    },
    /// Multi-sphere phantoms: the reported calibration's frames, every arc's edge
    /// points on their own sphere.
    SphereFit {
        arcs: usize,
        rms_mm: f64,
        rms_limit_mm: f64,
        /// The pixel size solved with it (`solve.sphere_fit.fit_pixel_size`).
        pixel_size_fitted: bool,
    },
    /// Multi-sphere phantoms: the sphere fit's arcs with every frame's pose free
    /// under the prior its boards' corners and the hand's motion give.
    SphereFitPosePrior {
        arcs: usize,
        rms_mm: f64,
        noise: PoseFitNoise,
        /// The pixel size held at the sphere fit's fitted one.
        pixel_size_fitted: bool,
    },
}

impl Method {
    /// The estimator's name in `summary.json` and the reports.
    pub fn name(&self) -> &'static str {
        match self {
            Method::CutoffWorstFirst { .. } => "cutoff_worst_first",
            Method::ThesisOneShot { .. } => "thesis_one_shot",
            Method::Ransac { .. } => "ransac",
            Method::Lmeds { .. } => "lmeds",
            Method::RansacLmScales => "ransac_lm_scales",
            Method::RansacSphereFit { .. } => "ransac_sphere_fit",
            Method::SphereFit { .. } => "sphere_fit",
            Method::SphereFitPosePrior { .. } => "sphere_fit_pose_prior",
        }
    }

    /// Every estimator's name, as a manifest may name one.
    pub const NAMES: [&'static str; 8] = crate::manifest::raw::ESTIMATOR_NAMES;
}

/// One estimator's calibration beside the thesis's (robust, refined, sphere fit).
#[derive(Debug, Clone)]
pub struct MethodResult {
    pub method: Method,
    pub frames_used: usize,
    /// Frames left out of the fit (robust estimators: the frames outside the consensus).
    pub frames_left_out: Vec<usize>,
    pub marker_T_image: Rigid,
    /// Pixel size the calibration maps with (estimated by the scale refinement).
    pub spacing_mm_per_px: [f64; 2],
    pub truth: Option<TruthComparison>,
}

/// Leave-one-out PRE, CR and bootstrap intervals of the primary calibration's frames.
#[derive(Debug, Clone)]
pub struct ResamplingSummary {
    pub leave_one_out: resampling::LeaveOneOut,
    pub reproducibility: resampling::Reproducibility,
    pub bootstrap: resampling::Bootstrap,
}

/// Everything one dataset's run produced.
#[derive(Debug)]
pub struct DatasetRun {
    pub experiment: String,
    pub dataset: String,
    pub dataset_folder: PathBuf,
    pub rendered: bool,
    pub camera: CameraStage,
    pub frames: Vec<FrameRecord>,
    pub all_frames_fit: HornFit,
    /// The usable frames' point pairs as solved, and how they were solved: what
    /// `probecal resolve` solves again from the run's folder.
    pub pairs: Vec<Correspondence>,
    pub solve: SolveSettings,
    pub thresholds: Vec<ThresholdRow>,
    /// Index into `thresholds` of the calibration that is the result.
    pub primary: usize,
    pub truth: Option<TruthSummary>,
    pub gates: Vec<GateResult>,
    pub spacing_mm_per_px: [f64; 2],
    /// The phantom's point feature (hemisphere centre, pin head); `None` for wires.
    pub feature_in_phantom_mm: Option<[f64; 3]>,
    /// Other estimators on the same frames (point phantoms).
    pub methods: Vec<MethodResult>,
    /// Wire phantoms: the start guess's offset and basin of convergence.
    pub start_guess: Option<crate::estimate::start_basin::StartGuess>,
    pub validation: Option<ResamplingSummary>,
    pub timings_s: Vec<(&'static str, f64)>,
    /// Every file the run read (for provenance).
    pub input_files: Vec<PathBuf>,
    pub seed: Option<u64>,
}

impl DatasetRun {
    pub fn primary_fit(&self) -> &HornFit {
        match &self.thresholds[self.primary].fit {
            Ok(fit) => fit,
            Err(_) => &self.all_frames_fit,
        }
    }
    pub fn used_frames(&self) -> usize {
        self.frames.iter().filter(|f| f.rejection.is_none()).count()
    }
    pub fn gates_passed(&self) -> bool {
        self.gates.iter().all(|g| g.passed)
    }
}

/// How a dataset's pairs are solved: everything the solve reads besides the pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveSettings {
    pub spacing_mm_per_px: [f64; 2],
    pub variant: crate::estimate::horn::Variant,
    /// Descending; infinity (all frames) first.
    pub cutoffs_mm: Vec<f64>,
    pub rule: crate::evaluate::CutoffRule,
    /// The cut-off whose calibration is the result.
    pub calibration_cutoff_mm: f64,
    pub min_frames: usize,
    /// Where line fits (wire phantoms) start.
    pub initial_marker_T_image: Option<Rigid>,
}

/// The noise values the fit used, for its description.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFitNoise {
    pub edge_sd_mm: f64,
    pub probe_corner_sd_px: f64,
    pub phantom_corner_sd_px: f64,
    pub tremor_sd_mm: f64,
    pub tremor_sd_deg: f64,
    /// With the intrinsics solved too: the focal length's SD the calibration
    /// gives them, px.
    pub intrinsics_fx_sd_px: Option<f64>,
    /// The echo edge's offset terms solved with the calibration, and their
    /// values `(a, b, c)`, mm (those not solved are 0).
    pub edge_offset: crate::estimate::edge_offset::EdgeOffset,
    pub edge_offset_mm: crate::estimate::edge_offset::EdgeTerms,
    /// The growth of the edge noise with the cut the arcs were weighed by.
    pub slice_blur: Option<crate::estimate::edge_blur::SliceBlur>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_estimator_name_is_one_a_manifest_may_name() {
        let noise = super::PoseFitNoise {
            edge_sd_mm: 0.1,
            probe_corner_sd_px: 0.1,
            phantom_corner_sd_px: 0.1,
            tremor_sd_mm: 0.1,
            tremor_sd_deg: 0.1,
            intrinsics_fx_sd_px: None,
            edge_offset: crate::estimate::edge_offset::EdgeOffset::None,
            edge_offset_mm: [0.0; 3],
            slice_blur: None,
        };
        let all = [
            Method::CutoffWorstFirst { cutoff_mm: 2.0 },
            Method::ThesisOneShot { cutoff_mm: 2.0 },
            Method::Ransac {
                threshold_mm: 1.0,
                noise_sd_mm: None,
            },
            Method::Lmeds { threshold_mm: 1.0 },
            Method::RansacLmScales,
            Method::RansacSphereFit {
                elevation_prior_sd_mm: None,
                edge_offset_mm: 0.0,
            },
            Method::SphereFit {
                arcs: 1,
                rms_mm: 0.1,
                rms_limit_mm: 0.3,
                pixel_size_fitted: false,
            },
            Method::SphereFitPosePrior {
                arcs: 1,
                rms_mm: 0.1,
                noise,
                pixel_size_fitted: false,
            },
        ];
        let names: Vec<&str> = all.iter().map(|m| m.name()).collect();
        assert_eq!(names, Method::NAMES.to_vec());
    }
    use crate::core::geometry::rigid_from_axis_angle;
    use nalgebra::Vector3;

    #[test]
    fn implausible_measurements_are_named() {
        let near = rigid_from_axis_angle(Vector3::new(0.1, 0.0, 0.0), Vector3::new(10.0, 20.0, 600.0));
        let far = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(0.0, 0.0, 1e12));
        let nan = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(f64::NAN, 0.0, 0.0));
        let names = ["camera_T_marker", "camera_T_phantom"];
        assert_eq!(Implausible::of(Some((near, near)), names, &[[10.0, 20.0]]), None);
        assert_eq!(Implausible::of(None, names, &[[1.0, 2.0]]), None);
        assert_eq!(
            Implausible::of(Some((near, nan)), names, &[]),
            Some(Implausible::PoseNotFinite {
                pose: "camera_T_phantom"
            })
        );
        let too_far = Implausible::of(Some((far, near)), names, &[]).unwrap();
        assert!(matches!(
            too_far,
            Implausible::PoseTooFar {
                pose: "camera_T_marker",
                ..
            }
        ));
        assert!(too_far.to_string().contains("more than 10000 mm"), "{too_far}");
        let pixel = Implausible::of(Some((near, near)), names, &[[f64::INFINITY, 3.0]]).unwrap();
        assert_eq!(pixel.to_string(), "a feature pixel (inf, 3) is not finite");
        assert_eq!(Rejection::Implausible(pixel).stage(), Stage::Plausibility);
    }
}
