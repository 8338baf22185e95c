//! What the tracked pipeline and its lag stages share: the resolved inputs, the
//! tracker's trajectories of a sequence ([`crate::core::trajectory`]: every path
//! that pairs a pose with an image reads it at the image's time plus the lag),
//! and each frame's pose and constraints at a lag.

use std::path::PathBuf;

use nalgebra::Matrix4;

use crate::core::geometry::Rigid;
use crate::core::trajectory::{self, Miss};
use crate::detect::nwire::Segmentation;
use crate::estimate::image_to_probe::{ConstraintModel, PixelModel};
use crate::estimate::model_selection::{FitSettings, FrameConstraints};
use crate::io::plus::sequence::Sequence;
use crate::manifest::tracked::{TimeOffset, TrackedManifest};
use crate::pipeline::sequence_frames::{constraints, timestamp_s, PoseFault, Role, TrackedFrame, TrackedRejection};
use crate::spec::nwire::NWire;

/// Everything the tracked pipeline needs, resolved.
#[derive(Debug, Clone)]
pub struct TrackedInputs {
    pub calibration_sequence: PathBuf,
    pub validation_sequence: Option<PathBuf>,
    /// `ProbeToTracker`-style names (without the `Transform` suffix).
    pub probe_transform: String,
    pub reference_transform: String,
    /// `reference_T_phantom` (PLUS `PhantomToReference`).
    pub reference_T_phantom: Matrix4<f64>,
    pub nwires: Vec<NWire>,
    pub spacing_guess_mm_per_px: f64,
    pub clip_rectangle_px: Option<[usize; 4]>,
    pub segmentation: Segmentation,
    /// Fixed, or `None`: chosen by cross-validation on the calibration frames.
    pub model: Option<ConstraintModel>,
    pub pixel_model: Option<PixelModel>,
    pub folds: usize,
    /// Drop constraints above mean + k SD and refit (PLUS: 3).
    pub reject_sd: Option<f64>,
    /// The tracker's lag behind the images: a frame's pose is interpolated at its
    /// timestamp plus this offset.
    pub time_offset: TimeOffset,
    /// Also correct the phantom's registration (`PhantomToReference`) from the
    /// calibration frames.
    pub refine_phantom: bool,
}

impl TrackedInputs {
    /// The tracked pipeline's inputs from a manifest.
    pub fn from_manifest(m: &TrackedManifest) -> TrackedInputs {
        TrackedInputs {
            calibration_sequence: m.calibration_sequence.clone(),
            validation_sequence: m.validation_sequence.clone(),
            probe_transform: m.probe_transform.clone(),
            reference_transform: m.reference_transform.clone(),
            reference_T_phantom: m.reference_T_phantom,
            nwires: m.nwires.clone(),
            spacing_guess_mm_per_px: m.spacing_guess_mm_per_px,
            clip_rectangle_px: m.clip_rectangle_px,
            segmentation: m.segmentation.clone(),
            model: m.model,
            pixel_model: m.pixel_model,
            folds: m.folds,
            reject_sd: m.reject_sd,
            time_offset: m.time_offset.clone(),
            refine_phantom: m.refine_phantom,
        }
    }
}

/// The probe's and the reference's recorded trajectories of one sequence.
#[derive(Debug, Clone)]
pub struct TrackerPaths {
    pub probe: Trajectory,
    pub reference: Trajectory,
    /// Poses by local quadratic regression with a Gaussian kernel of this SD (s) instead of
    /// interpolation: the lag's estimate scores every lag with poses of the same
    /// noise ([`crate::core::trajectory::Trajectory::smoothed_at`]).
    pub smoothing_s: Option<f64>,
}

impl TrackerPaths {
    pub fn of(sequence: &Sequence, inputs: &TrackedInputs) -> TrackerPaths {
        TrackerPaths {
            probe: Trajectory::of(sequence, &inputs.probe_transform),
            reference: Trajectory::of(sequence, &inputs.reference_transform),
            smoothing_s: None,
        }
    }

    /// The same trajectories read by local quadratic regression, kernel SD `sigma_s`.
    pub fn smoothed(&self, sigma_s: f64) -> TrackerPaths {
        TrackerPaths {
            smoothing_s: Some(sigma_s),
            ..self.clone()
        }
    }

    /// `marker_T_phantom` of `frame` (taken at `time_s`, `None`: no timestamp)
    /// for a tracker lag of `offset_s`: both transforms read along their
    /// trajectories at the image's time plus the lag, checked plausible.
    pub fn marker_T_phantom(
        &self,
        frame: usize,
        time_s: Option<f64>,
        offset_s: f64,
        reference_T_phantom: &Matrix4<f64>,
    ) -> Result<Matrix4<f64>, PoseFault> {
        // With no lag a frame's own sample is its pose, with or without a
        // timestamp; smoothed trajectories are read alike at every lag.
        let at = |path: &Trajectory| match (time_s, self.smoothing_s) {
            (Some(t), Some(sigma)) => path.smoothed_at(t + offset_s, sigma, frame),
            (Some(t), None) if offset_s != 0.0 => path.at(t + offset_s, frame),
            (_, _) if offset_s == 0.0 => path.own(frame).unwrap_or(Err(PoseFault::NoTimestamp {
                frame,
                transform: path.name().to_string(),
            })),
            (_, _) => Err(PoseFault::NoTimestamp {
                frame,
                transform: path.name().to_string(),
            }),
        };
        let (probe, reference) = (at(&self.probe)?, at(&self.reference)?);
        // The same plausibility check as the camera pipeline's, at this stage boundary.
        if let Some(fault) = crate::pipeline::record::Implausible::of(
            Some((probe, reference)),
            ["tracker_T_probe", "tracker_T_reference"],
            &[],
        ) {
            return Err(PoseFault::Implausible(fault));
        }
        Ok(probe.inverse().to_homogeneous() * reference.to_homogeneous() * reference_T_phantom)
    }
}

/// Sets each frame's `marker_T_phantom` for a tracker lag of `offset_s` (frames whose
/// transforms are unusable are rejected with the reason; earlier pose rejections
/// are re-evaluated).
pub fn attach_poses(sequence: &Sequence, frames: &mut [TrackedFrame], inputs: &TrackedInputs, offset_s: f64) {
    attach_poses_along(&TrackerPaths::of(sequence, inputs), frames, inputs, offset_s);
}

/// [`attach_poses`] with the trajectories already read.
pub fn attach_poses_along(paths: &TrackerPaths, frames: &mut [TrackedFrame], inputs: &TrackedInputs, offset_s: f64) {
    for frame in frames.iter_mut() {
        if matches!(frame.rejected, Some(TrackedRejection::Pose(_))) {
            frame.rejected = None;
        }
        frame.marker_T_phantom = None;
        if frame.rejected.is_some() {
            continue;
        }
        match paths.marker_T_phantom(frame.index, frame.timestamp_s, offset_s, &inputs.reference_T_phantom) {
            Ok(m) => frame.marker_T_phantom = Some(m),
            Err(e) => frame.rejected = Some(TrackedRejection::Pose(e)),
        }
    }
}

/// The usable frames' constraints of one sequence, in frame order.
pub fn usable_constraints(frames: &[TrackedFrame], nwires: &[NWire], role: Role) -> Vec<FrameConstraints> {
    frames
        .iter()
        .filter(|f| f.role == role && f.rejected.is_none())
        .map(|f| constraints(f, nwires))
        .collect()
}

pub fn fit_settings(inputs: &TrackedInputs) -> FitSettings {
    FitSettings {
        reject_sd: inputs.reject_sd,
        refine_phantom: inputs.refine_phantom,
    }
}

/// One named transform of a sequence, in time.
#[derive(Debug, Clone)]
pub struct Trajectory {
    name: String,
    path: trajectory::Trajectory<PoseFault>,
}

impl Trajectory {
    /// `name`'s samples in `sequence` (every frame; those with a timestamp in time).
    pub fn of(sequence: &Sequence, name: &str) -> Trajectory {
        Trajectory {
            name: name.to_string(),
            path: trajectory::Trajectory::from_samples((0..sequence.frames.len()).map(|frame| {
                (
                    frame,
                    timestamp_s(sequence, frame),
                    sequence.transform(frame, name).map_err(PoseFault::from),
                )
            })),
        }
    }

    /// The transform's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Frame `frame`'s own sample, whatever its time.
    pub fn own(&self, frame: usize) -> Option<Result<Rigid, PoseFault>> {
        self.path.own(frame)
    }

    /// The pose at `time_s`, for the image of frame `frame` (in the reasons).
    pub fn at(&self, time_s: f64, frame: usize) -> Result<Rigid, PoseFault> {
        self.path.at(time_s).map_err(|miss| self.fault(miss, time_s, frame))
    }

    /// The pose at `time_s` by local quadratic regression, kernel SD `sigma_s`.
    pub fn smoothed_at(&self, time_s: f64, sigma_s: f64, frame: usize) -> Result<Rigid, PoseFault> {
        self.path
            .smoothed_at(time_s, sigma_s)
            .map_err(|miss| self.fault(miss, time_s, frame))
    }

    fn fault(&self, miss: Miss<PoseFault>, time_s: f64, frame: usize) -> PoseFault {
        match miss {
            Miss::Outside(side) => PoseFault::OutsideTrajectory {
                frame,
                transform: self.name.clone(),
                time_s,
                side,
            },
            Miss::Gap { gap_s, limit_s } => PoseFault::Gap {
                frame,
                transform: self.name.clone(),
                time_s,
                gap_s,
                limit_s,
            },
            Miss::Sample(fault) => fault,
        }
    }
}
