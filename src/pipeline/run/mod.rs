//! The runner: one manifest's dataset, every stage, in order.
//!
//! dataset (render or folder) → camera intrinsics (stage 1, [`crate::pipeline::run::camera`]) →
//! per frame: board poses (stage 2) and the phantom's feature (stage 3,
//! [`crate::pipeline::frames`]) → point pairs and Horn (stage 4, [`crate::pipeline::solve`]) → BRE,
//! threshold table (stage 5, [`crate::evaluate`]), the other estimators and the
//! resampling metrics ([`crate::pipeline::run::methods`]) → and only then the ground truth
//! (rendered data, [`crate::pipeline::run::truth`]), which scores the estimates and is read by
//! nothing before it. Every frame's fate is kept: used, or rejected with the
//! stage and the reason.

pub mod camera;
pub mod design;
pub mod lab;
pub mod methods;
pub mod resolve;
pub mod sphere_pose;
pub mod truth;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::core::timing::StageClock;

use crate::detect::board_pose::RigBoards;
use crate::estimate::correspondence::Correspondence;
use crate::evaluate::resampling::FitInputs;
use crate::evaluate::ThresholdRow;
use crate::io::dataset;
use crate::io::fs::Lock;
use crate::io::truth::GroundTruth;
use crate::manifest::{CameraSource, Dataset, DatasetSource, Manifest};
pub use crate::pipeline::error::RunError;
use crate::pipeline::frames::{self, Targets};
use crate::pipeline::record::{DatasetRun, GateResult, TruthSummary};
pub use crate::pipeline::run::truth::true_calibration;
use crate::pipeline::settings;
use crate::pipeline::solve::{self, PairingInputs};
use crate::synth;
use methods::MethodInputs;

/// The dataset's folder: rendered into `datasets_root` (unless up to date), or recorded.
fn dataset_folder(
    manifest: &Manifest,
    dataset: &Dataset,
    datasets_root: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<(PathBuf, Option<Lock>), RunError> {
    let name = &dataset.name;
    match &dataset.source {
        DatasetSource::Render(spec) => {
            let folder = synth::dataset_folder(datasets_root, &manifest.experiment, name);
            let claim = claim_rendered(&folder, name, log)?;
            let outcome =
                synth::ensure_rendered(&settings::lab(manifest), spec, &folder).map_err(|source| RunError::Synth {
                    dataset: name.clone(),
                    source,
                })?;
            log(&format!(
                "dataset `{name}`: {} ({})",
                folder.display(),
                outcome_words(&outcome)
            ));
            Ok((folder, Some(claim)))
        }
        DatasetSource::Folder(folder) => Ok((folder.clone(), None)),
    }
}

/// Claims a rendered dataset's folder while it is rendered and read: another
/// process rendering or reading the same dataset is waited for (others run on).
fn claim_rendered(folder: &Path, dataset: &str, log: &mut dyn FnMut(&str)) -> Result<Lock, RunError> {
    let path = claim_file(folder);
    Lock::acquire_waiting(&path, &mut |m| log(m)).map_err(|e| RunError::Synth {
        dataset: dataset.to_string(),
        source: synth::SynthError::Io {
            message: e.reason(),
            path: path.clone(),
        },
    })
}

/// The lock file beside a rendered dataset's folder (`.<folder>.lock`).
pub fn claim_file(folder: &Path) -> PathBuf {
    let name = folder
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    folder.parent().unwrap_or(Path::new(".")).join(format!(".{name}.lock"))
}

/// Runs one dataset of a manifest. `datasets_root` holds rendered datasets.
pub fn run_dataset(
    manifest: &Manifest,
    dataset: &Dataset,
    datasets_root: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<DatasetRun, RunError> {
    let name = dataset.name.clone();
    let mut clock = StageClock::default();
    let (folder, claim) = clock.time("dataset", || dataset_folder(manifest, dataset, datasets_root, log))?;
    let files = dataset::load_frame_list(&folder).map_err(|source| RunError::Dataset {
        dataset: name.clone(),
        source,
    })?;
    let mut camera = clock.time("camera calibration", || camera::camera_stage(manifest, &name, &folder))?;
    log_camera(&camera, false, log);
    let rig = RigBoards::from_rig(&manifest.rig).map_err(|e| RunError::Unsupported(e.to_string()))?;
    let spacing = manifest.bscan_spacing_mm_per_px;
    let (detector, targets) = settings::detector(manifest);
    let mut frames = clock.time("frames (board poses and arcs)", || {
        frames::process_all(&files, &camera, &rig, &detector)
    })?;
    let started = Instant::now();
    if camera::refine_with_frames(manifest, &mut camera, &mut frames, &rig, &name)? {
        clock.record("camera refined with the frames' boards", started);
        log_camera(&camera, true, log);
    }
    let Calibrated {
        correspondences,
        start_guess,
        solve_settings,
        solved:
            solve::Calibrations {
                all_frames_fit,
                start,
                thresholds,
                primary,
            },
    } = clock.time("calibration and evaluation", || {
        calibrate(manifest, &name, &mut frames, targets, log)
    })?;
    let fit_inputs = FitInputs {
        spacing,
        variant: settings::variant(manifest),
        start: start.as_ref(),
        image_size_px: frames.iter().find_map(|f| f.bscan_size_px).unwrap_or([0, 0]),
    };
    let estimators = Estimators {
        manifest,
        camera: &camera,
        rig: &rig,
        targets,
        inputs: MethodInputs {
            records: &frames,
            frames: &correspondences,
            reported: &thresholds[primary],
            fit: &fit_inputs,
            feature_in_phantom_mm: [0.0; 3],
            sphere_radius_mm: None,
        },
    };
    let (validation, methods) = clock.time("methods and validation metrics", || estimators.run(log));
    let mut run = DatasetRun {
        gates: Vec::new(),
        input_files: input_files(manifest, &folder, &files, &camera),
        experiment: manifest.experiment.clone(),
        dataset: name,
        dataset_folder: folder,
        rendered: claim.is_some(),
        camera,
        frames,
        all_frames_fit,
        pairs: correspondences,
        solve: solve_settings,
        thresholds,
        primary,
        truth: None,
        spacing_mm_per_px: spacing,
        feature_in_phantom_mm: match targets {
            Targets::Point(p) => Some(p),
            Targets::Wires(_) | Targets::Spheres(_) => None,
        },
        methods,
        start_guess,
        validation,
        timings_s: Vec::new(),
        seed: match &dataset.source {
            DatasetSource::Render(spec) => Some(spec.seed),
            DatasetSource::Folder(_) => None,
        },
    };
    score_against_truth(manifest, &mut run)?;
    run.gates = evaluate_gates(manifest, &run.thresholds[run.primary], run.truth.as_ref(), &run.methods);
    run.timings_s = clock.into_timings();
    Ok(run)
}

/// Only now, with every estimate made, is the dataset's truth (rendered data)
/// read: to score the estimates, never to make them.
fn score_against_truth(manifest: &Manifest, run: &mut DatasetRun) -> Result<(), RunError> {
    let truth = GroundTruth::load(&run.dataset_folder).map_err(|source| RunError::Truth {
        dataset: run.dataset.clone(),
        source,
    })?;
    if let Some(t) = &truth {
        let arcs_against = truth::ArcCheck {
            spacing_mm_per_px: manifest.bscan_spacing_mm_per_px,
            noise: crate::pipeline::run::design::edge_noise(manifest),
        };
        truth::score_run(run, t, &arcs_against);
    }
    Ok(())
}

/// Logs the camera's intrinsics: as calibrated (with its RMS), or as refined
/// with the frames' boards.
fn log_camera(camera: &crate::pipeline::record::CameraStage, refined: bool, log: &mut dyn FnMut(&str)) {
    let Some(k) = &camera.intrinsics else { return };
    let line = format!("fx {:.2} fy {:.2} cx {:.2} cy {:.2} px", k.fx(), k.fy(), k.cx(), k.cy());
    if !refined {
        if let Some(rms) = k.rms_px {
            log(&format!("camera: {line}, RMS {rms:.3} px"));
        }
    } else if let Some(r) = camera.calibration.as_ref().and_then(|c| c.refined.as_ref()) {
        log(&format!(
            "camera refined with {} boards of the frames: {line}",
            r.boards_used
        ));
    }
}

/// The point pairs and the calibration at every cut-off.
struct Calibrated {
    correspondences: Vec<Correspondence>,
    start_guess: Option<crate::estimate::start_basin::StartGuess>,
    solve_settings: crate::pipeline::record::SolveSettings,
    solved: solve::Calibrations,
}

/// Stage 4 and 5: point pairs, Horn at every cut-off, each frame's BRE.
fn calibrate(
    manifest: &Manifest,
    name: &str,
    frames: &mut [crate::pipeline::record::FrameRecord],
    targets: Targets<'_>,
    log: &mut dyn FnMut(&str),
) -> Result<Calibrated, RunError> {
    let spacing = manifest.bscan_spacing_mm_per_px;
    let min_frames = manifest.thresholds.min_frames;
    let pairing = PairingInputs {
        dataset: name,
        spacing_mm_per_px: spacing,
        initial_marker_T_image: manifest.initial_marker_T_image,
        min_frames,
        fit_pixel_size: manifest.sphere_fit.fit_pixel_size,
    };
    let (correspondences, start_guess) = solve::point_pairs(frames, targets, &pairing, log)?;
    solve::enough_frames(frames, &correspondences, min_frames, name)?;
    let solve_settings = settings::solve(manifest);
    let solved = solve::calibrate(&correspondences, &solve_settings, name)?;
    solve::record_bre(frames, &correspondences, &solved.all_frames_fit, spacing);
    Ok(Calibrated {
        correspondences,
        start_guess,
        solve_settings,
        solved,
    })
}

/// The other estimators and the resampling metrics, after the reported calibration.
struct Estimators<'a> {
    manifest: &'a Manifest,
    camera: &'a crate::pipeline::record::CameraStage,
    rig: &'a RigBoards,
    targets: Targets<'a>,
    /// The feature and radius are filled per phantom.
    inputs: MethodInputs<'a>,
}

impl Estimators<'_> {
    fn run(
        &self,
        log: &mut dyn FnMut(&str),
    ) -> (
        Option<crate::pipeline::record::ResamplingSummary>,
        Vec<crate::pipeline::record::MethodResult>,
    ) {
        let manifest = self.manifest;
        let reported = self.inputs.reported;
        let primary_frames: Vec<Correspondence> = self
            .inputs
            .frames
            .iter()
            .filter(|c| reported.frames.contains(&c.frame))
            .cloned()
            .collect();
        let validation = match methods::resampling_stage(manifest, &primary_frames, reported, self.inputs.fit) {
            Ok(v) => Some(v),
            Err(e) => {
                log(&format!("validation metrics skipped: {e}"));
                None
            }
        };
        let camera = self.camera;
        let pose_inputs = match (&manifest.sphere_fit.pose_prior, &camera.intrinsics) {
            (Some(prior), Some(intrinsics)) => Some(crate::pipeline::run::sphere_pose::PoseInputs {
                camera: intrinsics,
                calibration: camera.calibration.as_ref(),
                probe_board: &self.rig.probe,
                phantom_board: &self.rig.phantom,
                prior,
            }),
            (Some(_), None) => {
                log("sphere fit with pose priors skipped: the poses come from a tracker, not the boards");
                None
            }
            (None, _) => None,
        };
        let methods = match self.targets {
            Targets::Point(feature) => methods::methods_stage(
                manifest,
                &MethodInputs {
                    feature_in_phantom_mm: feature,
                    sphere_radius_mm: settings::sphere_radius_mm(manifest),
                    ..self.inputs
                },
                log,
            ),
            Targets::Spheres(spheres) => methods::spheres_methods(
                &MethodInputs {
                    feature_in_phantom_mm: crate::spec::phantom::spheres_centre(spheres),
                    sphere_radius_mm: None,
                    ..self.inputs
                },
                spheres,
                manifest.sphere_fit.fit_pixel_size,
                pose_inputs.as_ref(),
                log,
            ),
            Targets::Wires(_) => Vec::new(),
        };
        (validation, methods)
    }
}

/// Every file the run read, for provenance.
fn input_files(
    manifest: &Manifest,
    folder: &Path,
    files: &[dataset::FrameFiles],
    camera: &crate::pipeline::record::CameraStage,
) -> Vec<PathBuf> {
    let mut input_files = vec![manifest.path.clone(), folder.join(dataset::FRAME_LIST)];
    for f in files {
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
    input_files
}

fn evaluate_gates(
    manifest: &Manifest,
    primary: &ThresholdRow,
    truth: Option<&TruthSummary>,
    methods: &[crate::pipeline::record::MethodResult],
) -> Vec<GateResult> {
    let g = &manifest.thresholds.gates;
    // The truth gates check the named estimator, or the reported calibration.
    let (checked, suffix) = match &g.method {
        Some(name) => (
            methods.iter().find(|m| m.method.name() == name).and_then(|m| m.truth),
            format!(" ({name})"),
        ),
        None => (truth.map(|t| t.calibration), String::new()),
    };
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
        &format!("truth_corner_error_mm{suffix}"),
        g.truth_corner_error_mm,
        checked.as_ref().map(|t| t.corner_error_mean_mm),
    );
    gate(
        &format!("truth_rotation_error_deg{suffix}"),
        g.truth_rotation_error_deg,
        checked.as_ref().map(|t| t.rotation_error_deg),
    );
    gate("bre_mean_mm", g.bre_mean_mm, primary.stats.map(|s| s.max_mean()));
    out
}

/// What a render did, in words.
fn outcome_words(outcome: &synth::RenderOutcome) -> String {
    match outcome {
        synth::RenderOutcome::Rendered => "rendered".into(),
        synth::RenderOutcome::UpToDate => "up to date".into(),
        synth::RenderOutcome::Repaired(reason) => format!("rendered again: {reason}"),
    }
}

/// Renders the datasets of a manifest without running the pipeline.
pub fn synth_only(manifest: &Manifest, datasets_root: &Path, log: &mut dyn FnMut(&str)) -> Result<(), RunError> {
    for d in &manifest.datasets {
        if let DatasetSource::Render(spec) = &d.source {
            let folder = synth::dataset_folder(datasets_root, &manifest.experiment, &d.name);
            let _claim = claim_rendered(&folder, &d.name, log)?;
            let clock = Instant::now();
            let outcome =
                synth::ensure_rendered(&settings::lab(manifest), spec, &folder).map_err(|source| RunError::Synth {
                    dataset: d.name.clone(),
                    source,
                })?;
            log(&format!(
                "dataset `{}`: {} ({}, {:.1} s)",
                d.name,
                folder.display(),
                outcome_words(&outcome),
                clock.elapsed().as_secs_f64()
            ));
        } else {
            log(&format!("dataset `{}`: recorded folder, nothing to render", d.name));
        }
    }
    Ok(())
}
