//! Marker rigs: the printed boards on the probe and the phantom, and the camera
//! calibration board.

use serde::{Deserialize, Serialize};

/// The marker rig that gives the poses of the probe marker M and the phantom P in the camera C.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Rig {
    Checkerboard {
        probe_board: Board,
        phantom_board: Board,
    },
    /// ArUco grid boards; the two boards are told apart by their marker ids.
    Aruco {
        /// OpenCV's predefined dictionary name, e.g. `DICT_4X4_50`.
        dictionary: String,
        probe_board: ArucoBoard,
        phantom_board: ArucoBoard,
        /// Sub-pixel corner refinement window (half size, px); 0 turns it off. It
        /// must stay below a marker cell's size in the image.
        #[serde(default = "default_aruco_window")]
        subpixel_half_window_px: u32,
        /// Fewest markers of a board for a pose.
        #[serde(default = "default_min_markers")]
        min_markers: usize,
    },
}

fn default_aruco_window() -> u32 {
    3
}
fn default_min_markers() -> usize {
    4
}

/// A grid board of ArUco markers with consecutive ids from `first_id`, row by row.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ArucoBoard {
    /// Markers `[columns, rows]`.
    pub markers: [u32; 2],
    pub marker_mm: f64,
    pub separation_mm: f64,
    pub first_id: u32,
}

/// A printed checkerboard with a white margin one square wide. Its identification
/// dots sit in the margin beside the origin corner: the first dot fixes which inner
/// corner is the origin (the same in every frame), the number of dots tells the
/// probe's board from the phantom's.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Board {
    /// Inner corners `[columns, rows]` (OpenCV's pattern size): 11x11 squares have 10x10.
    pub inner_corners: [u32; 2],
    pub square_mm: f64,
    /// 1 or 2 dots; the probe's and the phantom's board must differ.
    pub id_dots: u8,
}

/// Camera calibration from views of a plain checkerboard.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCalibrationBoard {
    /// Folder of board images; absent: the dataset's own `camera_calibration/` folder.
    #[serde(default)]
    pub images: Option<String>,
    pub inner_corners: [u32; 2],
    pub square_mm: f64,
    /// Also calibrate from the checkerboards the frames' photos show (each board
    /// of each frame one more view, its pose its own unknown), then pose every
    /// frame's boards again with those intrinsics: the frames' photos see the
    /// boards through the same lens as the calibration views.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub refine_with_frames: bool,
}
