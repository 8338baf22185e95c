//! A tracked transform as a trajectory in time: poses sampled at known times,
//! and the pose at any time between them.
//!
//! A pose at time `t` is interpolated between the two samples that bracket `t`
//! (the sample at exactly `t` when there is one): the rotation along the
//! shortest arc on SO(3) (quaternion slerp), the translation linearly, with the
//! same fraction of the way. This is how PLUS interpolates a tracker's buffer
//! (slerp and linear), so a lag applied here moves a pose as PLUS moves it when
//! its tracker's `LocalTimeOffsetSec` is set. A smooth fit of the whole
//! trajectory (a spline through the samples) would follow curved motion between
//! samples more closely, but it also spreads the tracker's noise into
//! neighbouring frames and reaches silently past a dropped or invalid sample;
//! piecewise interpolation uses only the two samples that bracket the time and
//! refuses where either is unusable.
//!
//! Refused, with the reason: a time before the first or after the last sample,
//! samples further apart than [`MAX_GAP_S`], and either bracketing sample
//! unusable (its own fault, of type `F`).

use std::collections::BTreeMap;

use nalgebra::{Matrix4, UnitQuaternion, Vector3};

use crate::core::geometry::Rigid;

/// Longest time between the two samples a pose is interpolated across, s: a
/// quarter second (four frames at 16 frames/s), beyond which a hand-held probe
/// may have turned a degree or more between them.
pub const MAX_GAP_S: f64 = 0.25;

/// Half-width of the smoothing kernel's window, in SDs.
const KERNEL_SDS: f64 = 4.0;

/// Two timestamps closer than this are the same instant, s.
pub const SAME_TIME_S: f64 = 1e-6;

/// Why no pose could be had at a time.
#[derive(Debug, Clone, PartialEq)]
pub enum Miss<F> {
    /// Before the first sample, after the last, or at no finite time.
    Outside(&'static str),
    /// The bracketing samples are further apart than the limit, s.
    Gap { gap_s: f64, limit_s: f64 },
    /// A bracketing sample is unusable.
    Sample(F),
}

/// One transform's samples in time order, and every frame's own sample.
#[derive(Debug, Clone)]
pub struct Trajectory<F> {
    samples: Vec<(f64, Result<Rigid, F>)>,
    own: BTreeMap<usize, Result<Rigid, F>>,
}

impl<F: Clone> Trajectory<F> {
    /// From `(frame, time, pose)` samples in any order; a sample with no finite
    /// time is only its frame's own.
    pub fn from_samples(samples: impl IntoIterator<Item = (usize, Option<f64>, Result<Rigid, F>)>) -> Trajectory<F> {
        let mut timed = Vec::new();
        let mut own = BTreeMap::new();
        for (frame, time, pose) in samples {
            own.insert(frame, pose.clone());
            if let Some(t) = time.filter(|t| t.is_finite()) {
                timed.push((t, pose));
            }
        }
        timed.sort_by(|a, b| a.0.total_cmp(&b.0));
        Trajectory { samples: timed, own }
    }

    /// Time span of the samples, s.
    pub fn span_s(&self) -> Option<(f64, f64)> {
        Some((self.samples.first()?.0, self.samples.last()?.0))
    }

    /// Frame `frame`'s own sample, whatever its time (`None`: no such frame).
    pub fn own(&self, frame: usize) -> Option<Result<Rigid, F>> {
        self.own.get(&frame).cloned()
    }

    /// The pose at `time_s`, between the samples that bracket it.
    pub fn at(&self, time_s: f64) -> Result<Rigid, Miss<F>> {
        if !time_s.is_finite() {
            return Err(Miss::Outside("at no time"));
        }
        let after = self.samples.partition_point(|s| s.0 < time_s - SAME_TIME_S);
        if let Some((t, pose)) = self.samples.get(after) {
            if (t - time_s).abs() <= SAME_TIME_S {
                return pose.clone().map_err(Miss::Sample);
            }
        }
        let Some(before) = after.checked_sub(1) else {
            return Err(Miss::Outside("before the first sample"));
        };
        let (Some((ta, a)), Some((tb, b))) = (self.samples.get(before), self.samples.get(after)) else {
            return Err(Miss::Outside("after the last sample"));
        };
        let gap_s = tb - ta;
        if gap_s > MAX_GAP_S {
            return Err(Miss::Gap {
                gap_s,
                limit_s: MAX_GAP_S,
            });
        }
        let a = a.clone().map_err(Miss::Sample)?;
        let b = b.clone().map_err(Miss::Sample)?;
        Ok(interpolate(&a, &b, (time_s - ta) / gap_s))
    }
}

impl<F: Clone> Trajectory<F> {
    /// The pose at `time_s` by local quadratic regression with a Gaussian
    /// kernel of SD `sigma_s` over the samples within four SDs of it (the
    /// kernel lowered by its value there, so that a sample enters or leaves the
    /// window with no weight and the pose moves continuously with the time):
    /// the quadratic in time that fits the samples best under the kernel's
    /// weights, read at `time_s`. Translations are fitted as they are; rotations
    /// as rotation vectors relative to the sample nearest `time_s`.
    ///
    /// With `sigma_s` at least the sampling interval, the noise of the result
    /// is nearly the same wherever `time_s` falls between samples (its
    /// variance moves by about 1 % of itself at one interval, where an
    /// interpolated pose's halves from a sample to halfway). The kernel is
    /// symmetric, so it shifts no motion in time, and the quadratic follows a
    /// curving path: a plain kernel average (Nadaraya–Watson) cuts a bend by
    /// `sigma² x''/2` (at one frame period of 78 ms, 0.3 mm at the turns of a
    /// 20 mm sweep back and forth every two seconds), which the lag would then absorb.
    /// Refused outside the samples' span, with no usable sample on either side
    /// within [`MAX_GAP_S`], at an unusable sample inside the window, or where
    /// the window's samples cannot hold a quadratic.
    pub fn smoothed_at(&self, time_s: f64, sigma_s: f64) -> Result<Rigid, Miss<F>> {
        if !time_s.is_finite() {
            return Err(Miss::Outside("at no time"));
        }
        let (first, last) = self.span_s().ok_or(Miss::Outside("before the first sample"))?;
        if time_s < first - SAME_TIME_S {
            return Err(Miss::Outside("before the first sample"));
        }
        if time_s > last + SAME_TIME_S {
            return Err(Miss::Outside("after the last sample"));
        }
        let lo = self.samples.partition_point(|s| s.0 < time_s - KERNEL_SDS * sigma_s);
        let hi = self.samples.partition_point(|s| s.0 <= time_s + KERNEL_SDS * sigma_s);
        let window = &self.samples[lo..hi];
        let before = window.iter().rev().find(|s| s.0 <= time_s).map(|s| time_s - s.0);
        let after = window.iter().find(|s| s.0 >= time_s).map(|s| s.0 - time_s);
        let gap_s = before.unwrap_or(f64::INFINITY) + after.unwrap_or(f64::INFINITY);
        if gap_s > MAX_GAP_S {
            return Err(Miss::Gap {
                gap_s,
                limit_s: MAX_GAP_S,
            });
        }
        let floor = (-0.5 * KERNEL_SDS * KERNEL_SDS).exp();
        let mut used = Vec::with_capacity(window.len());
        for (t, pose) in window {
            let d = (t - time_s) / sigma_s;
            let k = ((-0.5 * d * d).exp() - floor).max(0.0);
            if k > 0.0 {
                used.push((d, k, pose.clone().map_err(Miss::Sample)?));
            }
        }
        let weights = local_quadratic_weights(&used).ok_or(Miss::Outside("where too few samples hold a quadratic"))?;
        let nearest = used
            .iter()
            .min_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
            .map(|u| u.2.rotation)
            .ok_or(Miss::Outside("where too few samples hold a quadratic"))?;
        let mut translation = Vector3::zeros();
        let mut turn = Vector3::zeros();
        for ((_, _, pose), w) in used.iter().zip(&weights) {
            translation += pose.translation.vector * *w;
            turn += (nearest.inverse() * pose.rotation).scaled_axis() * *w;
        }
        Ok(Rigid::from_parts(
            translation.into(),
            nearest * UnitQuaternion::from_scaled_axis(turn),
        ))
    }
}

/// Each sample's weight in the local quadratic fit read at the kernel's centre:
/// `k_j (c0 + c1 d_j + c2 d_j²)` with `c` the first row of the weighted moment
/// matrix's inverse (`d` in kernel SDs, `k` the kernel's weight). The weights
/// sum to one and reproduce any quadratic in time exactly. `None` where the
/// moment matrix is singular (fewer than three distinct times) or the weights
/// would amplify the samples' noise more than tenfold.
fn local_quadratic_weights<P>(used: &[(f64, f64, P)]) -> Option<Vec<f64>> {
    let mut moments = nalgebra::Matrix3::zeros();
    for (d, k, _) in used {
        let basis = Vector3::new(1.0, *d, d * d);
        moments += basis * basis.transpose() * *k;
    }
    let row = moments.try_inverse()?.column(0).into_owned();
    let weights: Vec<f64> = used
        .iter()
        .map(|(d, k, _)| k * (row[0] + row[1] * d + row[2] * d * d))
        .collect();
    let gain: f64 = weights.iter().map(|w| w * w).sum();
    (weights.iter().all(|w| w.is_finite()) && gain <= 10.0).then_some(weights)
}

/// `a` moved the fraction `w` of the way to `b`: slerp of the rotation, linear
/// translation.
pub fn interpolate(a: &Rigid, b: &Rigid, w: f64) -> Rigid {
    let rotation = a.rotation.slerp(&b.rotation, w);
    let translation = a.translation.vector + (b.translation.vector - a.translation.vector) * w;
    Rigid::from_parts(translation.into(), rotation)
}

/// The same for 4x4 matrices whose upper-left block is a rotation (a stream's
/// samples, checked rigid where they were received).
pub fn interpolate_matrix(a: &Matrix4<f64>, b: &Matrix4<f64>, w: f64) -> Matrix4<f64> {
    let rigid = |m: &Matrix4<f64>| {
        let rotation = UnitQuaternion::from_matrix(&m.fixed_view::<3, 3>(0, 0).into_owned());
        let translation: Vector3<f64> = m.fixed_view::<3, 1>(0, 3).into_owned();
        Rigid::from_parts(translation.into(), rotation)
    };
    interpolate(&rigid(a), &rigid(b), w).to_homogeneous()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(angle_rad: f64, x_mm: f64) -> Rigid {
        Rigid::from_parts(
            Vector3::new(x_mm, 0.0, 0.0).into(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle_rad),
        )
    }

    /// Samples every 0.1 s turning 0.1 rad and moving 1 mm each.
    fn steady(n: usize) -> Trajectory<String> {
        Trajectory::from_samples((0..n).map(|k| (k, Some(10.0 + 0.1 * k as f64), Ok(pose(0.1 * k as f64, k as f64)))))
    }

    #[test]
    fn a_pose_is_read_between_the_samples_that_bracket_its_time() {
        let t = steady(10);
        // 0.35 s after frame 2: five frame periods further than one neighbour.
        let p = t.at(10.0 + 0.2 + 0.35).unwrap();
        assert!((p.translation.vector.x - 5.5).abs() < 1e-9, "{p:?}");
        assert!((p.rotation.angle() - 0.55).abs() < 1e-9);
        // Exactly at a sample: that sample.
        let q = t.at(10.3).unwrap();
        assert!((q.translation.vector.x - 3.0).abs() < 1e-12);
    }

    #[test]
    fn outside_the_samples_or_across_a_gap_is_refused_with_its_reason() {
        let t = steady(5);
        assert_eq!(t.at(9.9).unwrap_err(), Miss::Outside("before the first sample"));
        assert_eq!(t.at(10.5).unwrap_err(), Miss::Outside("after the last sample"));
        assert_eq!(t.at(f64::NAN).unwrap_err(), Miss::Outside("at no time"));
        let gappy: Trajectory<String> =
            Trajectory::from_samples([(0, Some(0.0), Ok(pose(0.0, 0.0))), (1, Some(0.3), Ok(pose(0.0, 1.0)))]);
        assert!(matches!(gappy.at(0.1), Err(Miss::Gap { gap_s, .. }) if (gap_s - 0.3).abs() < 1e-12));
    }

    #[test]
    fn an_unusable_bracketing_sample_refuses_the_pose() {
        let t = Trajectory::from_samples([
            (0, Some(0.0), Ok(pose(0.0, 0.0))),
            (1, Some(0.1), Err("INVALID".to_string())),
            (2, Some(0.2), Ok(pose(0.0, 2.0))),
            (3, None, Ok(pose(0.0, 3.0))),
        ]);
        assert_eq!(t.at(0.05).unwrap_err(), Miss::Sample("INVALID".to_string()));
        assert_eq!(t.at(0.15).unwrap_err(), Miss::Sample("INVALID".to_string()));
        assert!(t.at(0.0).is_ok());
        // A frame with no time is its own pose only.
        assert!(t.own(3).unwrap().is_ok() && t.span_s() == Some((0.0, 0.2)));
    }

    #[test]
    fn a_smoothed_pose_has_the_same_noise_wherever_it_falls_between_samples() {
        // Samples of a still pose with noise; the smoothed pose's scatter over
        // many trajectories is the same at a sample and halfway between two.
        let mut rng = crate::core::rng::Rng::new(5);
        let (mut at_sample, mut halfway) = (0.0, 0.0);
        let (mut interpolated_sample, mut interpolated_halfway) = (0.0, 0.0);
        for _ in 0..400 {
            let t: Trajectory<String> = Trajectory::from_samples(
                (0..40).map(|k| (k, Some(0.1 * k as f64), Ok(pose(0.0, rng.normal(0.0, 1.0))))),
            );
            at_sample += t.smoothed_at(2.0, 0.1).unwrap().translation.vector.x.powi(2);
            halfway += t.smoothed_at(2.05, 0.1).unwrap().translation.vector.x.powi(2);
            interpolated_sample += t.at(2.0).unwrap().translation.vector.x.powi(2);
            interpolated_halfway += t.at(2.05).unwrap().translation.vector.x.powi(2);
        }
        let ratio = halfway / at_sample;
        assert!((ratio - 1.0).abs() < 0.1, "{ratio}");
        // Interpolation halves the variance halfway.
        let ratio = interpolated_halfway / interpolated_sample;
        assert!(ratio < 0.65, "{ratio}");
        // Motion is not shifted: a steady turn and slide read where they are.
        let p = steady(10).smoothed_at(10.45, 0.1).unwrap();
        assert!((p.translation.vector.x - 4.5).abs() < 1e-9, "{p:?}");
        assert!((p.rotation.angle() - 0.45).abs() < 1e-3);
        // A bend is followed: a slide accelerating as t² and a turn as t² are
        // read on the curve, not cut inside it.
        let bend: Trajectory<String> = Trajectory::from_samples((0..40).map(|k| {
            let t = 0.1 * k as f64;
            (k, Some(t), Ok(pose(0.05 * t * t, 3.0 * t * t)))
        }));
        let p = bend.smoothed_at(2.05, 0.1).unwrap();
        assert!((p.translation.vector.x - 3.0 * 2.05 * 2.05).abs() < 1e-9, "{p:?}");
        assert!((p.rotation.angle() - 0.05 * 2.05 * 2.05).abs() < 1e-9, "{p:?}");
    }

    #[test]
    fn matrices_interpolate_as_rigid_poses() {
        let (a, b) = (pose(0.0, 0.0), pose(0.4, 4.0));
        let m = interpolate_matrix(&a.to_homogeneous(), &b.to_homogeneous(), 0.25);
        let r = interpolate(&a, &b, 0.25).to_homogeneous();
        assert!((m - r).abs().max() < 1e-12);
        assert!((m[(0, 3)] - 1.0).abs() < 1e-12);
    }
}
