//! Both boards of a rig in one photo, found as the rig's kind is found:
//! checkerboards ([`super::board_pose`]), ArUco grids ([`super::aruco_pose`])
//! or ChArUco boards ([`super::charuco_pose`]).

use opencv::core::Mat;

use super::board::PrintedBoard;
use super::board_pose::{estimate_checkerboards, BoardRejection, Detection, FramePoses, RigBoards, RigLayout};
use crate::io::camera_model::CameraIntrinsics;

/// Finds and poses both boards of a rig. The inner `Err` is a frame rejection reason.
pub fn estimate(
    image: &Mat,
    camera: &CameraIntrinsics,
    rig: &RigBoards,
) -> opencv::Result<Result<FramePoses, BoardRejection>> {
    match (&rig.probe, &rig.phantom, &rig.detection) {
        (PrintedBoard::Checkerboard(probe), PrintedBoard::Checkerboard(phantom), _) => estimate_checkerboards(
            image,
            camera,
            &RigLayout {
                probe: *probe,
                phantom: *phantom,
            },
        ),
        (
            PrintedBoard::Aruco(probe),
            PrintedBoard::Aruco(phantom),
            Detection::Aruco {
                subpixel_half_window_px,
                min_markers,
            },
        ) => super::aruco_pose::estimate_aruco(image, camera, probe, phantom, *subpixel_half_window_px, *min_markers),
        (
            PrintedBoard::Charuco(probe),
            PrintedBoard::Charuco(phantom),
            Detection::Charuco {
                min_corners,
                detector_params,
            },
        ) => super::charuco_pose::estimate_charuco(
            image,
            camera,
            probe,
            phantom,
            *min_corners,
            detector_params.as_deref(),
        ),
        _ => Ok(Err(BoardRejection::MixedRig)),
    }
}
