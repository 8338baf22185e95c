//! Ground truth of a rendered dataset, read by the evaluation stage only.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::core::geometry::{rigid_from_rows, Rigid};

/// Name of the ground-truth file inside a rendered dataset folder.
pub const GROUND_TRUTH_FILE: &str = "ground_truth.json";

#[derive(Debug, Clone, Deserialize)]
pub struct TruthFrame {
    pub frame: usize,
    pub kind: String,
    pub camera_T_marker_photo: [[f64; 4]; 4],
    /// The marker when the B-scan was taken (the hand moves between photo and B-scan).
    pub camera_T_marker_bscan: [[f64; 4]; 4],
    pub elevation_offset_mm: f64,
    pub centre_projection_px: [f64; 2],
    #[serde(default)]
    pub wire_dots_px: Vec<WireDot>,
}

/// Where a wire's axis crosses a B-scan plane.
#[derive(Debug, Clone, serde::Serialize, Deserialize)]
pub struct WireDot {
    pub wire: String,
    pub pixel: [f64; 2],
}

#[derive(Debug, Clone, Deserialize)]
struct RawTruth {
    marker_T_image: [[f64; 4]; 4],
    camera_T_phantom: [[f64; 4]; 4],
    bscan_size_px: [usize; 2],
    #[serde(default)]
    bscan_apex_mm: [f64; 2],
    #[serde(default = "one")]
    range_scale: f64,
    camera: TruthCamera,
    frames: Vec<TruthFrame>,
}

fn one() -> f64 {
    1.0
}

#[derive(Debug, Clone, Deserialize)]
pub struct TruthCamera {
    pub camera_matrix: [[f64; 3]; 3],
    pub distortion: [f64; 5],
}

/// What the evaluation compares against.
#[derive(Debug, Clone)]
pub struct GroundTruth {
    pub marker_T_image: Rigid,
    pub camera_T_phantom: Rigid,
    pub bscan_size_px: [usize; 2],
    /// The fan's virtual apex in the image frame, mm.
    pub bscan_apex_mm: [f64; 2],
    /// True range per displayed range (the medium's speed of sound over the
    /// scanner's; 1 when they agree).
    pub range_scale: f64,
    pub camera: TruthCamera,
    pub frames: Vec<TruthFrame>,
}

#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    #[error("{path}: {message}")]
    Bad { path: PathBuf, message: String },
}

impl GroundTruth {
    /// Reads `ground_truth.json` from a dataset folder; `Ok(None)` for recorded data without one.
    pub fn load(folder: &Path) -> Result<Option<GroundTruth>, TruthError> {
        let path = folder.join(GROUND_TRUTH_FILE);
        if !path.exists() {
            return Ok(None);
        }
        let bad = |message: String| TruthError::Bad {
            path: path.clone(),
            message,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| bad(e.to_string()))?;
        let raw: RawTruth = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        Ok(Some(GroundTruth {
            marker_T_image: rigid_from_rows(&raw.marker_T_image).map_err(|e| bad(format!("marker_T_image: {e}")))?,
            camera_T_phantom: rigid_from_rows(&raw.camera_T_phantom)
                .map_err(|e| bad(format!("camera_T_phantom: {e}")))?,
            bscan_size_px: raw.bscan_size_px,
            bscan_apex_mm: raw.bscan_apex_mm,
            range_scale: raw.range_scale,
            camera: raw.camera,
            frames: raw.frames,
        }))
    }

    pub fn frame(&self, frame: usize) -> Option<&TruthFrame> {
        self.frames.iter().find(|f| f.frame == frame)
    }
}
