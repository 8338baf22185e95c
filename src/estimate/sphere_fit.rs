//! The hemisphere without elevation bias: `marker_T_image` refined so that every
//! arc edge point lies on the sphere.
//!
//! When the B-scan plane misses the sphere centre by `d`, the arc has radius
//! `√(R² − d²)` and its centre is only the centre's *projection* onto the plane;
//! pairing it with the centre itself (the thesis's method) puts an error of `d`
//! along the plane's normal into every pair. Knowing `R`, each arc edge pixel
//! `x` must satisfy `|phantom_T_image · x − c| = R`: these point-to-sphere
//! distances, over all frames, are minimised by Levenberg–Marquardt from a
//! closed-form start. The in-plane position of the arc's centre is kept exactly;
//! the plane's elevation `d` comes from the arc's radius.
//!
//! Near `d = 0` the radius says little about `d` (`dr/dd = −d/r`), so each frame may
//! also carry a prior `d ~ N(0, σ_d)` (`elevation_prior_sd_mm`): with it the fit is
//! the MAP estimate between the thesis's assumption (`σ_d → 0`) and the sphere
//! alone (`σ_d → ∞`). The echo's leading edge may sit a little off the true
//! surface; `fit_radius_offset` estimates that offset as one more unknown, and
//! `fit_pixel_size` the pixel size across and along the beam as two more (a
//! medium whose speed of sound is not the scanner's scales every depth; on a
//! convex probe the scale acts along each beam, which the two sizes only
//! approximate).

use nalgebra::{DVector, Point3, Vector3};

use crate::core::geometry::{perturbed, pixel_to_image_mm, Rigid};
use crate::core::lm::{self, LmError};

/// One arc of a frame: its sphere (index into the settings' spheres), its edge
/// pixels and the frame's poses. A frame that cuts several spheres gives one
/// `ArcFrame` per arc.
#[derive(Debug, Clone)]
pub struct ArcFrame {
    pub frame: usize,
    pub sphere: usize,
    pub edge_px: Vec<[f64; 2]>,
    pub camera_T_marker: Rigid,
    pub camera_T_phantom: Rigid,
}

impl ArcFrame {
    fn phantom_T_marker(&self) -> Rigid {
        self.camera_T_phantom.inverse() * self.camera_T_marker
    }
}

/// A sphere the arcs lie on, in the phantom frame (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KnownSphere {
    pub centre_in_phantom_mm: Point3<f64>,
    pub radius_mm: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct SphereSettings {
    pub spheres: Vec<KnownSphere>,
    pub spacing_mm_per_px: [f64; 2],
    /// Prior spread of the plane's distance from the centre, mm; `None`: no prior.
    pub elevation_prior_sd_mm: Option<f64>,
    /// Also estimate a constant offset of the edge points from the sphere (mm).
    pub fit_radius_offset: bool,
    /// Edge points per frame are weighted so each frame counts as this many points.
    pub points_per_frame: f64,
    /// Also estimate the pixel size (two more unknowns, across and along the
    /// beam): a medium whose speed of sound is not the scanner's shows every
    /// echo at a scaled depth.
    pub fit_pixel_size: bool,
}

/// How many terms the offset has: `(a, b, c)`.
pub const TERMS: usize = 3;

/// The offset's terms, mm: `(a, b, c)`.
pub type EdgeTerms = [f64; TERMS];

#[derive(Debug, Clone)]
pub struct SphereFit {
    pub marker_T_image: Rigid,
    /// Estimated offset of the edge points outside the sphere, mm (0 when not fitted).
    pub radius_offset_mm: f64,
    /// The edge offset's terms `(a, b, c)` solved with the calibration, mm
    /// (`edge_offset`; 0 when not fitted).
    pub edge_offset_mm: EdgeTerms,
    /// The pixel size the fit maps edge pixels with: the settings' own, or the
    /// fitted one with `fit_pixel_size`, mm per pixel.
    pub spacing_mm_per_px: [f64; 2],
    /// RMS point-to-sphere distance, mm.
    pub rms_mm: f64,
    /// Signed distance of each arc's sphere centre from its frame's plane, mm.
    pub elevation_mm: Vec<(usize, f64)>,
    /// RMS point-to-sphere distance of each frame's edge points, mm, by frame.
    pub frame_rms_mm: Vec<(usize, f64)>,
    pub iterations: usize,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SphereFitError {
    #[error("{0} arcs with edge points; at least 3 are needed")]
    TooFewFrames(usize),
    #[error("sphere fit: {0}")]
    Lm(#[from] LmError),
    #[error(
        "the fitted pixel size {fitted_mm:?} mm/px is more than {:.0} % off the manifest's {nominal_mm:?}: no medium's speed of sound does that",
        MAX_PIXEL_SIZE_CHANGE * 100.0
    )]
    PixelSize { fitted_mm: [f64; 2], nominal_mm: [f64; 2] },
}

/// The most a fitted pixel size may differ from the manifest's: media from 1310
/// to 1770 m/s under a scanner's 1540 (water at any temperature, saline,
/// tissue-mimicking gels all lie inside). A fit beyond it has found something
/// other than the speed of sound and is refused.
pub const MAX_PIXEL_SIZE_CHANGE: f64 = 0.15;

fn model_at(start: &Rigid, x: &DVector<f64>) -> Rigid {
    perturbed(start, Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5]))
}

/// Signed distance of the sphere centre from the frame's image plane (image z), mm.
fn elevation(frame: &ArcFrame, marker_T_image: &Rigid, centre: &Point3<f64>) -> f64 {
    let image_T_phantom = (frame.phantom_T_marker() * marker_T_image).inverse();
    (image_T_phantom * centre).z
}

/// The edge points' RMS distance from their spheres under a calibration,
/// overall and per frame (consecutive arcs of one frame together), mm.
fn residual_rms(
    frames: &[&ArcFrame],
    points: &[Vec<Point3<f64>>],
    settings: &SphereSettings,
    marker_T_image: &Rigid,
    radius_offset_mm: f64,
) -> (f64, Vec<(usize, f64)>) {
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut per_frame: Vec<(usize, f64, usize)> = Vec::new();
    for (f, points) in frames.iter().zip(points) {
        if per_frame.last().is_none_or(|(k, _, _)| *k != f.frame) {
            per_frame.push((f.frame, 0.0, 0));
        }
        let phantom_T_image = f.phantom_T_marker() * marker_T_image;
        let KnownSphere {
            centre_in_phantom_mm: c,
            radius_mm,
        } = settings.spheres[f.sphere];
        for p in points {
            let squared = ((phantom_T_image * p - c).norm() - radius_mm - radius_offset_mm).powi(2);
            sum += squared;
            count += 1;
            if let Some(last) = per_frame.last_mut() {
                last.1 += squared;
                last.2 += 1;
            }
        }
    }
    let frame_rms_mm = per_frame
        .into_iter()
        .map(|(k, s, n)| (k, (s / n.max(1) as f64).sqrt()))
        .collect();
    ((sum / count.max(1) as f64).sqrt(), frame_rms_mm)
}

/// Refines `start` (e.g. Horn on the arc centres) on the arc edge points.
pub fn refine(start: &Rigid, frames: &[ArcFrame], settings: &SphereSettings) -> Result<SphereFit, SphereFitError> {
    let frames: Vec<&ArcFrame> = frames
        .iter()
        .filter(|f| f.edge_px.len() >= 3 && f.sphere < settings.spheres.len())
        .collect();
    if frames.len() < 3 {
        return Err(SphereFitError::TooFewFrames(frames.len()));
    }
    let sphere = |f: &ArcFrame| settings.spheres[f.sphere];
    let offset_at = settings.fit_radius_offset.then_some(6);
    let scale_at = settings
        .fit_pixel_size
        .then_some(6 + usize::from(settings.fit_radius_offset));
    let unknowns = 6 + usize::from(settings.fit_radius_offset) + 2 * usize::from(settings.fit_pixel_size);
    let spacing_of = |x: &DVector<f64>| match scale_at {
        Some(k) => [
            settings.spacing_mm_per_px[0] * (1.0 + x[k]),
            settings.spacing_mm_per_px[1] * (1.0 + x[k + 1]),
        ],
        None => settings.spacing_mm_per_px,
    };
    let in_image = |spacing: [f64; 2]| -> Vec<Vec<Point3<f64>>> {
        frames
            .iter()
            .map(|f| f.edge_px.iter().map(|p| pixel_to_image_mm(*p, spacing)).collect())
            .collect()
    };
    let fixed = in_image(settings.spacing_mm_per_px);
    let residuals = |x: &DVector<f64>| {
        let marker_T_image = model_at(start, x);
        let offset = offset_at.map_or(0.0, |k| x[k]);
        let scaled;
        let points_of = if scale_at.is_some() {
            scaled = in_image(spacing_of(x));
            &scaled
        } else {
            &fixed
        };
        let mut r = Vec::new();
        for (f, points) in frames.iter().zip(points_of) {
            let phantom_T_image = f.phantom_T_marker() * marker_T_image;
            let w = (settings.points_per_frame / points.len() as f64).sqrt();
            let KnownSphere {
                centre_in_phantom_mm: c,
                radius_mm,
            } = sphere(f);
            for p in points {
                r.push(w * ((phantom_T_image * p - c).norm() - radius_mm - offset));
            }
            if let Some(sd) = settings.elevation_prior_sd_mm {
                r.push(elevation(f, &marker_T_image, &c) / sd);
            }
        }
        DVector::from_vec(r)
    };
    let mut steps = DVector::from_element(unknowns, 1e-5);
    for k in 0..3 {
        steps[k] = 1e-7;
    }
    let out = lm::minimise(DVector::zeros(unknowns), &steps, 200, residuals)?;
    let marker_T_image = model_at(start, &out.x);
    let radius_offset_mm = offset_at.map_or(0.0, |k| out.x[k]);
    let spacing_mm_per_px = spacing_of(&out.x);
    let nominal = settings.spacing_mm_per_px;
    let plausible = |k: usize| {
        let change = (spacing_mm_per_px[k] / nominal[k] - 1.0).abs();
        change.is_finite() && change <= MAX_PIXEL_SIZE_CHANGE
    };
    if !(plausible(0) && plausible(1)) {
        return Err(SphereFitError::PixelSize {
            fitted_mm: spacing_mm_per_px,
            nominal_mm: nominal,
        });
    }
    let points = in_image(spacing_mm_per_px);
    let (rms_mm, frame_rms_mm) = residual_rms(&frames, &points, settings, &marker_T_image, radius_offset_mm);
    Ok(SphereFit {
        elevation_mm: frames
            .iter()
            .map(|f| (f.frame, elevation(f, &marker_T_image, &sphere(f).centre_in_phantom_mm)))
            .collect(),
        frame_rms_mm,
        marker_T_image,
        radius_offset_mm,
        edge_offset_mm: [0.0; TERMS],
        spacing_mm_per_px,
        rms_mm,
        iterations: out.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::core::rng::Rng;
    use crate::estimate::correspondence::{self, Correspondence};
    use crate::estimate::horn::{HornFit, Variant};
    use crate::evaluate;

    /// Frames whose planes all pass `offset_mm` beside the sphere centre (plus a
    /// spread), with the arc's edge points and the arc centre (the projection).
    fn planted(offset_mm: f64, spread_mm: f64, seed: u64) -> (Rigid, Vec<ArcFrame>, Vec<Correspondence>) {
        let marker_T_image = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 1.5), Vector3::new(-20.0, 160.0, 25.0));
        let camera_T_phantom = rigid_from_axis_angle(Vector3::new(2.0, 0.1, 0.2), Vector3::new(-100.0, 80.0, 500.0));
        let c = Point3::new(60.0, 45.0, -40.0);
        let (radius, spacing) = (15.0, [0.2, 0.2]);
        let mut rng = Rng::new(seed);
        let mut arcs = Vec::new();
        let mut centres = Vec::new();
        for k in 0..30 {
            // The arc's centre pixel, and the plane's elevation from the sphere centre.
            let centre_px = [rng.uniform(250.0, 450.0), rng.uniform(150.0, 350.0)];
            let d = offset_mm + rng.normal(0.0, spread_mm);
            let tilt = Vector3::new(rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(-0.1, 0.1));
            let phantom_R_image = rigid_from_axis_angle(tilt, Vector3::zeros()).rotation;
            // The image point at the arc's centre sits at c - d n (n: the image's z in the phantom).
            let on_plane = pixel_to_image_mm(centre_px, spacing).coords;
            let normal = phantom_R_image * Vector3::z();
            let t = c.coords - normal * d - phantom_R_image * on_plane;
            let phantom_T_image = Rigid::from_parts(t.into(), phantom_R_image);
            let camera_T_marker = camera_T_phantom * phantom_T_image * marker_T_image.inverse();
            let r = (radius * radius - d * d).sqrt();
            let edge_px: Vec<[f64; 2]> = (0..60)
                .map(|i| {
                    // The upper half of the circle (the dome, towards the probe).
                    let a = std::f64::consts::PI * (1.0 + i as f64 / 59.0);
                    [
                        centre_px[0] + (r * a.cos()) / spacing[0] + rng.normal(0.0, 0.3),
                        centre_px[1] + (r * a.sin()) / spacing[1] + rng.normal(0.0, 0.3),
                    ]
                })
                .collect();
            arcs.push(ArcFrame {
                frame: k,
                sphere: 0,
                edge_px,
                camera_T_marker,
                camera_T_phantom,
            });
            centres.push(Correspondence::point(
                k,
                centre_px,
                c,
                camera_T_marker,
                camera_T_phantom,
            ));
        }
        (marker_T_image, arcs, centres)
    }

    #[test]
    fn a_fitted_pixel_size_no_medium_gives_is_refused() {
        let (truth, arcs, _) = planted(0.0, 2.0, 21);
        // The manifest's size 5 % off the true 0.2 mm: found, and the fit kept.
        let near = SphereSettings {
            spacing_mm_per_px: [0.21, 0.21],
            fit_pixel_size: true,
            ..settings(None)
        };
        let fit = refine(&truth, &arcs, &near).unwrap();
        for k in 0..2 {
            assert!(
                (fit.spacing_mm_per_px[k] / 0.2 - 1.0).abs() < 0.01,
                "{:?}",
                fit.spacing_mm_per_px
            );
        }
        // 50 % off: the fit would need a medium at 1030 m/s and is refused.
        let far = SphereSettings {
            spacing_mm_per_px: [0.3, 0.3],
            ..near
        };
        assert!(matches!(
            refine(&truth, &arcs, &far),
            Err(SphereFitError::PixelSize { .. })
        ));
    }

    fn settings(prior: Option<f64>) -> SphereSettings {
        SphereSettings {
            spheres: vec![KnownSphere {
                centre_in_phantom_mm: Point3::new(60.0, 45.0, -40.0),
                radius_mm: 15.0,
            }],
            spacing_mm_per_px: [0.2, 0.2],
            elevation_prior_sd_mm: prior,
            fit_radius_offset: false,
            points_per_frame: 20.0,
            fit_pixel_size: false,
        }
    }

    #[test]
    fn sphere_fit_removes_a_planted_elevation_offset() {
        // Every plane 3 mm beside the centre: Horn on the arc centres is off by 3 mm
        // along the image's normal; the sphere fit is not.
        let (truth, arcs, centres) = planted(3.0, 0.3, 5);
        let horn = correspondence::solve(&centres, [0.2, 0.2], Variant::Rigid, None).unwrap();
        let before = evaluate::compare_with_truth(&horn, &truth, [800, 600], [0.2, 0.2]);
        assert!(before.corner_error_mean_mm > 2.5, "{before:?}");
        let fit = refine(&horn.target_T_source, &arcs, &settings(None)).unwrap();
        let after = evaluate::compare_with_truth(
            &HornFit {
                target_T_source: fit.marker_T_image,
                scale: 1.0,
                rms_residual_mm: fit.rms_mm,
            },
            &truth,
            [800, 600],
            [0.2, 0.2],
        );
        assert!(after.corner_error_mean_mm < 0.15, "before {before:?}, after {after:?}");
        // The planes' elevations are found (sign included).
        let mean_d = fit.elevation_mm.iter().map(|(_, d)| d).sum::<f64>() / fit.elevation_mm.len() as f64;
        assert!((mean_d.abs() - 3.0).abs() < 0.2, "mean elevation {mean_d}");
    }

    #[test]
    fn converges_from_perturbed_starts() {
        let (truth, arcs, _) = planted(1.0, 0.8, 11);
        let mut rng = Rng::new(3);
        for _ in 0..8 {
            // Up to 5 mm and about 3° off in every direction.
            let off = rigid_from_axis_angle(
                Vector3::new(
                    rng.uniform(-0.05, 0.05),
                    rng.uniform(-0.05, 0.05),
                    rng.uniform(-0.05, 0.05),
                ),
                Vector3::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0)),
            );
            let fit = refine(&(truth * off), &arcs, &settings(None)).unwrap();
            let error = (fit.marker_T_image.translation.vector - truth.translation.vector).norm();
            let angle = fit.marker_T_image.rotation.angle_to(&truth.rotation).to_degrees();
            assert!(error < 0.2 && angle < 0.1, "from {off:?}: {error} mm, {angle}°");
        }
    }

    #[test]
    fn the_prior_keeps_centred_planes_stable() {
        // Planes through the centre (d spread 0.5 mm): with the prior the fit is at
        // least as good as Horn on the centres.
        let (truth, arcs, centres) = planted(0.0, 0.5, 8);
        let horn = correspondence::solve(&centres, [0.2, 0.2], Variant::Rigid, None).unwrap();
        let before = evaluate::compare_with_truth(&horn, &truth, [800, 600], [0.2, 0.2]);
        let fit = refine(&horn.target_T_source, &arcs, &settings(Some(0.5))).unwrap();
        let after = evaluate::compare_with_truth(
            &HornFit {
                target_T_source: fit.marker_T_image,
                scale: 1.0,
                rms_residual_mm: fit.rms_mm,
            },
            &truth,
            [800, 600],
            [0.2, 0.2],
        );
        assert!(
            after.corner_error_mean_mm <= before.corner_error_mean_mm + 0.02,
            "before {before:?}, after {after:?}"
        );
    }
}
