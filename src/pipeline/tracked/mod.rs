//! The pipeline without a camera: poses from a tracker's sequence file, an N-wire
//! phantom, and the pixel size estimated with the calibration.
//!
//! Stages: read the sequences ([`crate::io::plus::sequence`]) and the phantom
//! definition ([`crate::io::plus::config`]); segment each B-scan's wire dots
//! ([`crate::detect::nwire`]); build constraints in the probe frame; fit `Calibration`
//! ([`crate::estimate::image_to_probe`]); evaluate PRE3D on the validation frames.

pub mod inputs;
pub mod resolution;
pub mod segment;
pub mod time;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix4, Point3};

use crate::core::geometry::Calibration;
use crate::core::stats::best_95;
use crate::detect::overlay::Overlay;
use crate::estimate::image_to_probe::{self, FitError};
use crate::estimate::model_selection::{self, Candidate, Selection};
use crate::io::plus::config::ConfigError;
use crate::io::plus::sequence::{Sequence, SequenceError};
use crate::manifest::tracked::{TimeOffset, TrackedManifest};
use crate::pipeline::record::GateResult;
pub use crate::pipeline::sequence_frames::{
    clip_or_overlay, constraints, segment_frames, timestamp_s, PoseFault, Role, SegmentationInputs, TrackedFrame,
    TrackedRejection,
};
pub use crate::pipeline::tracked::inputs::{
    attach_poses, attach_poses_along, fit_settings, usable_constraints, TrackedInputs, TrackerPaths,
};
use crate::pipeline::tracked::time::lag_joint::{self, LagEstimate};
use crate::pipeline::tracked::time::lag_span;
use crate::pipeline::tracked::time::sweep_lag::SweepLag;
use crate::spec::nwire::NWire;

#[derive(Debug, thiserror::Error)]
pub enum TrackedError {
    #[error("{0}")]
    Sequence(#[from] SequenceError),
    #[error("{0}")]
    Config(#[from] ConfigError),
    #[error("calibration: {0}")]
    Fit(#[from] FitError),
    #[error("temporal calibration: {0}")]
    Temporal(#[from] crate::pipeline::tracked::time::temporal::TemporalError),
    #[error("{sequence}: only {usable} frames could be segmented, at least {needed} are needed")]
    TooFewFrames {
        sequence: PathBuf,
        usable: usize,
        needed: usize,
    },
    #[error(
        "{sequence}: the B-scans are {width}x{height} px, the calibration sequence's are {want_width}x{want_height}"
    )]
    SizeMismatch {
        sequence: PathBuf,
        width: usize,
        height: usize,
        want_width: usize,
        want_height: usize,
    },
    #[error("{sequence}: {fault}; the tracker's lag cannot be applied on this clock")]
    Clock { sequence: PathBuf, fault: String },
    #[error(
        "{validation} is the same recording as the calibration sequence {calibration}: its PRE3D would score the calibration on its own frames; give a held-out recording, or none"
    )]
    SameRecording { calibration: PathBuf, validation: PathBuf },
    #[error("{0}")]
    ClipOutside(#[from] crate::pipeline::sequence_frames::ClipOutside),
    #[error("{sequence}: its {frames} frames hold no image (0x0 px: a tracker-only recording?); calibration needs the B-scans")]
    NoImages { sequence: PathBuf, frames: usize },
    #[error("{sequence}: {reason}")]
    NoPoses { sequence: PathBuf, reason: String },
}

/// What a run refuses of a recording before any frame is used: no images, a
/// size unlike the calibration sequence's (`calibration_px`), a clip rectangle
/// beyond the images, no frame with both poses, a clock a fixed lag cannot be
/// applied on. `run` calls it on each sequence it reads; `validate` and `init`
/// through [`preflight`].
pub fn check_recording(
    sequence: &Sequence,
    inputs: &TrackedInputs,
    calibration_px: Option<[usize; 2]>,
) -> Result<(), TrackedError> {
    if sequence.width == 0 || sequence.height == 0 {
        return Err(TrackedError::NoImages {
            sequence: sequence.path.clone(),
            frames: sequence.frames.len(),
        });
    }
    if let Some([want_width, want_height]) = calibration_px.filter(|&c| c != [sequence.width, sequence.height]) {
        return Err(TrackedError::SizeMismatch {
            sequence: sequence.path.clone(),
            width: sequence.width,
            height: sequence.height,
            want_width,
            want_height,
        });
    }
    if let Some(clip) = inputs.clip_rectangle_px {
        crate::pipeline::sequence_frames::clip_inside(sequence, clip)?;
    }
    let names = [inputs.probe_transform.as_str(), inputs.reference_transform.as_str()];
    let posed = |i: usize| names.iter().try_for_each(|n| sequence.transform(i, n).map(|_| ()));
    if let Some(Err(fault)) = (0..sequence.frames.len())
        .map(posed)
        .find(Result::is_ok)
        .or_else(|| (!sequence.frames.is_empty()).then(|| posed(0)))
    {
        return Err(TrackedError::NoPoses {
            sequence: sequence.path.clone(),
            reason: format!(
                "no frame has both `{}` and `{}` ({fault}); the transforms the frames hold: {}",
                names[0],
                names[1],
                sequence.transform_names().join(", ")
            ),
        });
    }
    if let TimeOffset::Fixed(s) = inputs.time_offset {
        refuse_clock(sequence, s)?;
    }
    Ok(())
}

/// Every check a run makes of its recordings before it uses a frame, without
/// running it: what `validate` and `init` refuse is what `run` would.
pub fn preflight(inputs: &TrackedInputs) -> Result<(), TrackedError> {
    let calibration = Sequence::read(&inputs.calibration_sequence)?;
    check_recording(&calibration, inputs, None)?;
    let size = [calibration.width, calibration.height];
    drop(calibration);
    if let Some(path) = &inputs.validation_sequence {
        refuse_same_recording(&inputs.calibration_sequence, path)?;
        check_recording(&Sequence::read(path)?, inputs, Some(size))?;
    }
    Ok(())
}

/// The tracked run's accuracy gates.
pub fn gates(run: &TrackedRun, manifest: &TrackedManifest) -> Vec<GateResult> {
    let mut out = Vec::new();
    if let Some(limit) = manifest.gates.pre3d_mm {
        let value = best_95(&run.pre3d(Role::Validation)).map(|s| s.mean);
        out.push(GateResult {
            name: "validation PRE3D (mean of best 95 %, mm)".into(),
            value,
            limit,
            passed: value.is_some_and(|v| v <= limit),
        });
    }
    out
}

#[derive(Debug, Clone)]
pub struct TrackedRun {
    pub frames: Vec<TrackedFrame>,
    pub fit: image_to_probe::Fit,
    pub closed_form: Calibration,
    pub constraints: usize,
    pub image_size_px: [usize; 2],
    /// The tracker lag used, s.
    pub time_offset_s: f64,
    /// When estimated: the spatio-temporal estimate, with the motion estimate.
    pub lag_estimate: Option<LagEstimate>,
    /// The model family's cross-validation on the calibration frames.
    pub selection: Selection,
    /// Pixels of the calibration sequence's screen overlay left out, when no
    /// clip rectangle was given.
    pub overlay_px: Option<usize>,
    /// The chosen model fitted with no lag, when a lag is applied.
    pub no_lag_fit: Option<image_to_probe::Fit>,
    /// When an estimated lag is applied: the chosen model refitted at lags
    /// across the lag's 90 % interval, with every frame's poses there.
    pub lag_span: Vec<lag_span::SpanPoint>,
}

impl TrackedRun {
    pub fn pre3d(&self, role: Role) -> Vec<f64> {
        self.frames
            .iter()
            .filter(|f| f.role == role && f.rejected.is_none())
            .flat_map(|f| f.pre3d_mm.iter().copied())
            .collect()
    }

    pub fn segmented(&self, role: Role) -> (usize, usize) {
        let of_role = self.frames.iter().filter(|f| f.role == role);
        let total = of_role.clone().count();
        (of_role.filter(|f| f.rejected.is_none()).count(), total)
    }
}

/// PRE3D of each pattern's middle dot in one frame, mm: the middle dot's pixel
/// mapped into the probe frame by `image_to_probe` against its position from the
/// phantom geometry (registration corrected by `phantom_correction`).
pub fn pre3d(
    frame: &TrackedFrame,
    nwires: &[NWire],
    image_to_probe: impl Fn([f64; 2]) -> Point3<f64>,
    phantom_correction: &crate::core::geometry::Rigid,
) -> Vec<f64> {
    let Some(marker_T_phantom) = frame.marker_T_phantom else {
        return Vec::new();
    };
    let marker_T_phantom = marker_T_phantom * phantom_correction.to_homogeneous();
    frame
        .dots_px
        .iter()
        .zip(nwires)
        .map(|(dots, nwire)| {
            let expected: Point3<f64> = marker_T_phantom.transform_point(&nwire.middle_in_phantom_mm(dots));
            (image_to_probe(dots[1]) - expected).norm()
        })
        .collect()
}

pub fn segmentation_inputs<'a>(
    inputs: &'a TrackedInputs,
    clip: [usize; 4],
    overlay: Option<&'a Overlay>,
) -> SegmentationInputs<'a> {
    SegmentationInputs {
        nwires: &inputs.nwires,
        spacing_guess_mm_per_px: inputs.spacing_guess_mm_per_px,
        segmentation: &inputs.segmentation,
        clip,
        overlay,
    }
}

/// Each frame of `sequence` segmented, inside the clip rectangle or with the
/// sequence's own overlay left out; the overlay's pixel count.
fn segment_sequence(
    sequence: &Sequence,
    role: Role,
    inputs: &TrackedInputs,
) -> Result<(Vec<TrackedFrame>, Option<usize>), TrackedError> {
    let (clip, overlay) = clip_or_overlay(
        sequence,
        inputs.clip_rectangle_px,
        &inputs.segmentation,
        inputs.spacing_guess_mm_per_px,
    )?;
    let frames = segment_frames(sequence, role, &segmentation_inputs(inputs, clip, overlay.as_ref()));
    Ok((frames, overlay.map(|o| o.pixels())))
}

/// The tracker's lag from the calibration sweep's own motion (the second,
/// independent estimate): poses with no lag map the wires into the images
/// through a calibration of the family's first constraints and its most
/// flexible pixel model; the lag is when the two motions line up.
fn lag_from_sweep(paths: &TrackerPaths, frames: &mut [TrackedFrame], inputs: &TrackedInputs) -> SweepLag {
    let family = Candidate::family(inputs.model, inputs.pixel_model);
    let candidate = Candidate {
        pixel_model: family[family.len() - 1].pixel_model,
        ..family[0]
    };
    attach_poses_along(paths, frames, inputs, 0.0);
    let usable = usable_constraints(frames, &inputs.nwires, Role::Calibration);
    match model_selection::fit(usable.iter(), candidate, fit_settings(inputs)) {
        Ok(trained) => crate::pipeline::tracked::time::sweep_lag::estimate(frames, &inputs.nwires, &trained.fit),
        Err(e) => SweepLag {
            unresolved: Some(format!("no calibration to map the poses with: {e}")),
            ..Default::default()
        },
    }
}

/// A lag is applied by interpolating between frames by their timestamps: a
/// clock that stands still or runs backwards would interpolate the wrong way.
fn refuse_clock(sequence: &Sequence, time_offset_s: f64) -> Result<(), TrackedError> {
    if time_offset_s == 0.0 {
        return Ok(());
    }
    match crate::pipeline::sequence_frames::clock_fault(sequence) {
        None => Ok(()),
        Some(fault) => Err(TrackedError::Clock {
            sequence: sequence.path.clone(),
            fault,
        }),
    }
}

/// A validation sequence that is the calibration sequence (the same file, or
/// the same bytes) would score the calibration on its own frames.
fn refuse_same_recording(calibration: &Path, validation: &Path) -> Result<(), TrackedError> {
    if crate::io::fs::same_recording(calibration, validation) {
        return Err(TrackedError::SameRecording {
            calibration: calibration.to_path_buf(),
            validation: validation.to_path_buf(),
        });
    }
    Ok(())
}

/// The model chosen by cross-validation on `frames`' calibration frames (at the
/// poses they carry), and its selection.
fn choose_model(frames: &[TrackedFrame], inputs: &TrackedInputs) -> Result<Selection, TrackedError> {
    let usable = usable_constraints(frames, &inputs.nwires, Role::Calibration);
    let family = Candidate::family(inputs.model, inputs.pixel_model);
    let (scored, chosen) = model_selection::select(&usable, &family, inputs.folds, fit_settings(inputs));
    let chosen = match chosen {
        Some(k) => k,
        // Nothing could be cross-validated: the fit on every frame says why.
        None => {
            model_selection::fit(usable.iter(), family[0], fit_settings(inputs))?;
            0
        }
    };
    Ok(Selection {
        folds: inputs.folds,
        frames: usable.len(),
        scored,
        chosen,
    })
}

/// The tracker's lag estimated with the calibration from the calibration
/// frames alone ([`crate::pipeline::tracked::time::lag`], then
/// [`crate::pipeline::tracked::time::lag_joint`]), beside the sweep's motion estimate.
fn estimate_lag(
    calibration: &Sequence,
    paths: &TrackerPaths,
    frames: &mut [TrackedFrame],
    inputs: &TrackedInputs,
) -> Result<LagEstimate, TrackedError> {
    if let Some(fault) = crate::pipeline::sequence_frames::clock_fault(calibration) {
        let why = format!("{}: {fault}", inputs.calibration_sequence.display());
        let motion = crate::pipeline::tracked::time::sweep_lag::SweepLag {
            unresolved: Some(why.clone()),
            ..Default::default()
        };
        return Ok(LagEstimate::refused(why, Some(motion)));
    }
    let motion = lag_from_sweep(paths, frames, inputs);
    // Every lag scored with poses of the same noise: the trajectory read by a
    // local quadratic fit under a kernel of one frame period.
    let sigma_s = SMOOTHING_PERIODS * median_period_s(frames).unwrap_or(0.0).max(1e-3);
    let paths = &paths.smoothed(sigma_s);
    let coarse = crate::pipeline::tracked::time::lag::search(paths, frames, inputs);
    let Some(coarse_lag) = coarse.lag_s else {
        return Ok(lag_joint::assemble(coarse, None, None, Some(motion)));
    };
    attach_poses_along(paths, frames, inputs, coarse_lag);
    let candidate = choose_model(frames, inputs)?.chosen();
    let joint = lag_joint::refine(paths, frames, inputs, &coarse, candidate);
    let cv = lag_joint::cross_validate(paths, frames, inputs, &coarse, candidate);
    Ok(lag_joint::assemble(coarse, joint, cv, Some(motion)))
}

/// The SD of the kernel the lag is estimated with, in frame periods: the
/// local quadratic fit's noise variance (the sum of its squared weights) varies
/// between samples by about 1 % of itself at k = 1 (13 % at 3/4, 42 % at 1/2;
/// an interpolated pose's falls by half from a sample to halfway). One frame
/// period makes every lag's poses nearly equally noisy.
pub const SMOOTHING_PERIODS: f64 = 1.0;

/// The median time between consecutive calibration frames, s.
fn median_period_s(frames: &[TrackedFrame]) -> Option<f64> {
    let mut times: Vec<f64> = frames
        .iter()
        .filter(|f| f.role == Role::Calibration)
        .filter_map(|f| f.timestamp_s)
        .collect();
    times.sort_by(f64::total_cmp);
    let mut gaps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).filter(|g| *g > 0.0).collect();
    gaps.sort_by(f64::total_cmp);
    gaps.get(gaps.len() / 2).copied()
}

/// Runs the tracked pipeline.
pub fn run(inputs: &TrackedInputs, min_frames: usize) -> Result<TrackedRun, TrackedError> {
    let calibration = Sequence::read(&inputs.calibration_sequence)?;
    check_recording(&calibration, inputs, None)?;
    let image_size_px = [calibration.width, calibration.height];
    let (mut frames, overlay_px) = segment_sequence(&calibration, Role::Calibration, inputs)?;
    let paths = TrackerPaths::of(&calibration, inputs);
    // The tracker's lag, from the calibration frames alone.
    let mut lag_estimate = None;
    let time_offset_s = match &inputs.time_offset {
        TimeOffset::Fixed(s) => *s,
        TimeOffset::Temporal { tracker, video } => {
            crate::pipeline::tracked::time::temporal::run(
                video,
                tracker,
                &inputs.probe_transform,
                &inputs.reference_transform,
            )?
            .tracker_lag_s
        }
        TimeOffset::Estimate => {
            let found = estimate_lag(&calibration, &paths, &mut frames, inputs)?;
            let lag = found.applied_s();
            lag_estimate = Some(found);
            lag
        }
    };
    refuse_clock(&calibration, time_offset_s)?;
    attach_poses_and_no_lag(&paths, &mut frames, inputs, time_offset_s);
    drop(calibration);
    let mut validation_paths = None;
    if let Some(path) = &inputs.validation_sequence {
        refuse_same_recording(&inputs.calibration_sequence, path)?;
        let validation = Sequence::read(path)?;
        check_recording(&validation, inputs, Some(image_size_px))?;
        refuse_clock(&validation, time_offset_s)?;
        let (mut more, _) = segment_sequence(&validation, Role::Validation, inputs)?;
        let paths = TrackerPaths::of(&validation, inputs);
        attach_poses_and_no_lag(&paths, &mut more, inputs, time_offset_s);
        frames.extend(more);
        validation_paths = Some(paths);
    }
    let usable = frames
        .iter()
        .filter(|f| f.role == Role::Calibration && f.rejected.is_none())
        .count();
    if usable < min_frames {
        return Err(TrackedError::TooFewFrames {
            sequence: inputs.calibration_sequence.clone(),
            usable,
            needed: min_frames,
        });
    }
    // The model, chosen on the calibration frames alone, at the lag applied.
    let selection = choose_model(&frames, inputs)?;
    let usable = usable_constraints(&frames, &inputs.nwires, Role::Calibration);
    let trained = model_selection::fit(usable.iter(), selection.chosen(), fit_settings(inputs))?;
    let (closed_form, fit, constraints) = (trained.closed_form, trained.fit, trained.constraints);
    for f in frames.iter_mut().filter(|f| f.rejected.is_none()) {
        f.pre3d_mm = pre3d(
            f,
            &inputs.nwires,
            |pixel| fit.image_to_probe.apply(pixel),
            &fit.phantom_correction,
        );
    }
    let no_lag_fit = (time_offset_s != 0.0)
        .then(|| no_lag_fit(&frames, inputs, selection.chosen()))
        .flatten();
    let lag_span = match lag_estimate
        .as_ref()
        .filter(|e| e.applied)
        .and_then(LagEstimate::interval_s)
    {
        Some(interval_s) => lag_span::refit(
            &frames,
            &paths,
            validation_paths.as_ref(),
            inputs,
            selection.chosen(),
            &lag_span::lags(interval_s, time_offset_s),
        ),
        None => Vec::new(),
    };
    Ok(TrackedRun {
        frames,
        fit,
        closed_form,
        constraints,
        image_size_px,
        time_offset_s,
        lag_estimate,
        selection,
        overlay_px,
        no_lag_fit,
        lag_span,
    })
}

/// Each frame's pose at `time_offset_s`, and with no lag too, for the
/// comparisons without it.
fn attach_poses_and_no_lag(
    paths: &TrackerPaths,
    frames: &mut [TrackedFrame],
    inputs: &TrackedInputs,
    time_offset_s: f64,
) {
    attach_poses_along(paths, frames, inputs, 0.0);
    let at_zero: Vec<Option<Matrix4<f64>>> = frames.iter().map(|f| f.marker_T_phantom).collect();
    attach_poses_along(paths, frames, inputs, time_offset_s);
    for (f, zero) in frames.iter_mut().zip(at_zero) {
        f.marker_T_phantom_no_lag = zero;
    }
}

/// The chosen model fitted to the calibration frames with no lag (each frame's
/// own poses), to score what the lag buys.
fn no_lag_fit(frames: &[TrackedFrame], inputs: &TrackedInputs, candidate: Candidate) -> Option<image_to_probe::Fit> {
    let at_zero: Vec<TrackedFrame> = frames
        .iter()
        .filter(|f| f.role == Role::Calibration && f.rejected.is_none())
        .map(|f| TrackedFrame {
            marker_T_phantom: f.marker_T_phantom_no_lag,
            ..f.clone()
        })
        .collect();
    let usable = usable_constraints(&at_zero, &inputs.nwires, Role::Calibration);
    model_selection::fit(usable.iter(), candidate, fit_settings(inputs))
        .ok()
        .map(|t| t.fit)
}
