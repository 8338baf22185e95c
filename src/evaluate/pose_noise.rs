//! How the camera's errors reach a frame's `phantom_T_marker`, to first order:
//! the board corners' localisation noise (independent per photo), the hand's
//! motion between the photo and the B-scan (independent per frame), and the
//! error of the camera's intrinsics (one error shared by every frame of a run,
//! known only as well as the camera calibration's views pin it down).
//!
//! Poses and intrinsics are perturbed in the coordinates of
//! [`crate::detect::projection`].

use nalgebra::{Matrix6, Point2, SMatrix, Vector3, Vector6};

use crate::core::geometry::Rigid;
use crate::detect::projection::{board_jacobians, pose_delta, step, POSE_STEP};
pub use crate::detect::projection::{intrinsics_vector, pose_at, IntrinsicsVector, INTRINSICS};
use crate::io::camera_model::CameraIntrinsics;

/// `d(pose coordinates) / d(intrinsics)`.
pub type PoseFromIntrinsics = SMatrix<f64, 6, INTRINSICS>;
pub type IntrinsicsInformation = SMatrix<f64, INTRINSICS, INTRINSICS>;

/// What a board's pose estimate (least squares on its corners) inherits: its
/// covariance per unit corner variance (px²), and its shift per unit error of
/// each intrinsic (the pose that best explains the corners under wrong intrinsics).
struct BoardPoseNoise {
    cov_per_px2: Matrix6<f64>,
    from_intrinsics: PoseFromIntrinsics,
}

fn board_pose_noise(
    camera: &CameraIntrinsics,
    camera_T_board: &Rigid,
    points_in_board: &[Point2<f64>],
) -> Option<BoardPoseNoise> {
    let (jp, jk) = board_jacobians(camera, camera_T_board, points_in_board)?;
    let normal = Matrix6::from_iterator((jp.transpose() * &jp).iter().copied());
    let cov_per_px2 = normal.try_inverse()?;
    let jpk = jp.transpose() * jk;
    let from_intrinsics = -cov_per_px2 * PoseFromIntrinsics::from_iterator(jpk.iter().copied());
    Some(BoardPoseNoise {
        cov_per_px2,
        from_intrinsics,
    })
}

/// One photo of the sweep: both boards' true poses and printed corners.
pub struct SweepPhoto<'a> {
    pub camera_T_marker: Rigid,
    pub camera_T_phantom: Rigid,
    pub marker_corners_mm: &'a [Point2<f64>],
    pub phantom_corners_mm: &'a [Point2<f64>],
}

/// The per-photo noise values (each value's source is stated where it is set).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PhotoNoise {
    /// SD of a probe-board corner's position per image axis, px.
    pub probe_corner_sd_px: f64,
    /// SD of a phantom-board corner's position per image axis, px.
    pub phantom_corner_sd_px: f64,
    /// SD of the hand's motion between photo and B-scan, per marker axis: mm and degrees.
    pub tremor_sd_mm: f64,
    pub tremor_sd_deg: f64,
}

/// A frame's `phantom_T_marker` error: the covariance of its own part (corners
/// of both boards, tremor) and its shift per unit intrinsics error.
pub struct FramePoseNoise {
    pub cov: Matrix6<f64>,
    pub from_intrinsics: PoseFromIntrinsics,
}

/// `d(phantom_T_marker coordinates) / d(board pose coordinates)` of one board.
fn relative_from_board(photo: &SweepPhoto, marker: bool) -> Matrix6<f64> {
    let relative = |m: &Rigid, p: &Rigid| p.inverse() * m;
    let base = relative(&photo.camera_T_marker, &photo.camera_T_phantom);
    let mut out = Matrix6::zeros();
    for c in 0..6 {
        let moved = if marker {
            relative(&pose_at(&photo.camera_T_marker, &step(c)), &photo.camera_T_phantom)
        } else {
            relative(&photo.camera_T_marker, &pose_at(&photo.camera_T_phantom, &step(c)))
        };
        out.set_column(c, &(pose_delta(&base, &moved) / POSE_STEP));
    }
    out
}

/// The frame's `phantom_T_marker` noise under `noise`, or `None` if a board is
/// behind the camera or its pose is not determined by its corners.
pub fn frame_pose_noise(camera: &CameraIntrinsics, photo: &SweepPhoto, noise: &PhotoNoise) -> Option<FramePoseNoise> {
    let marker = board_pose_noise(camera, &photo.camera_T_marker, photo.marker_corners_mm)?;
    let phantom = board_pose_noise(camera, &photo.camera_T_phantom, photo.phantom_corners_mm)?;
    let lm = relative_from_board(photo, true);
    let lp = relative_from_board(photo, false);
    // The tremor: the marker moved by a small rigid motion in its own frame.
    let base = photo.camera_T_phantom.inverse() * photo.camera_T_marker;
    let mut lt = Matrix6::zeros();
    for c in 0..6 {
        let mut shift = Vector3::zeros();
        let mut angle = Vector3::zeros();
        if c < 3 {
            angle[c] = POSE_STEP;
        } else {
            shift[c - 3] = POSE_STEP;
        }
        lt.set_column(c, &(pose_delta(&base, &(base * Rigid::new(shift, angle))) / POSE_STEP));
    }
    let tremor = Matrix6::from_diagonal(&Vector6::new(
        noise.tremor_sd_deg.to_radians().powi(2),
        noise.tremor_sd_deg.to_radians().powi(2),
        noise.tremor_sd_deg.to_radians().powi(2),
        noise.tremor_sd_mm.powi(2),
        noise.tremor_sd_mm.powi(2),
        noise.tremor_sd_mm.powi(2),
    ));
    let cov = lm * marker.cov_per_px2 * lm.transpose() * noise.probe_corner_sd_px.powi(2)
        + lp * phantom.cov_per_px2 * lp.transpose() * noise.phantom_corner_sd_px.powi(2)
        + lt * tremor * lt.transpose();
    Some(FramePoseNoise {
        cov,
        from_intrinsics: lm * marker.from_intrinsics + lp * phantom.from_intrinsics,
    })
}

/// The information the camera calibration's views hold on the intrinsics
/// (each view's board pose a free unknown, marginalised), with corner noise
/// `corner_sd_px` per image axis; `None` if a view is behind the camera.
pub fn calibration_information(
    camera: &CameraIntrinsics,
    camera_T_views: &[Rigid],
    corners_mm: &[Point2<f64>],
    corner_sd_px: f64,
) -> Option<IntrinsicsInformation> {
    let mut info = IntrinsicsInformation::zeros();
    for view in camera_T_views {
        let (jp, jk) = board_jacobians(camera, view, corners_mm)?;
        let pp = Matrix6::from_iterator((jp.transpose() * &jp).iter().copied()).try_inverse()?;
        let kk = IntrinsicsInformation::from_iterator((jk.transpose() * &jk).iter().copied());
        let pk = PoseFromIntrinsics::from_iterator((jp.transpose() * &jk).iter().copied());
        info += kk - pk.transpose() * pp * pk;
    }
    Some(info / corner_sd_px.powi(2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;

    fn camera() -> CameraIntrinsics {
        crate::detect::projection::rendered_camera()
    }

    fn grid(n: u32, square_mm: f64) -> Vec<Point2<f64>> {
        (0..n)
            .flat_map(|j| (0..n).map(move |i| Point2::new(i as f64 * square_mm, j as f64 * square_mm)))
            .collect()
    }

    #[test]
    fn a_focal_error_moves_a_board_along_the_line_of_sight_in_proportion() {
        // A fronto-parallel board at 600 mm seen with a focal length 0.1 % too
        // long is placed 0.1 % farther: 0.6 mm along z, nothing else to first order.
        let board = grid(10, 13.0);
        let camera_T_board = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(-58.5, -58.5, 600.0));
        let noise = board_pose_noise(&camera(), &camera_T_board, &board).unwrap();
        let mut dk = IntrinsicsVector::zeros();
        dk[0] = 1.4;
        dk[1] = 1.4;
        let shift = noise.from_intrinsics * dk;
        assert!((shift[5] - 0.6).abs() < 0.01, "z shift {shift}");
        assert!(shift[3].abs() < 0.01 && shift[4].abs() < 0.01, "{shift}");
    }

    #[test]
    fn more_views_pin_the_intrinsics_down_better() {
        let board = grid(9, 30.0);
        let views: Vec<Rigid> = (0..12)
            .map(|k| {
                let a = k as f64 * 0.5;
                rigid_from_axis_angle(
                    Vector3::new(0.4 * a.cos(), 0.4 * a.sin(), 0.1 * a),
                    Vector3::new(-120.0 + 20.0 * a.sin(), -100.0, 700.0 + 60.0 * a.cos()),
                )
            })
            .collect();
        let sd = |info: IntrinsicsInformation| info.try_inverse().unwrap()[(0, 0)].sqrt();
        let few = sd(calibration_information(&camera(), &views[..6], &board, 0.1).unwrap());
        let all = sd(calibration_information(&camera(), &views, &board, 0.1).unwrap());
        let noisy = sd(calibration_information(&camera(), &views, &board, 0.2).unwrap());
        assert!(all < few, "fx SD {all} px from 12 views vs {few} from 6");
        assert!((noisy / all - 2.0).abs() < 1e-6, "SD scales with the corner noise");
    }
}
