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
    /// ChArUco boards (ArUco markers in the white squares of a chessboard):
    /// the chessboard corners between found markers are interpolated, so a
    /// partly hidden board still gives its visible corners, each identified.
    Charuco {
        probe_board: CharucoBoard,
        phantom_board: CharucoBoard,
        /// Fewest chessboard corners of a board for a pose.
        #[serde(default = "default_min_corners")]
        min_corners: usize,
        /// An OpenCV detector parameters file (`detector_params.yml`, as
        /// OpenCV's samples write it); absent: OpenCV's defaults.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        detector_params: Option<String>,
    },
}

fn default_aruco_window() -> u32 {
    3
}
fn default_min_markers() -> usize {
    4
}
fn default_min_corners() -> usize {
    6
}

/// A ChArUco board as OpenCV's `CharucoBoard` lays it out: `squares[0] x
/// squares[1]` squares, the top-left one black, a marker centred in every
/// white square, ids `first_id..` row by row from the top.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CharucoBoard {
    /// Squares `[x, y]`.
    pub squares: [u32; 2],
    pub square_mm: f64,
    pub marker_mm: f64,
    /// OpenCV's predefined dictionary name (`DICT_6X6_250`) or a dictionary
    /// file (OpenCV FileStorage, as `tutorial_dict.yml`), relative to the manifest.
    pub dictionary: String,
    /// Id of the board's first marker (OpenCV's boards start at 0); two boards
    /// of one dictionary must not share ids.
    #[serde(default)]
    pub first_id: u32,
}

impl CharucoBoard {
    /// Markers on the board: one per white square.
    pub fn markers(&self) -> u32 {
        self.squares[0] * self.squares[1] / 2
    }
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
