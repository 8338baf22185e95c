//! The Cramér–Rao bound of a dome phantom's calibration (the sphere fit's
//! model): what no unbiased estimator can beat for a given layout, sweep and noise.
//!
//! Each arc edge point `x` (image frame, mm) of sphere `k` in a frame measures
//! `|P · M · x − c_k| − R_k = 0` with Gaussian noise `σ_edge` along the normal.
//! `M` is `marker_T_image` (six unknowns); `P` is the frame's `phantom_T_marker`,
//! measured from the photo's two board poses, so known only up to their error
//! (`evaluate::pose_noise`): each frame's own part (its corners' noise, the
//! hand's motion between photo and B-scan) is six nuisance unknowns per frame
//! with that Gaussian prior, marginalised frame by frame (Schur complement); the
//! part the camera's intrinsics error puts into every frame alike is nine
//! unknowns shared by all frames, with the camera calibration's own
//! information as their prior, marginalised last. The edge noise is correlated along an arc
//! (speckle, blur), so each arc counts as `points_per_arc` independent points,
//! as the sphere fit weighs it, and its points' variance grows with how far the
//! plane cuts from the dome's centre when the noise has a [`SliceBlur`]. The bound on the calibration maps to an RMS
//! error over the image's corners and centre (the study's measure).

use nalgebra::{DMatrix, Matrix6, Point3, Vector6};

use super::pose_noise::{pose_at as at, IntrinsicsInformation, PoseFromIntrinsics, INTRINSICS};
use crate::core::geometry::Rigid;
use crate::estimate::edge_blur::{variance_factor, SliceBlur};
use crate::estimate::edge_offset::EdgeOffset;
use crate::estimate::sphere_fit::KnownSphere;

/// One frame of the bound: the true `phantom_T_marker`, each arc's sphere
/// (index) with its edge points in the image frame (mm), and the error of its
/// `phantom_T_marker` (in [`perturbed`](crate::core::geometry::perturbed)'s coordinates: rotation rad, translation mm).
#[derive(Debug, Clone)]
pub struct BoundFrame {
    pub phantom_T_marker: Rigid,
    pub arcs: Vec<(usize, Vec<Point3<f64>>)>,
    /// Covariance of the frame's own pose error (independent between frames).
    pub pose_cov: Matrix6<f64>,
    /// The pose's shift per unit error of the camera's intrinsics.
    pub pose_from_intrinsics: PoseFromIntrinsics,
}

/// The arcs' noise (each value's source is stated where it is set).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EdgeNoise {
    /// SD of an edge point's distance from its sphere, mm.
    pub edge_sd_mm: f64,
    /// Independent points an arc is worth.
    pub points_per_arc: f64,
    /// How the edge noise grows as the plane cuts a dome farther from its
    /// centre (absent: every arc alike), [`SliceBlur`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slice_blur: Option<SliceBlur>,
}

const STEP: f64 = 1e-6;

fn unit(k: usize) -> Vector6<f64> {
    let mut v = Vector6::zeros();
    v[k] = STEP;
    v
}

/// The bound's RMS error over `probes` (image frame, mm), or `None` when the
/// layout leaves the calibration unobserved.
/// `intrinsics_information` is what the camera calibration knows of the
/// intrinsics (the inverse of their covariance). `edge_offset` is the model of
/// the echo edge's offset from its sphere that the fit solves with the
/// calibration: its unknowns are nuisances without a prior, marginalised with
/// the intrinsics (linearised at no offset).
pub fn corner_rms_bound(
    marker_T_image: &Rigid,
    frames: &[BoundFrame],
    spheres: &[KnownSphere],
    noise: &EdgeNoise,
    intrinsics_information: &IntrinsicsInformation,
    edge_offset: EdgeOffset,
    probes: &[Point3<f64>],
) -> Option<f64> {
    const N: usize = 6 + INTRINSICS;
    let q = edge_offset.unknowns();
    let n = N + q;
    // Information on (calibration, intrinsics, edge offsets), each frame's own pose error marginalised.
    let mut info = DMatrix::<f64>::zeros(n, n);
    let image_T_marker = marker_T_image.inverse();
    for frame in frames {
        let rows: usize = frame.arcs.iter().map(|(_, p)| p.len()).sum();
        if rows == 0 {
            continue;
        }
        let mut j_cal = DMatrix::<f64>::zeros(rows, 6);
        let mut j_pose = DMatrix::<f64>::zeros(rows, 6);
        let mut j_offset = DMatrix::<f64>::zeros(rows, q);
        let mut weights = Vec::with_capacity(rows);
        let mut row = 0;
        let image_T_phantom = image_T_marker * frame.phantom_T_marker.inverse();
        for (k, points) in &frame.arcs {
            let sphere = spheres.get(*k)?;
            let cut_mm = (image_T_phantom * sphere.centre_in_phantom_mm).z;
            let w = noise.points_per_arc
                / points.len() as f64
                / noise.edge_sd_mm.powi(2)
                / variance_factor(noise.slice_blur, sphere.radius_mm, cut_mm);
            let offset_terms = edge_offset.terms(sphere, cut_mm);
            let residual = |p: &Rigid, m: &Rigid, x: &Point3<f64>| {
                (p * (m * x) - sphere.centre_in_phantom_mm).norm() - sphere.radius_mm
            };
            for x in points {
                let r0 = residual(&frame.phantom_T_marker, marker_T_image, x);
                for c in 0..6 {
                    j_cal[(row, c)] = (residual(&frame.phantom_T_marker, &at(marker_T_image, &unit(c)), x) - r0) / STEP;
                    j_pose[(row, c)] =
                        (residual(&at(&frame.phantom_T_marker, &unit(c)), marker_T_image, x) - r0) / STEP;
                }
                for (j, t) in offset_terms.iter().enumerate() {
                    j_offset[(row, j)] = -t;
                }
                weights.push(w);
                row += 1;
            }
        }
        let w = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(weights));
        let from_intrinsics = DMatrix::from_iterator(6, INTRINSICS, frame.pose_from_intrinsics.iter().copied());
        let mut g = DMatrix::<f64>::zeros(rows, n);
        g.columns_mut(0, 6).copy_from(&j_cal);
        g.columns_mut(6, INTRINSICS).copy_from(&(&j_pose * from_intrinsics));
        g.columns_mut(N, q).copy_from(&j_offset);
        let pose_prior = frame.pose_cov.try_inverse()?;
        let a = g.transpose() * &w * &g;
        let b = g.transpose() * &w * &j_pose;
        let c = j_pose.transpose() * &w * &j_pose + DMatrix::from_iterator(6, 6, pose_prior.iter().copied());
        let c_inv = c.try_inverse()?;
        info += a - &b * c_inv * b.transpose();
    }
    // The calibration's knowledge of the intrinsics, then the intrinsics and
    // the edge offsets marginalised.
    let own = Matrix6::from_iterator(info.view((0, 0), (6, 6)).iter().copied());
    let shared = info.view((0, 6), (6, INTRINSICS));
    // The nuisances: the intrinsics when some frame depends on them, the offsets.
    let mut nuisance: Vec<usize> = Vec::with_capacity(INTRINSICS + q);
    if shared.iter().any(|v| *v != 0.0) {
        nuisance.extend(6..N);
    }
    nuisance.extend(N..n);
    let info = if nuisance.is_empty() {
        own
    } else {
        let mut prior = DMatrix::<f64>::zeros(n, n);
        prior
            .view_mut((6, 6), (INTRINSICS, INTRINSICS))
            .copy_from(intrinsics_information);
        let mut kk = DMatrix::from_fn(nuisance.len(), nuisance.len(), |i, j| {
            info[(nuisance[i], nuisance[j])] + prior[(nuisance[i], nuisance[j])]
        });
        let mut ck = DMatrix::from_fn(6, nuisance.len(), |i, j| info[(i, nuisance[j])]);
        // Scaled so that focal lengths (px), distortion (unitless) and offsets (mm) invert alike.
        let scale = DMatrix::from_diagonal(&kk.diagonal().map(|d| 1.0 / d.max(f64::MIN_POSITIVE).sqrt()));
        kk = &scale * kk * &scale;
        ck *= &scale;
        let reduced = &ck * kk.try_inverse()? * ck.transpose();
        own - Matrix6::from_iterator(reduced.iter().copied())
    };
    probe_rms(marker_T_image, &info.try_inverse()?, probes)
}

/// The RMS over `probes` of the position error a calibration covariance `cov`
/// gives them (image frame, mm), or `None` when it is not finite.
fn probe_rms(marker_T_image: &Rigid, cov: &Matrix6<f64>, probes: &[Point3<f64>]) -> Option<f64> {
    let mut sum = 0.0;
    for q in probes {
        let q0 = marker_T_image * q;
        let mut j = nalgebra::Matrix3x6::<f64>::zeros();
        for c in 0..6 {
            let d = (at(marker_T_image, &unit(c)) * q - q0) / STEP;
            j.set_column(c, &d);
        }
        sum += (j * cov * j.transpose()).trace();
    }
    let rms = (sum / probes.len().max(1) as f64).sqrt();
    rms.is_finite().then_some(rms)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::estimate::edge_offset::{self, EdgeTerms};
    use crate::estimate::sphere_bundle;
    use nalgebra::Vector3;

    /// Each frame's own pose error: 0.02° and 0.2 mm per axis.
    fn own_pose_cov() -> Matrix6<f64> {
        let r = 0.02f64.to_radians().powi(2);
        Matrix6::from_diagonal(&Vector6::new(r, r, r, 0.04, 0.04, 0.04))
    }

    fn frames(elevations: &[f64], spheres: &[KnownSphere], shift: &PoseFromIntrinsics) -> Vec<BoundFrame> {
        // Planes through the phantom's x–z plane, shifted along y by `d`, tilted a little.
        let mut out = Vec::new();
        for (i, d) in elevations.iter().enumerate() {
            let tilt = Vector3::new(0.05 * ((i % 3) as f64 - 1.0), 0.0, 0.04 * ((i % 5) as f64 - 2.0));
            let phantom_T_image = rigid_from_axis_angle(
                Vector3::new(-std::f64::consts::FRAC_PI_2, 0.0, 0.0) + tilt,
                Vector3::new(-40.0, *d, 50.0),
            );
            let marker_T_image = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(-20.0, 160.0, 25.0));
            let phantom_T_marker = phantom_T_image * marker_T_image.inverse();
            let image_T_phantom = phantom_T_image.inverse();
            let arcs = spheres
                .iter()
                .enumerate()
                .filter_map(|(k, s)| {
                    let p = image_T_phantom * s.centre_in_phantom_mm;
                    let r2 = s.radius_mm.powi(2) - p.z * p.z;
                    (r2 > 0.0).then(|| {
                        let r = r2.sqrt();
                        let points = (0..40)
                            .map(|j| {
                                let a = (-55.0 + 110.0 * j as f64 / 39.0f64).to_radians();
                                Point3::new(p.x + r * a.sin(), p.y - r * a.cos(), 0.0)
                            })
                            .collect();
                        (k, points)
                    })
                })
                .collect();
            out.push(BoundFrame {
                phantom_T_marker,
                arcs,
                pose_cov: own_pose_cov(),
                pose_from_intrinsics: *shift,
            });
        }
        out
    }

    fn probes() -> [Point3<f64>; 3] {
        [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(80.0, 0.0, 0.0),
            Point3::new(40.0, 60.0, 0.0),
        ]
    }

    fn three_domes() -> Vec<KnownSphere> {
        [(-22.0, -5.0), (0.0, 0.0), (22.0, 5.0)]
            .iter()
            .map(|(x, y)| KnownSphere {
                centre_in_phantom_mm: Point3::new(*x, *y, 0.0),
                radius_mm: 10.0,
            })
            .collect()
    }

    fn elevations() -> Vec<f64> {
        (0..40).map(|i| 0.5 * ((i % 7) as f64 - 3.0) / 3.0).collect()
    }

    /// The pose-prior sphere fit under `model` on data drawn from the bound's
    /// own model (edge points with independent Gaussian distances from their
    /// spheres plus the offset `terms_mm` gives ([`edge_offset::offset_mm`]), each
    /// frame's pose off by the hand's Gaussian motion, no shared error): its
    /// RMS corner error over many draws, over the bound's under the same model.
    /// With `blur`, each point's variance grows with its arc's cut as
    /// [`SliceBlur`] says, and the fit and the bound both know it.
    // A test scenario read top to bottom: the rule on functions is for the code under test.
    #[allow(clippy::too_many_lines)]
    fn fit_over_bound(model: EdgeOffset, terms_mm: EdgeTerms, blur: Option<SliceBlur>) -> f64 {
        use crate::core::rng::Rng;
        use crate::estimate::sphere_bundle::PosePriors;
        use crate::estimate::sphere_fit::{self, ArcFrame, SphereSettings};
        let spheres = three_domes();
        let spacing = [0.2, 0.2];
        let (edge_sd_mm, hand_mm, hand_deg): (f64, f64, f64) = (0.12, 0.1, 0.03);
        let r = hand_deg.to_radians().powi(2);
        let pose_cov = Matrix6::from_diagonal(&Vector6::new(
            r,
            r,
            r,
            hand_mm * hand_mm,
            hand_mm * hand_mm,
            hand_mm * hand_mm,
        ));
        let truth = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 0.01), Vector3::new(-20.0, 160.0, 25.0));
        let camera_T_phantom = rigid_from_axis_angle(Vector3::new(2.0, 0.1, 0.2), Vector3::new(-100.0, 80.0, 500.0));
        let probes: Vec<Point3<f64>> = [[0.0, 0.0], [100.0, 0.0], [0.0, 80.0], [100.0, 80.0], [50.0, 40.0]]
            .iter()
            .map(|p| Point3::new(p[0], p[1], 0.0))
            .collect();
        let noise = EdgeNoise {
            edge_sd_mm,
            points_per_arc: 40.0,
            slice_blur: blur,
        };
        let mut rng = Rng::new(21);
        let trials = 30;
        let (mut error2, mut bound2) = (0.0, 0.0);
        for _ in 0..trials {
            let (mut bound_frames, mut arcs) = (Vec::new(), Vec::new());
            for frame in 0..40 {
                let tilt = Vector3::new(
                    rng.uniform(-0.15, 0.15),
                    rng.uniform(-0.15, 0.15),
                    rng.uniform(-0.1, 0.1),
                );
                let phantom_T_image = rigid_from_axis_angle(
                    Vector3::new(-std::f64::consts::FRAC_PI_2, 0.0, 0.0) + tilt,
                    Vector3::new(
                        -40.0 + rng.uniform(-3.0, 3.0),
                        rng.normal(0.0, 2.0),
                        50.0 + rng.uniform(-5.0, 5.0),
                    ),
                );
                let phantom_T_marker = phantom_T_image * truth.inverse();
                let image_T_phantom = phantom_T_image.inverse();
                let hand = rigid_from_axis_angle(
                    Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0))
                        * hand_deg.to_radians(),
                    Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0)) * hand_mm,
                );
                let mut frame_arcs = Vec::new();
                for (k, sphere) in spheres.iter().enumerate() {
                    let c = image_T_phantom * sphere.centre_in_phantom_mm;
                    if c.z.abs() > 0.8 * sphere.radius_mm {
                        continue;
                    }
                    let rho = (sphere.radius_mm.powi(2) - c.z * c.z).sqrt();
                    let offset = edge_offset::offset_mm(&terms_mm, sphere, c.z);
                    let sd = edge_sd_mm * variance_factor(blur, sphere.radius_mm, c.z).sqrt();
                    let on_circle: Vec<Point3<f64>> = (0..40)
                        .map(|j| {
                            let a = (-55.0 + 110.0 * j as f64 / 39.0f64).to_radians();
                            Point3::new(c.x + rho * a.sin(), c.y - rho * a.cos(), 0.0)
                        })
                        .collect();
                    // In the plane, radially, so far that the distance from the sphere is N(0, σ).
                    let edge_px = on_circle
                        .iter()
                        .map(|p| {
                            let out = (p - Point3::new(c.x, c.y, 0.0)) / rho;
                            let q = p + out * (offset + rng.normal(0.0, sd)) * sphere.radius_mm / rho;
                            [q.x / spacing[0], q.y / spacing[1]]
                        })
                        .collect();
                    arcs.push(ArcFrame {
                        frame,
                        sphere: k,
                        edge_px,
                        camera_T_marker: camera_T_phantom * phantom_T_marker * hand,
                        camera_T_phantom,
                    });
                    frame_arcs.push((k, on_circle));
                }
                bound_frames.push(BoundFrame {
                    phantom_T_marker,
                    arcs: frame_arcs,
                    pose_cov,
                    pose_from_intrinsics: PoseFromIntrinsics::zeros(),
                });
            }
            let settings = SphereSettings {
                spheres: spheres.clone(),
                spacing_mm_per_px: spacing,
                elevation_prior_sd_mm: None,
                fit_radius_offset: false,
                points_per_frame: 40.0,
                fit_pixel_size: false,
            };
            let plain = sphere_fit::refine(&truth, &arcs, &settings).unwrap();
            let mut frames: Vec<(usize, Matrix6<f64>)> = arcs.iter().map(|a| (a.frame, pose_cov)).collect();
            frames.dedup_by_key(|f| f.0);
            let priors = PosePriors {
                edge_sd_mm,
                frames,
                shared: None,
                edge_offset: model,
                slice_blur: blur,
            };
            let fit = sphere_bundle::refine(&plain.marker_T_image, &arcs, &settings, &priors).unwrap();
            error2 += probes
                .iter()
                .map(|q| (fit.marker_T_image * q - truth * q).norm_squared())
                .sum::<f64>()
                / probes.len() as f64;
            let bound = corner_rms_bound(
                &truth,
                &bound_frames,
                &spheres,
                &noise,
                &IntrinsicsInformation::zeros(),
                model,
                &probes,
            )
            .unwrap();
            bound2 += bound * bound;
        }
        (error2 / bound2).sqrt()
    }

    #[test]
    fn the_pose_prior_fit_reaches_the_bound_on_its_own_model() {
        let ratio = fit_over_bound(EdgeOffset::None, [0.0; 3], None);
        assert!((0.8..=1.2).contains(&ratio), "RMS error over the bound: {ratio}");
    }

    /// Arcs noisier the farther their plane cuts from their dome's centre, as a
    /// slice of 1.5 mm (SD 0.5 mm) over a pulse of SD 0.3 mm makes them: the
    /// fit that weighs them so reaches the bound that knows it.
    #[test]
    fn the_pose_prior_fit_reaches_the_bound_with_the_slice_blur() {
        let blur = SliceBlur {
            axial_sd_mm: 0.3,
            elevation_sd_mm: 0.5,
        };
        let ratio = fit_over_bound(EdgeOffset::None, [0.0; 3], Some(blur));
        assert!((0.8..=1.2).contains(&ratio), "RMS error over the bound: {ratio}");
    }

    /// Edges that sit outside their spheres by more the more oblique the cut:
    /// the fit that solves the offset reaches its (larger) bound; the fit that
    /// assumes none is biased well past its own.
    #[test]
    fn an_edge_offset_is_solved_with_the_calibration_at_its_bound() {
        // About what the renderer's echoes show: +0.02 mm when the plane
        // passes near the centre, +0.13 mm at d = 0.75 R.
        let offset_mm = [0.02, 0.2, 0.0];
        let solved = fit_over_bound(EdgeOffset::ConstantAndObliquity, offset_mm, None);
        assert!((0.8..=1.2).contains(&solved), "RMS error over the bound: {solved}");
        let ignored = fit_over_bound(EdgeOffset::None, offset_mm, None);
        assert!(ignored > 1.5, "the offset ignored: RMS error over the bound {ignored}");
        // The slice's shape, d²/(R·r), steeper near the dome's rim.
        let slice = fit_over_bound(EdgeOffset::Slice, [0.0, 0.0, 0.13], None);
        assert!((0.8..=1.2).contains(&slice), "slice: RMS error over the bound {slice}");
    }

    #[test]
    fn domes_at_different_offsets_bound_the_calibration_below_one_dome() {
        let truth = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(-20.0, 160.0, 25.0));
        let noise = EdgeNoise {
            edge_sd_mm: 0.1,
            points_per_arc: 20.0,
            slice_blur: None,
        };
        let none = PoseFromIntrinsics::zeros();
        let known = IntrinsicsInformation::zeros();
        let d = elevations();
        let one = [KnownSphere {
            centre_in_phantom_mm: Point3::new(0.0, 0.0, 0.0),
            radius_mm: 15.0,
        }];
        let three = three_domes();
        let b1 = corner_rms_bound(
            &truth,
            &frames(&d, &one, &none),
            &one,
            &noise,
            &known,
            EdgeOffset::None,
            &probes(),
        )
        .unwrap();
        let b3 = corner_rms_bound(
            &truth,
            &frames(&d, &three, &none),
            &three,
            &noise,
            &known,
            EdgeOffset::None,
            &probes(),
        )
        .unwrap();
        assert!(b3 < 0.5 * b1, "three domes {b3} mm vs one {b1} mm");
        // More noise, a larger bound.
        let noisy = EdgeNoise {
            edge_sd_mm: 0.2,
            ..noise
        };
        let b3n = corner_rms_bound(
            &truth,
            &frames(&d, &three, &none),
            &three,
            &noisy,
            &known,
            EdgeOffset::None,
            &probes(),
        )
        .unwrap();
        assert!(b3n > b3, "{b3n} vs {b3}");
        // Arcs cut off their domes' centres worth less under a thick slice: a larger bound.
        let blurred = EdgeNoise {
            slice_blur: Some(SliceBlur {
                axial_sd_mm: 0.3,
                elevation_sd_mm: 0.5,
            }),
            ..noise
        };
        let b3b = corner_rms_bound(
            &truth,
            &frames(&d, &three, &none),
            &three,
            &blurred,
            &known,
            EdgeOffset::None,
            &probes(),
        )
        .unwrap();
        assert!(b3b > b3 * 1.01, "{b3b} vs {b3}");
    }

    #[test]
    fn an_error_every_frame_shares_does_not_average_out() {
        // The first intrinsic shifts every frame's pose by 1 mm along x per unit.
        let truth = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(-20.0, 160.0, 25.0));
        let noise = EdgeNoise {
            edge_sd_mm: 0.1,
            points_per_arc: 20.0,
            slice_blur: None,
        };
        let three = three_domes();
        let d = elevations();
        let mut shift = PoseFromIntrinsics::zeros();
        shift[(3, 0)] = 1.0;
        let independent = corner_rms_bound(
            &truth,
            &frames(&d, &three, &PoseFromIntrinsics::zeros()),
            &three,
            &noise,
            &IntrinsicsInformation::zeros(),
            EdgeOffset::None,
            &probes(),
        )
        .unwrap();
        let bound_with_sd = |sd: f64| {
            // Intrinsics other than the first are known exactly (large information).
            let mut info = IntrinsicsInformation::identity() * 1e12;
            info[(0, 0)] = sd.powi(-2);
            corner_rms_bound(
                &truth,
                &frames(&d, &three, &shift),
                &three,
                &noise,
                &info,
                EdgeOffset::None,
                &probes(),
            )
            .unwrap()
        };
        let exact = bound_with_sd(1e-9);
        assert!(
            (exact - independent).abs() < 1e-6 * independent,
            "{exact} vs {independent}"
        );
        // A shared 0.3 mm error along x cannot be averaged over the frames: most
        // of it is added (in quadrature) to the bound.
        let shared = bound_with_sd(0.3);
        let added = (shared.powi(2) - independent.powi(2)).sqrt();
        assert!(
            added > 0.2 && added < 0.35,
            "{shared} vs {independent}: {added} mm added"
        );
        assert!(shared > bound_with_sd(0.1), "less calibration noise, a smaller bound");
    }
}
