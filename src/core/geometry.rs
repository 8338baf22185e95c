//! Rigid transforms and the frame conventions used throughout probecal.
//!
//! # Conventions
//! - A transform named `a_T_b` maps coordinates expressed in frame `b` to
//!   coordinates expressed in frame `a`: `x_in_a = a_T_b * x_in_b`.
//!   The thesis writes the same transform as `T_{b->a}`.
//! - Frames: `camera` (C, OpenCV pinhole: x right, y down, z forward),
//!   `marker` (M, the board on the probe), `phantom` (P, the board fixed to the
//!   phantom container), `image` (U, the B-scan: pixel (u, v) sits at
//!   `(sx * u, sy * v, 0)` millimetres, u = column, v = row).
//! - Lengths are millimetres, angles degrees unless a name says radians.
//! - Board frames follow OpenCV: origin on the board's first inner corner,
//!   x along the corner rows, y along the columns, z into the board.

use nalgebra::{Isometry3, Matrix3, Matrix4, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// A rigid transform. The name of the variable holding it says its frames.
pub type Rigid = Isometry3<f64>;

/// Builds a rigid transform from a rotation matrix and a translation (mm).
pub fn rigid_from_parts(rotation: &Matrix3<f64>, translation_mm: &Vector3<f64>) -> Rigid {
    let rotation = Rotation3::from_matrix_unchecked(*rotation);
    Isometry3::from_parts(
        Translation3::from(*translation_mm),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// Rotation about `axis` by `angle_deg`, then a translation.
pub fn rigid_from_axis_angle(axis_angle_rad: Vector3<f64>, translation_mm: Vector3<f64>) -> Rigid {
    Isometry3::new(translation_mm, axis_angle_rad)
}

/// `start` moved by a small step, as the solvers parameterise it: the rotation
/// `exp([rotation_rad]ₓ)` applied after `start`'s (about the target frame's
/// origin), and `translation_mm` added to its translation.
pub fn perturbed(start: &Rigid, rotation_rad: Vector3<f64>, translation_mm: Vector3<f64>) -> Rigid {
    let delta = rigid_from_axis_angle(rotation_rad, Vector3::zeros());
    Rigid::from_parts(
        (start.translation.vector + translation_mm).into(),
        delta.rotation * start.rotation,
    )
}

/// Homogeneous 4x4 matrix, row-major as nested arrays (for JSON and tables).
pub fn to_rows(transform: &Rigid) -> [[f64; 4]; 4] {
    let m: Matrix4<f64> = transform.to_homogeneous();
    let mut rows = [[0.0; 4]; 4];
    for (r, row) in rows.iter_mut().enumerate() {
        for (c, value) in row.iter_mut().enumerate() {
            *value = m[(r, c)];
        }
    }
    rows
}

/// Why a 4x4 matrix is not a rigid transform.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RigidError {
    #[error("matrix has a non-finite entry")]
    NotFinite,
    #[error("last row is not [0 0 0 1]")]
    NotHomogeneous,
    #[error("rotation part is not orthonormal (|R^T R - I| = {0:.2e})")]
    NotOrthonormal(f64),
    #[error("rotation part is a reflection (det R = {0:.3})")]
    Reflection(f64),
}

/// Parses a row-major 4x4 matrix as a rigid transform, rejecting anything that is not one.
pub fn rigid_from_rows(rows: &[[f64; 4]; 4]) -> Result<Rigid, RigidError> {
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(RigidError::NotFinite);
    }
    let last = rows[3];
    if last[0].abs() > 1e-9 || last[1].abs() > 1e-9 || last[2].abs() > 1e-9 || (last[3] - 1.0).abs() > 1e-9 {
        return Err(RigidError::NotHomogeneous);
    }
    let r = Matrix3::from_fn(|i, j| rows[i][j]);
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    if off > 1e-6 {
        return Err(RigidError::NotOrthonormal(off));
    }
    let det = r.determinant();
    if det < 0.0 {
        return Err(RigidError::Reflection(det));
    }
    Ok(rigid_from_parts(&r, &Vector3::new(rows[0][3], rows[1][3], rows[2][3])))
}

/// The image's four corners, then its centre, in the image frame (mm): where a
/// calibration's error is measured.
pub fn image_probe_points(image_size_px: [usize; 2], spacing_mm_per_px: [f64; 2]) -> [Point3<f64>; 5] {
    let (w, h) = (
        (image_size_px[0].max(1) - 1) as f64,
        (image_size_px[1].max(1) - 1) as f64,
    );
    [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h], [w / 2.0, h / 2.0]].map(|p| pixel_to_image_mm(p, spacing_mm_per_px))
}

/// Angle of the relative rotation between two transforms, degrees.
pub fn rotation_angle_between_deg(a: &Rigid, b: &Rigid) -> f64 {
    a.rotation.angle_to(&b.rotation).to_degrees()
}

/// Euler angles (degrees) in the ZYX convention: `R = Rz(yaw) Ry(pitch) Rx(roll)`,
/// returned as `[roll_x, pitch_y, yaw_z]`.
pub fn euler_zyx_deg(transform: &Rigid) -> [f64; 3] {
    let (roll, pitch, yaw) = transform.rotation.euler_angles();
    [roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees()]
}

/// The B-scan pixel `(u, v)` as a point of the image frame, millimetres.
/// Where the line through `p` and `q` (image frame, mm) meets the image plane
/// z = 0: the parameter `t` along `p → q` (0 at `p`, 1 at `q`) and the point.
/// `None` when the line runs parallel to the plane.
pub fn line_meets_image_plane(p: &Point3<f64>, q: &Point3<f64>) -> Option<(f64, Point3<f64>)> {
    if (q.z - p.z).abs() < 1e-12 {
        return None;
    }
    let t = p.z / (p.z - q.z);
    Some((t, p + (q - p) * t))
}

pub fn pixel_to_image_mm(pixel: [f64; 2], spacing_mm_per_px: [f64; 2]) -> Point3<f64> {
    Point3::new(pixel[0] * spacing_mm_per_px[0], pixel[1] * spacing_mm_per_px[1], 0.0)
}

/// A probe calibration: `marker_T_image` after the B-scan's pixel size, so that
/// pixel `(u, v)` sits at `marker_T_image · (sx u + k v, sy v, 0)` in the marker
/// frame (mm), `k` the shear (0 but for PLUS's affine model: any linear map of the
/// image plane is a rotation times this upper-triangular one). PLUS calls the
/// marker frame `Probe` and this calibration `Calibration`.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub marker_T_image: Rigid,
    pub spacing_mm_per_px: [f64; 2],
    /// `k`: mm along the image's x axis per pixel row.
    pub shear_mm_per_px: f64,
}

impl Calibration {
    /// A calibration without shear.
    pub fn new(marker_T_image: Rigid, spacing_mm_per_px: [f64; 2]) -> Calibration {
        Calibration {
            marker_T_image,
            spacing_mm_per_px,
            shear_mm_per_px: 0.0,
        }
    }

    /// A pixel in the image frame, mm.
    pub fn pixel_in_image_mm(&self, pixel: [f64; 2]) -> Point3<f64> {
        Point3::new(
            pixel[0] * self.spacing_mm_per_px[0] + pixel[1] * self.shear_mm_per_px,
            pixel[1] * self.spacing_mm_per_px[1],
            0.0,
        )
    }

    /// A pixel in the marker frame, mm.
    pub fn apply(&self, pixel: [f64; 2]) -> Point3<f64> {
        self.marker_T_image * self.pixel_in_image_mm(pixel)
    }

    /// A point `elevation_mm` off the image plane at a pixel, in the marker frame, mm.
    pub fn apply_at(&self, pixel: [f64; 2], elevation_mm: f64) -> Point3<f64> {
        let mut p = self.pixel_in_image_mm(pixel);
        p.z = elevation_mm;
        self.marker_T_image * p
    }

    /// The homogeneous matrix mapping `(u, v, 0, 1)` (PLUS's `Calibration`).
    pub fn matrix(&self) -> Matrix4<f64> {
        let mut scale = Matrix4::from_diagonal(&nalgebra::Vector4::new(
            self.spacing_mm_per_px[0],
            self.spacing_mm_per_px[1],
            // The out-of-plane axis is scaled like the mean pixel size, as PLUS does.
            (self.spacing_mm_per_px[0] + self.spacing_mm_per_px[1]) / 2.0,
            1.0,
        ));
        scale[(0, 1)] = self.shear_mm_per_px;
        self.marker_T_image.to_homogeneous() * scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_and_rejects_non_rigid() {
        let t = rigid_from_axis_angle(Vector3::new(0.1, -0.2, 0.3), Vector3::new(1.0, 2.0, 3.0));
        let back = rigid_from_rows(&to_rows(&t)).expect("rigid");
        assert!((back.to_homogeneous() - t.to_homogeneous()).abs().max() < 1e-12);

        let mut scaled = to_rows(&t);
        scaled[0][0] *= 1.1;
        assert!(matches!(rigid_from_rows(&scaled), Err(RigidError::NotOrthonormal(_))));
        let mut nan = to_rows(&t);
        nan[1][3] = f64::NAN;
        assert_eq!(rigid_from_rows(&nan), Err(RigidError::NotFinite));
        let mut mirrored = to_rows(&Rigid::identity());
        mirrored[2][2] = -1.0;
        assert!(matches!(rigid_from_rows(&mirrored), Err(RigidError::Reflection(_))));
    }
}
