//! Stage 1: the camera's intrinsics (from a file, or calibrated from the
//! dataset's board views), or the tracker whose poses replace the camera's.

use std::path::Path;

use super::record::{CameraStage, TrackerSource};
use super::run::RunError;
use crate::detect::camera_calibration;
use crate::io::camera_model::CameraIntrinsics;
use crate::io::tracker_poses::TrackerPoses;
use crate::manifest::{CameraSource, Manifest};

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
