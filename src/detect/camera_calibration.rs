//! Stage 1: camera intrinsics from views of a plain checkerboard.
//!
//! Same procedure as OpenCV's calibration sample and its own regression test:
//! corners by [`crate::detect::corners::detect_chessboard`], `calibrateCamera` with flags 0
//! (k1, k2, p1, p2, k3 and a free aspect ratio); the RMS and the per-view RMS
//! reprojection errors are kept with the result.

use std::path::{Path, PathBuf};

use opencv::calib3d;
use opencv::core::{Mat, Size, Vector};
use opencv::prelude::*;

use crate::detect::board::BoardLayout;
use crate::detect::corners::{image_points, object_points, search_chessboard_reduced, Found, Search, SubPix};
use crate::io::camera_model::CameraIntrinsics;
use crate::io::image::read_gray;

/// One calibration view and what became of it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CalibrationView {
    pub image: PathBuf,
    pub used: bool,
    /// Why the view was not used.
    pub reason: Option<String>,
    pub rms_px: Option<f64>,
    /// Which search found its board.
    pub found_by: Option<Found>,
}

/// The stage's output.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CameraCalibration {
    pub intrinsics: CameraIntrinsics,
    pub views: Vec<CalibrationView>,
    pub inner_corners: [u32; 2],
    pub square_mm: f64,
    /// What the views leave poorly constrained (the calibration is kept).
    pub warnings: Vec<String>,
    /// The corners of the views used, in the order solved, px.
    #[serde(skip)]
    pub used_corners_px: Vec<Vec<[f64; 2]>>,
    /// Set when more board views (the frames' boards) refined these intrinsics.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined: Option<Refinement>,
}

/// A view whose every corner lies within this many pixels of an earlier view's
/// is the same view again: while a corner stays within its pixel the corner
/// detector's sub-pixel error and the lens's departure from its model there
/// repeat, so the view adds only its sensor noise, and counted again it would
/// make one pose look like many. The calibration refuses it; a refinement with
/// the frames' boards counts a static board once (`camera_refinement::repeats`).
pub const DUPLICATE_VIEW_PX: f64 = 1.0;

/// Views whose boards all face the camera within this angle of each other leave
/// the focal length and the board distance confounded.
pub const MIN_ORIENTATION_SPREAD_DEG: f64 = 10.0;

#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    #[error("{0}: no images (.png, .jpg, .jpeg, .bmp, .tif) found")]
    NoImages(PathBuf),
    #[error("{path}: cannot list the folder: {message}")]
    Unreadable { path: PathBuf, message: String },
    #[error("the board ({cols}x{rows} inner corners) was found in {found} of {total} views; at least {needed} are needed:\n{details}")]
    TooFewViews {
        cols: u32,
        rows: u32,
        found: usize,
        total: usize,
        needed: usize,
        details: String,
    },
    #[error("views differ in size: {first} is {w0}x{h0}, {other} is {w1}x{h1}")]
    MixedSizes {
        first: PathBuf,
        w0: i32,
        h0: i32,
        other: PathBuf,
        w1: i32,
        h1: i32,
    },
    #[error("the camera's solve with the frames' boards diverged (a board behind the camera or a singular system)")]
    Diverged,
    #[error("{0}")]
    Board(String),
    #[error("opencv: {0}")]
    OpenCv(#[from] opencv::Error),
}

/// Views larger than this are searched reduced and refined at full size (images up
/// to this size, like OpenCV's 640x480 samples, go through OpenCV's procedure as is).
pub const SEARCH_MAX_SIDE_PX: i32 = 1000;

/// Fewest usable views accepted for a calibration.
pub const MIN_VIEWS: usize = 4;

/// Image files given directly, or the images of folders, sorted by name.
pub fn collect_images(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, CalibrationError> {
    let mut out = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input).map_err(|e| CalibrationError::Unreadable {
                path: input.clone(),
                message: e.to_string(),
            })?;
            let mut files: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.extension()
                        .map(|e| {
                            matches!(
                                e.to_string_lossy().to_lowercase().as_str(),
                                "png" | "jpg" | "jpeg" | "bmp" | "tif" | "tiff"
                            )
                        })
                        .unwrap_or(false)
                })
                .collect();
            files.sort();
            if files.is_empty() {
                return Err(CalibrationError::NoImages(input.clone()));
            }
            out.extend(files);
        } else {
            out.push(input.clone());
        }
    }
    Ok(out)
}

/// The views used so far: the board's points and each view's corners, and
/// where each view sits in the list of all views.
#[derive(Default)]
struct UsedViews {
    object: Vector<Vector<opencv::core::Point3f>>,
    imagep: Vector<Vector<opencv::core::Point2f>>,
    index: Vec<usize>,
    corners: Vec<Vec<[f64; 2]>>,
}

impl UsedViews {
    /// Uses a view's corners, unless an earlier view is the same view.
    fn add(
        &mut self,
        views: &mut Vec<CalibrationView>,
        path: &Path,
        corners: Vec<[f64; 2]>,
        found_by: Found,
        board_points: &Vector<opencv::core::Point3f>,
    ) {
        if let Some(same) = duplicate_of(&corners, &self.corners) {
            let shift_px = max_shift_px(&corners, &self.corners[same]);
            let earlier = views[self.index[same]].image.display().to_string();
            let reason = format!("the same view as {earlier} (every corner within {shift_px:.2} px): it adds nothing");
            views.push(CalibrationView::unused(path, reason, Some(found_by)));
            return;
        }
        self.object.push(board_points.clone());
        self.imagep.push(image_points(&corners));
        self.corners.push(corners);
        self.index.push(views.len());
        views.push(CalibrationView {
            image: path.to_path_buf(),
            used: true,
            reason: None,
            rms_px: None,
            found_by: Some(found_by),
        });
    }

    /// A view whose corners disagree with the others (a corner pulled off by
    /// glare or the image edge) is dropped, once, and the camera solved again.
    fn without_outliers(
        &mut self,
        views: &mut [CalibrationView],
        solved: Solved,
        image_size: Size,
    ) -> Result<Solved, CalibrationError> {
        let mut sorted = solved.per_view.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let limit = (OUTLIER_VIEW_RATIO * median).max(OUTLIER_VIEW_FLOOR_PX);
        let outliers: Vec<usize> = (0..solved.per_view.len())
            .filter(|&i| solved.per_view[i] > limit)
            .collect();
        if !outliers.is_empty() && self.index.len() - outliers.len() >= MIN_VIEWS {
            for &i in &outliers {
                let view = &mut views[self.index[i]];
                view.used = false;
                view.reason = Some(format!(
                "per-view RMS {:.3} px is above {limit:.3} px ({OUTLIER_VIEW_RATIO} times the median {median:.3} px): dropped and solved again",
                solved.per_view[i]
            ));
                view.rms_px = Some(solved.per_view[i]);
            }
            let keep: Vec<usize> = (0..self.index.len()).filter(|i| !outliers.contains(i)).collect();
            self.object = keep
                .iter()
                .map(|&i| self.object.get(i))
                .collect::<opencv::Result<_>>()?;
            self.imagep = keep
                .iter()
                .map(|&i| self.imagep.get(i))
                .collect::<opencv::Result<_>>()?;
            self.index = keep.iter().map(|&i| self.index[i]).collect();
            self.corners = keep.iter().map(|&i| self.corners[i].clone()).collect();
            return Ok(solve(&self.object, &self.imagep, image_size)?);
        }
        Ok(solved)
    }
}

impl CalibrationView {
    /// A view not used, and why.
    pub(crate) fn unused(path: &Path, reason: String, found_by: Option<Found>) -> CalibrationView {
        CalibrationView {
            image: path.to_path_buf(),
            used: false,
            reason: Some(reason),
            rms_px: None,
            found_by,
        }
    }
}

/// Too few views with a board: each image's fate listed.
pub(super) fn too_few_views(views: &[CalibrationView], inner_corners: [u32; 2], found: usize) -> CalibrationError {
    let details = views
        .iter()
        .filter_map(|v| v.reason.as_ref().map(|r| format!("  {}: {r}", v.image.display())))
        .collect::<Vec<_>>()
        .join("\n");
    CalibrationError::TooFewViews {
        cols: inner_corners[0],
        rows: inner_corners[1],
        found,
        total: views.len(),
        needed: MIN_VIEWS,
        details,
    }
}

/// Each image's size and board corners (with how they were found), decoded and
/// searched on every core, in the images' order.
#[allow(clippy::type_complexity)]
fn search_views(
    images: &[PathBuf],
    inner_corners: [u32; 2],
    subpix: SubPix,
    search: Search,
) -> Vec<Result<(Size, opencv::Result<Option<(Vec<[f64; 2]>, Found)>>), crate::io::image::ImageError>> {
    crate::core::parallel::parallel_map(images.len(), |i| {
        read_gray(&images[i]).map(|image| {
            let size = Size::new(image.cols(), image.rows());
            (
                size,
                search_chessboard_reduced(&image, inner_corners, subpix, SEARCH_MAX_SIDE_PX, search),
            )
        })
    })
}

/// Calibrates from the given image files.
pub fn calibrate(
    images: &[PathBuf],
    inner_corners: [u32; 2],
    square_mm: f64,
    subpix: SubPix,
    search: Search,
) -> Result<CameraCalibration, CalibrationError> {
    let layout = BoardLayout {
        inner_corners,
        square_mm,
        id_dots: 0,
    };
    let board_points = object_points(&layout.corners_in_board_mm());
    let mut views = Vec::new();
    let mut used = UsedViews::default();
    let mut size: Option<(PathBuf, Size)> = None;
    let searched = search_views(images, inner_corners, subpix, search);
    for (path, searched) in images.iter().zip(searched) {
        let (this, found) = match searched {
            Ok(s) => s,
            Err(e) => {
                views.push(CalibrationView::unused(path, e.to_string(), None));
                continue;
            }
        };
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
        match found? {
            Some((corners, found_by)) => used.add(&mut views, path, corners, found_by, &board_points),
            None => views.push(CalibrationView::unused(
                path,
                format!(
                    "no {}x{} chessboard found (adaptive threshold, OpenCV's default flags, findChessboardCornersSB)",
                    inner_corners[0], inner_corners[1]
                ),
                None,
            )),
        }
    }
    if used.object.len() < MIN_VIEWS {
        return Err(too_few_views(&views, inner_corners, used.object.len()));
    }
    let image_size = size.map(|s| s.1).unwrap_or_default();
    let solved = solve(&used.object, &used.imagep, image_size)?;
    let solved = used.without_outliers(&mut views, solved, image_size)?;
    let (used_index, used_corners) = (used.index, used.corners);
    for (i, view_index) in used_index.iter().enumerate() {
        views[*view_index].rms_px = Some(solved.per_view[i]);
    }
    let warnings: Vec<String> = (solved.orientation_spread_deg < MIN_ORIENTATION_SPREAD_DEG)
        .then(|| {
            format!(
                "the boards of the {} views used face the camera within {:.1}° of each other (less than {MIN_ORIENTATION_SPREAD_DEG}°): the focal length is poorly constrained; add views with the board tilted",
                used_index.len(),
                solved.orientation_spread_deg
            )
        })
        .into_iter()
        .collect();
    let Solved {
        camera_matrix: k,
        distortion: d,
        rms,
        per_view,
        ..
    } = solved;
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
        square_mm,
        warnings,
        used_corners_px: used_corners,
        refined: None,
    })
}

/// The largest distance between corresponding corners of two views, px.
pub(super) fn max_shift_px(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt())
        .fold(0.0, f64::max)
}

/// The earlier view these corners repeat, if any (see [`DUPLICATE_VIEW_PX`]).
fn duplicate_of(corners: &[[f64; 2]], earlier: &[Vec<[f64; 2]>]) -> Option<usize> {
    earlier
        .iter()
        .position(|e| e.len() == corners.len() && max_shift_px(corners, e) < DUPLICATE_VIEW_PX)
}

/// A view is an outlier above this multiple of the median per-view RMS...
pub const OUTLIER_VIEW_RATIO: f64 = 3.0;
/// ...and above this many pixels.
pub const OUTLIER_VIEW_FLOOR_PX: f64 = 0.5;

struct Solved {
    camera_matrix: [[f64; 3]; 3],
    distortion: [f64; 5],
    rms: f64,
    per_view: Vec<f64>,
    /// The largest angle between two views' board normals, degrees.
    orientation_spread_deg: f64,
}

/// `calibrateCamera` (flags 0) and the per-view RMS, as OpenCV's sample computes it.
fn solve(
    object: &Vector<Vector<opencv::core::Point3f>>,
    imagep: &Vector<Vector<opencv::core::Point2f>>,
    image_size: Size,
) -> opencv::Result<Solved> {
    let mut camera_matrix = Mat::default();
    let mut distortion = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let rms = calib3d::calibrate_camera_def(
        object,
        imagep,
        image_size,
        &mut camera_matrix,
        &mut distortion,
        &mut rvecs,
        &mut tvecs,
    )?;
    let mut k = [[0.0; 3]; 3];
    for (r, row) in k.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = *camera_matrix.at_2d::<f64>(r as i32, c as i32)?;
        }
    }
    let mut d = [0.0; 5];
    for (i, v) in distortion.data_typed::<f64>()?.iter().take(5).enumerate() {
        d[i] = *v;
    }
    let mut per_view = Vec::new();
    for i in 0..object.len() {
        let mut projected = Vector::<opencv::core::Point2f>::new();
        calib3d::project_points_def(
            &object.get(i)?,
            &rvecs.get(i)?,
            &tvecs.get(i)?,
            &camera_matrix,
            &distortion,
            &mut projected,
        )?;
        let measured = imagep.get(i)?;
        let sum: f64 = projected
            .iter()
            .zip(measured.iter())
            .map(|(p, m)| ((p.x - m.x) as f64).powi(2) + ((p.y - m.y) as f64).powi(2))
            .sum();
        per_view.push((sum / measured.len() as f64).sqrt());
    }
    let mut normals = Vec::new();
    for r in rvecs.iter() {
        let mut rotation = Mat::default();
        calib3d::rodrigues_def(&r, &mut rotation)?;
        // The board's z axis in the camera frame: the rotation's third column.
        let column = |row: i32| rotation.at_2d::<f64>(row, 2).copied();
        normals.push(nalgebra::Vector3::new(column(0)?, column(1)?, column(2)?));
    }
    let orientation_spread_deg = normals
        .iter()
        .enumerate()
        .flat_map(|(i, a)| normals[i + 1..].iter().map(move |b| a.angle(b).to_degrees()))
        .fold(0.0, f64::max);
    Ok(Solved {
        camera_matrix: k,
        distortion: d,
        rms,
        per_view,
        orientation_spread_deg,
    })
}

/// Calibrates from files and folders (the `calibrate-camera` command and the
/// pipeline), each board searched as `search` says.
pub fn calibrate_from(
    inputs: &[PathBuf],
    inner_corners: [u32; 2],
    square_mm: f64,
    search: Search,
) -> Result<CameraCalibration, CalibrationError> {
    let images = collect_images(inputs)?;
    calibrate(&images, inner_corners, square_mm, SubPix::default(), search)
}

/// Convenience for a single folder.
pub fn calibrate_folder(
    folder: &Path,
    inner_corners: [u32; 2],
    square_mm: f64,
) -> Result<CameraCalibration, CalibrationError> {
    calibrate_from(&[folder.to_path_buf()], inner_corners, square_mm, Search::Thorough)
}

/// What the added views changed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Refinement {
    /// The intrinsics from the calibration views alone.
    pub views_only: crate::io::camera_model::CameraIntrinsics,
    /// Added views used.
    pub boards_used: usize,
    /// Added views left out, each with its reason.
    pub boards_dropped: Vec<String>,
    /// Added views left out as a repeat of an earlier one (`camera_refinement::repeats`).
    pub boards_repeated: usize,
    /// RMS reprojection error over the added views used, px.
    pub boards_rms_px: f64,
    /// The SD of each intrinsic (`fx, fy, cx, cy` px, `k1, k2, p1, p2, k3`)
    /// from every view's corners, the noise their residuals show.
    pub intrinsics_sd: Option<[f64; super::projection::INTRINSICS]>,
    /// What every view (calibration and frames' boards) knows of the intrinsics.
    #[serde(skip)]
    pub intrinsics_information: Option<super::projection::KMatrix>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Board corners seen by a known camera from boards tilted by `tilt_deg` at most.
    fn views(
        tilt_deg: f64,
    ) -> (
        Vector<Vector<opencv::core::Point3f>>,
        Vector<Vector<opencv::core::Point2f>>,
    ) {
        let layout = BoardLayout {
            inner_corners: [9, 6],
            square_mm: 30.0,
            id_dots: 0,
        };
        let board = object_points(&layout.corners_in_board_mm());
        let k = Mat::from_slice_2d(&[[1000.0, 0.0, 640.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]]).unwrap();
        let mut object = Vector::new();
        let mut image = Vector::new();
        for i in 0..8 {
            let a = (i as f64 / 7.0 - 0.5) * tilt_deg.to_radians();
            let r = [a, -0.7 * a, 0.1 * i as f64];
            let t = [-120.0 + 10.0 * i as f64, -75.0, 900.0 + 40.0 * i as f64];
            let rvec = Mat::from_slice(&r).unwrap();
            let tvec = Mat::from_slice(&t).unwrap();
            let mut projected = Vector::<opencv::core::Point2f>::new();
            calib3d::project_points_def(&board, &rvec, &tvec, &k, &Mat::default(), &mut projected).unwrap();
            object.push(board.clone());
            image.push(projected);
        }
        (object, image)
    }

    #[test]
    fn the_orientation_spread_of_the_views_is_measured() {
        let (object, image) = views(40.0);
        let wide = solve(&object, &image, Size::new(1280, 720)).unwrap();
        assert!(wide.orientation_spread_deg > 30.0, "{}", wide.orientation_spread_deg);
        let (object, image) = views(2.0);
        let flat = solve(&object, &image, Size::new(1280, 720)).unwrap();
        assert!(
            flat.orientation_spread_deg < MIN_ORIENTATION_SPREAD_DEG,
            "{}",
            flat.orientation_spread_deg
        );
    }

    #[test]
    fn a_repeated_view_is_found() {
        let a = vec![[10.0, 20.0], [30.0, 40.0]];
        let moved = vec![[10.3, 20.0], [30.0, 40.2]];
        let other = vec![[15.0, 20.0], [30.0, 40.0]];
        assert_eq!(duplicate_of(&moved, std::slice::from_ref(&a)), Some(0));
        assert_eq!(duplicate_of(&other, &[a]), None);
    }
}
