//! Calibration from tracked B-scans with the pixel size unknown: `marker_T_image`
//! (rigid) and the pixel spacing `(sx, sy)`, so that pixel `(u, v)` sits at
//! `marker_T_image * (sx u, sy v, 0)` in the probe frame (mm).
//!
//! Each segmented dot gives a constraint: either a known point (an N-wire's middle
//! dot, a crossing) or a known line (a wire) in the probe frame. The start comes
//! from Horn's closed form with an isotropic scale on the point constraints; a
//! Levenberg–Marquardt refinement then fits all eight unknowns, and constraints
//! whose residual exceeds mean + k SD are dropped and the fit repeated.

use nalgebra::{DVector, Matrix4, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::geometry::{perturbed, rigid_from_axis_angle, Calibration, Rigid};
use crate::core::lm::{self, LmError};
use crate::estimate::horn::{self, HornError, Variant};

/// Which constraints the dots give.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ConstraintModel {
    /// Only each N's middle dot, at its similar-triangles position (PLUS's method).
    MiddlePoints,
    /// Every dot on its own wire (a line constraint per dot), plus the middle dot's point.
    #[default]
    Wires,
}

/// How the pixel grid maps onto the image plane (PLUS's model family).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PixelModel {
    /// One pixel size for both axes (7 unknowns with the pose).
    Isotropic,
    /// A pixel size per axis (8 unknowns).
    #[default]
    Anisotropic,
    /// Any linear map of the image plane: both pixel sizes and a shear (9
    /// unknowns); PLUS's least-squares `ImageToProbe`.
    Affine,
}

impl PixelModel {
    pub const ALL: [PixelModel; 3] = [PixelModel::Isotropic, PixelModel::Anisotropic, PixelModel::Affine];

    /// Unknowns of the image plane's map beyond the pose.
    fn unknowns(self) -> usize {
        match self {
            PixelModel::Isotropic => 1,
            PixelModel::Anisotropic => 2,
            PixelModel::Affine => 3,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            PixelModel::Isotropic => "isotropic",
            PixelModel::Anisotropic => "anisotropic",
            PixelModel::Affine => "affine",
        }
    }
}

/// What a segmented pixel must map onto, in the phantom frame (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    Point(Point3<f64>),
    /// A point of the line and its unit direction.
    Line(Point3<f64>, Vector3<f64>),
}

/// One segmented pixel, the frame's `marker_T_phantom` and its target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraint {
    pub pixel: [f64; 2],
    /// The feature's distance off the image plane (image z, mm); 0 in the plane.
    pub elevation_mm: f64,
    pub marker_T_phantom: Matrix4<f64>,
    pub target_in_phantom: Target,
}

impl Constraint {
    /// The 3D residual (probe frame, mm) of a pixel mapped by `model`, with the
    /// phantom's registration corrected by `phantom_correction` (phantom frame).
    pub fn residual_with(&self, model: &Calibration, phantom_correction: &Rigid) -> Vector3<f64> {
        let marker_T_phantom = self.marker_T_phantom * phantom_correction.to_homogeneous();
        let mapped = model.apply_at(self.pixel, self.elevation_mm);
        match self.target_in_phantom {
            Target::Point(p) => mapped - marker_T_phantom.transform_point(&p),
            Target::Line(p, d) => {
                let point = marker_T_phantom.transform_point(&p);
                let direction = marker_T_phantom.transform_vector(&d).normalize();
                let w = mapped - point;
                w - direction * w.dot(&direction)
            }
        }
    }

    /// The 3D residual vector of a pixel mapped by `model` (mm).
    pub fn residual(&self, model: &Calibration) -> Vector3<f64> {
        self.residual_with(model, &Rigid::identity())
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("{0} point constraints, at least 3 are needed for the closed-form start")]
    TooFewPoints(usize),
    #[error("closed-form start: {0}")]
    Horn(#[from] HornError),
    #[error("refinement: {0}")]
    Lm(#[from] LmError),
    #[error("the fitted pixel size {0:?} mm is not positive")]
    BadSpacing([f64; 2]),
}

/// The fit and which constraints it kept.
#[derive(Debug, Clone)]
pub struct Fit {
    pub image_to_probe: Calibration,
    /// Correction of the phantom's registration (`registered_T_refined`, phantom
    /// frame), identity unless it was refined.
    pub phantom_correction: Rigid,
    /// Per input constraint: kept in the final fit.
    pub inlier: Vec<bool>,
    /// Per input constraint: residual norm under the final fit, mm.
    pub residual_mm: Vec<f64>,
    pub iterations: usize,
    /// Standard deviations of the unknowns `[rx, ry, rz (rad), tx, ty, tz (mm), sx, sy,
    /// k (mm/px)]` from the residual variance and `(J^T J)^-1` (an isotropic model's
    /// `sy` is its `sx`; a shear not fitted has SD 0).
    pub sd: Vec<f64>,
    pub pixel_model: PixelModel,
}

/// The calibration and phantom correction at unknowns `x`: the pose's 6, the
/// pixel model's, then the phantom correction's 6 when refined.
fn unpack(start: &Rigid, start_correction: &Rigid, pixel: PixelModel, x: &DVector<f64>) -> (Calibration, Rigid) {
    let marker_T_image = perturbed(start, Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5]));
    let model = match pixel {
        PixelModel::Isotropic => Calibration::new(marker_T_image, [x[6], x[6]]),
        PixelModel::Anisotropic => Calibration::new(marker_T_image, [x[6], x[7]]),
        PixelModel::Affine => Calibration {
            marker_T_image,
            spacing_mm_per_px: [x[6], x[7]],
            shear_mm_per_px: x[8],
        },
    };
    let c = 6 + pixel.unknowns();
    let correction = if x.len() > c {
        rigid_from_axis_angle(
            Vector3::new(x[c], x[c + 1], x[c + 2]),
            Vector3::new(x[c + 3], x[c + 4], x[c + 5]),
        ) * start_correction
    } else {
        *start_correction
    };
    (model, correction)
}

fn residuals(model: &Calibration, correction: &Rigid, constraints: &[&Constraint]) -> DVector<f64> {
    let mut out = DVector::zeros(constraints.len() * 3);
    for (i, c) in constraints.iter().enumerate() {
        let r = c.residual_with(model, correction);
        out.fixed_rows_mut::<3>(i * 3).copy_from(&r);
    }
    out
}

/// The unknowns' start (the pose at zero, the pixel map at `model`'s) and their
/// finite-difference steps.
fn start_vector(
    model: &Calibration,
    pixel: PixelModel,
    unknowns: usize,
    pose_and_pixel: usize,
) -> (DVector<f64>, DVector<f64>) {
    let mut x0 = DVector::zeros(unknowns);
    let mut steps = DVector::from_element(unknowns, 1e-5);
    for k in [0, 1, 2, pose_and_pixel, pose_and_pixel + 1, pose_and_pixel + 2] {
        if k < unknowns {
            steps[k] = 1e-6;
        }
    }
    let [sx, sy] = model.spacing_mm_per_px;
    let pixel_start = match pixel {
        PixelModel::Isotropic => vec![(sx + sy) / 2.0],
        PixelModel::Anisotropic => vec![sx, sy],
        PixelModel::Affine => vec![sx, sy, model.shear_mm_per_px],
    };
    for (k, v) in pixel_start.into_iter().enumerate() {
        x0[6 + k] = v;
        steps[6 + k] = 1e-8;
    }
    (x0, steps)
}

/// Closed-form start: Horn with isotropic scale on the point constraints.
pub fn closed_form(constraints: &[Constraint]) -> Result<Calibration, FitError> {
    let (source, target): (Vec<Point3<f64>>, Vec<Point3<f64>>) = constraints
        .iter()
        .filter(|c| c.elevation_mm == 0.0)
        .filter_map(|c| match c.target_in_phantom {
            Target::Point(p) => Some((
                Point3::new(c.pixel[0], c.pixel[1], 0.0),
                c.marker_T_phantom.transform_point(&p),
            )),
            Target::Line(..) => None,
        })
        .unzip();
    if source.len() < 3 {
        return Err(FitError::TooFewPoints(source.len()));
    }
    let fit = horn::solve(&source, &target, Variant::Similarity)?;
    Ok(Calibration::new(fit.target_T_source, [fit.scale, fit.scale]))
}

/// What [`refine`] fits and drops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineSettings {
    pub pixel_model: PixelModel,
    /// Drop constraints above mean + this many SD and refit (`None`: keep all).
    pub reject_sd: Option<f64>,
    /// Also correct the phantom's registration (6 more unknowns).
    pub refine_phantom: bool,
}

/// Refines `start` on the given constraints, dropping those above mean + `reject_sd` SD
/// (repeated until none is dropped, at most 10 rounds).
pub fn refine(start: &Calibration, constraints: &[Constraint], settings: &RefineSettings) -> Result<Fit, FitError> {
    let pixel = settings.pixel_model;
    let reject_sd = settings.reject_sd;
    let mut inlier = vec![true; constraints.len()];
    let mut model = start.clone();
    let mut correction = Rigid::identity();
    let mut iterations = 0;
    let mut last_cost = 0.0;
    let pose_and_pixel = 6 + pixel.unknowns();
    let unknowns = pose_and_pixel + if settings.refine_phantom { 6 } else { 0 };
    let mut last_normal = nalgebra::DMatrix::zeros(unknowns, unknowns);
    for _round in 0..10 {
        let kept: Vec<&Constraint> = constraints
            .iter()
            .zip(&inlier)
            .filter(|(_, k)| **k)
            .map(|(c, _)| c)
            .collect();
        let base = model.marker_T_image;
        let base_correction = correction;
        let (x0, steps) = start_vector(&model, pixel, unknowns, pose_and_pixel);
        let out = lm::minimise(x0, &steps, 100, |x| {
            let (m, c) = unpack(&base, &base_correction, pixel, x);
            residuals(&m, &c, &kept)
        })?;
        iterations += out.iterations;
        (model, correction) = unpack(&base, &base_correction, pixel, &out.x);
        last_cost = out.cost / (kept.len() * 3).saturating_sub(unknowns).max(1) as f64;
        last_normal = out.normal_matrix;
        let Some(k) = reject_sd else { break };
        let norms: Vec<f64> = constraints
            .iter()
            .map(|c| c.residual_with(&model, &correction).norm())
            .collect();
        let kept_norms: Vec<f64> = norms
            .iter()
            .zip(&inlier)
            .filter(|(_, k)| **k)
            .map(|(n, _)| *n)
            .collect();
        let mean = kept_norms.iter().sum::<f64>() / kept_norms.len() as f64;
        let sd = (kept_norms.iter().map(|n| (n - mean).powi(2)).sum::<f64>() / kept_norms.len() as f64).sqrt();
        let limit = mean + k * sd;
        let next: Vec<bool> = norms.iter().map(|n| *n <= limit).collect();
        if next == inlier {
            break;
        }
        inlier = next;
    }
    if !(model.spacing_mm_per_px[0] > 0.0 && model.spacing_mm_per_px[1] > 0.0) {
        return Err(FitError::BadSpacing(model.spacing_mm_per_px));
    }
    let residual_mm = constraints
        .iter()
        .map(|c| c.residual_with(&model, &correction).norm())
        .collect();
    let fitted: Vec<f64> = last_normal
        .try_inverse()
        .map(|inv| {
            (0..unknowns)
                .map(|k| (inv[(k, k)] * last_cost).max(0.0).sqrt())
                .collect()
        })
        .unwrap_or_else(|| vec![f64::NAN; unknowns]);
    // One layout whatever the model: pose, sx, sy, shear.
    let mut sd = fitted[..6].to_vec();
    match pixel {
        PixelModel::Isotropic => sd.extend([fitted[6], fitted[6], 0.0]),
        PixelModel::Anisotropic => sd.extend([fitted[6], fitted[7], 0.0]),
        PixelModel::Affine => sd.extend_from_slice(&fitted[6..9]),
    }
    sd.extend_from_slice(&fitted[pose_and_pixel..]);
    Ok(Fit {
        image_to_probe: model,
        phantom_correction: correction,
        inlier,
        residual_mm,
        iterations,
        sd,
        pixel_model: pixel,
    })
}

/// A rigid `marker_T_image` with the pixel spacing trusted, refined by
/// Levenberg–Marquardt on point and line constraints from `start`. Returns the fit
/// and its RMS residual (mm).
pub fn refine_rigid(start: &Rigid, spacing: [f64; 2], constraints: &[Constraint]) -> Result<(Rigid, f64), LmError> {
    let model_at = |x: &DVector<f64>| {
        Calibration::new(
            perturbed(start, Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5])),
            spacing,
        )
    };
    let refs: Vec<&Constraint> = constraints.iter().collect();
    let mut steps = DVector::from_element(6, 1e-5);
    for k in 0..3 {
        steps[k] = 1e-7;
    }
    let out = lm::minimise(DVector::zeros(6), &steps, 200, |x| {
        residuals(&model_at(x), &Rigid::identity(), &refs)
    })?;
    let rms = (out.cost / constraints.len().max(1) as f64).sqrt();
    Ok((model_at(&out.x).marker_T_image, rms))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::Rng;

    #[test]
    fn recovers_pixel_size_and_pose_from_noisy_points_with_an_outlier() {
        let truth = Calibration::new(
            rigid_from_axis_angle(Vector3::new(0.3, -1.4, 0.2), Vector3::new(11.0, 48.0, -0.4)),
            [0.0803, 0.0745],
        );
        let mut rng = Rng::new(4);
        let mut constraints: Vec<Constraint> = (0..200)
            .map(|_| {
                let pixel = [rng.uniform(150.0, 650.0), rng.uniform(150.0, 500.0)];
                let noise = Vector3::new(rng.normal(0.0, 0.2), rng.normal(0.0, 0.2), rng.normal(0.0, 0.2));
                Constraint {
                    pixel,
                    elevation_mm: 0.0,
                    marker_T_phantom: Matrix4::identity(),
                    target_in_phantom: Target::Point(truth.apply(pixel) + noise),
                }
            })
            .collect();
        if let Target::Point(p) = &mut constraints[7].target_in_phantom {
            p.x += 8.0;
        }
        let start = closed_form(&constraints).unwrap();
        let settings = RefineSettings {
            pixel_model: PixelModel::Anisotropic,
            reject_sd: Some(3.0),
            refine_phantom: false,
        };
        let fit = refine(&start, &constraints, &settings).unwrap();
        assert!(!fit.inlier[7]);
        // The rigid refinement with the spacing trusted, from a start 5 mm and 3° off, on lines.
        let lines: Vec<Constraint> = constraints
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != 7)
            .map(|(i, c)| {
                let Target::Point(p) = c.target_in_phantom else {
                    unreachable!()
                };
                let direction = [Vector3::x(), Vector3::y(), Vector3::z()][i % 3];
                Constraint {
                    target_in_phantom: Target::Line(p + direction * 7.0, direction),
                    ..*c
                }
            })
            .collect();
        let start =
            truth.marker_T_image * rigid_from_axis_angle(Vector3::new(0.03, -0.04, 0.02), Vector3::new(5.0, -3.0, 2.0));
        let (rigid, rms) = refine_rigid(&start, truth.spacing_mm_per_px, &lines).unwrap();
        let refined = Calibration::new(rigid, truth.spacing_mm_per_px);
        assert!(rms < 0.3, "{rms}");
        for pixel in [[0.0, 0.0], [820.0, 616.0]] {
            let e = (refined.apply(pixel) - truth.apply(pixel)).norm();
            assert!(e < 0.2, "{e}");
        }
        let s = fit.image_to_probe.spacing_mm_per_px;
        assert!((s[0] - 0.0803).abs() < 4e-4 && (s[1] - 0.0745).abs() < 4e-4, "{s:?}");
        for pixel in [[0.0, 0.0], [820.0, 616.0]] {
            let e = (fit.image_to_probe.apply(pixel) - truth.apply(pixel)).norm();
            assert!(e < 0.3, "{e}");
        }
    }

    /// Points from a sheared pixel grid: the affine model finds the shear, the
    /// rigid models cannot and leave a larger residual.
    #[test]
    fn the_affine_model_recovers_a_shear_the_others_cannot() {
        let truth = Calibration {
            marker_T_image: rigid_from_axis_angle(Vector3::new(0.3, -1.4, 0.2), Vector3::new(11.0, 48.0, -0.4)),
            spacing_mm_per_px: [0.0803, 0.0745],
            shear_mm_per_px: 0.004,
        };
        let mut rng = Rng::new(5);
        let constraints: Vec<Constraint> = (0..300)
            .map(|_| {
                let pixel = [rng.uniform(100.0, 700.0), rng.uniform(100.0, 550.0)];
                let noise = Vector3::new(rng.normal(0.0, 0.1), rng.normal(0.0, 0.1), rng.normal(0.0, 0.1));
                Constraint {
                    pixel,
                    elevation_mm: 0.0,
                    marker_T_phantom: Matrix4::identity(),
                    target_in_phantom: Target::Point(truth.apply(pixel) + noise),
                }
            })
            .collect();
        let start = closed_form(&constraints).unwrap();
        let rms = |pixel_model| {
            let settings = RefineSettings {
                pixel_model,
                reject_sd: None,
                refine_phantom: false,
            };
            let fit = refine(&start, &constraints, &settings).unwrap();
            let n = fit.residual_mm.len() as f64;
            let rms = (fit.residual_mm.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
            (fit, rms)
        };
        let (affine, affine_rms) = rms(PixelModel::Affine);
        assert!(
            (affine.image_to_probe.shear_mm_per_px - 0.004).abs() < 2e-4,
            "{affine:?}"
        );
        assert_eq!(affine.sd.len(), 9);
        assert!(affine.sd[8] > 0.0 && affine.sd[8] < 1e-3, "{:?}", affine.sd);
        let (anisotropic, anisotropic_rms) = rms(PixelModel::Anisotropic);
        assert_eq!(anisotropic.image_to_probe.shear_mm_per_px, 0.0);
        let (isotropic, isotropic_rms) = rms(PixelModel::Isotropic);
        let [sx, sy] = isotropic.image_to_probe.spacing_mm_per_px;
        assert_eq!(sx, sy);
        assert!(
            affine_rms < 0.2 && anisotropic_rms > affine_rms + 0.1,
            "{affine_rms} {anisotropic_rms}"
        );
        assert!(isotropic_rms > anisotropic_rms, "{isotropic_rms} {anisotropic_rms}");
        for pixel in [[0.0, 0.0], [820.0, 616.0]] {
            let e = (affine.image_to_probe.apply(pixel) - truth.apply(pixel)).norm();
            assert!(e < 0.2, "{e}");
        }
    }
}
