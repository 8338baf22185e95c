//! Chessboard inner-corner detection: OpenCV's `findChessboardCorners` (adaptive
//! threshold) followed by `cornerSubPix`. The camera calibration
//! and the per-frame board poses both go through this one function.

use opencv::core::{Mat, Point2f, Size, TermCriteria, TermCriteria_Type, Vector};
use opencv::prelude::*;
use opencv::{calib3d, imgproc};

/// Sub-pixel refinement settings (OpenCV's calibration sample: 11x11 window, 30 iterations, eps 0.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubPix {
    /// Half the search window (OpenCV's `winSize`).
    pub half_window_px: i32,
    pub max_iterations: i32,
    pub epsilon_px: f64,
}

impl Default for SubPix {
    fn default() -> Self {
        SubPix {
            half_window_px: 5,
            max_iterations: 30,
            epsilon_px: 0.1,
        }
    }
}

/// OpenCV's corner search with an adaptive threshold. The image is not
/// histogram-equalised (`CALIB_CB_NORMALIZE_IMAGE`): OpenCV 4.6 equalises only
/// for its slow fallback search, and there the equalised background texture
/// gives many more false squares. On a board it cannot find (a cable across the
/// probe's board, say) the search took 1.4 s at 960x540 with equalisation and
/// 0.36 s without. OpenCV's own sample photos are all still found and their
/// published calibration reproduced (`tests/opencv_chessboard.rs`), and every
/// rendered experiment keeps the frames it kept.
fn find(image: &Mat, inner_corners: [u32; 2]) -> opencv::Result<Option<Vector<Point2f>>> {
    let pattern = Size::new(inner_corners[0] as i32, inner_corners[1] as i32);
    let mut corners = Vector::<Point2f>::new();
    let flags = calib3d::CALIB_CB_ADAPTIVE_THRESH;
    Ok(calib3d::find_chessboard_corners(image, pattern, &mut corners, flags)?.then_some(corners))
}

/// `cornerSubPix` on `image` from the given starting corners.
fn refine(image: &Mat, mut corners: Vector<Point2f>, subpix: SubPix) -> opencv::Result<Vec<[f64; 2]>> {
    let criteria = TermCriteria::new(
        TermCriteria_Type::EPS as i32 + TermCriteria_Type::COUNT as i32,
        subpix.max_iterations,
        subpix.epsilon_px,
    )?;
    let window = Size::new(subpix.half_window_px, subpix.half_window_px);
    imgproc::corner_sub_pix(image, &mut corners, window, Size::new(-1, -1), criteria)?;
    Ok(corners.iter().map(|p| [p.x as f64, p.y as f64]).collect())
}

/// Inner corners of a `cols x rows` chessboard in OpenCV's order, or `None` if not found.
pub fn detect_chessboard(
    image: &Mat,
    inner_corners: [u32; 2],
    subpix: SubPix,
) -> opencv::Result<Option<Vec<[f64; 2]>>> {
    match find(image, inner_corners)? {
        Some(corners) => refine(image, corners, subpix).map(Some),
        None => Ok(None),
    }
}

/// Like [`detect_chessboard`], but the board is searched on a copy reduced to at
/// most `max_side_px` and its corners refined on the full image. On megapixel
/// photos this is many times faster, and it bounds the time OpenCV's search can
/// take on a partly hidden board (seen: two minutes at 1920x1080, 0.2 s at half size).
pub fn detect_chessboard_reduced(
    image: &Mat,
    inner_corners: [u32; 2],
    subpix: SubPix,
    max_side_px: i32,
) -> opencv::Result<Option<Vec<[f64; 2]>>> {
    let side = image.cols().max(image.rows());
    let factor = ((side + max_side_px - 1) / max_side_px).max(1);
    if factor == 1 {
        return detect_chessboard(image, inner_corners, subpix);
    }
    let mut reduced = Mat::default();
    let size = Size::new(image.cols() / factor, image.rows() / factor);
    imgproc::resize(image, &mut reduced, size, 0.0, 0.0, imgproc::INTER_AREA)?;
    let Some(corners) = find(&reduced, inner_corners)? else {
        return Ok(None);
    };
    // Pixel centres: x_full = (x_reduced + 0.5) * factor - 0.5.
    let f = factor as f32;
    let full: Vector<Point2f> = corners
        .iter()
        .map(|p| Point2f::new((p.x + 0.5) * f - 0.5, (p.y + 0.5) * f - 0.5))
        .collect();
    refine(image, full, subpix).map(Some)
}

/// `Mat` of 3D object points for OpenCV calls.
pub fn object_points(points_mm: &[nalgebra::Point2<f64>]) -> Vector<opencv::core::Point3f> {
    points_mm
        .iter()
        .map(|p| opencv::core::Point3f::new(p.x as f32, p.y as f32, 0.0))
        .collect()
}

/// `Vector<Point2f>` of image points for OpenCV calls.
pub fn image_points(points_px: &[[f64; 2]]) -> Vector<Point2f> {
    points_px
        .iter()
        .map(|p| Point2f::new(p[0] as f32, p[1] as f32))
        .collect()
}
