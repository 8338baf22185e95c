//! Both ChArUco boards of a photo and their poses: markers by OpenCV's
//! `detectMarkers`, each board's markers told apart by id, its chessboard
//! corners between found markers by `interpolateCornersCharuco` (with the
//! calibrated camera: the markers' pose projects each corner, then OpenCV
//! refines it to sub-pixel), and the pose from those corners with the board's
//! known geometry. A hidden part of a board costs its corners, not the frame.

use nalgebra::{Point2, Point3};
use opencv::aruco::DetectorParameters;
use opencv::core::{Mat, Point2f, Point3f, Ptr, Vector};

use super::aruco::{self, ArucoError, Marker};
use super::aruco_pose::planar_pose;
use super::board::CharucoLayout;
use super::board_pose::{BoardObservation, BoardRejection, FramePoses, MAX_REPROJECTION_RMS_PX};
use super::charuco_calibration::CharucoSpec;
use crate::io::camera_model::CameraIntrinsics;

/// Fewest markers next to a corner for OpenCV to interpolate it (OpenCV's
/// own default for `interpolateCornersCharuco`).
const MIN_MARKERS_PER_CORNER: i32 = 2;

/// The corners' own refinement: the checkerboard path's window cap, iterations and step.
const REFINE_MAX_HALF_WINDOW_PX: i32 = 5;
const REFINE_MAX_ITERATIONS: i32 = 40;
const REFINE_EPSILON_PX: f64 = 0.01;

/// A corner whose residual from the board's pose exceeds this many times the
/// median residual, and [`OUTLIER_FLOOR_PX`], is left out and the pose solved again.
const OUTLIER_TIMES_MEDIAN: f64 = 5.0;
/// Below this residual no corner is an outlier: the corner noise of a sharp photo, px.
const OUTLIER_FLOOR_PX: f64 = 0.75;

/// The corners of one board found in a photo (corner ids ascending).
#[derive(Debug, Clone, PartialEq)]
pub struct BoardCorners {
    pub markers: usize,
    pub corner_ids: Vec<i32>,
    pub corners_px: Vec<[f64; 2]>,
}

/// One board's markers among all found ones, its corners interpolated.
pub fn board_corners(
    image: &Mat,
    camera: &CameraIntrinsics,
    layout: &CharucoLayout,
    markers: &[Marker],
) -> Result<BoardCorners, ArucoError> {
    let mut corners = Vector::<Vector<Point2f>>::new();
    let mut ids = Vector::<i32>::new();
    for m in markers
        .iter()
        .filter(|m| m.id >= 0 && layout.ids().contains(&(m.id as u32)))
    {
        corners.push(
            m.corners_px
                .iter()
                .map(|p| Point2f::new(p[0] as f32, p[1] as f32))
                .collect(),
        );
        // OpenCV's board numbers its markers from 0.
        ids.push(m.id - layout.first_id as i32);
    }
    let mut found = BoardCorners {
        markers: ids.len(),
        corner_ids: Vec::new(),
        corners_px: Vec::new(),
    };
    if ids.is_empty() {
        return Ok(found);
    }
    let spec = CharucoSpec {
        squares: layout.squares,
        square_mm: layout.square_mm,
        marker_mm: layout.marker_mm,
        dictionary: layout.dictionary.clone(),
    };
    let (_, board) = spec.board().map_err(|e| ArucoError::Board(e.to_string()))?;
    let (k, d) = (camera.camera_matrix_mat()?, camera.distortion_mat()?);
    let mut charuco = Vector::<Point2f>::new();
    let mut charuco_ids = Vector::<i32>::new();
    opencv::aruco::interpolate_corners_charuco(
        &corners,
        &ids,
        image,
        &board,
        &mut charuco,
        &mut charuco_ids,
        &k,
        &d,
        MIN_MARKERS_PER_CORNER,
    )?;
    let marker_corners: Vec<[f64; 2]> = corners
        .iter()
        .flat_map(|c| c.iter().map(|p| [p.x as f64, p.y as f64]).collect::<Vec<_>>())
        .collect();
    let mut pairs: Vec<(i32, [f64; 2])> = Vec::with_capacity(charuco.len());
    for (id, p) in charuco_ids.iter().zip(charuco.iter()) {
        let start = [p.x as f64, p.y as f64];
        if !(start[0].is_finite() && start[1].is_finite()) {
            continue;
        }
        pairs.push((id, refine_corner(image, start, &marker_corners)?));
    }
    pairs.sort_by_key(|p| p.0);
    found.corner_ids = pairs.iter().map(|p| p.0).collect();
    found.corners_px = pairs.iter().map(|p| p.1).collect();
    Ok(found)
}

/// OpenCV's interpolation ends its `cornerSubPix` at 0.1 px steps (its
/// default detector parameters, which it does not take from the caller); each
/// corner is refined on to 0.01 px, as a checkerboard's are, in the largest
/// window (at most 5 px each side) that stays clear of the markers' corners:
/// the nearest lies diagonally `d` px away, so the half-window is below `d/√2`.
fn refine_corner(image: &Mat, start: [f64; 2], marker_corners: &[[f64; 2]]) -> Result<[f64; 2], ArucoError> {
    let nearest = marker_corners
        .iter()
        .map(|m| (m[0] - start[0]).hypot(m[1] - start[1]))
        .fold(f64::INFINITY, f64::min);
    let half = (nearest / std::f64::consts::SQRT_2 - 1.0)
        .floor()
        .min(REFINE_MAX_HALF_WINDOW_PX as f64);
    if half.is_nan() || half < 2.0 {
        return Ok(start);
    }
    let half = half as i32;
    let mut corner = Vector::<Point2f>::from_iter([Point2f::new(start[0] as f32, start[1] as f32)]);
    let criteria = opencv::core::TermCriteria::new(
        opencv::core::TermCriteria_Type::EPS as i32 + opencv::core::TermCriteria_Type::COUNT as i32,
        REFINE_MAX_ITERATIONS,
        REFINE_EPSILON_PX,
    )?;
    opencv::imgproc::corner_sub_pix(
        image,
        &mut corner,
        opencv::core::Size::new(half, half),
        opencv::core::Size::new(-1, -1),
        criteria,
    )?;
    let p = corner.get(0)?;
    let refined = [p.x as f64, p.y as f64];
    // A refinement that wanders off its window is not trusted.
    let moved = (refined[0] - start[0]).hypot(refined[1] - start[1]);
    Ok(if refined.iter().all(|v| v.is_finite()) && moved <= half as f64 {
        refined
    } else {
        start
    })
}

/// One board's pose from its corners; `Err` is the rejection reason.
fn board_pose(
    camera: &CameraIntrinsics,
    layout: &CharucoLayout,
    name: &'static str,
    found: &BoardCorners,
    min_corners: usize,
) -> opencv::Result<Result<BoardObservation, BoardRejection>> {
    let corners_mm = layout.corners_mm();
    if found.corner_ids.len() < min_corners {
        return Ok(Err(BoardRejection::TooFewCorners {
            board: name,
            found: found.corner_ids.len(),
            total: corners_mm.len(),
            markers: found.markers,
            needed: min_corners,
        }));
    }
    let mut points: Vec<(Point2<f64>, [f64; 2])> = Vec::new();
    for (id, px) in found.corner_ids.iter().zip(&found.corners_px) {
        if let Some(p) = usize::try_from(*id).ok().and_then(|i| corners_mm.get(i)) {
            points.push((*p, *px));
        }
    }
    let solve = |points: &[(Point2<f64>, [f64; 2])]| {
        let object: Vector<Point3f> = points
            .iter()
            .map(|(p, _)| Point3f::new(p.x as f32, p.y as f32, 0.0))
            .collect();
        let pixels: Vec<[f64; 2]> = points.iter().map(|(_, px)| *px).collect();
        planar_pose(camera, name, &object, &pixels)
    };
    let first = match solve(&points)? {
        Ok(o) => o,
        Err(reason) => return Ok(Err(reason)),
    };
    // A corner next to something lying over the board (a finger, a cable) is
    // interpolated from its markers but refined onto the occluder's edge: it
    // stands apart from the pose the other corners agree on, and is left out.
    let residuals: Vec<f64> = points
        .iter()
        .map(|(p, px)| {
            camera
                .project(&(first.camera_T_board * Point3::new(p.x, p.y, 0.0)))
                .map_or(f64::INFINITY, |q| {
                    ((q[0] - px[0]).powi(2) + (q[1] - px[1]).powi(2)).sqrt()
                })
        })
        .collect();
    let mut sorted = residuals.clone();
    sorted.sort_by(f64::total_cmp);
    let limit_px = (OUTLIER_TIMES_MEDIAN * sorted[sorted.len() / 2]).max(OUTLIER_FLOOR_PX);
    let kept: Vec<(Point2<f64>, [f64; 2])> = points
        .iter()
        .zip(&residuals)
        .filter(|(_, r)| **r <= limit_px)
        .map(|(p, _)| *p)
        .collect();
    if kept.len() == points.len() || kept.len() < min_corners {
        return Ok(Ok(first));
    }
    solve(&kept)
}

/// Finds both ChArUco boards (told apart by marker ids) and poses them.
pub fn estimate_charuco(
    image: &Mat,
    camera: &CameraIntrinsics,
    probe: &CharucoLayout,
    phantom: &CharucoLayout,
    min_corners: usize,
    detector_params: Option<&std::path::Path>,
) -> opencv::Result<Result<FramePoses, BoardRejection>> {
    let parameters = match aruco::detector_parameters(detector_params) {
        Ok(p) => p,
        Err(e) => return Ok(Err(BoardRejection::Markers(e.to_string()))),
    };
    let mut poses = Vec::new();
    let mut searched: Option<(String, Vec<Marker>)> = None;
    for (layout, name) in [(probe, "probe"), (phantom, "phantom")] {
        // One marker search per dictionary.
        if searched.as_ref().map(|s| &s.0) != Some(&layout.dictionary) {
            let markers = match detect_markers(image, &layout.dictionary, &parameters) {
                Ok(m) => m,
                Err(ArucoError::OpenCv(e)) => return Err(e),
                Err(e) => return Ok(Err(BoardRejection::Markers(e.to_string()))),
            };
            searched = Some((layout.dictionary.clone(), markers));
        }
        let markers = searched.as_ref().map(|s| s.1.as_slice()).unwrap_or_default();
        let found = match board_corners(image, camera, layout, markers) {
            Ok(f) => f,
            Err(ArucoError::OpenCv(e)) => return Err(e),
            Err(e) => return Ok(Err(BoardRejection::Markers(e.to_string()))),
        };
        match board_pose(camera, layout, name, &found, min_corners)? {
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

/// Markers of one dictionary with the given detector parameters (OpenCV's
/// corner refinement as the parameters say).
fn detect_markers(
    image: &Mat,
    dictionary: &str,
    parameters: &Ptr<DetectorParameters>,
) -> Result<Vec<Marker>, ArucoError> {
    let dictionary = aruco::dictionary(dictionary)?;
    aruco::detect_with(image, &dictionary, parameters)
}
