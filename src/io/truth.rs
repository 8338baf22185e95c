//! Ground truth of a rendered dataset, read by the evaluation stage only.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::core::geometry::{rigid_from_rows, Rigid};
use crate::spec::phantom::Phantom;

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
    /// The phantom as built (a rig with measurement errors states another in its manifest).
    #[serde(default)]
    phantom: Option<Phantom>,
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
    /// The phantom as built, where the truth states it.
    pub phantom: Option<Phantom>,
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
        let text = crate::io::fs::read_text_capped(&path, crate::core::limits::MAX_TEXT_FILE_BYTES)
            .map_err(|e| bad(e.to_string()))?;
        let raw: RawTruth = crate::io::unique_keys::json(&text).map_err(|e| bad(e.to_string()))?;
        Ok(Some(GroundTruth {
            marker_T_image: rigid_from_rows(&raw.marker_T_image).map_err(|e| bad(format!("marker_T_image: {e}")))?,
            camera_T_phantom: rigid_from_rows(&raw.camera_T_phantom)
                .map_err(|e| bad(format!("camera_T_phantom: {e}")))?,
            bscan_size_px: raw.bscan_size_px,
            bscan_apex_mm: raw.bscan_apex_mm,
            range_scale: raw.range_scale,
            camera: raw.camera,
            frames: raw.frames,
            phantom: raw.phantom,
        }))
    }

    pub fn frame(&self, frame: usize) -> Option<&TruthFrame> {
        self.frames.iter().find(|f| f.frame == frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth_text(phantom: &str) -> String {
        let identity = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
        format!(
            r#"{{"marker_T_image": {identity}, "camera_T_phantom": {identity}, "bscan_size_px": [801, 601],
                "camera": {{"camera_matrix": [[1400,0,960],[0,1400,540],[0,0,1]], "distortion": [0,0,0,0,0]}},
                "frames": []{phantom}}}"#
        )
    }

    fn load_text(name: &str, text: &str) -> Result<Option<GroundTruth>, TruthError> {
        let folder = std::env::temp_dir().join(format!("probecal-truth-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(folder.join(GROUND_TRUTH_FILE), text).unwrap();
        let truth = GroundTruth::load(&folder);
        std::fs::remove_dir_all(&folder).unwrap();
        truth
    }

    #[test]
    fn the_phantom_as_built_is_read_when_the_truth_states_it() {
        let text = truth_text(
            r#", "phantom": {"spheres": {"spheres": [{"name": "dome1", "centre_in_phantom_mm": [1.0, 2.0, 3.5], "radius_mm": 10.0}]}}"#,
        );
        let truth = load_text("spheres", &text).unwrap().unwrap();
        match truth.phantom {
            Some(Phantom::Spheres { spheres }) => assert_eq!(spheres[0].centre_in_phantom_mm, [1.0, 2.0, 3.5]),
            other => panic!("{other:?}"),
        }
        assert!(load_text("none", &truth_text("")).unwrap().unwrap().phantom.is_none());
        // A phantom the truth states wrongly is an error naming the file.
        let bad = load_text("bad", &truth_text(r#", "phantom": {"spheres": {"domes": []}}"#)).unwrap_err();
        assert!(bad.to_string().contains(GROUND_TRUTH_FILE), "{bad}");
    }
}
