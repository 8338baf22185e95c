//! Calibration from the images themselves: the correction of `ImageToProbe`
//! that makes two or more overlapping tracked sweeps compound alike in the
//! Reference frame, without the phantom's geometry.
//!
//! Each sweep is compounded on one grid (trilinear splatting of block-averaged
//! pixels, [`compound`]); the sweeps' volumes are compared by normalised
//! correlation over the voxels every sweep covers; a Gauss–Newton search moves
//! the calibration in the directions the sweeps hold and leaves the others at
//! the start ([`refine`]).
//!
//! The correction acts in the probe's frame about the image's centre: a turn
//! `ω` (rotation vector) about the centre `c`, then a move `t`, after the start
//! `probe_T_pixel` (which keeps its pixel sizes, PLUS's affine ones included):
//! `probe_T_pixel(q) = D(q) · probe_T_pixel_start`, `D(q) x = R(ω)(x − c) + c + t`.
//! The six unknowns are in millimetres: `t`, and `ω · r` with `r` the image's
//! half-diagonal, so a unit is a millimetre at the image's corners either way.

pub mod check;
pub mod compound;
pub mod overlay;
pub mod profile;
pub mod refine;
pub mod resample;

use nalgebra::{Matrix4, Point3, Rotation3, Vector3, Vector6};

/// One frame of a sweep: its pose and its block-averaged pixel values.
#[derive(Debug, Clone)]
pub struct SweepFrame {
    /// The frame's index in its sequence.
    pub index: usize,
    /// Probe (marker) millimetres to Reference millimetres at the frame's time.
    pub reference_T_probe: Matrix4<f64>,
    /// One value per [`Sweep::samples_px`], in the same order.
    pub values: Vec<f32>,
}

/// A tracked sweep reduced to what the comparison needs.
#[derive(Debug, Clone)]
pub struct Sweep {
    pub name: String,
    /// The pixel (column, row) each value of a frame stands for: the centre of
    /// its block of pixels.
    pub samples_px: Vec<[f64; 2]>,
    pub frames: Vec<SweepFrame>,
}

/// The geometry the correction is expressed in.
#[derive(Debug, Clone, Copy)]
pub struct Frame0 {
    /// The start calibration: pixel (column, row, 0, 1) to probe millimetres.
    pub probe_T_pixel: Matrix4<f64>,
    /// The image's centre in the probe frame, mm.
    pub centre_in_probe_mm: Point3<f64>,
    /// The image's half-diagonal, mm: a rotation unknown is `angle_rad · radius_mm`.
    pub radius_mm: f64,
    /// The image's four corners, pixels (for the corner error).
    pub corners_px: [[f64; 2]; 4],
    pub size_px: [usize; 2],
}

impl Frame0 {
    pub fn new(probe_T_pixel: Matrix4<f64>, width_px: usize, height_px: usize) -> Frame0 {
        let (w, h) = ((width_px.max(1) - 1) as f64, (height_px.max(1) - 1) as f64);
        let corners_px = [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]];
        let at = |p: [f64; 2]| probe_T_pixel.transform_point(&Point3::new(p[0], p[1], 0.0));
        let centre = at([w / 2.0, h / 2.0]);
        let radius_mm = corners_px
            .iter()
            .map(|&c| (at(c) - centre).norm())
            .fold(0.0, f64::max)
            .max(1e-3);
        Frame0 {
            probe_T_pixel,
            centre_in_probe_mm: centre,
            radius_mm,
            corners_px,
            size_px: [width_px, height_px],
        }
    }

    /// The same image with the start moved by `q`.
    pub fn moved(&self, q: &Vector6<f64>) -> Frame0 {
        Frame0::new(self.calibration(q), self.size_px[0], self.size_px[1])
    }

    /// The correction `D(q)` as a 4x4 matrix in the probe frame.
    pub fn correction(&self, q: &Vector6<f64>) -> Matrix4<f64> {
        let t = Vector3::new(q[0], q[1], q[2]);
        let omega = Vector3::new(q[3], q[4], q[5]) / self.radius_mm;
        let r = Rotation3::new(omega);
        let c = self.centre_in_probe_mm.coords;
        let mut d = Matrix4::identity();
        d.fixed_view_mut::<3, 3>(0, 0).copy_from(r.matrix());
        d.fixed_view_mut::<3, 1>(0, 3).copy_from(&(c - r * c + t));
        d
    }

    /// `probe_T_pixel` after the correction `q`.
    pub fn calibration(&self, q: &Vector6<f64>) -> Matrix4<f64> {
        self.correction(q) * self.probe_T_pixel
    }

    /// The largest distance, mm, between where two calibrations put the image's corners.
    pub fn corner_error_mm(&self, a: &Matrix4<f64>, b: &Matrix4<f64>) -> f64 {
        self.corners_px
            .iter()
            .map(|p| {
                let p = Point3::new(p[0], p[1], 0.0);
                (a.transform_point(&p) - b.transform_point(&p)).norm()
            })
            .fold(0.0, f64::max)
    }

    /// The correction that takes the start to `target`, with `target`'s pixel
    /// sizes taken as the start's (the rigid part of `target · start⁻¹`).
    pub fn unknowns_of(&self, target: &Matrix4<f64>) -> Option<Vector6<f64>> {
        let d = target * self.probe_T_pixel.try_inverse()?;
        let m = d.fixed_view::<3, 3>(0, 0).into_owned();
        let svd = m.svd(true, true);
        let r = svd.u? * svd.v_t?;
        let rot = Rotation3::from_matrix_unchecked(r);
        let c = self.centre_in_probe_mm.coords;
        let t = d.fixed_view::<3, 1>(0, 3).into_owned() - (c - r * c);
        let w = rot.scaled_axis() * self.radius_mm;
        Some(Vector6::new(t[0], t[1], t[2], w[0], w[1], w[2]))
    }
}

/// The names of the six unknowns, in order (the probe frame's axes).
pub const UNKNOWNS: [&str; 6] = [
    "move along x",
    "move along y",
    "move along z",
    "turn about x",
    "turn about y",
    "turn about z",
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_correction_read_back_is_the_correction() {
        let start = Matrix4::new(
            -0.0005, 0.0745, 0.0008, 11.2, -0.0803, -0.0001, 0.0017, 48.4, 0.0018, -0.0008, 0.0774, -0.4, 0.0, 0.0,
            0.0, 1.0,
        );
        let f = Frame0::new(start, 820, 616);
        let q = Vector6::new(1.0, -2.0, 0.5, 3.0, -1.5, 2.0);
        let back = f.unknowns_of(&f.calibration(&q)).unwrap();
        assert!((back - q).norm() < 1e-6, "{back:?}");
        // A turn about the centre leaves the centre where it was.
        let turned = f.calibration(&Vector6::new(0.0, 0.0, 0.0, 5.0, 5.0, 5.0));
        let centre = Point3::new(409.5, 307.5, 0.0);
        assert!((turned.transform_point(&centre) - start.transform_point(&centre)).norm() < 1e-9);
        // A unit turn moves the farthest corner by about a millimetre.
        let one = f.calibration(&Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0));
        assert!((f.corner_error_mm(&one, &start) - 1.0).abs() < 1e-3);
    }
}
