//! The runner: one manifest, every dataset, every stage, in order.
//!
//! dataset (render or folder) → camera intrinsics (stage 1) → per frame: board
//! poses (stage 2) and arc centre (stage 3) → Horn (stage 4) → BRE, threshold
//! table, ground truth (stage 5). Every frame's fate is kept: used, or rejected
//! with the stage and the reason.

use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::Point3;
use opencv::prelude::MatTraitConst;

use crate::core::geometry::{rigid_from_rows, rotation_angle_between_deg, Rigid};
use crate::core::parallel::parallel_map;
use crate::detect::arc::{self, ArcFeature, ArcSettings};
use crate::detect::board_pose::{self, FramePoses, RigBoards};
use crate::detect::camera_calibration::{self, CameraCalibration};
use crate::detect::spot::{self, Spot, SpotSettings};
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::{HornError, HornFit};
use crate::estimate::wire_matching::{self, FrameDots, WireAxis};
use crate::evaluate::resampling;
use crate::evaluate::{self, EvaluationInputs, ThresholdRow, TruthComparison};
use crate::io::camera_model::CameraIntrinsics;
use crate::io::dataset::{self, FrameFiles};
use crate::io::image::{read_gray, read_gray_sized};
use crate::io::tracker_poses::{TrackedFrame, TrackerPoses};
use crate::io::truth::GroundTruth;
use crate::manifest::{CameraSource, Dataset, DatasetSource, Manifest};
use crate::spec::phantom::Phantom;
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
        }
    }
}

/// What happened to one frame.
#[derive(Debug, Clone)]
pub struct FrameRecord {
    pub files: FrameFiles,
    pub rejection: Option<(Stage, String)>,
    /// Board poses from the photo (camera stage).
    pub poses: Option<FramePoses>,
    /// Poses from a tracker instead (no camera).
    pub tracked: Option<TrackedFrame>,
    pub arc: Option<ArcFeature>,
    /// Compact echoes found (point and wire phantoms), strongest first.
    pub spots: Vec<Spot>,
    /// The feature pixels used: the arc's centre, the pin head, the wire dots.
    pub features_px: Vec<[f64; 2]>,
    /// Wire phantoms: the wire of each feature.
    pub wire_labels: Vec<String>,
    /// All-frames BRE `[x, y, z]` and 3D distance, mm (used frames).
    pub bre_mm: Option<([f64; 3], f64)>,
    /// Truth: frame kind and errors of the detections (rendered data).
    pub truth_kind: Option<String>,
    pub truth_arc_centre_error_px: Option<f64>,
    pub truth_elevation_offset_mm: Option<f64>,
    pub truth_probe_pose_error: Option<(f64, f64)>,
    /// Phantom board pose error (mm, degrees) against the truth.
    pub truth_phantom_pose_error: Option<(f64, f64)>,
    /// Probe board position error along the camera's viewing axis, mm.
    pub truth_probe_depth_error_mm: Option<f64>,
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
#[derive(Debug, Clone, serde::Serialize)]
pub struct GateResult {
    pub name: String,
    pub limit: f64,
    pub value: Option<f64>,
    pub passed: bool,
}

/// Truth for the whole dataset.
#[derive(Debug, Clone)]
pub struct TruthSummary {
    pub calibration: TruthComparison,
    /// `None` without a camera (tracker poses).
    pub camera_focal_error_px: Option<f64>,
    pub camera_principal_error_px: Option<f64>,
    pub arc_centre_error_px: Option<(f64, f64)>,
    pub probe_pose_translation_error_mm: Option<(f64, f64)>,
    pub probe_pose_rotation_error_deg: Option<(f64, f64)>,
    pub phantom_pose_translation_error_mm: Option<(f64, f64)>,
}

/// One estimator's calibration beside the thesis's (robust, refined, sphere fit).
#[derive(Debug, Clone)]
pub struct MethodResult {
    pub name: &'static str,
    pub description: String,
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
pub struct ValidationSummary {
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
    pub validation: Option<ValidationSummary>,
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

fn camera_stage(manifest: &Manifest, dataset: &str, folder: &Path) -> Result<CameraStage, RunError> {
    match &manifest.camera {
        CameraSource::IntrinsicsFile(path) => Ok(CameraStage {
            intrinsics: Some(CameraIntrinsics::load(path).map_err(|source| RunError::Intrinsics {
                dataset: dataset.into(),
                source,
            })?),
            calibration: None,
            source: format!("file {}", path.display()),
            tracker: None,
        }),
        CameraSource::TrackerCsv(csv) => {
            let poses = TrackerPoses::read(&folder.join(&csv.file)).map_err(|source| RunError::TrackerPoses {
                dataset: dataset.into(),
                source,
            })?;
            Ok(CameraStage {
                intrinsics: None,
                calibration: None,
                source: format!(
                    "no camera: tracker poses {} and {} from the dataset's {}",
                    csv.probe_transform, csv.reference_transform, csv.file
                ),
                tracker: Some(TrackerSource {
                    poses,
                    probe_transform: csv.probe_transform.clone(),
                    reference_transform: csv.reference_transform.clone(),
                }),
            })
        }
        CameraSource::Calibrate { images: given, board } => {
            let images = given.clone().unwrap_or_else(|| folder.join("camera_calibration"));
            // Described without machine-specific paths: the outputs must not depend on them.
            let described = match given {
                Some(path) => path.display().to_string(),
                None => "the dataset's camera_calibration/ folder".to_string(),
            };
            let calibration = camera_calibration::calibrate_folder(&images, board.inner_corners, board.square_mm)
                .map_err(|source| RunError::Calibration {
                    dataset: dataset.into(),
                    source,
                })?;
            Ok(CameraStage {
                intrinsics: Some(calibration.intrinsics.clone()),
                source: format!("calibrated from {described}"),
                calibration: Some(calibration),
                tracker: None,
            })
        }
    }
}

/// The B-scan feature detector of a phantom.
#[derive(Debug, Clone, Copy)]
enum Detector {
    Arc(ArcSettings),
    PinHead(SpotSettings),
    WireDots(SpotSettings),
}

/// Where a phantom's features lie: one known point, or on known wires.
#[derive(Debug, Clone, Copy)]
enum Targets<'a> {
    Point([f64; 3]),
    Wires(&'a [crate::spec::phantom::Wire]),
}

/// Two pin-head candidates closer in strength than this make the pin head ambiguous.
const PIN_HEAD_MIN_STRENGTH_RATIO: f64 = 1.5;

/// The echoes that look like a pin head of radius `r`: no wider across the beam
/// than the head plus the beam's blur, followed by a comet tail (the head's
/// reverberation) along the beam. Strongest first.
fn pin_head_candidates(spots: &[Spot], r: f64) -> Vec<Spot> {
    spots
        .iter()
        .filter(|s| s.width_mm <= 2.0 * r + 1.0 && s.length_mm >= 2.0 * r + 1.5)
        .cloned()
        .collect()
}

fn process_frame(
    files: &FrameFiles,
    camera: &CameraStage,
    rig: &RigBoards,
    detector: &Detector,
) -> Result<FrameRecord, RunError> {
    let mut record = FrameRecord {
        files: files.clone(),
        rejection: None,
        poses: None,
        tracked: None,
        arc: None,
        spots: Vec::new(),
        features_px: Vec::new(),
        wire_labels: Vec::new(),
        bre_mm: None,
        truth_kind: None,
        truth_arc_centre_error_px: None,
        truth_elevation_offset_mm: None,
        truth_probe_pose_error: None,
        truth_phantom_pose_error: None,
        truth_probe_depth_error_mm: None,
        bscan_size_px: None,
    };
    match (&camera.intrinsics, &camera.tracker) {
        (Some(intrinsics), _) => {
            let Some(photo_file) = &files.camera_image else {
                record.rejection = Some((Stage::CameraImage, "the frame list names no camera image".into()));
                return Ok(record);
            };
            let photo = match read_gray_sized(photo_file, intrinsics.image_size_px) {
                Ok(m) => m,
                Err(e) => {
                    record.rejection = Some((Stage::CameraImage, e.to_string()));
                    return Ok(record);
                }
            };
            match board_pose::estimate(&photo, intrinsics, rig)? {
                Ok(poses) => record.poses = Some(poses),
                Err(reason) => {
                    record.rejection = Some((Stage::BoardPose, reason));
                    return Ok(record);
                }
            }
        }
        (None, Some(t)) => match t.poses.frame(files.frame, &t.probe_transform, &t.reference_transform) {
            Ok(tracked) => record.tracked = Some(tracked),
            Err(reason) => {
                record.rejection = Some((Stage::TrackerPose, reason));
                return Ok(record);
            }
        },
        (None, None) => {
            return Err(RunError::Unsupported(
                "neither a camera nor a tracker gives the poses".into(),
            ))
        }
    }
    let bscan = match read_gray(&files.bscan_image) {
        Ok(m) => m,
        Err(e) => {
            record.rejection = Some((Stage::BscanImage, e.to_string()));
            return Ok(record);
        }
    };
    record.bscan_size_px = Some([bscan.cols() as usize, bscan.rows() as usize]);
    let spots = match detector {
        Detector::Arc(arc) => {
            match arc::detect(&bscan, arc) {
                Ok(Ok(feature)) => {
                    record.features_px = vec![feature.centre_px];
                    record.arc = Some(feature);
                }
                Ok(Err(reason)) => record.rejection = Some((Stage::Arc, reason)),
                Err(e) => record.rejection = Some((Stage::BscanImage, e.to_string())),
            }
            return Ok(record);
        }
        Detector::PinHead(settings) | Detector::WireDots(settings) => match spot::detect(&bscan, settings) {
            Ok(spots) => spots,
            Err(e) => {
                record.rejection = Some((Stage::BscanImage, e.to_string()));
                return Ok(record);
            }
        },
    };
    record.spots = spots.spots.clone();
    let px = |p: [f64; 2]| format!("({:.0}, {:.0})", p[0], p[1]);
    match detector {
        Detector::PinHead(settings) => match pin_head_candidates(&spots.spots, settings.object_radius_mm).as_slice() {
            [] => {
                record.rejection = Some((
                    Stage::Spot,
                    format!(
                        "no echo as wide as the pin head with a comet tail behind it ({} compact echoes, {} surface echoes)",
                        spots.spots.len(),
                        spots.surfaces
                    ),
                ))
            }
            [first, second, ..] if first.strength < PIN_HEAD_MIN_STRENGTH_RATIO * second.strength => {
                record.rejection = Some((
                    Stage::Spot,
                    format!(
                        "ambiguous: compact echoes of similar strength at {} and {} px",
                        px(first.echo_px),
                        px(second.echo_px)
                    ),
                ))
            }
            [first, ..] => record.features_px = vec![first.centre_px],
        },
        _ => {
            if spots.spots.len() < 2 {
                record.rejection = Some((
                    Stage::Wires,
                    format!(
                        "{} compact echoes, at least 2 wire dots are needed ({} surface echoes)",
                        spots.spots.len(),
                        spots.surfaces
                    ),
                ));
            } else {
                record.features_px = spots.spots.iter().map(|s| s.centre_px).collect();
            }
        }
    }
    Ok(record)
}

fn mean_max(values: &[f64]) -> Option<(f64, f64)> {
    (!values.is_empty()).then(|| {
        (
            values.iter().sum::<f64>() / values.len() as f64,
            values.iter().cloned().fold(0.0, f64::max),
        )
    })
}

/// Runs one dataset of a manifest. `datasets_root` holds rendered datasets.
pub fn run_dataset(
    manifest: &Manifest,
    dataset: &Dataset,
    datasets_root: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<DatasetRun, RunError> {
    let name = dataset.name.clone();
    let mut timings = Vec::new();
    let clock = Instant::now();
    let (folder, rendered) = match &dataset.source {
        DatasetSource::Render(spec) => {
            let folder = synth::dataset_folder(datasets_root, &manifest.experiment, &name);
            let outcome = synth::ensure_rendered(&super::settings::lab(manifest), spec, &folder).map_err(|source| {
                RunError::Synth {
                    dataset: name.clone(),
                    source,
                }
            })?;
            log(&format!(
                "dataset `{name}`: {} ({})",
                folder.display(),
                if outcome == synth::RenderOutcome::Rendered {
                    "rendered"
                } else {
                    "up to date"
                }
            ));
            (folder, true)
        }
        DatasetSource::Folder(folder) => (folder.clone(), false),
    };
    timings.push(("dataset", clock.elapsed().as_secs_f64()));
    let files = dataset::load_frame_list(&folder).map_err(|source| RunError::Dataset {
        dataset: name.clone(),
        source,
    })?;

    let clock = Instant::now();
    let camera = camera_stage(manifest, &name, &folder)?;
    timings.push(("camera calibration", clock.elapsed().as_secs_f64()));
    if let Some((k, rms)) = camera.intrinsics.as_ref().and_then(|k| Some((k, k.rms_px?))) {
        log(&format!(
            "camera: fx {:.2} fy {:.2} cx {:.2} cy {:.2} px, RMS {rms:.3} px",
            k.fx(),
            k.fy(),
            k.cx(),
            k.cy()
        ));
    }

    let clock = Instant::now();
    let rig = RigBoards::from_rig(&manifest.rig).map_err(|e| RunError::Unsupported(e.to_string()))?;
    let spacing = manifest.bscan_spacing_mm_per_px;
    let (detector, targets) = match &manifest.phantom {
        Phantom::Hemisphere {
            centre_in_phantom_mm,
            radius_mm,
        } => (
            Detector::Arc(ArcSettings {
                spacing_mm_per_px: spacing,
                radius_mm: [
                    manifest.arc_detection.radius_fraction[0] * radius_mm,
                    manifest.arc_detection.radius_fraction[1] * radius_mm,
                ],
                min_span_deg: manifest.arc_detection.min_span_deg,
                max_rms_px: manifest.arc_detection.max_rms_px,
                min_points: manifest.arc_detection.min_points,
                fixed_radius_mm: (manifest.arc_detection.fit_radius == crate::manifest::FitRadius::Known)
                    .then_some(*radius_mm),
            }),
            Targets::Point(*centre_in_phantom_mm),
        ),
        Phantom::Point {
            position_in_phantom_mm,
            head_radius_mm,
        } => (
            Detector::PinHead(SpotSettings {
                spacing_mm_per_px: spacing,
                object_radius_mm: *head_radius_mm,
            }),
            Targets::Point(*position_in_phantom_mm),
        ),
        Phantom::FourWire {
            wire_diameter_mm,
            wires,
        } => (
            Detector::WireDots(SpotSettings {
                spacing_mm_per_px: spacing,
                object_radius_mm: wire_diameter_mm / 2.0,
            }),
            Targets::Wires(wires),
        ),
    };
    let progress = crate::core::progress::Progress::new(files.len(), "board poses and B-scan features");
    let mut frames = parallel_map(files.len(), |i| {
        let record = process_frame(&files[i], &camera, &rig, &detector);
        progress.inc();
        record
    })
    .into_iter()
    .collect::<Result<Vec<_>, _>>()?;
    progress.finish();
    timings.push(("frames (board poses and arcs)", clock.elapsed().as_secs_f64()));

    let clock = Instant::now();
    let usable = |f: &FrameRecord| f.rejection.is_none() && f.pose_pair().is_some() && !f.features_px.is_empty();
    let min_frames = manifest.thresholds.min_frames;
    let variant = match manifest.solve_variant {
        crate::manifest::SolveVariant::Rigid => crate::estimate::horn::Variant::Rigid,
        crate::manifest::SolveVariant::Similarity => crate::estimate::horn::Variant::Similarity,
    };
    let correspondences: Vec<Correspondence> = match targets {
        Targets::Point(feature) => frames
            .iter()
            .filter(|f| usable(f))
            .filter_map(|f| {
                let (camera_T_marker, camera_T_phantom) = f.pose_pair()?;
                Some(Correspondence::point(
                    f.files.frame,
                    f.features_px[0],
                    Point3::from(nalgebra::Vector3::from(feature)),
                    camera_T_marker,
                    camera_T_phantom,
                ))
            })
            .collect(),
        Targets::Wires(wires) => {
            let axes: Vec<WireAxis> = wires
                .iter()
                .map(|w| WireAxis {
                    name: w.name.clone(),
                    start_in_phantom_mm: Point3::from(w.start_in_phantom_mm),
                    end_in_phantom_mm: Point3::from(w.end_in_phantom_mm),
                })
                .collect();
            let dots: Vec<FrameDots> = frames
                .iter()
                .filter(|f| usable(f))
                .filter_map(|f| {
                    let (camera_T_marker, camera_T_phantom) = f.pose_pair()?;
                    Some(FrameDots {
                        frame: f.files.frame,
                        dots_px: f.features_px.clone(),
                        camera_T_marker,
                        camera_T_phantom,
                    })
                })
                .collect();
            let start = manifest.initial_marker_T_image.ok_or_else(|| {
                RunError::Unsupported("the four_wire phantom needs solve.initial_marker_T_image".into())
            })?;
            let matching =
                wire_matching::match_and_solve(&dots, &axes, &start, spacing, min_frames).map_err(|source| {
                    RunError::Solve {
                        dataset: name.clone(),
                        source,
                    }
                })?;
            log(&format!(
                "wires: {} frames paired in {} rounds, {} left out",
                matching.correspondences.len(),
                matching.rounds,
                matching.rejected.len()
            ));
            for f in frames.iter_mut() {
                if let Some((_, reason)) = matching.rejected.iter().find(|(k, _)| *k == f.files.frame) {
                    f.rejection = Some((Stage::Wires, reason.clone()));
                }
                if let Some((_, labels)) = matching.labels.iter().find(|(k, _)| *k == f.files.frame) {
                    f.wire_labels = labels.clone();
                }
                if let Some(c) = matching.correspondences.iter().find(|c| c.frame == f.files.frame) {
                    f.features_px = c.features.iter().map(|o| o.pixel).collect();
                }
            }
            matching.correspondences
        }
    };
    // Where line fits start: the manifest's guess, refined on all frames below.
    let mut start = manifest.initial_marker_T_image;
    let min_frames = manifest.thresholds.min_frames;
    if correspondences.len() < min_frames {
        let reasons = frames
            .iter()
            .filter_map(|f| {
                f.rejection
                    .as_ref()
                    .map(|(s, r)| format!("  frame {}: {}: {r}", f.files.frame, s.label()))
            })
            .collect::<Vec<_>>()
            .join("\n");
        return Err(RunError::TooFewFrames {
            dataset: name,
            used: correspondences.len(),
            total: frames.len(),
            needed: min_frames,
            reasons,
        });
    }
    let all_frames_fit =
        correspondence::solve(&correspondences, spacing, variant, start.as_ref()).map_err(|source| {
            RunError::Solve {
                dataset: name.clone(),
                source,
            }
        })?;
    if start.is_some() {
        start = Some(all_frames_fit.target_T_source);
    }
    for f in frames.iter_mut() {
        if let Some(c) = correspondences.iter().find(|c| c.frame == f.files.frame) {
            f.bre_mm = Some(correspondence::bre(c, &all_frames_fit, spacing));
        }
    }

    // Ground truth is read here, after every estimate is made, and only for evaluation.
    let truth = GroundTruth::load(&folder).map_err(|source| RunError::Truth {
        dataset: name.clone(),
        source,
    })?;
    let inputs = EvaluationInputs {
        start,
        spacing,
        cutoffs_mm: &manifest.thresholds.bre_cutoffs_mm,
        rule: manifest.thresholds.cutoff_rule,
        min_frames,
        variant,
        truth: truth.as_ref().map(|t| (t.marker_T_image, t.bscan_size_px)),
    };
    let thresholds = evaluate::threshold_table(&correspondences, &inputs)?;
    let primary = thresholds
        .iter()
        .position(|r| r.cutoff_mm == manifest.thresholds.calibration_cutoff_mm)
        .unwrap_or(0);
    if let Err(e) = &thresholds[primary].fit {
        return Err(RunError::Cutoff {
            dataset: name,
            cutoff: crate::evaluate::cutoff_label(thresholds[primary].cutoff_mm),
            kept: thresholds[primary].frames.len(),
            source: e.clone(),
        });
    }
    timings.push(("calibration and evaluation", clock.elapsed().as_secs_f64()));

    // The calibration's truth comparison exists whenever truth was given (its fit succeeded above).
    let truth_summary = truth.as_ref().zip(thresholds[primary].truth).map(|(t, calibration)| {
        let mut arc_errors = Vec::new();
        let mut pose_t = Vec::new();
        let mut pose_r = Vec::new();
        let mut phantom_t = Vec::new();
        for f in frames.iter_mut() {
            let Some(tf) = t.frame(f.files.frame) else { continue };
            f.truth_kind = Some(tf.kind.clone());
            f.truth_elevation_offset_mm = Some(tf.elevation_offset_mm);
            let distance = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            // The feature pixels against the truth: the centre's projection, or each
            // paired wire dot against its wire's true dot.
            let error = if f.wire_labels.is_empty() {
                f.features_px.first().map(|p| distance(*p, tf.centre_projection_px))
            } else {
                let errors: Vec<f64> = f
                    .features_px
                    .iter()
                    .zip(&f.wire_labels)
                    .filter_map(|(p, label)| {
                        let dot = tf.wire_dots_px.iter().find(|d| &d.wire == label)?;
                        Some(distance(*p, dot.pixel))
                    })
                    .collect();
                (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64)
            };
            if let Some(e) = error {
                f.truth_arc_centre_error_px = Some(e);
                if f.rejection.is_none() && tf.kind == "normal" {
                    arc_errors.push(e);
                }
            }
            let pose_error = |est: &Rigid, truth: &Rigid| {
                (
                    (est.translation.vector - truth.translation.vector).norm(),
                    rotation_angle_between_deg(est, truth),
                )
            };
            // A photo's pose is compared with the marker when the photo was taken; a
            // tracker's with the marker at the B-scan (it is synchronised with it).
            let true_marker = if f.tracked.is_some() {
                &tf.camera_T_marker_bscan
            } else {
                &tf.camera_T_marker_photo
            };
            if let (Some((camera_T_marker, camera_T_phantom)), Ok(true_pose)) =
                (f.pose_pair(), rigid_from_rows(true_marker))
            {
                let (dt, dr) = pose_error(&camera_T_marker, &true_pose);
                f.truth_probe_pose_error = Some((dt, dr));
                f.truth_probe_depth_error_mm =
                    Some((camera_T_marker.translation.vector.z - true_pose.translation.vector.z).abs());
                pose_t.push(dt);
                pose_r.push(dr);
                let (pt, pr) = pose_error(&camera_T_phantom, &t.camera_T_phantom);
                f.truth_phantom_pose_error = Some((pt, pr));
                phantom_t.push(pt);
            }
        }
        let tk = &t.camera.camera_matrix;
        TruthSummary {
            calibration,
            camera_focal_error_px: camera
                .intrinsics
                .as_ref()
                .map(|k| (k.fx() - tk[0][0]).abs().max((k.fy() - tk[1][1]).abs())),
            camera_principal_error_px: camera
                .intrinsics
                .as_ref()
                .map(|k| ((k.cx() - tk[0][2]).powi(2) + (k.cy() - tk[1][2]).powi(2)).sqrt()),
            arc_centre_error_px: mean_max(&arc_errors),
            probe_pose_translation_error_mm: mean_max(&pose_t),
            probe_pose_rotation_error_deg: mean_max(&pose_r),
            phantom_pose_translation_error_mm: mean_max(&phantom_t),
        }
    });

    let clock = Instant::now();
    let truth_transform = truth.as_ref().map(|t| (t.marker_T_image, t.bscan_size_px));
    let image_size_px = truth_transform
        .map(|(_, size)| size)
        .or_else(|| frames.iter().find_map(|f| f.bscan_size_px))
        .unwrap_or([0, 0]);
    let fit_inputs = resampling::FitInputs {
        spacing,
        variant,
        start: start.as_ref(),
        image_size_px,
    };
    let primary_frames: Vec<Correspondence> = correspondences
        .iter()
        .filter(|c| thresholds[primary].frames.contains(&c.frame))
        .cloned()
        .collect();
    let validation = match validation_stage(manifest, &primary_frames, &thresholds[primary], &fit_inputs) {
        Ok(v) => Some(v),
        Err(e) => {
            log(&format!("validation metrics skipped: {e}"));
            None
        }
    };
    let methods = match targets {
        Targets::Point(feature) => {
            let sphere = match &manifest.phantom {
                Phantom::Hemisphere { radius_mm, .. } => Some(*radius_mm),
                _ => None,
            };
            methods_stage(
                manifest,
                &frames,
                &correspondences,
                &thresholds[primary],
                &fit_inputs,
                (feature, sphere),
                truth_transform,
                log,
            )
        }
        Targets::Wires(_) => Vec::new(),
    };
    timings.push(("methods and validation metrics", clock.elapsed().as_secs_f64()));

    let gates = evaluate_gates(manifest, &thresholds[primary], truth_summary.as_ref());
    let mut input_files = vec![manifest.path.clone(), folder.join(crate::io::dataset::FRAME_LIST)];
    for f in &files {
        if camera.intrinsics.is_some() {
            input_files.extend(f.camera_image.clone());
        }
        input_files.push(f.bscan_image.clone());
    }
    if let Some(cal) = &camera.calibration {
        input_files.extend(cal.views.iter().map(|v| v.image.clone()));
    }
    match &manifest.camera {
        CameraSource::IntrinsicsFile(path) => input_files.push(path.clone()),
        CameraSource::TrackerCsv(csv) => input_files.push(folder.join(&csv.file)),
        CameraSource::Calibrate { .. } => {}
    }
    let seed = match &dataset.source {
        DatasetSource::Render(spec) => Some(spec.seed),
        DatasetSource::Folder(_) => None,
    };
    Ok(DatasetRun {
        experiment: manifest.experiment.clone(),
        dataset: name,
        dataset_folder: folder,
        rendered,
        camera,
        frames,
        all_frames_fit,
        thresholds,
        primary,
        truth: truth_summary,
        gates,
        spacing_mm_per_px: spacing,
        feature_in_phantom_mm: match targets {
            Targets::Point(p) => Some(p),
            Targets::Wires(_) => None,
        },
        methods,
        validation,
        timings_s: timings,
        input_files,
        seed,
    })
}

fn validation_stage(
    manifest: &Manifest,
    frames: &[Correspondence],
    primary: &ThresholdRow,
    inputs: &resampling::FitInputs<'_>,
) -> Result<ValidationSummary, HornError> {
    let full = primary.fit.clone()?;
    let v = &manifest.validation;
    Ok(ValidationSummary {
        leave_one_out: resampling::leave_one_out(frames, inputs)?,
        reproducibility: resampling::reproducibility(frames, inputs, v.cr_half_splits, v.seed)?,
        bootstrap: resampling::bootstrap(frames, &full, inputs, v.bootstrap_resamples, v.seed)?,
    })
}

/// Ground-truth error of a calibration that maps pixels with `spacing` (the truth
/// maps them with the manifest's `truth_spacing`).
fn truth_of(
    marker_T_image: &Rigid,
    spacing: [f64; 2],
    truth_spacing: [f64; 2],
    truth: Option<(Rigid, [usize; 2])>,
) -> Option<TruthComparison> {
    let (t, size) = truth?;
    let estimate = HornFit {
        target_T_source: *marker_T_image,
        scale: 1.0,
        rms_residual_mm: 0.0,
    };
    Some(evaluate::compare_mapped(&estimate, spacing, &t, truth_spacing, size))
}

/// The frames (their numbers) an estimator did not keep.
fn left_out(frames: &[Correspondence], kept: impl Fn(&Correspondence) -> bool) -> Vec<usize> {
    frames.iter().filter(|f| !kept(f)).map(|f| f.frame).collect()
}

/// The frames outside a robust estimator's consensus (`inliers` runs along `frames`).
fn outside_consensus(frames: &[Correspondence], inliers: &[bool]) -> Vec<usize> {
    frames
        .iter()
        .zip(inliers)
        .filter(|(_, k)| !**k)
        .map(|(f, _)| f.frame)
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn methods_stage(
    manifest: &Manifest,
    records: &[FrameRecord],
    frames: &[Correspondence],
    thesis: &ThresholdRow,
    inputs: &resampling::FitInputs<'_>,
    (feature, sphere_radius): ([f64; 3], Option<f64>),
    truth: Option<(Rigid, [usize; 2])>,
    log: &mut dyn FnMut(&str),
) -> Vec<MethodResult> {
    let spacing = inputs.spacing;
    let truth_of = |m: &Rigid, s: [f64; 2]| truth_of(m, s, spacing, truth);
    let mut out = Vec::new();
    if let Ok(fit) = &thesis.fit {
        out.push(MethodResult {
            name: "cutoff_worst_first",
            description: format!(
                "the reported calibration: Horn on the feature centres, frames above {} mm removed worst first, re-solving after each",
                crate::evaluate::cutoff_label(thesis.cutoff_mm)
            ),
            frames_used: thesis.frames.len(),
            frames_left_out: left_out(frames, |f| thesis.frames.contains(&f.frame)),
            marker_T_image: fit.target_T_source,
            spacing_mm_per_px: spacing,
            truth: truth_of(&fit.target_T_source, spacing),
        });
    }
    // The thesis's own procedure: one Horn fit on all frames, every frame whose BRE
    // under it exceeds the cut-off dropped at once, Horn again.
    if thesis.cutoff_mm.is_finite() {
        if let Ok(all) = correspondence::solve(frames, spacing, inputs.variant, None) {
            let kept: Vec<Correspondence> = frames
                .iter()
                .filter(|f| {
                    let (axes, norm) = correspondence::bre(f, &all, spacing);
                    let value = match manifest.thresholds.cutoff_rule {
                        crate::evaluate::CutoffRule::MaxAxis => axes.iter().cloned().fold(0.0, f64::max),
                        crate::evaluate::CutoffRule::Norm => norm,
                    };
                    value < thesis.cutoff_mm
                })
                .cloned()
                .collect();
            if let Ok(fit) = correspondence::solve(&kept, spacing, inputs.variant, None) {
                out.push(MethodResult {
                    name: "thesis_one_shot",
                    description: format!(
                        "the thesis's procedure: Horn on all frames, every frame above {} mm dropped at once, Horn again",
                        crate::evaluate::cutoff_label(thesis.cutoff_mm)
                    ),
                    frames_used: kept.len(),
                    frames_left_out: left_out(frames, |f| kept.iter().any(|c| c.frame == f.frame)),
                    marker_T_image: fit.target_T_source,
                    spacing_mm_per_px: spacing,
                    truth: truth_of(&fit.target_T_source, spacing),
                });
            }
        }
    }
    let mut ransac = None;
    for method in [
        crate::estimate::robust::RobustMethod::Ransac,
        crate::estimate::robust::RobustMethod::Lmeds,
    ] {
        let settings = crate::estimate::robust::RobustSettings {
            method,
            ..manifest.robust
        };
        match crate::estimate::robust::solve(frames, spacing, inputs.variant, &settings) {
            Ok(r) => {
                let used = r.inliers.iter().filter(|k| **k).count();
                let name = match method {
                    crate::estimate::robust::RobustMethod::Ransac => "ransac",
                    crate::estimate::robust::RobustMethod::Lmeds => "lmeds",
                };
                out.push(MethodResult {
                    name,
                    description: format!(
                        "{} over frames (samples of 3, Horn inside), inlier threshold {:.3} mm{}",
                        name.to_uppercase(),
                        r.threshold_mm,
                        if settings.threshold_mm.is_some() && method == crate::estimate::robust::RobustMethod::Ransac {
                            " (manifest)"
                        } else {
                            " (from the data)"
                        }
                    ),
                    frames_used: used,
                    frames_left_out: outside_consensus(frames, &r.inliers),
                    marker_T_image: r.fit.target_T_source,
                    spacing_mm_per_px: spacing,
                    truth: truth_of(&r.fit.target_T_source, spacing),
                });
                if method == crate::estimate::robust::RobustMethod::Ransac {
                    ransac = Some(r);
                }
            }
            Err(e) => log(&format!("{method:?}: {e}")),
        }
    }
    let Some(ransac) = ransac else { return out };
    let ransac_left_out = outside_consensus(frames, &ransac.inliers);
    let inliers: Vec<&Correspondence> = frames
        .iter()
        .zip(&ransac.inliers)
        .filter(|(_, k)| **k)
        .map(|(f, _)| f)
        .collect();
    // Levenberg–Marquardt with the pixel size as two more unknowns.
    let constraints: Vec<crate::estimate::image_to_probe::Constraint> = inliers
        .iter()
        .flat_map(|f| {
            let marker_T_phantom = f.marker_T_phantom().to_homogeneous();
            f.features
                .iter()
                .map(move |o| crate::estimate::image_to_probe::Constraint {
                    pixel: o.pixel,
                    probe_T_phantom: marker_T_phantom,
                    target_in_phantom: o.target_in_phantom,
                })
        })
        .collect();
    let start = crate::estimate::image_to_probe::ImageToProbe {
        probe_T_image: ransac.fit.target_T_source,
        spacing_mm_per_px: spacing,
    };
    match crate::estimate::image_to_probe::refine(&start, &constraints, None, false) {
        Ok(fit) => {
            let m = &fit.image_to_probe;
            out.push(MethodResult {
                name: "ransac_lm_scales",
                description: format!(
                    "RANSAC's frames, Levenberg–Marquardt with the pixel size as unknowns ({:.4} x {:.4} mm/px)",
                    m.spacing_mm_per_px[0], m.spacing_mm_per_px[1]
                ),
                frames_used: inliers.len(),
                frames_left_out: ransac_left_out.clone(),
                marker_T_image: m.probe_T_image,
                spacing_mm_per_px: m.spacing_mm_per_px,
                truth: truth_of(&m.probe_T_image, m.spacing_mm_per_px),
            });
        }
        Err(e) => log(&format!("LM with pixel scales: {e}")),
    }
    let Some(radius_mm) = sphere_radius else { return out };
    let arcs: Vec<crate::estimate::sphere_fit::ArcFrame> = inliers
        .iter()
        .filter_map(|c| {
            let record = records.iter().find(|r| r.files.frame == c.frame)?;
            Some(crate::estimate::sphere_fit::ArcFrame {
                frame: c.frame,
                edge_px: record.arc.as_ref()?.arc_points_px.clone(),
                camera_T_marker: c.camera_T_marker,
                camera_T_phantom: c.camera_T_phantom,
            })
        })
        .collect();
    let settings = crate::estimate::sphere_fit::SphereSettings {
        centre_in_phantom_mm: Point3::from(nalgebra::Vector3::from(feature)),
        radius_mm,
        spacing_mm_per_px: spacing,
        elevation_prior_sd_mm: manifest.sphere_fit.elevation_prior_sd_mm,
        fit_radius_offset: manifest.sphere_fit.fit_radius_offset,
        points_per_frame: 20.0,
    };
    match crate::estimate::sphere_fit::refine(&ransac.fit.target_T_source, &arcs, &settings) {
        Ok(fit) => out.push(MethodResult {
            name: "ransac_sphere_fit",
            description: format!(
                "RANSAC's frames, every arc edge point on the sphere (LM; elevation prior {}, edge offset {:.3} mm)",
                settings
                    .elevation_prior_sd_mm
                    .map(|s| format!("{s} mm"))
                    .unwrap_or_else(|| "none".into()),
                fit.radius_offset_mm
            ),
            frames_used: arcs.len(),
            frames_left_out: ransac_left_out,
            marker_T_image: fit.marker_T_image,
            spacing_mm_per_px: spacing,
            truth: truth_of(&fit.marker_T_image, spacing),
        }),
        Err(e) => log(&format!("sphere fit: {e}")),
    }
    out
}

fn evaluate_gates(manifest: &Manifest, primary: &ThresholdRow, truth: Option<&TruthSummary>) -> Vec<GateResult> {
    let g = &manifest.thresholds.gates;
    let mut out = Vec::new();
    let mut gate = |name: &str, limit: Option<f64>, value: Option<f64>| {
        if let Some(limit) = limit {
            out.push(GateResult {
                name: name.to_string(),
                limit,
                value,
                passed: value.is_some_and(|v| v <= limit),
            });
        }
    };
    gate(
        "truth_corner_error_mm",
        g.truth_corner_error_mm,
        truth.map(|t| t.calibration.corner_error_mean_mm),
    );
    gate(
        "truth_rotation_error_deg",
        g.truth_rotation_error_deg,
        truth.map(|t| t.calibration.rotation_error_deg),
    );
    gate("bre_mean_mm", g.bre_mean_mm, primary.stats.map(|s| s.max_mean()));
    out
}

/// Renders the datasets of a manifest without running the pipeline.
pub fn synth_only(manifest: &Manifest, datasets_root: &Path, log: &mut dyn FnMut(&str)) -> Result<(), RunError> {
    for d in &manifest.datasets {
        if let DatasetSource::Render(spec) = &d.source {
            let folder = synth::dataset_folder(datasets_root, &manifest.experiment, &d.name);
            let clock = Instant::now();
            let outcome = synth::ensure_rendered(&super::settings::lab(manifest), spec, &folder).map_err(|source| {
                RunError::Synth {
                    dataset: d.name.clone(),
                    source,
                }
            })?;
            log(&format!(
                "dataset `{}`: {} ({}, {:.1} s)",
                d.name,
                folder.display(),
                if outcome == synth::RenderOutcome::Rendered {
                    "rendered"
                } else {
                    "up to date"
                },
                clock.elapsed().as_secs_f64()
            ));
        } else {
            log(&format!("dataset `{}`: recorded folder, nothing to render", d.name));
        }
    }
    Ok(())
}
