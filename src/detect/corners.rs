//! Chessboard inner-corner detection: OpenCV's `findChessboardCorners` (adaptive
//! threshold) followed by `cornerSubPix`. The camera calibration
//! and the per-frame board poses both go through this one function; the camera
//! calibration searches a view that the first search misses again, as OpenCV's
//! own calibration does and then with `findChessboardCornersSB`
//! ([`Search::Thorough`]).

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
fn find(image: &Mat, inner_corners: [u32; 2], search: Search) -> opencv::Result<Option<(Vector<Point2f>, Found)>> {
    let pattern = Size::new(inner_corners[0] as i32, inner_corners[1] as i32);
    let order: &[Found] = match search {
        Search::Fast => &[Found::AdaptiveThreshold],
        Search::Thorough => &[Found::AdaptiveThreshold, Found::OpenCvDefault, Found::SectorBased],
        Search::OpenCvSample => &[Found::OpenCvDefault, Found::AdaptiveThreshold, Found::SectorBased],
    };
    for way in order {
        let mut corners = Vector::<Point2f>::new();
        let found = match way {
            Found::AdaptiveThreshold => {
                calib3d::find_chessboard_corners(image, pattern, &mut corners, calib3d::CALIB_CB_ADAPTIVE_THRESH)?
            }
            Found::OpenCvDefault => calib3d::find_chessboard_corners(
                image,
                pattern,
                &mut corners,
                calib3d::CALIB_CB_ADAPTIVE_THRESH | calib3d::CALIB_CB_NORMALIZE_IMAGE,
            )?,
            Found::SectorBased => calib3d::find_chessboard_corners_sb(
                image,
                pattern,
                &mut corners,
                calib3d::CALIB_CB_NORMALIZE_IMAGE | calib3d::CALIB_CB_EXHAUSTIVE | calib3d::CALIB_CB_ACCURACY,
            )?,
        };
        if found {
            return Ok(Some((corners, *way)));
        }
    }
    Ok(None)
}

/// How hard a board is searched for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Search {
    /// The adaptive threshold alone (per-frame board poses: a frame whose board
    /// is hidden costs one search).
    Fast,
    /// Then OpenCV's default flags (adaptive threshold and a normalised image, as
    /// its calibration sample), then `findChessboardCornersSB` (normalised,
    /// exhaustive, accurate) before giving up: the pipeline's camera
    /// calibration, where a view lost is information lost. A board the first
    /// search finds keeps the corners it always had, so committed studies
    /// reproduce.
    Thorough,
    /// OpenCV's calibration sample's search first (its default flags), then the
    /// adaptive threshold alone, then `findChessboardCornersSB`: the
    /// `calibrate-camera` command, whose views and corners are then OpenCV's own
    /// (`cornerSubPix` stops within 0.1 px, so where it starts shows in the
    /// result).
    OpenCvSample,
}

/// Which search found a board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Found {
    AdaptiveThreshold,
    OpenCvDefault,
    SectorBased,
}

impl std::fmt::Display for Found {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Found::AdaptiveThreshold => "findChessboardCorners, adaptive threshold",
            Found::OpenCvDefault => "findChessboardCorners, adaptive threshold and normalised image",
            Found::SectorBased => "findChessboardCornersSB",
        })
    }
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
    Ok(search_chessboard(image, inner_corners, subpix, Search::Fast)?.map(|(c, _)| c))
}

/// Like [`detect_chessboard`], searched as `search` says; which search found it.
pub fn search_chessboard(
    image: &Mat,
    inner_corners: [u32; 2],
    subpix: SubPix,
    search: Search,
) -> opencv::Result<Option<(Vec<[f64; 2]>, Found)>> {
    match find(image, inner_corners, search)? {
        Some((corners, found)) => Ok(Some((refine(image, corners, subpix)?, found))),
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
    Ok(search_chessboard_reduced(image, inner_corners, subpix, max_side_px, Search::Fast)?.map(|(c, _)| c))
}

/// Like [`detect_chessboard_reduced`], searched as `search` says; which search
/// found it.
pub fn search_chessboard_reduced(
    image: &Mat,
    inner_corners: [u32; 2],
    subpix: SubPix,
    max_side_px: i32,
    search: Search,
) -> opencv::Result<Option<(Vec<[f64; 2]>, Found)>> {
    let side = image.cols().max(image.rows());
    let factor = ((side + max_side_px - 1) / max_side_px).max(1);
    if factor == 1 {
        return search_chessboard(image, inner_corners, subpix, search);
    }
    let mut reduced = Mat::default();
    let size = Size::new(image.cols() / factor, image.rows() / factor);
    imgproc::resize(image, &mut reduced, size, 0.0, 0.0, imgproc::INTER_AREA)?;
    let Some((corners, found)) = find(&reduced, inner_corners, search)? else {
        return Ok(None);
    };
    // Pixel centres: x_full = (x_reduced + 0.5) * factor - 0.5.
    let f = factor as f32;
    let full: Vector<Point2f> = corners
        .iter()
        .map(|p| Point2f::new((p.x + 0.5) * f - 0.5, (p.y + 0.5) * f - 0.5))
        .collect();
    Ok(Some((refine(image, full, subpix)?, found)))
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
