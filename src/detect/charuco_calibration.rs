//! Camera intrinsics from views of a ChArUco board (ArUco markers in the white
//! squares of a chessboard), as OpenCV's ChArUco calibration does: markers by
//! `detectMarkers` (OpenCV's default detector parameters), the chessboard
//! corners between them by `interpolateCornersCharuco` (from the markers'
//! homographies, no camera model yet), then `calibrateCameraCharuco` with flags
//! 0 (k1, k2, p1, p2, k3). A view whose board gives fewer than
//! [`MIN_VIEW_CORNERS`] corners is not used, and says so. A partly hidden board
//! still gives its visible corners, each with its id.

use std::path::{Path, PathBuf};

use opencv::aruco::{self, CharucoBoard, DetectorParameters, Dictionary};
use opencv::core::{Mat, Point2f, Ptr, Size, Vector};
use opencv::prelude::*;

use super::aruco::{dictionary_file, predefined, ArucoError};
use super::camera_calibration::{
    max_shift_px, CalibrationError, CalibrationView, CameraCalibration, DUPLICATE_VIEW_PX, MIN_VIEWS,
};
use crate::io::camera_model::CameraIntrinsics;
use crate::io::image::read_gray;

/// Fewest corners a view must give (a homography needs four; six off one
/// line leave the view's pose determined with a margin).
pub const MIN_VIEW_CORNERS: usize = 6;

/// A ChArUco board as printed.
#[derive(Debug, Clone, PartialEq)]
pub struct CharucoSpec {
    /// Squares along x and y.
    pub squares: [u32; 2],
    pub square_mm: f64,
    pub marker_mm: f64,
    /// An OpenCV dictionary name (`DICT_6X6_250`) or a dictionary file.
    pub dictionary: String,
}

/// Why a ChArUco board as given cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoardSpecError {
    #[error("--charuco {x}x{y}: a ChArUco board has 2 to {most} squares a side")]
    Squares { x: u32, y: u32, most: u32 },
    #[error("--square-mm {0}: a positive size")]
    SquareMm(f64),
    #[error("--marker-mm {marker_mm}: a positive size smaller than the square ({square_mm} mm)")]
    MarkerMm { marker_mm: f64, square_mm: f64 },
    #[error("a {x}x{y} ChArUco board holds {markers} markers, the dictionary `{dictionary}` has {available}")]
    TooFewMarkers {
        x: u32,
        y: u32,
        markers: i32,
        dictionary: String,
        available: i32,
    },
    /// The dictionary could not be opened, or OpenCV refused the board.
    #[error("{0}")]
    Dictionary(String),
}

impl CharucoSpec {
    /// Checks the sizes and opens the dictionary; the OpenCV board.
    pub fn board(&self) -> Result<(Ptr<Dictionary>, Ptr<CharucoBoard>), BoardSpecError> {
        let [x, y] = self.squares;
        let limit = crate::core::limits::MAX_BOARD_CORNERS;
        if x < 2 || y < 2 || x > limit + 1 || y > limit + 1 {
            return Err(BoardSpecError::Squares { x, y, most: limit + 1 });
        }
        if !(self.square_mm.is_finite() && self.square_mm > 0.0) {
            return Err(BoardSpecError::SquareMm(self.square_mm));
        }
        if !(self.marker_mm.is_finite() && self.marker_mm > 0.0 && self.marker_mm < self.square_mm) {
            return Err(BoardSpecError::MarkerMm {
                marker_mm: self.marker_mm,
                square_mm: self.square_mm,
            });
        }
        let dictionary = if self.dictionary.starts_with("DICT_") {
            predefined(&self.dictionary)
        } else {
            dictionary_file(Path::new(&self.dictionary))
        }
        .map_err(|e| BoardSpecError::Dictionary(e.to_string()))?;
        let markers = (x * y / 2) as i32;
        let available = dictionary.bytes_list().rows();
        if markers > available {
            return Err(BoardSpecError::TooFewMarkers {
                x,
                y,
                markers,
                dictionary: self.dictionary.clone(),
                available,
            });
        }
        let board = aruco::CharucoBoard::create(
            x as i32,
            y as i32,
            self.square_mm as f32,
            self.marker_mm as f32,
            &dictionary,
        )
        .map_err(|e| BoardSpecError::Dictionary(e.to_string()))?;
        Ok((dictionary, board))
    }
}

/// A view's markers and ChArUco corners (ids ascending).
#[derive(Debug, Clone, PartialEq)]
pub struct CharucoView {
    pub marker_ids: Vec<i32>,
    pub corner_ids: Vec<i32>,
    pub corners_px: Vec<[f64; 2]>,
}

/// The markers and interpolated chessboard corners of one image.
pub fn detect_view(
    image: &Mat,
    dictionary: &Ptr<Dictionary>,
    board: &Ptr<CharucoBoard>,
) -> Result<CharucoView, ArucoError> {
    let parameters = DetectorParameters::create()?;
    let mut corners = Vector::<Vector<Point2f>>::new();
    let mut ids = Vector::<i32>::new();
    let mut rejected = Vector::<Vector<Point2f>>::new();
    aruco::detect_markers(image, dictionary, &mut corners, &mut ids, &parameters, &mut rejected)?;
    let mut marker_ids: Vec<i32> = ids.iter().collect();
    marker_ids.sort_unstable();
    let mut view = CharucoView {
        marker_ids,
        corner_ids: Vec::new(),
        corners_px: Vec::new(),
    };
    if ids.is_empty() {
        return Ok(view);
    }
    let mut charuco = Vector::<Point2f>::new();
    let mut charuco_ids = Vector::<i32>::new();
    aruco::interpolate_corners_charuco(
        &corners,
        &ids,
        image,
        board,
        &mut charuco,
        &mut charuco_ids,
        &Mat::default(),
        &Mat::default(),
        2,
    )?;
    let mut found: Vec<(i32, [f64; 2])> = charuco_ids
        .iter()
        .zip(charuco.iter())
        .map(|(id, p)| (id, [p.x as f64, p.y as f64]))
        .collect();
    found.sort_by_key(|c| c.0);
    view.corner_ids = found.iter().map(|c| c.0).collect();
    view.corners_px = found.iter().map(|c| c.1).collect();
    Ok(view)
}

/// A used view: its index among the views, its corners' ids and pixels.
type SeenView = (usize, Vec<i32>, Vec<[f64; 2]>);

/// The earlier used view `view` repeats (the same corners, each within
/// [`DUPLICATE_VIEW_PX`]), and the largest shift, px.
fn same_view(view: &CharucoView, seen: &[SeenView]) -> Option<(usize, f64)> {
    seen.iter().find_map(|(index, ids, px)| {
        let shift = max_shift_px(&view.corners_px, px);
        (*ids == view.corner_ids && shift < DUPLICATE_VIEW_PX).then_some((*index, shift))
    })
}

/// Calibrates from the given image files.
pub fn calibrate(images: &[PathBuf], spec: &CharucoSpec) -> Result<CameraCalibration, CalibrationError> {
    let (dictionary, board) = spec.board().map_err(|e| CalibrationError::Board(e.to_string()))?;
    let mut views = Vec::new();
    let mut corners = Vector::<Vector<Point2f>>::new();
    let mut ids = Vector::<Vector<i32>>::new();
    let mut used = Vec::new();
    let mut seen: Vec<SeenView> = Vec::new();
    let mut size: Option<(PathBuf, Size)> = None;
    for path in images {
        let image = match read_gray(path) {
            Ok(i) => i,
            Err(e) => {
                views.push(CalibrationView::unused(path, e.to_string(), None));
                continue;
            }
        };
        let this = image.size()?;
        match &size {
            None => size = Some((path.clone(), this)),
            Some((first, s)) if *s != this => {
                return Err(CalibrationError::MixedSizes {
                    first: first.clone(),
                    w0: s.width,
                    h0: s.height,
                    other: path.clone(),
                    w1: this.width,
                    h1: this.height,
                })
            }
            _ => {}
        }
        let view = detect_view(&image, &dictionary, &board).map_err(|e| match e {
            ArucoError::OpenCv(e) => CalibrationError::OpenCv(e),
            other => CalibrationError::Board(other.to_string()),
        })?;
        if view.corner_ids.len() < MIN_VIEW_CORNERS {
            views.push(CalibrationView::unused(
                path,
                format!(
                    "{} ChArUco corners from {} markers, at least {MIN_VIEW_CORNERS} are needed",
                    view.corner_ids.len(),
                    view.marker_ids.len()
                ),
                None,
            ));
            continue;
        }
        // The same view twice (a copied photo) adds nothing, as for a chessboard.
        if let Some((earlier, shift_px)) = same_view(&view, &seen) {
            let earlier = views[earlier].image.display().to_string();
            let reason = format!("the same view as {earlier} (every corner within {shift_px:.2} px): it adds nothing");
            views.push(CalibrationView::unused(path, reason, None));
            continue;
        }
        seen.push((views.len(), view.corner_ids.clone(), view.corners_px.clone()));
        corners.push(
            view.corners_px
                .iter()
                .map(|p| Point2f::new(p[0] as f32, p[1] as f32))
                .collect(),
        );
        ids.push(view.corner_ids.iter().copied().collect());
        used.push(views.len());
        views.push(CalibrationView {
            image: path.clone(),
            used: true,
            reason: None,
            rms_px: None,
            found_by: None,
        });
    }
    let inner_corners = [spec.squares[0] - 1, spec.squares[1] - 1];
    if used.len() < MIN_VIEWS {
        return Err(super::camera_calibration::too_few_views(
            &views,
            inner_corners,
            used.len(),
        ));
    }
    let image_size = size.map(|s| s.1).unwrap_or_default();
    let (rms, k, d, per_view) = solve(&corners, &ids, &board, image_size)?;
    for (i, v) in used.iter().enumerate() {
        views[*v].rms_px = per_view.get(i).copied();
    }
    Ok(CameraCalibration {
        intrinsics: CameraIntrinsics {
            image_size_px: [image_size.width as u32, image_size.height as u32],
            camera_matrix: k,
            distortion: d,
            rms_px: Some(rms),
            per_view_rms_px: per_view,
        },
        views,
        inner_corners,
        square_mm: spec.square_mm,
        warnings: Vec::new(),
        used_corners_px: Vec::new(),
        refined: None,
    })
}

/// `calibrateCameraCharuco` (flags 0): RMS, camera matrix, distortion and the
/// per-view RMS, px.
#[allow(clippy::type_complexity)]
fn solve(
    corners: &Vector<Vector<Point2f>>,
    ids: &Vector<Vector<i32>>,
    board: &Ptr<CharucoBoard>,
    image_size: Size,
) -> Result<(f64, [[f64; 3]; 3], [f64; 5], Vec<f64>), CalibrationError> {
    let mut camera_matrix = Mat::default();
    let mut distortion = Mat::default();
    let (mut rvecs, mut tvecs) = (Vector::<Mat>::new(), Vector::<Mat>::new());
    let (mut sd_intrinsics, mut sd_extrinsics, mut per_view) = (Mat::default(), Mat::default(), Mat::default());
    let rms = aruco::calibrate_camera_charuco_extended_def(
        corners,
        ids,
        board,
        image_size,
        &mut camera_matrix,
        &mut distortion,
        &mut rvecs,
        &mut tvecs,
        &mut sd_intrinsics,
        &mut sd_extrinsics,
        &mut per_view,
    )?;
    let k: [[f64; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            camera_matrix
                .at_2d::<f64>(r as i32, c as i32)
                .copied()
                .unwrap_or(f64::NAN)
        })
    });
    let mut d = [0.0; 5];
    for (i, v) in distortion.data_typed::<f64>()?.iter().take(5).enumerate() {
        d[i] = *v;
    }
    if !(rms.is_finite() && k.iter().flatten().chain(&d).all(|v| v.is_finite())) {
        return Err(CalibrationError::Board(format!(
            "calibrateCameraCharuco gave a non-finite result (RMS {rms}) on {} views",
            corners.len()
        )));
    }
    Ok((rms, k, d, per_view.data_typed::<f64>()?.to_vec()))
}
