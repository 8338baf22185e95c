//! Point pairs and their solve: a frame's feature pixel `(u, v)` gives
//! `points_in_image = (sx u, sy v, 0)`; the phantom feature `p` gives
//! `points_in_marker = marker_T_camera · camera_T_phantom · p`. Horn's closed form
//! on these pairs is `marker_T_image`; a frame's back-projection residual (BRE) is
//! its features' distance from their targets in the phantom frame.

use nalgebra::{Point3, Vector3};

use crate::core::geometry::{pixel_to_image_mm, Rigid};
use crate::estimate::horn::{self, HornError, HornFit, Variant};
use crate::estimate::image_to_probe::{self, Constraint, Target};

/// One segmented feature of a frame: its pixel and where it lies in the phantom.
#[derive(Debug, Clone, PartialEq)]
pub struct Observed {
    pub pixel: [f64; 2],
    /// Where the feature sits off the image plane, along the image's z (mm): 0 for
    /// a feature in the plane; for a sphere's arc, its centre's elevation.
    pub elevation_mm: f64,
    pub target_in_phantom: Target,
}

impl Observed {
    /// The feature in the image frame, mm.
    pub fn in_image_mm(&self, spacing: [f64; 2]) -> Point3<f64> {
        let mut p = pixel_to_image_mm(self.pixel, spacing);
        p.z = self.elevation_mm;
        p
    }
}

/// One usable frame's measurements.
#[derive(Debug, Clone)]
pub struct Correspondence {
    pub frame: usize,
    /// One feature (hemisphere, pin head) or several (wire dots).
    pub features: Vec<Observed>,
    pub camera_T_marker: Rigid,
    pub camera_T_phantom: Rigid,
}

impl Correspondence {
    /// A frame with one point feature.
    pub fn point(
        frame: usize,
        pixel: [f64; 2],
        feature_in_phantom: Point3<f64>,
        camera_T_marker: Rigid,
        camera_T_phantom: Rigid,
    ) -> Correspondence {
        Correspondence {
            frame,
            features: vec![Observed {
                pixel,
                elevation_mm: 0.0,
                target_in_phantom: Target::Point(feature_in_phantom),
            }],
            camera_T_marker,
            camera_T_phantom,
        }
    }

    /// Each feature as a constraint of the calibration with the pixel size.
    pub fn constraints(&self) -> impl Iterator<Item = Constraint> + '_ {
        let marker_T_phantom = self.marker_T_phantom().to_homogeneous();
        self.features.iter().map(move |o| Constraint {
            pixel: o.pixel,
            elevation_mm: o.elevation_mm,
            marker_T_phantom,
            target_in_phantom: o.target_in_phantom,
        })
    }

    pub fn marker_T_phantom(&self) -> Rigid {
        self.camera_T_marker.inverse() * self.camera_T_phantom
    }

    /// A feature back-projected into the phantom frame through a calibration.
    pub fn reconstruct_in_phantom(&self, feature: &Observed, calibration: &HornFit, spacing: [f64; 2]) -> Point3<f64> {
        let in_image = feature.in_image_mm(spacing);
        self.camera_T_phantom.inverse() * (self.camera_T_marker * calibration.apply(&in_image))
    }

    /// Residual of each feature in the phantom frame (mm): to its point, or
    /// perpendicular to its line.
    pub fn residuals_in_phantom(&self, calibration: &HornFit, spacing: [f64; 2]) -> Vec<Vector3<f64>> {
        self.features
            .iter()
            .map(|f| {
                let p = self.reconstruct_in_phantom(f, calibration, spacing);
                match f.target_in_phantom {
                    Target::Point(q) => p - q,
                    Target::Line(q, d) => {
                        let w = p - q;
                        w - d * w.dot(&d)
                    }
                }
            })
            .collect()
    }
}

/// Solves `marker_T_image` (and a scale, for the similarity variant) from frames.
/// Point features alone: Horn's closed form. With line features (wires): rigid
/// Levenberg–Marquardt from `start`.
pub fn solve(
    frames: &[Correspondence],
    spacing: [f64; 2],
    variant: Variant,
    start: Option<&Rigid>,
) -> Result<HornFit, HornError> {
    let all_points = frames
        .iter()
        .flat_map(|f| &f.features)
        .all(|o| matches!(o.target_in_phantom, Target::Point(_)));
    if all_points {
        let mut points_in_image = Vec::new();
        let mut points_in_marker = Vec::new();
        for f in frames {
            let marker_T_phantom = f.marker_T_phantom();
            for o in &f.features {
                if let Target::Point(p) = o.target_in_phantom {
                    points_in_image.push(o.in_image_mm(spacing));
                    points_in_marker.push(marker_T_phantom * p);
                }
            }
        }
        return horn::solve(&points_in_image, &points_in_marker, variant);
    }
    let Some(start) = start else {
        return Err(HornError::Refinement(
            "line features need a start (solve.initial_marker_T_image)".into(),
        ));
    };
    let constraints: Vec<Constraint> = frames.iter().flat_map(Correspondence::constraints).collect();
    // Six unknowns; each line feature gives two equations, a point three.
    let equations: usize = frames
        .iter()
        .flat_map(|f| &f.features)
        .map(|o| match o.target_in_phantom {
            Target::Point(_) => 3,
            Target::Line(..) => 2,
        })
        .sum();
    if equations < 9 {
        return Err(HornError::TooFewPairs(constraints.len()));
    }
    let (marker_T_image, rms) =
        image_to_probe::refine_rigid(start, spacing, &constraints).map_err(|e| HornError::Refinement(e.to_string()))?;
    Ok(HornFit {
        target_T_source: marker_T_image,
        scale: 1.0,
        rms_residual_mm: rms,
    })
}

/// Per-axis BRE of one frame, mm: `[|dx|, |dy|, |dz|]` and the 3D distance, of its
/// features' residuals in the phantom frame (averaged over its features).
pub fn bre(frame: &Correspondence, calibration: &HornFit, spacing: [f64; 2]) -> ([f64; 3], f64) {
    let residuals = frame.residuals_in_phantom(calibration, spacing);
    let n = residuals.len().max(1) as f64;
    let mut axes = [0.0; 3];
    let mut norm = 0.0;
    for d in &residuals {
        axes[0] += d.x.abs() / n;
        axes[1] += d.y.abs() / n;
        axes[2] += d.z.abs() / n;
        norm += d.norm() / n;
    }
    (axes, norm)
}

/// Synthetic frames for the estimators' tests.
#[cfg(test)]
pub(crate) mod test_frames {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::core::rng::Rng;

    /// Frames of a swept probe whose feature pixel is exact, then blurred by
    /// `noise_px`; the frames in `outliers` get a feature pixel far off.
    pub(crate) fn frames(
        n: usize,
        noise_px: f64,
        outliers: &[usize],
        seed: u64,
    ) -> (Rigid, Point3<f64>, Vec<Correspondence>) {
        let marker_T_image = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 1.5), Vector3::new(-20.0, 160.0, 25.0));
        let camera_T_phantom = rigid_from_axis_angle(Vector3::new(2.0, 0.1, 0.2), Vector3::new(-100.0, 80.0, 500.0));
        let feature = Point3::new(60.0, 45.0, -40.0);
        let spacing = [0.2, 0.2];
        let mut rng = Rng::new(seed);
        let frames = (0..n)
            .map(|k| {
                let px = [rng.uniform(250.0, 450.0), rng.uniform(150.0, 350.0)];
                let tilt = Vector3::new(rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(-0.1, 0.1));
                let phantom_R_image = rigid_from_axis_angle(tilt, Vector3::zeros()).rotation;
                let t = feature.coords - phantom_R_image * pixel_to_image_mm(px, spacing).coords;
                let phantom_T_image = Rigid::from_parts(t.into(), phantom_R_image);
                let camera_T_marker = camera_T_phantom * phantom_T_image * marker_T_image.inverse();
                let mut seen = [px[0] + rng.normal(0.0, noise_px), px[1] + rng.normal(0.0, noise_px)];
                if outliers.contains(&k) {
                    seen = [seen[0] + rng.uniform(40.0, 80.0), seen[1] - rng.uniform(40.0, 80.0)];
                }
                Correspondence::point(k, seen, feature, camera_T_marker, camera_T_phantom)
            })
            .collect();
        (marker_T_image, feature, frames)
    }
}
