//! The camera's intrinsics solved again with more views of known boards: the
//! calibration views and, as views of their own, the boards the frames' photos
//! show. Every board view brings its own pose as an unknown, and a board seen at
//! many tilts (the probe's, over a sweep) adds the foreshortening that pins the
//! focal length and the principal point down. A board seen again where an
//! earlier photo saw it (the phantom's, in every frame of a fixed camera) is
//! that view again and counted once ([`repeats`]): its photos differ by the
//! sensor's noise only, while the corner detector's sub-pixel error and the
//! lens's departures from its model at those pixels repeat in every one.
//!
//! The solve is the one `calibrateCamera` (flags 0) does, the sum of squared
//! reprojection errors over the nine intrinsics and every view's pose, by
//! Levenberg–Marquardt; but with the poses eliminated per view (the normal
//! equations' Schur complement), so a hundred views cost milliseconds where
//! OpenCV's dense Jacobian costs tens of seconds.

use nalgebra::{DVector, Matrix6, Point2, SMatrix, Vector6};

use super::board::BoardLayout;
use super::board_pose::pnp;
use super::camera_calibration::{
    max_shift_px, CalibrationError, CameraCalibration, DUPLICATE_VIEW_PX, OUTLIER_VIEW_FLOOR_PX, OUTLIER_VIEW_RATIO,
};
use super::corners::object_points;
use super::projection::{board_jacobians, intrinsics_vector, pose_at, projections, with_intrinsics, INTRINSICS};
use crate::core::geometry::Rigid;
use crate::io::camera_model::CameraIntrinsics;

pub use super::projection::KMatrix;
type KByPose = SMatrix<f64, INTRINSICS, 6>;
type KVector = SMatrix<f64, INTRINSICS, 1>;

/// The most Levenberg–Marquardt iterations of the bundle.
pub const MAX_ITERATIONS: usize = 100;

/// A bundle's solution: the intrinsics, each view's pose, each view's RMS (px).
#[derive(Debug, Clone)]
pub struct Bundle {
    pub camera: CameraIntrinsics,
    pub camera_T_views: Vec<Rigid>,
    pub per_view_rms_px: Vec<f64>,
    /// RMS over every corner, px.
    pub rms_px: f64,
    pub iterations: usize,
    /// What the views know of the intrinsics at the solution (see [`information`]).
    pub intrinsics_information: Option<KMatrix>,
}

/// The information `views` hold on the intrinsics at `camera` and `poses`
/// (each view's pose marginalised: the normal equations' Schur complement),
/// with the corner noise estimated from the residuals (their sum of squares
/// over the degrees of freedom left: two per corner, less the nine intrinsics
/// and six per view). `None` if a corner is behind the camera, a view's pose
/// is not determined, or no degree of freedom is left.
pub fn information(camera: &CameraIntrinsics, poses: &[Rigid], views: &[BoardView]) -> Option<KMatrix> {
    let mut s = KMatrix::zeros();
    let mut squares = 0.0;
    let mut corners = 0usize;
    for (pose, view) in poses.iter().zip(views) {
        squares += residuals(camera, pose, view)?.norm_squared();
        corners += view.corners_px.len();
        let (jp, jk) = board_jacobians(camera, pose, &view.corners_mm)?;
        let v = Matrix6::from_iterator((jp.transpose() * &jp).iter().copied()).try_inverse()?;
        let w = KByPose::from_iterator((jk.transpose() * &jp).iter().copied());
        s += KMatrix::from_iterator((jk.transpose() * &jk).iter().copied()) - w * v * w.transpose();
    }
    let dof = (2 * corners)
        .checked_sub(INTRINSICS + 6 * views.len())
        .filter(|d| *d > 0)?;
    let variance = squares / dof as f64;
    (variance > 0.0 && variance.is_finite()).then(|| s / variance)
}

/// The standard deviations the information `info` gives each intrinsic, or
/// `None` if it leaves one undetermined.
pub fn intrinsics_sd(info: &KMatrix) -> Option<[f64; INTRINSICS]> {
    // Scaled so that focal lengths (px) and distortion (unitless) invert alike.
    let scale = KMatrix::from_diagonal(&info.diagonal().map(|d| 1.0 / d.max(f64::MIN_POSITIVE).sqrt()));
    let cov = scale * (scale * info * scale).try_inverse()? * scale;
    let mut out = [0.0; INTRINSICS];
    for (k, o) in out.iter_mut().enumerate() {
        *o = cov[(k, k)].sqrt();
        if !o.is_finite() {
            return None;
        }
    }
    Some(out)
}

/// One view's residuals (projection minus measured, `[u0, v0, …]`), or `None`
/// if a corner falls behind the camera.
fn residuals(camera: &CameraIntrinsics, pose: &Rigid, view: &BoardView) -> Option<DVector<f64>> {
    let projected = projections(camera, pose, &view.corners_mm)?;
    Some(DVector::from_iterator(
        projected.len(),
        projected
            .iter()
            .zip(view.corners_px.iter().flatten())
            .map(|(p, m)| p - m),
    ))
}

fn cost(camera: &CameraIntrinsics, poses: &[Rigid], views: &[BoardView]) -> Option<f64> {
    let mut sum = 0.0;
    for (pose, view) in poses.iter().zip(views) {
        sum += residuals(camera, pose, view)?.norm_squared();
    }
    sum.is_finite().then_some(sum)
}

/// Minimises the reprojection error of `views` over the intrinsics and every
/// view's pose, from `camera` and `poses`. `None` if a start is behind the camera.
pub fn bundle(camera: &CameraIntrinsics, poses: Vec<Rigid>, views: &[BoardView]) -> Option<Bundle> {
    let mut camera = camera.clone();
    let mut poses = poses;
    let mut current = cost(&camera, &poses, views)?;
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        // Normal equations, block by block: intrinsics (U), pose of view i (V_i), coupling (W_i).
        let mut u = KMatrix::zeros();
        let mut gk = KVector::zeros();
        let mut blocks = Vec::with_capacity(views.len());
        for (pose, view) in poses.iter().zip(views) {
            let e = residuals(&camera, pose, view)?;
            let (jp, jk) = board_jacobians(&camera, pose, &view.corners_mm)?;
            let v = Matrix6::from_iterator((jp.transpose() * &jp).iter().copied());
            let w = KByPose::from_iterator((jk.transpose() * &jp).iter().copied());
            let gp = Vector6::from_iterator((jp.transpose() * &e).iter().copied());
            u += KMatrix::from_iterator((jk.transpose() * &jk).iter().copied());
            gk += KVector::from_iterator((jk.transpose() * &e).iter().copied());
            blocks.push((v, w, gp));
        }
        let step = loop {
            let damp6 = |m: &Matrix6<f64>| m + Matrix6::from_diagonal(&(m.diagonal() * lambda));
            let mut s = u + KMatrix::from_diagonal(&(u.diagonal() * lambda));
            let mut b = gk;
            let mut inverses = Vec::with_capacity(blocks.len());
            for (v, w, gp) in &blocks {
                let vi = damp6(v).try_inverse()?;
                s -= w * vi * w.transpose();
                b -= w * vi * gp;
                inverses.push(vi);
            }
            let dk = -s.lu().solve(&b)?;
            let dposes: Vec<Vector6<f64>> = blocks
                .iter()
                .zip(&inverses)
                .map(|((_, w, gp), vi)| -vi * (gp + w.transpose() * dk))
                .collect();
            let k = with_intrinsics(&camera, &(intrinsics_vector(&camera) + dk));
            let moved: Vec<Rigid> = poses.iter().zip(&dposes).map(|(p, d)| pose_at(p, d)).collect();
            match cost(&k, &moved, views) {
                Some(c) if c <= current => {
                    lambda = (lambda / 10.0).max(1e-12);
                    break Some((k, moved, c));
                }
                _ if lambda < 1e12 => lambda *= 10.0,
                _ => break None,
            }
        };
        let Some((k, moved, c)) = step else { break };
        let decrease = current - c;
        camera = k;
        poses = moved;
        current = c;
        if decrease <= 1e-12 * current.max(f64::MIN_POSITIVE) {
            break;
        }
    }
    let per_view_rms_px = poses
        .iter()
        .zip(views)
        .map(|(p, v)| residuals(&camera, p, v).map(|e| (e.norm_squared() / v.corners_px.len() as f64).sqrt()))
        .collect::<Option<Vec<f64>>>()?;
    let corners: usize = views.iter().map(|v| v.corners_px.len()).sum();
    Some(Bundle {
        intrinsics_information: information(&camera, &poses, views),
        camera,
        camera_T_views: poses,
        per_view_rms_px,
        rms_px: (current / corners.max(1) as f64).sqrt(),
        iterations,
    })
}

/// Each view's pose under `camera` (OpenCV's iterative PnP).
fn initial_poses(camera: &CameraIntrinsics, views: &[BoardView]) -> opencv::Result<Vec<Rigid>> {
    views
        .iter()
        .map(|v| pnp(camera, &object_points(&v.corners_mm), &v.corners_px, None).map(|o| o.camera_T_board))
        .collect()
}

/// For each view, the earlier view it repeats, if any: one of the same board
/// points (in its frame, in the same order) with every corner within
/// [`DUPLICATE_VIEW_PX`] of that view's. Only views that repeat none are
/// compared with, so the first photo of a static board stands for all of them.
pub fn repeats(views: &[BoardView]) -> Vec<Option<usize>> {
    let mut distinct: Vec<usize> = Vec::new();
    let mut out = Vec::with_capacity(views.len());
    for (i, view) in views.iter().enumerate() {
        let same = |k: &usize| {
            let earlier = &views[*k];
            earlier.corners_mm == view.corners_mm
                && earlier.corners_px.len() == view.corners_px.len()
                && max_shift_px(&earlier.corners_px, &view.corners_px) < DUPLICATE_VIEW_PX
        };
        let repeated = distinct.iter().find(|k| same(k)).copied();
        if repeated.is_none() {
            distinct.push(i);
        }
        out.push(repeated);
    }
    out
}

/// One more view of a known board.
#[derive(Debug, Clone)]
pub struct BoardView {
    /// Names the view in the report, e.g. `frame 12, probe board`.
    pub label: String,
    /// The board's points in its own frame, mm.
    pub corners_mm: Vec<Point2<f64>>,
    /// Their pixels, in the same order.
    pub corners_px: Vec<[f64; 2]>,
}

pub use super::camera_calibration::Refinement;

/// The calibration's own views, in the order solved.
fn calibration_views(calibration: &CameraCalibration) -> Vec<BoardView> {
    let layout = BoardLayout {
        inner_corners: calibration.inner_corners,
        square_mm: calibration.square_mm,
        id_dots: 0,
    };
    calibration
        .used_corners_px
        .iter()
        .enumerate()
        .map(|(i, corners)| BoardView {
            label: format!("calibration view {i}"),
            corners_mm: layout.corners_in_board_mm(),
            corners_px: corners.clone(),
        })
        .collect()
}

/// What the calibration knows of its intrinsics: every view it was solved
/// with (the frames' boards too when they refined it), see [`information`].
/// `None` when the calibration's corners are not at hand (a calibration read
/// back from a file) or they leave an intrinsic undetermined.
pub fn calibration_information(calibration: &CameraCalibration) -> Option<KMatrix> {
    if let Some(refined) = &calibration.refined {
        return refined.intrinsics_information;
    }
    let views = calibration_views(calibration);
    if views.is_empty() {
        return None;
    }
    let poses = initial_poses(&calibration.intrinsics, &views).ok()?;
    information(&calibration.intrinsics, &poses, &views)
}

/// `calibration` solved again by [`bundle`] (from its own intrinsics) with
/// `boards` as more views, each counted once ([`repeats`]: a view of a board
/// where an earlier one saw it is left out). A board view whose RMS is above [`OUTLIER_VIEW_RATIO`] times the
/// median of the added views (and above [`OUTLIER_VIEW_FLOOR_PX`]) is dropped,
/// once, and the camera solved again, as for the calibration views.
pub fn refine_with_boards(
    calibration: &CameraCalibration,
    boards: &[BoardView],
) -> Result<CameraCalibration, CalibrationError> {
    let own = calibration_views(calibration);
    let n_own = own.len();
    let start = &calibration.intrinsics;
    let solve_with = |kept: &[&BoardView]| -> Result<Bundle, CalibrationError> {
        let views: Vec<BoardView> = own.iter().cloned().chain(kept.iter().map(|b| (*b).clone())).collect();
        let poses = initial_poses(start, &views)?;
        bundle(start, poses, &views).ok_or(CalibrationError::Diverged)
    };
    let repeated = repeats(boards);
    let mut kept: Vec<&BoardView> = boards
        .iter()
        .zip(&repeated)
        .filter(|(_, r)| r.is_none())
        .map(|(b, _)| b)
        .collect();
    let boards_repeated = boards.len() - kept.len();
    let mut dropped = Vec::new();
    let mut solved = solve_with(&kept)?;
    let mut added: Vec<f64> = solved.per_view_rms_px[n_own..].to_vec();
    if !added.is_empty() {
        let mut sorted = added.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let limit = (OUTLIER_VIEW_RATIO * median).max(OUTLIER_VIEW_FLOOR_PX);
        if added.iter().any(|&rms| rms > limit) {
            let mut next = Vec::new();
            for (b, &rms) in kept.iter().zip(&added) {
                if rms > limit {
                    dropped.push(format!(
                        "{}: RMS {rms:.3} px is above {limit:.3} px ({OUTLIER_VIEW_RATIO} times the median {median:.3} px)",
                        b.label
                    ));
                } else {
                    next.push(*b);
                }
            }
            kept = next;
            solved = solve_with(&kept)?;
            added = solved.per_view_rms_px[n_own..].to_vec();
        }
    }
    let squares: f64 = kept
        .iter()
        .zip(&added)
        .map(|(b, rms)| rms * rms * b.corners_px.len() as f64)
        .sum();
    let corners: usize = kept.iter().map(|b| b.corners_px.len()).sum();
    let mut out = calibration.clone();
    out.intrinsics.camera_matrix = solved.camera.camera_matrix;
    out.intrinsics.distortion = solved.camera.distortion;
    out.intrinsics.rms_px = Some(solved.rms_px);
    out.intrinsics.per_view_rms_px = solved.per_view_rms_px[..n_own].to_vec();
    let mut own_rms = solved.per_view_rms_px[..n_own].iter();
    for view in out.views.iter_mut().filter(|v| v.used) {
        view.rms_px = own_rms.next().copied();
    }
    out.refined = Some(Refinement {
        views_only: calibration.intrinsics.clone(),
        boards_used: kept.len(),
        boards_dropped: dropped,
        boards_repeated,
        boards_rms_px: (squares / corners.max(1) as f64).sqrt(),
        intrinsics_sd: solved.intrinsics_information.as_ref().and_then(intrinsics_sd),
        intrinsics_information: solved.intrinsics_information,
    });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::core::rng::Rng;
    use nalgebra::Vector3;

    fn truth() -> CameraIntrinsics {
        crate::detect::projection::rendered_camera()
    }

    /// Views of a 9x6 board of 30 mm at varied tilts, corners projected by
    /// `camera` with Gaussian noise of `sd_px`.
    fn views(camera: &CameraIntrinsics, sd_px: f64, count: usize, seed: u64) -> Vec<BoardView> {
        let layout = BoardLayout {
            inner_corners: [9, 6],
            square_mm: 30.0,
            id_dots: 0,
        };
        let mut rng = Rng::new(seed);
        (0..count)
            .map(|k| {
                let a = k as f64 * 0.7;
                let pose = rigid_from_axis_angle(
                    Vector3::new(0.5 * a.cos(), 0.5 * a.sin(), 0.2 * a.sin()),
                    Vector3::new(-120.0 + 60.0 * a.sin(), -75.0 + 40.0 * a.cos(), 700.0 + 80.0 * a.cos()),
                );
                let corners_mm = layout.corners_in_board_mm();
                let projected = projections(camera, &pose, &corners_mm).unwrap();
                let corners_px = projected
                    .chunks(2)
                    .map(|uv| [uv[0] + rng.normal(0.0, sd_px), uv[1] + rng.normal(0.0, sd_px)])
                    .collect();
                BoardView {
                    label: format!("view {k}"),
                    corners_mm,
                    corners_px,
                }
            })
            .collect()
    }

    #[test]
    fn the_bundle_finds_the_camera_from_a_wrong_start() {
        let views = views(&truth(), 0.0, 12, 1);
        let mut start = truth();
        start.camera_matrix[0][0] += 15.0;
        start.camera_matrix[1][1] -= 10.0;
        start.camera_matrix[0][2] += 6.0;
        start.distortion[0] = -0.08;
        let poses = initial_poses(&start, &views).unwrap();
        let b = bundle(&start, poses, &views).unwrap();
        let error = (intrinsics_vector(&b.camera) - intrinsics_vector(&truth())).abs();
        assert!(error.rows(0, 4).max() < 1e-4, "matrix error {error}");
        assert!(b.rms_px < 1e-5, "RMS {}", b.rms_px);
    }

    #[test]
    fn the_bundle_reaches_opencvs_calibrate_camera_optimum() {
        // Same objective as calibrateCamera (flags 0), so the same minimum on noisy corners.
        let views = views(&truth(), 0.1, 14, 7);
        let object: opencv::core::Vector<opencv::core::Vector<opencv::core::Point3f>> =
            views.iter().map(|v| object_points(&v.corners_mm)).collect();
        let pixels: opencv::core::Vector<opencv::core::Vector<opencv::core::Point2f>> = views
            .iter()
            .map(|v| super::super::corners::image_points(&v.corners_px))
            .collect();
        let mut k = opencv::core::Mat::default();
        let mut d = opencv::core::Mat::default();
        let mut r = opencv::core::Vector::<opencv::core::Mat>::new();
        let mut t = opencv::core::Vector::<opencv::core::Mat>::new();
        let size = opencv::core::Size::new(1920, 1080);
        let rms =
            opencv::calib3d::calibrate_camera_def(&object, &pixels, size, &mut k, &mut d, &mut r, &mut t).unwrap();
        use opencv::prelude::MatTraitConst;
        let fx = *k.at_2d::<f64>(0, 0).unwrap();
        let cy = *k.at_2d::<f64>(1, 2).unwrap();
        let mut start = truth();
        start.camera_matrix[0][0] += 8.0;
        let poses = initial_poses(&start, &views).unwrap();
        let b = bundle(&start, poses, &views).unwrap();
        assert!((b.camera.fx() - fx).abs() < 1e-3, "fx {} vs OpenCV {fx}", b.camera.fx());
        assert!((b.camera.cy() - cy).abs() < 1e-3, "cy {} vs OpenCV {cy}", b.camera.cy());
        assert!((b.rms_px - rms).abs() < 1e-6, "RMS {} vs OpenCV {rms}", b.rms_px);
    }

    #[test]
    fn the_information_predicts_the_spread_of_the_solved_intrinsics() {
        // The SDs the information gives (from the views' own residuals) against
        // the scatter of the intrinsics solved from 40 noisy draws of the views.
        let mut solved = Vec::new();
        let mut predicted = Vec::new();
        for seed in 0..40 {
            let views = views(&truth(), 0.1, 10, 100 + seed);
            let poses = initial_poses(&truth(), &views).unwrap();
            let b = bundle(&truth(), poses, &views).unwrap();
            solved.push(intrinsics_vector(&b.camera));
            predicted.push(intrinsics_sd(&b.intrinsics_information.unwrap()).unwrap());
        }
        for (k, name) in ["fx", "fy", "cx", "cy", "k1"].iter().enumerate() {
            let mean = solved.iter().map(|v| v[k]).sum::<f64>() / solved.len() as f64;
            let scatter =
                (solved.iter().map(|v| (v[k] - mean).powi(2)).sum::<f64>() / (solved.len() - 1) as f64).sqrt();
            let sd = predicted.iter().map(|p| p[k]).sum::<f64>() / predicted.len() as f64;
            let ratio = scatter / sd;
            assert!(
                (0.7..1.4).contains(&ratio),
                "{name}: scatter {scatter:.4}, predicted SD {sd:.4}"
            );
        }
    }

    #[test]
    fn a_board_seen_again_in_place_is_one_view_and_a_moved_one_is_another() {
        // Ten photos of one static board (0.1 px of sensor noise apart), the
        // same board moved by two pixels, and a board of other points where
        // the first one was: only the static board's nine later photos repeat.
        let moving = views(&truth(), 0.0, 3, 1);
        let mut rng = Rng::new(7);
        let mut all: Vec<BoardView> = (0..10)
            .map(|k| BoardView {
                label: format!("photo {k}"),
                corners_mm: moving[0].corners_mm.clone(),
                corners_px: moving[0]
                    .corners_px
                    .iter()
                    .map(|p| [p[0] + rng.normal(0.0, 0.1), p[1] + rng.normal(0.0, 0.1)])
                    .collect(),
            })
            .collect();
        let mut moved = moving[0].clone();
        for p in moved.corners_px.iter_mut() {
            p[0] += 2.0;
        }
        let mut other = moving[0].clone();
        other.corners_mm.iter_mut().for_each(|p| p.x += 1.0);
        all.extend([moved, other, moving[1].clone(), moving[2].clone()]);
        let repeated = repeats(&all);
        assert_eq!(repeated[0], None);
        assert!(repeated[1..10].iter().all(|r| *r == Some(0)), "{repeated:?}");
        assert!(repeated[10..].iter().all(|r| r.is_none()), "{repeated:?}");
    }

    #[test]
    fn a_refinement_counts_a_static_board_once() {
        // The calibration's views, then 30 photos of one static board: solved
        // with the first photo alone, as if the other 29 were not there.
        let own = views(&truth(), 0.05, 8, 3);
        let calibration = CameraCalibration {
            intrinsics: truth(),
            views: Vec::new(),
            inner_corners: [9, 6],
            square_mm: 30.0,
            warnings: Vec::new(),
            used_corners_px: own.iter().map(|v| v.corners_px.clone()).collect(),
            refined: None,
        };
        let board = views(&truth(), 0.0, 1, 9).remove(0);
        let mut rng = Rng::new(11);
        let photos: Vec<BoardView> = (0..30)
            .map(|k| BoardView {
                label: format!("frame {k}"),
                corners_mm: board.corners_mm.clone(),
                corners_px: board
                    .corners_px
                    .iter()
                    .map(|p| [p[0] + rng.normal(0.0, 0.05), p[1] + rng.normal(0.0, 0.05)])
                    .collect(),
            })
            .collect();
        let all = refine_with_boards(&calibration, &photos).unwrap();
        let first = refine_with_boards(&calibration, &photos[..1]).unwrap();
        let (a, b) = (all.refined.unwrap(), first.refined.unwrap());
        assert_eq!((a.boards_used, a.boards_repeated), (1, 29));
        assert_eq!((b.boards_used, b.boards_repeated), (1, 0));
        assert_eq!(a.intrinsics_information, b.intrinsics_information);
        assert_eq!(all.intrinsics.camera_matrix, first.intrinsics.camera_matrix);
    }
}
