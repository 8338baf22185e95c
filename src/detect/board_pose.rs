//! Stage 2: the poses of the probe board (M) and the phantom board (P) in one photo.
//!
//! Both boards are in the same image and may have the same pattern, so boards are
//! found one at a time: each found board is identified, then painted over before
//! the next search. Identification uses the printed dots (see [`crate::detect::board`]):
//! among the re-orderings of the detected corner grid that keep the board
//! right-handed, the one with a dot beside its origin corner fixes the origin (the
//! same physical corner in every frame); the number of dots tells probe from
//! phantom. The pose is OpenCV's iterative PnP on all corners, with its RMS
//! reprojection error.

use nalgebra::{DMatrix, Matrix3, Point2, Vector3};
use opencv::core::{Mat, Point, Scalar, Vector};
use opencv::prelude::*;
use opencv::{calib3d, imgproc};

use crate::core::geometry::{rigid_from_parts, Rigid};
use crate::detect::aruco;
use crate::detect::board::{ArucoLayout, BoardLayout, CharucoLayout, PrintedBoard};
use crate::detect::corners::{detect_chessboard_reduced, image_points, object_points, SubPix};
use crate::io::camera_model::CameraIntrinsics;

/// One board seen in one photo.
#[derive(Debug, Clone)]
pub struct BoardObservation {
    pub camera_T_board: Rigid,
    pub reprojection_rms_px: f64,
    /// Inner corners in canonical order (origin first), pixels.
    pub corners_px: Vec<[f64; 2]>,
}

/// Both boards of one frame.
#[derive(Debug, Clone)]
pub struct FramePoses {
    pub camera_T_marker: BoardObservation,
    pub camera_T_phantom: BoardObservation,
}

/// A checkerboard rig as the detector needs it.
#[derive(Debug, Clone, Copy)]
pub struct RigLayout {
    pub probe: BoardLayout,
    pub phantom: BoardLayout,
}

/// Boards are searched on photos reduced to this size (corners refined at full size).
pub const SEARCH_MAX_SIDE_PX: i32 = 1000;

/// Reprojection error above which a pose is not trusted, px.
pub const MAX_REPROJECTION_RMS_PX: f64 = 1.0;

/// Why a photo gives no pair of board poses. `board` is `probe` or `phantom`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoardRejection {
    #[error("a {}x{} board was found but no identification dot beside any of its corners", .inner_corners[0], .inner_corners[1])]
    NoOriginDot { inner_corners: [u32; 2] },
    #[error("a {}x{} board shows {candidates} candidate origin dots: ambiguous", .inner_corners[0], .inner_corners[1])]
    AmbiguousOrigin { inner_corners: [u32; 2], candidates: usize },
    #[error("found a {}x{} board with {dots} identification dot(s), which no board of the rig has", .inner_corners[0], .inner_corners[1])]
    UnknownBoard { inner_corners: [u32; 2], dots: u8 },
    #[error("found the {board} board twice")]
    FoundTwice { board: &'static str },
    #[error("{board} board: {found} of {total} markers found (need {needed})")]
    TooFewMarkers {
        board: &'static str,
        found: usize,
        total: usize,
        needed: usize,
    },
    #[error("{board} board: no pose from {points} points")]
    NoPose { board: &'static str, points: usize },
    #[error("{board} board: {found} of {total} ChArUco corners from {markers} markers (need {needed})")]
    TooFewCorners {
        board: &'static str,
        found: usize,
        total: usize,
        markers: usize,
        needed: usize,
    },
    /// Both planar-PnP solutions explain the corners about equally.
    #[error("{board} board: ambiguous pose, two solutions {apart_deg:.1}° apart fit with {:.2} and {:.2} px", .errors_px[0], .errors_px[1])]
    AmbiguousPose {
        board: &'static str,
        apart_deg: f64,
        errors_px: [f64; 2],
    },
    #[error("{board} board pose has a reprojection error of {rms_px:.2} px (limit {limit_px} px)")]
    Reprojection {
        board: &'static str,
        rms_px: f64,
        limit_px: f64,
    },
    /// The marker dictionary or the marker detection failed.
    #[error("{0}")]
    Markers(String),
    #[error("boards not found")]
    NotFound,
    #[error("the rig mixes board kinds")]
    MixedRig,
    #[error("probe board not found")]
    ProbeBoardMissing,
    #[error("phantom board not found")]
    PhantomBoardMissing,
    #[error("neither board found")]
    NeitherBoard,
}

type IndexMap = fn(usize, usize, usize, usize) -> (usize, usize);

/// Re-orderings of a detected `cols x rows` grid: canonical (i, j) -> detected (i', j').
fn grid_symmetries(square: bool) -> Vec<(&'static str, IndexMap)> {
    let mut maps: Vec<(&'static str, IndexMap)> = vec![
        ("identity", |i, j, _, _| (i, j)),
        ("rotate 180", |i, j, c, r| (c - 1 - i, r - 1 - j)),
        ("mirror x", |i, j, c, _| (c - 1 - i, j)),
        ("mirror y", |i, j, _, r| (i, r - 1 - j)),
    ];
    if square {
        maps.push(("transpose", |i, j, _, _| (j, i)));
        maps.push(("rotate 90", |i, j, c, _| (c - 1 - j, i)));
        maps.push(("rotate 270", |i, j, _, r| (j, r - 1 - i)));
        maps.push(("anti-transpose", |i, j, c, r| (c - 1 - j, r - 1 - i)));
    }
    maps
}

/// Homography from board millimetres to normalised image coordinates (DLT).
fn homography(board_mm: &[Point2<f64>], normalized: &[(f64, f64)]) -> Option<Matrix3<f64>> {
    let n = board_mm.len();
    let scale = 0.01;
    let mut a = DMatrix::<f64>::zeros(2 * n, 9);
    for (k, (b, m)) in board_mm.iter().zip(normalized).enumerate() {
        let (x, y) = (b.x * scale, b.y * scale);
        let (u, v) = *m;
        let rows = [
            [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u],
            [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v],
        ];
        for (r, row) in rows.iter().enumerate() {
            for (c, value) in row.iter().enumerate() {
                a[(2 * k + r, c)] = *value;
            }
        }
    }
    let svd = (a.transpose() * &a).symmetric_eigen();
    let (min_index, _) = svd.eigenvalues.iter().enumerate().min_by(|x, y| x.1.total_cmp(y.1))?;
    let h = svd.eigenvectors.column(min_index);
    let m = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let unscale = Matrix3::new(scale, 0.0, 0.0, 0.0, scale, 0.0, 0.0, 0.0, 1.0);
    Some(m * unscale)
}

fn apply_h(h: &Matrix3<f64>, p: Point2<f64>) -> (f64, f64) {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    (q.x / q.z, q.y / q.z)
}

fn to_pixel(camera: &CameraIntrinsics, normalized: (f64, f64)) -> [f64; 2] {
    let (xd, yd) = camera.distort_normalized(normalized.0, normalized.1);
    [camera.fx() * xd + camera.cx(), camera.fy() * yd + camera.cy()]
}

fn bilinear(image: &Mat, p: [f64; 2]) -> Option<f64> {
    let (w, h) = (image.cols(), image.rows());
    let (x, y) = (p[0], p[1]);
    if x < 0.0 || y < 0.0 || x >= (w - 1) as f64 || y >= (h - 1) as f64 {
        return None;
    }
    let (x0, y0) = (x.floor() as i32, y.floor() as i32);
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |xx: i32, yy: i32| image.at_2d::<u8>(yy, xx).map(|v| *v as f64).ok();
    let top = at(x0, y0)? * (1.0 - fx) + at(x0 + 1, y0)? * fx;
    let bottom = at(x0, y0 + 1)? * (1.0 - fx) + at(x0 + 1, y0 + 1)? * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

/// Mean grey level of a small disc of the board (radius in mm) seen through `h`.
fn sample_disc(
    image: &Mat,
    camera: &CameraIntrinsics,
    h: &Matrix3<f64>,
    centre: Point2<f64>,
    radius_mm: f64,
) -> Option<f64> {
    let mut sum = 0.0;
    let mut count = 0.0;
    for dy in -2..=2 {
        for dx in -2..=2 {
            let p = Point2::new(
                centre.x + dx as f64 * radius_mm / 2.0,
                centre.y + dy as f64 * radius_mm / 2.0,
            );
            sum += bilinear(image, to_pixel(camera, apply_h(h, p)))?;
            count += 1.0;
        }
    }
    Some(sum / count)
}

/// A found grid, ordered and identified.
struct Identified {
    corners_px: Vec<[f64; 2]>,
    dots: u8,
    paper_px: [[f64; 2]; 4],
}

fn identify(
    image: &Mat,
    camera: &CameraIntrinsics,
    detected: &[[f64; 2]],
    inner_corners: [u32; 2],
    square_mm: f64,
) -> Result<Identified, BoardRejection> {
    let (cols, rows) = (inner_corners[0] as usize, inner_corners[1] as usize);
    let layout = BoardLayout {
        inner_corners,
        square_mm,
        id_dots: 0,
    };
    let board_mm = layout.corners_in_board_mm();
    let normalized: Vec<(f64, f64)> = detected.iter().map(|p| camera.undistort_pixel(*p)).collect();
    let s = square_mm;
    let [dot1, dot2] = BoardLayout::dot_slots_mm(s);
    let mut candidates = Vec::new();
    for (name, map) in grid_symmetries(cols == rows) {
        let ordered: Vec<usize> = (0..rows)
            .flat_map(|j| (0..cols).map(move |i| (i, j)))
            .map(|(i, j)| {
                let (di, dj) = map(i, j, cols, rows);
                dj * cols + di
            })
            .collect();
        let ordered_norm: Vec<(f64, f64)> = ordered.iter().map(|&k| normalized[k]).collect();
        let Some(h) = homography(&board_mm, &ordered_norm) else {
            continue;
        };
        let o = apply_h(&h, Point2::new(0.0, 0.0));
        let ex = apply_h(&h, Point2::new(s, 0.0));
        let ey = apply_h(&h, Point2::new(0.0, s));
        let cross = (ex.0 - o.0) * (ey.1 - o.1) - (ex.1 - o.1) * (ey.0 - o.0);
        if cross <= 0.0 {
            continue; // a mirror image: not a right-handed board seen from the front
        }
        let r = 0.12 * s;
        let white = sample_disc(image, camera, &h, Point2::new(-1.5 * s, 0.5 * s), r);
        let black = sample_disc(image, camera, &h, Point2::new(-0.5 * s, -0.5 * s), r);
        let first = sample_disc(image, camera, &h, dot1, r);
        let second = sample_disc(image, camera, &h, dot2, r);
        let (Some(white), Some(black), Some(first), Some(second)) = (white, black, first, second) else {
            continue;
        };
        let contrast = white - black;
        if contrast < 20.0 {
            continue;
        }
        let darkness = |v: f64| (white - v) / contrast;
        candidates.push((name, ordered, h, darkness(first), darkness(second)));
    }
    let with_dot: Vec<_> = candidates.iter().filter(|c| c.3 > 0.5).collect();
    match with_dot.as_slice() {
        [one] => {
            let (_, ordered, h, _, second) = one;
            let [x0, y0, x1, y1] = BoardLayout {
                inner_corners,
                square_mm,
                id_dots: 0,
            }
            .paper_bounds_mm();
            let paper =
                [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].map(|(x, y)| to_pixel(camera, apply_h(h, Point2::new(x, y))));
            Ok(Identified {
                corners_px: ordered.iter().map(|&k| detected[k]).collect(),
                dots: if *second > 0.5 { 2 } else { 1 },
                paper_px: paper,
            })
        }
        [] => Err(BoardRejection::NoOriginDot { inner_corners }),
        many => Err(BoardRejection::AmbiguousOrigin {
            inner_corners,
            candidates: many.len(),
        }),
    }
}

/// Pose of a board from its points (board frame, mm) and their pixels: iterative
/// PnP, optionally started from a guess; RMS reprojection error.
pub(super) fn pnp(
    camera: &CameraIntrinsics,
    object: &Vector<opencv::core::Point3f>,
    corners_px: &[[f64; 2]],
    guess: Option<(&Mat, &Mat)>,
) -> opencv::Result<BoardObservation> {
    let image = image_points(corners_px);
    let k = camera.camera_matrix_mat()?;
    let d = camera.distortion_mat()?;
    let (mut rvec, mut tvec) = match guess {
        Some((r, t)) => (r.try_clone()?, t.try_clone()?),
        None => (Mat::default(), Mat::default()),
    };
    calib3d::solve_pnp(
        object,
        &image,
        &k,
        &d,
        &mut rvec,
        &mut tvec,
        guess.is_some(),
        calib3d::SOLVEPNP_ITERATIVE,
    )?;
    let rms = reprojection_rms(object, &image, &rvec, &tvec, &k, &d)?;
    Ok(BoardObservation {
        camera_T_board: rigid_from_rvec_tvec(&rvec, &tvec)?,
        reprojection_rms_px: rms,
        corners_px: corners_px.to_vec(),
    })
}

fn reprojection_rms(
    object: &Vector<opencv::core::Point3f>,
    image: &Vector<opencv::core::Point2f>,
    rvec: &Mat,
    tvec: &Mat,
    k: &Mat,
    d: &Mat,
) -> opencv::Result<f64> {
    let mut projected = Vector::<opencv::core::Point2f>::new();
    calib3d::project_points_def(object, rvec, tvec, k, d, &mut projected)?;
    let sum: f64 = projected
        .iter()
        .zip(image.iter())
        .map(|(p, m)| ((p.x - m.x) as f64).powi(2) + ((p.y - m.y) as f64).powi(2))
        .sum();
    Ok((sum / image.len().max(1) as f64).sqrt())
}

pub(super) fn rigid_from_rvec_tvec(rvec: &Mat, tvec: &Mat) -> opencv::Result<Rigid> {
    let mut r = Mat::default();
    calib3d::rodrigues_def(rvec, &mut r)?;
    let rot = Matrix3::from_fn(|i, j| *r.at_2d::<f64>(i as i32, j as i32).unwrap_or(&0.0));
    let t = Vector3::new(*tvec.at::<f64>(0)?, *tvec.at::<f64>(1)?, *tvec.at::<f64>(2)?);
    Ok(rigid_from_parts(&rot, &t))
}

/// A checkerboard's pose from its identified corners (canonical order).
pub fn solve_pose(
    camera: &CameraIntrinsics,
    layout: &BoardLayout,
    corners_px: &[[f64; 2]],
) -> opencv::Result<BoardObservation> {
    pnp(camera, &object_points(&layout.corners_in_board_mm()), corners_px, None)
}

/// How a rig's boards are found.
#[derive(Debug, Clone, PartialEq)]
pub enum Detection {
    Checkerboard,
    Aruco {
        subpixel_half_window_px: u32,
        min_markers: usize,
    },
    Charuco {
        /// Fewest chessboard corners of a board for its pose.
        min_corners: usize,
        /// OpenCV detector parameters file; `None`: OpenCV's defaults.
        detector_params: Option<std::path::PathBuf>,
    },
}

/// The rig's two boards as printed, and how to find them.
#[derive(Debug, Clone, PartialEq)]
pub struct RigBoards {
    pub probe: PrintedBoard,
    pub phantom: PrintedBoard,
    pub detection: Detection,
}

impl RigBoards {
    /// The boards a rig describes.
    pub fn from_rig(rig: &crate::spec::rig::Rig) -> Result<RigBoards, aruco::ArucoError> {
        use crate::spec::rig::Rig;
        Ok(match rig {
            Rig::Checkerboard {
                probe_board,
                phantom_board,
            } => {
                let layout = |b: &crate::spec::rig::Board| {
                    PrintedBoard::Checkerboard(BoardLayout {
                        inner_corners: b.inner_corners,
                        square_mm: b.square_mm,
                        id_dots: b.id_dots,
                    })
                };
                RigBoards {
                    probe: layout(probe_board),
                    phantom: layout(phantom_board),
                    detection: Detection::Checkerboard,
                }
            }
            Rig::Aruco {
                dictionary,
                probe_board,
                phantom_board,
                subpixel_half_window_px,
                min_markers,
            } => {
                let layout = |b: &crate::spec::rig::ArucoBoard| {
                    ArucoLayout::new(dictionary, b.markers, b.marker_mm, b.separation_mm, b.first_id)
                        .map(PrintedBoard::Aruco)
                };
                RigBoards {
                    probe: layout(probe_board)?,
                    phantom: layout(phantom_board)?,
                    detection: Detection::Aruco {
                        subpixel_half_window_px: *subpixel_half_window_px,
                        min_markers: *min_markers,
                    },
                }
            }
            Rig::Charuco {
                probe_board,
                phantom_board,
                min_corners,
                detector_params,
            } => RigBoards {
                probe: PrintedBoard::Charuco(CharucoLayout::new(probe_board)?),
                phantom: PrintedBoard::Charuco(CharucoLayout::new(phantom_board)?),
                detection: Detection::Charuco {
                    min_corners: *min_corners,
                    detector_params: detector_params.as_ref().map(std::path::PathBuf::from),
                },
            },
        })
    }
}

/// Finds, identifies and poses both checkerboards. The inner `Err` is a frame rejection reason.
pub fn estimate_checkerboards(
    image: &Mat,
    camera: &CameraIntrinsics,
    rig: &RigLayout,
) -> opencv::Result<Result<FramePoses, BoardRejection>> {
    let mut work = image.try_clone()?;
    let subpix = SubPix {
        half_window_px: 5,
        max_iterations: 40,
        epsilon_px: 0.01,
    };
    let mut found: [Option<BoardObservation>; 2] = [None, None];
    let boards = [(rig.probe, "probe"), (rig.phantom, "phantom")];
    // One board per search; a found board is painted over before the next search.
    for _ in 0..2 {
        // Larger patterns first, so that a small pattern is not found inside a large board.
        let mut wanted: Vec<BoardLayout> = boards
            .iter()
            .zip(&found)
            .filter(|(_, f)| f.is_none())
            .map(|(b, _)| b.0)
            .collect();
        wanted.sort_by_key(|b| std::cmp::Reverse(b.inner_corners[0] * b.inner_corners[1]));
        wanted.dedup_by_key(|b| b.inner_corners);
        let mut detection = None;
        for pattern in wanted {
            if let Some(corners) = detect_chessboard_reduced(&work, pattern.inner_corners, subpix, SEARCH_MAX_SIDE_PX)?
            {
                detection = Some((pattern, corners));
                break;
            }
        }
        let Some((pattern, corners)) = detection else { break };
        let identified = match identify(image, camera, &corners, pattern.inner_corners, pattern.square_mm) {
            Ok(i) => i,
            Err(reason) => return Ok(Err(reason)),
        };
        let Some(slot) = boards
            .iter()
            .position(|(b, _)| b.id_dots == identified.dots && b.inner_corners == pattern.inner_corners)
        else {
            return Ok(Err(BoardRejection::UnknownBoard {
                inner_corners: pattern.inner_corners,
                dots: identified.dots,
            }));
        };
        let (layout, name) = boards[slot];
        if found[slot].is_some() {
            return Ok(Err(BoardRejection::FoundTwice { board: name }));
        }
        let observation = solve_pose(camera, &layout, &identified.corners_px)?;
        if observation.reprojection_rms_px > MAX_REPROJECTION_RMS_PX {
            return Ok(Err(BoardRejection::Reprojection {
                board: name,
                rms_px: observation.reprojection_rms_px,
                limit_px: MAX_REPROJECTION_RMS_PX,
            }));
        }
        let polygon: Vector<Point> = identified
            .paper_px
            .iter()
            .map(|p| Point::new(p[0].round() as i32, p[1].round() as i32))
            .collect();
        imgproc::fill_convex_poly_def(&mut work, &polygon, Scalar::all(128.0))?;
        found[slot] = Some(observation);
    }
    let [probe, phantom] = found;
    Ok(match (probe, phantom) {
        (Some(m), Some(p)) => Ok(FramePoses {
            camera_T_marker: m,
            camera_T_phantom: p,
        }),
        (None, Some(_)) => Err(BoardRejection::ProbeBoardMissing),
        (Some(_), None) => Err(BoardRejection::PhantomBoardMissing),
        (None, None) => Err(BoardRejection::NeitherBoard),
    })
}
