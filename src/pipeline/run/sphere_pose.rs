//! The multi-sphere fit with each frame's pose uncertain
//! ([`crate::estimate::sphere_bundle`]): the priors it needs, from the run's
//! own data and the manifest's stated hand motion.
//!
//! - Each frame's `phantom_T_marker` covariance: its two boards' poses from their
//!   corners, with the corner noise this run's boards show (the median
//!   reprojection RMS of each board over the frames, scaled for the pose's six
//!   unknowns), and the hand's motion between photo and B-scan
//!   (`solve.sphere_fit.pose_prior`), first order ([`crate::evaluate::pose_noise`]).
//! - The edge points' noise: the median RMS of the arcs about their own circles,
//!   grown for arcs cut off their domes' centres by the scanner's pulse and
//!   slice when the manifest states them (`solve.sphere_fit.pose_prior.slice_blur`).
//! - The camera's intrinsics, one error every frame's pose shares: each frame's
//!   pose shift per unit intrinsic error ([`crate::evaluate::pose_noise`]), and
//!   what the camera calibration's views (the frames' boards too, when they
//!   refined it) know of the intrinsics, with the noise their residuals show
//!   ([`crate::detect::camera_refinement::calibration_information`]). A camera
//!   read from a file brings no views: its intrinsics are then taken as exact.
//! - The echo edge's offset from its sphere: the terms the manifest names
//!   (`solve.sphere_fit.pose_prior.edge_offset`), solved without a prior
//!   ([`crate::estimate::edge_offset`]).

use crate::core::geometry::Rigid;
use crate::core::stats::median;
use crate::detect::board::PrintedBoard;
use crate::detect::camera_calibration::CameraCalibration;
use crate::detect::camera_refinement::{calibration_information, intrinsics_sd};
use crate::estimate::sphere_bundle::{self, PosePriors, SharedError};
use crate::estimate::sphere_fit::{ArcFrame, SphereFit, SphereFitError, SphereSettings};
use crate::evaluate::pose_noise::{frame_pose_noise, PhotoNoise, SweepPhoto};
use crate::io::camera_model::CameraIntrinsics;
use crate::manifest::raw::PosePrior;
use crate::pipeline::record::FrameRecord;
pub use crate::pipeline::record::PoseFitNoise;

/// What the pose-prior fit needs from the run.
pub struct PoseInputs<'a> {
    pub camera: &'a CameraIntrinsics,
    /// The calibration the intrinsics come from, if the run calibrated the camera.
    pub calibration: Option<&'a CameraCalibration>,
    pub probe_board: &'a PrintedBoard,
    pub phantom_board: &'a PrintedBoard,
    pub prior: &'a PosePrior,
}

/// A board's corner SD from its reprojection RMS (the pose's 6 unknowns taken out).
fn corner_sd(rms_px: &mut [f64], corners: usize) -> Option<f64> {
    if rms_px.is_empty() || corners <= 3 {
        return None;
    }
    let scale = (2.0 * corners as f64 / (2.0 * corners as f64 - 6.0)).sqrt();
    Some(median(rms_px) * scale)
}

/// Why the pose-prior sphere fit could not run.
#[derive(Debug, thiserror::Error)]
pub enum PoseFitError {
    #[error("no {0}-board poses")]
    NoPoses(&'static str),
    #[error("no arcs")]
    NoArcs,
    #[error("the arcs' edge noise {0} mm is not positive")]
    EdgeNoise(f64),
    #[error("frame {0}: a board's pose is not determined by its corners")]
    Undetermined(usize),
    #[error("{0}")]
    Fit(SphereFitError),
}

/// The pose-prior sphere fit of `arcs` from `start` (the plain sphere fit), or
/// why it could not run.
pub fn fit(
    start: &Rigid,
    arcs: &[ArcFrame],
    records: &[FrameRecord],
    settings: &SphereSettings,
    inputs: &PoseInputs<'_>,
) -> Result<(SphereFit, PoseFitNoise), PoseFitError> {
    let frames: Vec<&FrameRecord> = records
        .iter()
        .filter(|r| arcs.iter().any(|a| a.frame == r.files.frame))
        .collect();
    let mut probe_rms = Vec::new();
    let mut phantom_rms = Vec::new();
    let mut edge_mm = Vec::new();
    let spacing = (settings.spacing_mm_per_px[0] * settings.spacing_mm_per_px[1]).sqrt();
    for r in &frames {
        if let Some(p) = &r.poses {
            probe_rms.push(p.camera_T_marker.reprojection_rms_px);
            phantom_rms.push(p.camera_T_phantom.reprojection_rms_px);
        }
        edge_mm.extend(r.arcs.iter().map(|a| a.rms_px * spacing));
    }
    let probe_corners = inputs.probe_board.feature_points_mm();
    let phantom_corners = inputs.phantom_board.feature_points_mm();
    let (tremor_sd_mm, tremor_sd_deg) = inputs.prior.tremor_sd();
    let noise = PhotoNoise {
        probe_corner_sd_px: corner_sd(&mut probe_rms, probe_corners.len()).ok_or(PoseFitError::NoPoses("probe"))?,
        phantom_corner_sd_px: corner_sd(&mut phantom_rms, phantom_corners.len())
            .ok_or(PoseFitError::NoPoses("phantom"))?,
        tremor_sd_mm,
        tremor_sd_deg,
    };
    if edge_mm.is_empty() {
        return Err(PoseFitError::NoArcs);
    }
    let edge_sd_mm = median(&mut edge_mm);
    if !(edge_sd_mm > 0.0 && edge_sd_mm.is_finite()) {
        return Err(PoseFitError::EdgeNoise(edge_sd_mm));
    }
    let intrinsics_information = inputs.calibration.and_then(calibration_information);
    let mut priors = Vec::new();
    let mut shifts = Vec::new();
    for r in &frames {
        let Some(p) = &r.poses else { continue };
        let photo = SweepPhoto {
            camera_T_marker: p.camera_T_marker.camera_T_board,
            camera_T_phantom: p.camera_T_phantom.camera_T_board,
            marker_corners_mm: &probe_corners,
            phantom_corners_mm: &phantom_corners,
        };
        match frame_pose_noise(inputs.camera, &photo, &noise) {
            Some(n) => {
                priors.push((r.files.frame, n.cov));
                shifts.push((
                    r.files.frame,
                    nalgebra::DMatrix::from_iterator(6, n.from_intrinsics.ncols(), n.from_intrinsics.iter().copied()),
                ));
            }
            None => return Err(PoseFitError::Undetermined(r.files.frame)),
        }
    }
    let fitted = sphere_bundle::refine(
        start,
        arcs,
        settings,
        &PosePriors {
            edge_sd_mm,
            frames: priors,
            shared: intrinsics_information.map(|info| SharedError {
                information: nalgebra::DMatrix::from_iterator(info.nrows(), info.ncols(), info.iter().copied()),
                frames: shifts,
            }),
            edge_offset: inputs.prior.edge_offset,
            slice_blur: inputs.prior.slice_blur,
        },
    )
    .map_err(PoseFitError::Fit)?;
    let edge_offset_mm = fitted.edge_offset_mm;
    Ok((
        fitted,
        PoseFitNoise {
            edge_sd_mm,
            probe_corner_sd_px: noise.probe_corner_sd_px,
            phantom_corner_sd_px: noise.phantom_corner_sd_px,
            tremor_sd_mm,
            tremor_sd_deg,
            intrinsics_fx_sd_px: intrinsics_information.as_ref().and_then(intrinsics_sd).map(|sd| sd[0]),
            edge_offset: inputs.prior.edge_offset,
            edge_offset_mm,
            slice_blur: inputs.prior.slice_blur,
        },
    ))
}
