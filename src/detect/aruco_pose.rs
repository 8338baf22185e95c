//! Both ArUco grid boards of a photo, told apart by their marker ids, and their
//! poses; a board whose two planar-PnP solutions fit about equally is refused.

use super::board_pose::{
    pnp, rigid_from_rvec_tvec, BoardObservation, BoardRejection, FramePoses, MAX_REPROJECTION_RMS_PX,
};
use crate::core::geometry::rotation_angle_between_deg;
use crate::detect::aruco;
use crate::detect::board::ArucoLayout;
use crate::detect::corners::image_points;
use crate::io::camera_model::CameraIntrinsics;
use opencv::calib3d;
use opencv::core::{Mat, Vector};
use opencv::prelude::*;

/// Two planar-PnP solutions fitting within this much of each other are ambiguous.
const AMBIGUITY_RATIO: f64 = 1.3;

/// Pose of one ArUco board from its detected markers; `Err` is the rejection reason.
fn aruco_board_pose(
    camera: &CameraIntrinsics,
    layout: &ArucoLayout,
    name: &'static str,
    markers: &[aruco::Marker],
    min_markers: usize,
) -> opencv::Result<Result<BoardObservation, BoardRejection>> {
    let mine: Vec<&aruco::Marker> = markers
        .iter()
        .filter(|m| m.id >= 0 && layout.ids().contains(&(m.id as u32)))
        .collect();
    let total = layout.ids().len();
    if mine.len() < min_markers {
        return Ok(Err(BoardRejection::TooFewMarkers {
            board: name,
            found: mine.len(),
            total,
            needed: min_markers,
        }));
    }
    let mut object = Vector::<opencv::core::Point3f>::new();
    let mut corners_px = Vec::new();
    for m in &mine {
        let Some(corners) = layout.marker_corners_mm(m.id as u32) else {
            continue;
        };
        for (c, px) in corners.iter().zip(&m.corners_px) {
            object.push(opencv::core::Point3f::new(c.x as f32, c.y as f32, 0.0));
            corners_px.push(*px);
        }
    }
    planar_pose(camera, name, &object, &corners_px)
}

/// A planar board's pose from its identified points (board mm, z = 0) and
/// their pixels. Planar targets admit two poses (IPPE gives both); when both
/// explain the points about equally, the pose is ambiguous and refused.
pub(super) fn planar_pose(
    camera: &CameraIntrinsics,
    name: &'static str,
    object: &Vector<opencv::core::Point3f>,
    corners_px: &[[f64; 2]],
) -> opencv::Result<Result<BoardObservation, BoardRejection>> {
    let image = image_points(corners_px);
    let (k, d) = (camera.camera_matrix_mat()?, camera.distortion_mat()?);
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let mut errors = Mat::default();
    let solutions = calib3d::solve_pnp_generic(
        object,
        &image,
        &k,
        &d,
        &mut rvecs,
        &mut tvecs,
        false,
        calib3d::SolvePnPMethod::SOLVEPNP_IPPE,
        &Mat::default(),
        &Mat::default(),
        &mut errors,
    )?;
    if solutions < 1 {
        return Ok(Err(BoardRejection::NoPose {
            board: name,
            points: corners_px.len(),
        }));
    }
    if solutions >= 2 {
        let mut errors64 = Mat::default();
        errors.convert_to_def(&mut errors64, opencv::core::CV_64F)?;
        let e0 = *errors64.at::<f64>(0)?;
        let e1 = *errors64.at::<f64>(1)?;
        let angle = rotation_angle_between_deg(
            &rigid_from_rvec_tvec(&rvecs.get(0)?, &tvecs.get(0)?)?,
            &rigid_from_rvec_tvec(&rvecs.get(1)?, &tvecs.get(1)?)?,
        );
        if e1 <= AMBIGUITY_RATIO * e0 && angle > 1.0 {
            return Ok(Err(BoardRejection::AmbiguousPose {
                board: name,
                apart_deg: angle,
                errors_px: [e0, e1],
            }));
        }
    }
    let observation = pnp(camera, object, corners_px, Some((&rvecs.get(0)?, &tvecs.get(0)?)))?;
    Ok(Ok(observation))
}

/// Finds both ArUco boards (told apart by marker ids) and poses them.
pub fn estimate_aruco(
    image: &Mat,
    camera: &CameraIntrinsics,
    probe: &ArucoLayout,
    phantom: &ArucoLayout,
    subpixel_half_window_px: u32,
    min_markers: usize,
) -> opencv::Result<Result<FramePoses, BoardRejection>> {
    let dictionary = match aruco::predefined(&probe.dictionary) {
        Ok(d) => d,
        Err(e) => return Ok(Err(BoardRejection::Markers(e.to_string()))),
    };
    let window = (subpixel_half_window_px > 0).then_some(subpixel_half_window_px as i32);
    let markers = match aruco::detect(image, &dictionary, window) {
        Ok(m) => m,
        Err(aruco::ArucoError::OpenCv(e)) => return Err(e),
        Err(e) => return Ok(Err(BoardRejection::Markers(e.to_string()))),
    };
    let mut poses = Vec::new();
    for (layout, name) in [(probe, "probe"), (phantom, "phantom")] {
        match aruco_board_pose(camera, layout, name, &markers, min_markers)? {
            Ok(o) if o.reprojection_rms_px > MAX_REPROJECTION_RMS_PX => {
                return Ok(Err(BoardRejection::Reprojection {
                    board: name,
                    rms_px: o.reprojection_rms_px,
                    limit_px: MAX_REPROJECTION_RMS_PX,
                }))
            }
            Ok(o) => poses.push(o),
            Err(reason) => return Ok(Err(reason)),
        }
    }
    let phantom_pose = poses.pop();
    let probe_pose = poses.pop();
    Ok(match (probe_pose, phantom_pose) {
        (Some(m), Some(p)) => Ok(FramePoses {
            camera_T_marker: m,
            camera_T_phantom: p,
        }),
        _ => Err(BoardRejection::NotFound),
    })
}
