//! The sphere fit with each frame's pose uncertain: `marker_T_image` and a
//! correction to every frame's `phantom_T_marker`, solved together.
//!
//! The plain sphere fit ([`super::sphere_fit`]) takes each frame's
//! `phantom_T_marker` (from the photo's two board poses) as exact. It is not:
//! the boards' corners are noisy and the hand moves between the photo and the
//! B-scan. An arc cut far from its dome's centre pins the plane's elevation
//! hard (`dr/dd = −d/r` is large there), so a frame with such an arc pulls the
//! calibration towards its own pose error. Here each frame's pose may move by
//! `δ_f`, with the prior `δ_f ~ N(0, Σ_f)` that the board corners and the hand
//! give (`Σ_f` from the caller, in [`perturbed`]'s coordinates of
//! `phantom_T_marker`: rotation vector on the left, then translation, rad and
//! mm), and the edge points weighted by their own noise `σ_e` (grown, with a
//! [`SliceBlur`], for arcs cut off their domes' centres): the maximum a
//! posteriori calibration under the model the design's Cramér–Rao bound
//! assumes. The poses are eliminated frame by frame (the normal equations'
//! Schur complement), so the solve stays a 6-unknown one per iteration.
//!
//! An error every frame shares (the camera's intrinsics: a focal length too
//! long places every board too far) does not average out over the frames; it
//! may be modelled too ([`SharedError`]): each frame's pose error is then its
//! own part plus its shift per unit shared error times that error, which is
//! solved with the calibration under its prior (what the camera calibration
//! knows of it). This is the model of the design's bound in full.

use nalgebra::{DMatrix, DVector, Matrix6, Point3, Vector6};

use super::bundle_frame::{at, split, FrameArcs};
use super::edge_blur::{variance_factor, SliceBlur};
use super::edge_offset::{offset_mm, EdgeOffset};
use super::sphere_fit::{ArcFrame, SphereFit, SphereFitError, SphereSettings};
use crate::core::geometry::{pixel_to_image_mm, Rigid};

/// The most Levenberg–Marquardt iterations.
pub const MAX_ITERATIONS: usize = 100;

/// What the fit needs beyond the plain sphere fit's settings.
#[derive(Debug, Clone)]
pub struct PosePriors {
    /// SD of an edge point about its sphere, mm (the arcs' own fit RMS).
    pub edge_sd_mm: f64,
    /// Per frame: the covariance of its `phantom_T_marker` error.
    pub frames: Vec<(usize, Matrix6<f64>)>,
    /// An error every frame's pose shares (the camera's intrinsics), if modelled.
    pub shared: Option<SharedError>,
    /// The echo edge's offset from its sphere: the terms solved with the
    /// calibration ([`EdgeOffset`]).
    pub edge_offset: EdgeOffset,
    /// How an edge point's noise grows as the plane cuts farther from its
    /// dome's centre ([`SliceBlur`]; the cut taken under `start`): absent,
    /// every arc alike.
    pub slice_blur: Option<SliceBlur>,
}

/// An error `k` every frame's pose shares: frame `f`'s pose error is
/// `F_f k + e_f`, with `e_f` its own (`PosePriors::frames`) and `k ~ N(0, I⁻¹)`.
#[derive(Debug, Clone)]
pub struct SharedError {
    /// `I`, the prior information on `k` (m × m).
    pub information: DMatrix<f64>,
    /// Per frame: `F_f`, the pose's shift per unit `k` (6 × m).
    pub frames: Vec<(usize, DMatrix<f64>)>,
}

/// `m` scaled to unit diagonal: `(D m D, D)`, so that unknowns of different
/// units (mm, rad, px, unitless distortion) solve alike.
fn equilibrated(m: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
    let d = DMatrix::from_diagonal(&m.diagonal().map(|v| 1.0 / v.max(f64::MIN_POSITIVE).sqrt()));
    (&d * m * &d, d)
}

/// Each frame's arcs with its pose prior (whitened) and its pose's dependence
/// on the shared unknowns; an arc with too few points, no prior or a weight that
/// is not a positive number is left out.
fn frame_arcs(
    start: &Rigid,
    arcs: &[ArcFrame],
    settings: &SphereSettings,
    priors: &PosePriors,
    m: usize,
) -> Vec<FrameArcs> {
    let mut frames: Vec<FrameArcs> = Vec::new();
    for a in arcs
        .iter()
        .filter(|a| a.edge_px.len() >= 3 && a.sphere < settings.spheres.len())
    {
        let Some((_, cov)) = priors.frames.iter().find(|(k, _)| *k == a.frame) else {
            continue;
        };
        let from_shared = match &priors.shared {
            None => DMatrix::zeros(6, 0),
            Some(shared) => match shared.frames.iter().find(|(k, _)| *k == a.frame) {
                Some((_, f)) if f.shape() == (6, m) => f.clone(),
                _ => continue,
            },
        };
        let points: Vec<Point3<f64>> = a
            .edge_px
            .iter()
            .map(|p| pixel_to_image_mm(*p, settings.spacing_mm_per_px))
            .collect();
        let phantom_T_marker = a.camera_T_phantom.inverse() * a.camera_T_marker;
        let sphere = settings.spheres[a.sphere];
        let cut_mm = ((phantom_T_marker * start).inverse() * sphere.centre_in_phantom_mm).z;
        let weight = (settings.points_per_frame
            / points.len() as f64
            / variance_factor(priors.slice_blur, sphere.radius_mm, cut_mm))
        .sqrt();
        // A weight that is not a positive number (a pose or start not finite) leaves the arc out.
        if !(weight.is_finite() && weight > 0.0) {
            continue;
        }
        let arc = (sphere, weight, points);
        match frames.iter_mut().find(|f| f.frame == a.frame) {
            Some(f) => f.arcs.push(arc),
            None => {
                let Some(l) = cov.cholesky() else { continue };
                let Some(whiten) = l.l().try_inverse() else { continue };
                frames.push(FrameArcs {
                    frame: a.frame,
                    phantom_T_marker,
                    arcs: vec![arc],
                    information: whiten.transpose() * whiten,
                    whiten,
                    from_shared,
                });
            }
        }
    }
    frames
}

/// The fit at the solution: the calibration, the edge offsets, and the arcs'
/// residual RMS overall and per frame.
#[allow(clippy::too_many_arguments)]
fn fitted(
    start: &Rigid,
    frames: &[FrameArcs],
    x: &DVector<f64>,
    deltas: &[Vector6<f64>],
    m: usize,
    model: EdgeOffset,
    settings: &SphereSettings,
    iterations: usize,
) -> SphereFit {
    let (c, k, free) = split(x, m);
    let o = model.expand(free.as_slice());
    let marker_T_image = at(start, &c);
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut frame_rms_mm = Vec::new();
    let mut elevation_mm = Vec::new();
    for (f, e) in frames.iter().zip(deltas) {
        let phantom_T_marker = at(&f.phantom_T_marker, &f.correction(&k, e));
        let phantom_T_image = phantom_T_marker * marker_T_image;
        let image_T_phantom = phantom_T_image.inverse();
        let (mut s, mut n) = (0.0, 0usize);
        for (sphere, _, points) in &f.arcs {
            let elevation = (image_T_phantom * sphere.centre_in_phantom_mm).z;
            let offset = offset_mm(&o, sphere, elevation);
            for p in points {
                s += ((phantom_T_image * p - sphere.centre_in_phantom_mm).norm() - sphere.radius_mm - offset).powi(2);
                n += 1;
            }
            elevation_mm.push((f.frame, elevation));
        }
        sum += s;
        count += n;
        frame_rms_mm.push((f.frame, (s / n.max(1) as f64).sqrt()));
    }
    SphereFit {
        marker_T_image,
        radius_offset_mm: o[0],
        edge_offset_mm: o,
        spacing_mm_per_px: settings.spacing_mm_per_px,
        rms_mm: (sum / count.max(1) as f64).sqrt(),
        elevation_mm,
        frame_rms_mm,
        iterations,
    }
}

/// The normal equations of one step: the unknowns all frames share (U, g) and
/// each frame's own (V, W, g_e).
#[allow(clippy::type_complexity)]
fn normal_equations(
    start: &Rigid,
    frames: &[FrameArcs],
    x: &DVector<f64>,
    deltas: &[Vector6<f64>],
    shared_information: &DMatrix<f64>,
    model: EdgeOffset,
    sd: f64,
) -> (
    DMatrix<f64>,
    DVector<f64>,
    Vec<(Matrix6<f64>, DMatrix<f64>, Vector6<f64>)>,
) {
    let m = shared_information.nrows();
    let n = x.len();
    let mut u = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    u.view_mut((6, 6), (m, m)).copy_from(shared_information);
    g.rows_mut(6, m).copy_from(&(shared_information * x.rows(6, m)));
    let mut blocks = Vec::with_capacity(frames.len());
    let (c, k, free) = split(x, m);
    for (f, e) in frames.iter().zip(deltas) {
        let (r, jx, jd) = f.linearised(start, (&c, &k, &free), e, model, sd);
        u += jx.transpose() * &jx;
        g += jx.transpose() * &r;
        let v = Matrix6::from_iterator((jd.transpose() * &jd).iter().copied()) + f.information;
        let w = jx.transpose() * &jd;
        let ge = Vector6::from_iterator((jd.transpose() * &r).iter().copied()) + f.information * e;
        blocks.push((v, w, ge));
    }
    (u, g, blocks)
}

/// Refines `start` (the plain sphere fit) with every frame's pose free under its prior.
pub fn refine(
    start: &Rigid,
    arcs: &[ArcFrame],
    settings: &SphereSettings,
    priors: &PosePriors,
) -> Result<SphereFit, SphereFitError> {
    let m = priors.shared.as_ref().map_or(0, |s| s.information.nrows());
    let frames = frame_arcs(start, arcs, settings, priors, m);
    let arc_count: usize = frames.iter().map(|f| f.arcs.len()).sum();
    if arc_count < 3 {
        return Err(SphereFitError::TooFewFrames(arc_count));
    }
    let shared_information = priors
        .shared
        .as_ref()
        .map_or_else(|| DMatrix::zeros(0, 0), |s| s.information.clone());
    let model = priors.edge_offset;
    let q = model.unknowns();
    let n = 6 + m + q;
    let sd = priors.edge_sd_mm;
    let mut x = DVector::zeros(n);
    let mut deltas = vec![Vector6::zeros(); frames.len()];
    let total = |x: &DVector<f64>, deltas: &[Vector6<f64>]| -> f64 {
        let k = x.rows(6, m);
        let prior = (k.transpose() * &shared_information * k)[(0, 0)];
        frames
            .iter()
            .zip(deltas)
            .map(|(f, e)| f.cost(start, x, m, model, e, sd))
            .sum::<f64>()
            + prior
    };
    let mut current = total(&x, &deltas);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS && current.is_finite() {
        iterations += 1;
        let (u, g, blocks) = normal_equations(start, &frames, &x, &deltas, &shared_information, model, sd);
        let accepted = loop {
            let mut s = &u + DMatrix::from_diagonal(&(u.diagonal() * lambda));
            let mut b = g.clone();
            let mut inverses = Vec::with_capacity(blocks.len());
            let mut singular = false;
            for (v, w, ge) in &blocks {
                let Some(vi) = (v + Matrix6::from_diagonal(&(v.diagonal() * lambda))).try_inverse() else {
                    singular = true;
                    break;
                };
                let wv = w * DMatrix::from_iterator(6, 6, vi.iter().copied());
                s -= &wv * w.transpose();
                b -= &wv * DVector::from_iterator(6, ge.iter().copied());
                inverses.push(vi);
            }
            let dx = if singular {
                None
            } else {
                let (scaled, d) = equilibrated(&s);
                scaled.lu().solve(&(-(&d * &b))).map(|y| &d * y)
            };
            if let Some(dx) = dx {
                let next_x = &x + &dx;
                let next: Vec<Vector6<f64>> = blocks
                    .iter()
                    .zip(&inverses)
                    .zip(&deltas)
                    .map(|(((_, w, ge), vi), e)| {
                        e - vi * (ge + Vector6::from_iterator((w.transpose() * &dx).iter().copied()))
                    })
                    .collect();
                let cost = total(&next_x, &next);
                if cost.is_finite() && cost <= current {
                    lambda = (lambda / 10.0).max(1e-12);
                    break Some((next_x, next, cost));
                }
            }
            if lambda >= 1e12 {
                break None;
            }
            lambda *= 10.0;
        };
        let Some((next_x, next, cost)) = accepted else { break };
        let decrease = current - cost;
        x = next_x;
        deltas = next;
        current = cost;
        if decrease <= 1e-12 * current.max(f64::MIN_POSITIVE) {
            break;
        }
    }
    Ok(fitted(start, &frames, &x, &deltas, m, model, settings, iterations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::core::rng::Rng;
    use crate::estimate::sphere_fit;
    use crate::estimate::sphere_fit::KnownSphere;
    use nalgebra::Vector3;

    const SPACING: [f64; 2] = [0.2, 0.2];

    fn spheres() -> Vec<KnownSphere> {
        (0..4)
            .map(|i| KnownSphere {
                centre_in_phantom_mm: Point3::new(24.0 * i as f64, 3.0 * (i % 2) as f64, -10.0 - 4.0 * i as f64),
                radius_mm: 12.5,
            })
            .collect()
    }

    /// Frames of four domes seen by planes at varied tilts; every frame's
    /// reported marker pose off the true one by the hand's motion (`tremor`:
    /// mm and degrees per axis, in the marker's frame).
    fn planted(tremor: (f64, f64), seed: u64) -> (Rigid, Vec<ArcFrame>) {
        let marker_T_image = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 1.5), Vector3::new(-20.0, 160.0, 25.0));
        let camera_T_phantom = rigid_from_axis_angle(Vector3::new(2.0, 0.1, 0.2), Vector3::new(-100.0, 80.0, 500.0));
        let mut rng = Rng::new(seed);
        let mut arcs = Vec::new();
        for k in 0..40 {
            // Image x along the row of domes, image y down into the phantom (-z), image z along y.
            let base = nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
            let tilt = rigid_from_axis_angle(
                Vector3::new(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.1, 0.1)),
                Vector3::zeros(),
            );
            let rotation = tilt.rotation * nalgebra::UnitQuaternion::from_matrix(&base);
            let origin = Vector3::new(-30.0 + rng.uniform(-3.0, 3.0), rng.normal(0.0, 2.0), 20.0);
            let phantom_T_image = Rigid::from_parts(origin.into(), rotation);
            let image_T_phantom = phantom_T_image.inverse();
            let camera_T_marker_true = camera_T_phantom * phantom_T_image * marker_T_image.inverse();
            let jitter = rigid_from_axis_angle(
                Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0)) * tremor.1.to_radians(),
                Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0)) * tremor.0,
            );
            for (s, sphere) in spheres().iter().enumerate() {
                let c = image_T_phantom * sphere.centre_in_phantom_mm;
                if c.z.abs() > 0.8 * sphere.radius_mm {
                    continue;
                }
                let r = (sphere.radius_mm.powi(2) - c.z * c.z).sqrt();
                let edge_px = (0..40)
                    .map(|i| {
                        let a = std::f64::consts::PI * (1.2 + 0.6 * i as f64 / 39.0);
                        [
                            (c.x + r * a.cos() + rng.normal(0.0, 0.14)) / SPACING[0],
                            (c.y + r * a.sin() + rng.normal(0.0, 0.14)) / SPACING[1],
                        ]
                    })
                    .collect();
                arcs.push(ArcFrame {
                    frame: k,
                    sphere: s,
                    edge_px,
                    camera_T_marker: camera_T_marker_true * jitter,
                    camera_T_phantom,
                });
            }
        }
        (marker_T_image, arcs)
    }

    fn settings() -> SphereSettings {
        SphereSettings {
            spheres: spheres(),
            spacing_mm_per_px: SPACING,
            elevation_prior_sd_mm: None,
            fit_radius_offset: false,
            points_per_frame: 20.0,
            fit_pixel_size: false,
        }
    }

    /// The prior of every frame: the hand's motion, isotropic per axis, in
    /// `phantom_T_marker`'s left coordinates (a rotation and a shift in the
    /// marker's frame, turned into the phantom's, keep their isotropic spread).
    fn priors(arcs: &[ArcFrame], tremor: (f64, f64)) -> PosePriors {
        let (mm, deg) = tremor;
        let cov = Matrix6::from_diagonal(&Vector6::new(
            deg.to_radians().powi(2),
            deg.to_radians().powi(2),
            deg.to_radians().powi(2),
            mm * mm,
            mm * mm,
            mm * mm,
        ));
        let mut frames: Vec<(usize, Matrix6<f64>)> = arcs.iter().map(|a| (a.frame, cov)).collect();
        frames.dedup_by_key(|f| f.0);
        PosePriors {
            edge_sd_mm: 0.14,
            frames,
            shared: None,
            edge_offset: EdgeOffset::None,
            slice_blur: None,
        }
    }

    fn corner_error(a: &Rigid, b: &Rigid) -> f64 {
        let corners = [[0.0, 0.0], [160.0, 0.0], [0.0, 120.0], [160.0, 120.0], [80.0, 60.0]];
        corners
            .iter()
            .map(|p| {
                let q = Point3::new(p[0], p[1], 0.0);
                (a * q - b * q).norm()
            })
            .sum::<f64>()
            / 5.0
    }

    #[test]
    fn pose_priors_take_the_hands_motion_out_of_the_calibration() {
        let tremor = (0.2, 0.06);
        let (mut plain_sum, mut posed_sum) = (0.0, 0.0);
        for seed in 1..=4 {
            let (truth, arcs) = planted(tremor, seed);
            let plain = sphere_fit::refine(&truth, &arcs, &settings()).unwrap();
            let posed = refine(&plain.marker_T_image, &arcs, &settings(), &priors(&arcs, tremor)).unwrap();
            plain_sum += corner_error(&plain.marker_T_image, &truth);
            posed_sum += corner_error(&posed.marker_T_image, &truth);
        }
        assert!(
            posed_sum < 0.7 * plain_sum,
            "mean corner error with pose priors {:.3} mm, without {:.3} mm",
            posed_sum / 4.0,
            plain_sum / 4.0
        );
    }

    #[test]
    fn an_error_every_frame_shares_is_solved_with_the_calibration() {
        // Every frame's phantom_T_marker is off along the phantom's z by its own
        // multiple (0.5 to 1.5, known) of one shared 0.8 mm: as a focal length
        // error moves every board along its line of sight by its own depth.
        let tremor = (0.05, 0.02);
        let (mut alone_sum, mut shared_sum) = (0.0, 0.0);
        for seed in 1..=3 {
            let (truth, mut arcs) = planted(tremor, seed);
            let scale = |frame: usize| 0.5 + (frame % 11) as f64 / 10.0;
            for a in &mut arcs {
                let shift = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.8 * scale(a.frame)));
                a.camera_T_marker = a.camera_T_phantom * shift * a.camera_T_phantom.inverse() * a.camera_T_marker;
            }
            let plain = sphere_fit::refine(&truth, &arcs, &settings()).unwrap();
            let alone = priors(&arcs, tremor);
            let mut with_shared = alone.clone();
            with_shared.shared = Some(SharedError {
                information: DMatrix::from_element(1, 1, 1.0),
                frames: alone
                    .frames
                    .iter()
                    .map(|(f, _)| {
                        (
                            *f,
                            DMatrix::from_column_slice(6, 1, &[0.0, 0.0, 0.0, 0.0, 0.0, scale(*f)]),
                        )
                    })
                    .collect(),
            });
            let fitted_alone = refine(&plain.marker_T_image, &arcs, &settings(), &alone).unwrap();
            let fitted_shared = refine(&plain.marker_T_image, &arcs, &settings(), &with_shared).unwrap();
            alone_sum += corner_error(&fitted_alone.marker_T_image, &truth);
            shared_sum += corner_error(&fitted_shared.marker_T_image, &truth);
        }
        assert!(
            shared_sum < 0.5 * alone_sum,
            "mean corner error with the shared error solved {:.3} mm, without {:.3} mm",
            shared_sum / 3.0,
            alone_sum / 3.0
        );
    }

    #[test]
    fn exact_poses_with_a_tight_prior_give_the_plain_fit() {
        let (truth, arcs) = planted((0.0, 0.0), 9);
        let plain = sphere_fit::refine(&truth, &arcs, &settings()).unwrap();
        let posed = refine(&plain.marker_T_image, &arcs, &settings(), &priors(&arcs, (1e-5, 1e-5))).unwrap();
        let apart = corner_error(&plain.marker_T_image, &posed.marker_T_image);
        assert!(apart < 1e-3, "{apart} mm apart");
    }
}
