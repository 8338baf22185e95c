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

use crate::arc_detection::{self, ArcFeature, ArcSettings};
use crate::board_pose::{self, FramePoses, RigBoards};
use crate::camera_calibration::{self, CameraCalibration};
use crate::camera_model::CameraIntrinsics;
use crate::dataset::{self, FrameFiles};
use crate::evaluate::{self, Correspondence, EvaluationInputs, ThresholdRow, TruthComparison};
use crate::geometry::{rigid_from_rows, rotation_angle_between_deg, Rigid};
use crate::horn::{HornError, HornFit};
use crate::image::{read_gray, read_gray_sized};
use crate::manifest::{CameraSource, Dataset, DatasetSource, Manifest, Phantom};
use crate::parallel::parallel_map;
use crate::synth;
use crate::truth::GroundTruth;

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("dataset `{dataset}`: {source}")]
    Dataset {
        dataset: String,
        source: crate::dataset::DatasetError,
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
        source: crate::camera_model::IntrinsicsError,
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
        source: crate::truth::TruthError,
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
}

impl Stage {
    pub fn label(self) -> &'static str {
        match self {
            Stage::CameraImage => "camera image",
            Stage::BoardPose => "board pose",
            Stage::BscanImage => "B-scan image",
            Stage::Arc => "arc detection",
        }
    }
}

/// What happened to one frame.
#[derive(Debug, Clone)]
pub struct FrameRecord {
    pub files: FrameFiles,
    pub rejection: Option<(Stage, String)>,
    pub poses: Option<FramePoses>,
    pub arc: Option<ArcFeature>,
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

/// Camera intrinsics and, if calibrated here, the calibration.
#[derive(Debug, Clone)]
pub struct CameraStage {
    pub intrinsics: CameraIntrinsics,
    pub calibration: Option<CameraCalibration>,
    pub source: String,
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
    pub camera_focal_error_px: f64,
    pub camera_principal_error_px: f64,
    pub arc_centre_error_px: Option<(f64, f64)>,
    pub probe_pose_translation_error_mm: Option<(f64, f64)>,
    pub probe_pose_rotation_error_deg: Option<(f64, f64)>,
    pub phantom_pose_translation_error_mm: Option<(f64, f64)>,
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
    pub feature_in_phantom_mm: [f64; 3],
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
            intrinsics: CameraIntrinsics::load(path).map_err(|source| RunError::Intrinsics {
                dataset: dataset.into(),
                source,
            })?,
            calibration: None,
            source: format!("file {}", path.display()),
        }),
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
                intrinsics: calibration.intrinsics.clone(),
                source: format!("calibrated from {described}"),
                calibration: Some(calibration),
            })
        }
    }
}

fn process_frame(
    files: &FrameFiles,
    camera: &CameraIntrinsics,
    rig: &RigBoards,
    arc: &ArcSettings,
) -> Result<FrameRecord, RunError> {
    let mut record = FrameRecord {
        files: files.clone(),
        rejection: None,
        poses: None,
        arc: None,
        bre_mm: None,
        truth_kind: None,
        truth_arc_centre_error_px: None,
        truth_elevation_offset_mm: None,
        truth_probe_pose_error: None,
        truth_phantom_pose_error: None,
        truth_probe_depth_error_mm: None,
        bscan_size_px: None,
    };
    let photo = match read_gray_sized(&files.camera_image, camera.image_size_px) {
        Ok(m) => m,
        Err(e) => {
            record.rejection = Some((Stage::CameraImage, e.to_string()));
            return Ok(record);
        }
    };
    match board_pose::estimate(&photo, camera, rig)? {
        Ok(poses) => record.poses = Some(poses),
        Err(reason) => {
            record.rejection = Some((Stage::BoardPose, reason));
            return Ok(record);
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
    match arc_detection::detect(&bscan, arc) {
        Ok(Ok(feature)) => record.arc = Some(feature),
        Ok(Err(reason)) => record.rejection = Some((Stage::Arc, reason)),
        Err(e) => record.rejection = Some((Stage::BscanImage, e.to_string())),
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
    let Phantom::Hemisphere {
        centre_in_phantom_mm,
        radius_mm,
    } = &manifest.phantom
    else {
        return Err(RunError::Unsupported(
            "only the hemisphere phantom can be run in this version".into(),
        ));
    };
    let clock = Instant::now();
    let (folder, rendered) = match &dataset.source {
        DatasetSource::Render(spec) => {
            let folder = synth::dataset_folder(datasets_root, &manifest.experiment, &name);
            let outcome = synth::ensure_rendered(manifest, spec, &folder).map_err(|source| RunError::Synth {
                dataset: name.clone(),
                source,
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
    if let Some(rms) = camera.intrinsics.rms_px {
        log(&format!(
            "camera: fx {:.2} fy {:.2} cx {:.2} cy {:.2} px, RMS {rms:.3} px",
            camera.intrinsics.fx(),
            camera.intrinsics.fy(),
            camera.intrinsics.cx(),
            camera.intrinsics.cy()
        ));
    }

    let clock = Instant::now();
    let rig = RigBoards::from_manifest(&manifest.rig).map_err(|e| RunError::Unsupported(e.to_string()))?;
    let spacing = manifest.bscan_spacing_mm_per_px;
    let arc_settings = ArcSettings {
        spacing_mm_per_px: spacing,
        radius_mm: [
            manifest.arc_detection.radius_fraction[0] * radius_mm,
            manifest.arc_detection.radius_fraction[1] * radius_mm,
        ],
        min_span_deg: manifest.arc_detection.min_span_deg,
        max_rms_px: manifest.arc_detection.max_rms_px,
        min_points: manifest.arc_detection.min_points,
        fixed_radius_mm: (manifest.arc_detection.fit_radius == crate::manifest::FitRadius::Known).then_some(*radius_mm),
    };
    let progress = crate::progress::Progress::new(files.len(), "board poses and arcs");
    let mut frames = parallel_map(files.len(), |i| {
        let record = process_frame(&files[i], &camera.intrinsics, &rig, &arc_settings);
        progress.inc();
        record
    })
    .into_iter()
    .collect::<Result<Vec<_>, _>>()?;
    progress.finish();
    timings.push(("frames (board poses and arcs)", clock.elapsed().as_secs_f64()));

    let clock = Instant::now();
    let feature = Point3::from(nalgebra::Vector3::from(*centre_in_phantom_mm));
    let correspondences: Vec<Correspondence> = frames
        .iter()
        .filter(|f| f.rejection.is_none())
        .filter_map(|f| {
            let (poses, arc) = (f.poses.as_ref()?, f.arc.as_ref()?);
            Some(Correspondence {
                frame: f.files.frame,
                feature_px: arc.centre_px,
                camera_T_marker: poses.camera_T_marker.camera_T_board,
                camera_T_phantom: poses.camera_T_phantom.camera_T_board,
            })
        })
        .collect();
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
    let variant = match manifest.solve_variant {
        crate::manifest::SolveVariant::Rigid => crate::horn::Variant::Rigid,
        crate::manifest::SolveVariant::Similarity => crate::horn::Variant::Similarity,
    };
    let all_frames_fit =
        evaluate::solve(&correspondences, &feature, spacing, variant).map_err(|source| RunError::Solve {
            dataset: name.clone(),
            source,
        })?;
    for f in frames.iter_mut() {
        if let Some(c) = correspondences.iter().find(|c| c.frame == f.files.frame) {
            f.bre_mm = Some(evaluate::bre(c, &all_frames_fit, &feature, spacing));
        }
    }

    // Ground truth is read here, after every estimate is made, and only for evaluation.
    let truth = GroundTruth::load(&folder).map_err(|source| RunError::Truth {
        dataset: name.clone(),
        source,
    })?;
    let inputs = EvaluationInputs {
        feature_in_phantom: feature,
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
            cutoff: crate::output::cutoff_label(thresholds[primary].cutoff_mm),
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
            if let Some(arc) = &f.arc {
                let e = ((arc.centre_px[0] - tf.centre_projection_px[0]).powi(2)
                    + (arc.centre_px[1] - tf.centre_projection_px[1]).powi(2))
                .sqrt();
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
            if let (Some(poses), Ok(true_pose)) = (&f.poses, rigid_from_rows(&tf.camera_T_marker_photo)) {
                let (dt, dr) = pose_error(&poses.camera_T_marker.camera_T_board, &true_pose);
                f.truth_probe_pose_error = Some((dt, dr));
                f.truth_probe_depth_error_mm = Some(
                    (poses.camera_T_marker.camera_T_board.translation.vector.z - true_pose.translation.vector.z).abs(),
                );
                pose_t.push(dt);
                pose_r.push(dr);
                let (pt, pr) = pose_error(&poses.camera_T_phantom.camera_T_board, &t.camera_T_phantom);
                f.truth_phantom_pose_error = Some((pt, pr));
                phantom_t.push(pt);
            }
        }
        let k = &camera.intrinsics;
        let tk = &t.camera.camera_matrix;
        TruthSummary {
            calibration,
            camera_focal_error_px: (k.fx() - tk[0][0]).abs().max((k.fy() - tk[1][1]).abs()),
            camera_principal_error_px: ((k.cx() - tk[0][2]).powi(2) + (k.cy() - tk[1][2]).powi(2)).sqrt(),
            arc_centre_error_px: mean_max(&arc_errors),
            probe_pose_translation_error_mm: mean_max(&pose_t),
            probe_pose_rotation_error_deg: mean_max(&pose_r),
            phantom_pose_translation_error_mm: mean_max(&phantom_t),
        }
    });

    let gates = evaluate_gates(manifest, &thresholds[primary], truth_summary.as_ref());
    let mut input_files = vec![manifest.path.clone(), folder.join(crate::dataset::FRAME_LIST)];
    for f in &files {
        input_files.push(f.camera_image.clone());
        input_files.push(f.bscan_image.clone());
    }
    if let Some(cal) = &camera.calibration {
        input_files.extend(cal.views.iter().map(|v| v.image.clone()));
    }
    if let CameraSource::IntrinsicsFile(path) = &manifest.camera {
        input_files.push(path.clone());
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
        feature_in_phantom_mm: *centre_in_phantom_mm,
        timings_s: timings,
        input_files,
        seed,
    })
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
            let outcome = synth::ensure_rendered(manifest, spec, &folder).map_err(|source| RunError::Synth {
                dataset: d.name.clone(),
                source,
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
