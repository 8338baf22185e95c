//! A board's corner projections and their derivatives by the board's pose and
//! by the camera's intrinsics (finite differences). Poses move in
//! [`perturbed`]'s coordinates: a rotation vector (rad) applied on the left,
//! then a translation (mm) added. The intrinsics vector is OpenCV's `fx, fy,
//! cx, cy` (px) and `k1, k2, p1, p2, k3`, all nine free as `calibrateCamera`
//! (flags 0) estimates them.

use nalgebra::{Point2, Point3, SVector, Vector3, Vector6};

use crate::core::geometry::{perturbed, Rigid};
use crate::io::camera_model::CameraIntrinsics;

/// The number of intrinsics the camera calibration estimates.
pub const INTRINSICS: usize = 9;

/// A matrix over the intrinsics (their information, their covariance).
pub type KMatrix = nalgebra::SMatrix<f64, INTRINSICS, INTRINSICS>;
pub type IntrinsicsVector = SVector<f64, INTRINSICS>;

pub fn intrinsics_vector(camera: &CameraIntrinsics) -> IntrinsicsVector {
    let [k1, k2, p1, p2, k3] = camera.distortion;
    IntrinsicsVector::from_column_slice(&[camera.fx(), camera.fy(), camera.cx(), camera.cy(), k1, k2, p1, p2, k3])
}

pub fn with_intrinsics(camera: &CameraIntrinsics, v: &IntrinsicsVector) -> CameraIntrinsics {
    let mut out = camera.clone();
    out.camera_matrix = [[v[0], 0.0, v[2]], [0.0, v[1], v[3]], [0.0, 0.0, 1.0]];
    out.distortion = [v[4], v[5], v[6], v[7], v[8]];
    out
}

/// Step of the finite differences for each intrinsic (px for the matrix,
/// unitless for the distortion) and for the pose coordinates.
pub const INTRINSICS_STEP: [f64; INTRINSICS] = [1e-4, 1e-4, 1e-4, 1e-4, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7];
pub const POSE_STEP: f64 = 1e-7;

/// `base` moved by `delta` in [`perturbed`]'s coordinates (rotation vector rad, translation mm).
pub fn pose_at(base: &Rigid, delta: &Vector6<f64>) -> Rigid {
    perturbed(
        base,
        Vector3::new(delta[0], delta[1], delta[2]),
        Vector3::new(delta[3], delta[4], delta[5]),
    )
}

/// The pose coordinate `c` moved by one finite-difference step.
pub fn step(c: usize) -> Vector6<f64> {
    let mut d = Vector6::zeros();
    d[c] = POSE_STEP;
    d
}

/// The coordinates `delta` with `pose_at(base, delta) = moved`.
pub fn pose_delta(base: &Rigid, moved: &Rigid) -> Vector6<f64> {
    let r = (moved.rotation * base.rotation.inverse()).scaled_axis();
    let t = moved.translation.vector - base.translation.vector;
    Vector6::new(r.x, r.y, r.z, t.x, t.y, t.z)
}

/// The projections of `points_in_board` (mm, z = 0) as one column `[u0, v0, u1, …]`.
pub fn projections(
    camera: &CameraIntrinsics,
    camera_T_board: &Rigid,
    points_in_board: &[Point2<f64>],
) -> Option<Vec<f64>> {
    let mut out = Vec::with_capacity(2 * points_in_board.len());
    for p in points_in_board {
        let [u, v] = camera.project(&(camera_T_board * Point3::new(p.x, p.y, 0.0)))?;
        out.extend([u, v]);
    }
    Some(out)
}

/// Jacobians of a board's corner projections: by its pose (2N x 6) and by the
/// intrinsics (2N x 9). `None` if a corner is behind the camera.
pub fn board_jacobians(
    camera: &CameraIntrinsics,
    camera_T_board: &Rigid,
    points_in_board: &[Point2<f64>],
) -> Option<(nalgebra::DMatrix<f64>, nalgebra::DMatrix<f64>)> {
    let base = projections(camera, camera_T_board, points_in_board)?;
    let rows = base.len();
    let mut by_pose = nalgebra::DMatrix::zeros(rows, 6);
    for c in 0..6 {
        let moved = projections(camera, &pose_at(camera_T_board, &step(c)), points_in_board)?;
        for r in 0..rows {
            by_pose[(r, c)] = (moved[r] - base[r]) / POSE_STEP;
        }
    }
    let v0 = intrinsics_vector(camera);
    let mut by_intrinsics = nalgebra::DMatrix::zeros(rows, INTRINSICS);
    for (c, step) in INTRINSICS_STEP.iter().enumerate() {
        let mut v = v0;
        v[c] += step;
        let moved = projections(&with_intrinsics(camera, &v), camera_T_board, points_in_board)?;
        for r in 0..rows {
            by_intrinsics[(r, c)] = (moved[r] - base[r]) / step;
        }
    }
    Some((by_pose, by_intrinsics))
}

/// The rendered labs' camera (1920x1080, f = 1400 px, mild barrel distortion), for tests.
#[cfg(test)]
pub(crate) fn rendered_camera() -> CameraIntrinsics {
    CameraIntrinsics {
        image_size_px: [1920, 1080],
        camera_matrix: [[1400.0, 0.0, 966.0], [0.0, 1400.0, 535.5], [0.0, 0.0, 1.0]],
        distortion: [-0.12, 0.05, 0.0, 0.0, 0.0],
        rms_px: None,
        per_view_rms_px: Vec::new(),
    }
}
