//! Stage 1: the camera's intrinsics (from a file, or calibrated from the
//! dataset's board views), or the tracker whose poses replace the camera's.

use std::path::Path;

use crate::detect::board::PrintedBoard;
use crate::detect::board_pose::{RigBoards, RigLayout};
use crate::detect::camera_calibration;
use crate::detect::camera_refinement::{self, BoardView};
use crate::io::camera_model::CameraIntrinsics;
use crate::io::tracker_poses::TrackerPoses;
use crate::manifest::{CameraSource, Manifest};
use crate::pipeline::error::RunError;
use crate::pipeline::record::{CameraStage, FrameRecord, Rejection, TrackerSource};

pub fn camera_stage(manifest: &Manifest, dataset: &str, folder: &Path) -> Result<CameraStage, RunError> {
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

/// `camera.calibrate.refine_with_frames`: the intrinsics solved again with
/// every pair of boards the frames' photos show (frames whose poses passed
/// their checks), then every frame's boards posed again with them. Returns
/// whether it ran.
pub fn refine_with_frames(
    manifest: &Manifest,
    camera: &mut CameraStage,
    frames: &mut [FrameRecord],
    rig: &RigBoards,
    dataset: &str,
) -> Result<bool, RunError> {
    let CameraSource::Calibrate { board, .. } = &manifest.camera else {
        return Ok(false);
    };
    if !board.refine_with_frames {
        return Ok(false);
    }
    let (PrintedBoard::Checkerboard(probe), PrintedBoard::Checkerboard(phantom)) = (&rig.probe, &rig.phantom) else {
        return Err(RunError::Unsupported(
            "camera.calibrate.refine_with_frames takes a checkerboard rig".into(),
        ));
    };
    let Some(calibration) = &camera.calibration else {
        return Ok(false);
    };
    let mut boards = Vec::new();
    for record in frames.iter() {
        let Some(poses) = &record.poses else { continue };
        if matches!(record.rejection, Some(Rejection::Implausible(_))) {
            continue;
        }
        for (name, layout, observation) in [
            ("probe", probe, &poses.camera_T_marker),
            ("phantom", phantom, &poses.camera_T_phantom),
        ] {
            boards.push(BoardView {
                label: format!("frame {}, {name} board", record.files.frame),
                corners_mm: layout.corners_in_board_mm(),
                corners_px: observation.corners_px.clone(),
            });
        }
    }
    let refined =
        camera_refinement::refine_with_boards(calibration, &boards).map_err(|source| RunError::Calibration {
            dataset: dataset.into(),
            source,
        })?;
    let layout = RigLayout {
        probe: *probe,
        phantom: *phantom,
    };
    for record in frames.iter_mut() {
        crate::pipeline::frames::pose_again(record, &refined.intrinsics, &layout)?;
    }
    if let Some(r) = &refined.refined {
        camera.source = match r.boards_repeated {
            0 => format!("{}, refined with {} boards of the frames' photos", camera.source, r.boards_used),
            n => format!(
                "{}, refined with {} boards of the frames' photos ({n} more showed a board where an earlier photo had it and were counted once)",
                camera.source, r.boards_used
            ),
        };
    }
    camera.intrinsics = Some(refined.intrinsics.clone());
    camera.calibration = Some(refined);
    Ok(true)
}
