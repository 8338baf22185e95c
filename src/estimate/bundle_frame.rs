//! One frame of the pose-prior sphere fit: its arcs, its pose prior, and the
//! residuals and Jacobians the bundle adjustment solves with.

use nalgebra::{DMatrix, DVector, Matrix6, Point3, Vector3, Vector6};

use super::edge_offset::{offset_mm, EdgeOffset, EdgeTerms};
use super::sphere_fit::KnownSphere;
use crate::core::geometry::{perturbed, Rigid};

/// Finite-difference steps: rotations (rad), translations (mm).
pub(super) const ROTATION_STEP: f64 = 1e-7;
pub(super) const TRANSLATION_STEP: f64 = 1e-6;

pub(super) fn at(base: &Rigid, d: &Vector6<f64>) -> Rigid {
    perturbed(base, Vector3::new(d[0], d[1], d[2]), Vector3::new(d[3], d[4], d[5]))
}

pub(super) fn step_of(c: usize) -> f64 {
    if c < 3 {
        ROTATION_STEP
    } else {
        TRANSLATION_STEP
    }
}

/// One frame's arcs: the poses, and each arc's sphere, weight and points (image, mm).
pub(super) struct FrameArcs {
    pub(super) frame: usize,
    pub(super) phantom_T_marker: Rigid,
    pub(super) arcs: Vec<(KnownSphere, f64, Vec<Point3<f64>>)>,
    /// Whitens the frame's own pose error: `L⁻¹` with `Σ = L Lᵀ`.
    pub(super) whiten: Matrix6<f64>,
    pub(super) information: Matrix6<f64>,
    /// `F_f` (6 × m; m = 0 without a shared error).
    pub(super) from_shared: DMatrix<f64>,
}

impl FrameArcs {
    /// The frame's pose correction: its share of `k` and its own `e`.
    pub(super) fn correction(&self, k: &DVector<f64>, e: &Vector6<f64>) -> Vector6<f64> {
        if k.is_empty() {
            return *e;
        }
        e + Vector6::from_iterator((&self.from_shared * k).iter().copied())
    }

    /// Whitened point residuals under the calibration `c` (from `start`), pose
    /// correction `d` and edge offsets `o`.
    pub(super) fn residuals(
        &self,
        start: &Rigid,
        c: &Vector6<f64>,
        d: &Vector6<f64>,
        o: &EdgeTerms,
        edge_sd_mm: f64,
    ) -> DVector<f64> {
        let phantom_T_image = at(&self.phantom_T_marker, d) * at(start, c);
        // Only a solved offset needs the plane's distance from each centre.
        let image_T_phantom = o.iter().any(|t| *t != 0.0).then(|| phantom_T_image.inverse());
        let mut out = Vec::new();
        for (sphere, weight, points) in &self.arcs {
            let offset = image_T_phantom.map_or(0.0, |image_T_phantom| {
                offset_mm(o, sphere, (image_T_phantom * sphere.centre_in_phantom_mm).z)
            });
            for p in points {
                let distance = (phantom_T_image * p - sphere.centre_in_phantom_mm).norm() - sphere.radius_mm - offset;
                out.push(weight * distance / edge_sd_mm);
            }
        }
        DVector::from_vec(out)
    }

    pub(super) fn cost(
        &self,
        start: &Rigid,
        x: &DVector<f64>,
        m: usize,
        model: EdgeOffset,
        e: &Vector6<f64>,
        edge_sd_mm: f64,
    ) -> f64 {
        let (c, k, o) = split(x, m);
        self.residuals(
            start,
            &c,
            &self.correction(&k, e),
            &model.expand(o.as_slice()),
            edge_sd_mm,
        )
        .norm_squared()
            + (self.whiten * e).norm_squared()
    }
}

/// The calibration's correction, the shared error (`m` values) and the edge
/// offsets, from the unknowns `x`.
impl FrameArcs {
    /// The frame's residuals and their Jacobians: on the shared unknowns (the
    /// calibration, the shared error, the edge offsets) and on the frame's own
    /// pose correction.
    pub(super) fn linearised(
        &self,
        start: &Rigid,
        (c, k, free): (&Vector6<f64>, &DVector<f64>, &DVector<f64>),
        e: &Vector6<f64>,
        model: EdgeOffset,
        sd: f64,
    ) -> (DVector<f64>, DMatrix<f64>, DMatrix<f64>) {
        let f = self;
        let (c, m, q) = (*c, k.len(), free.len());
        let n = 6 + m + q;
        let o = model.expand(free.as_slice());
        let d = f.correction(k, e);
        let r = f.residuals(start, &c, &d, &o, sd);
        let mut jc = DMatrix::zeros(r.len(), 6);
        let mut jd = DMatrix::zeros(r.len(), 6);
        for j in 0..6 {
            let mut s = Vector6::zeros();
            s[j] = step_of(j);
            jc.set_column(j, &((f.residuals(start, &(c + s), &d, &o, sd) - &r) / s[j]));
            jd.set_column(j, &((f.residuals(start, &c, &(d + s), &o, sd) - &r) / s[j]));
        }
        let mut jx = DMatrix::zeros(r.len(), n);
        jx.columns_mut(0, 6).copy_from(&jc);
        if m > 0 {
            jx.columns_mut(6, m).copy_from(&(&jd * &f.from_shared));
        }
        for j in 0..q {
            let mut stepped = free.clone();
            stepped[j] += TRANSLATION_STEP;
            let column = (f.residuals(start, &c, &d, &model.expand(stepped.as_slice()), sd) - &r) / TRANSLATION_STEP;
            jx.set_column(6 + m + j, &column);
        }
        (r, jx, jd)
    }
}

pub(super) fn split(x: &DVector<f64>, m: usize) -> (Vector6<f64>, DVector<f64>, DVector<f64>) {
    (
        Vector6::from_iterator(x.rows(0, 6).iter().copied()),
        x.rows(6, m).into_owned(),
        x.rows(6 + m, x.len() - 6 - m).into_owned(),
    )
}
