//! A tracked transform as a trajectory in time: the poses a sequence recorded,
//! each at its frame's timestamp, and the pose at any time between them.
//!
//! A pose at time `t` is interpolated between the two recorded samples that
//! bracket `t` (the sample at exactly `t` when there is one): the rotation along
//! the shortest arc on SO(3) (quaternion slerp), the translation linearly, with
//! the same fraction of the way. This is PLUS's own interpolation of a tracker's
//! buffer (`vtkPlusBuffer`: slerp and linear), so a lag applied here moves a
//! pose as PLUS moves it when its `LocalTimeOffsetSec` is set. A smooth fit of
//! the whole trajectory (a spline through the samples) would follow curved
//! motion between samples more closely, but it also smooths the tracker's
//! noise into neighbouring frames and reaches past a dropped or invalid sample
//! silently; piecewise interpolation uses only the two samples that bracket the
//! time and refuses where either is unusable.
//!
//! Refused, with the reason: a time before the first or after the last sample,
//! samples further apart than [`MAX_GAP_S`], and either bracketing sample
//! unusable (its status, its numbers, no timestamp).
//!
//! Every path that pairs a pose with an image goes through [`Trajectory::at`]:
//! the tracked run ([`crate::pipeline::tracked::attach_poses`]), its live replays
//! and streams, and the reconstruction's frame poses.

use nalgebra::{Matrix4, UnitQuaternion, Vector3};

use crate::core::geometry::Rigid;
use crate::io::plus::sequence::Sequence;
use crate::pipeline::sequence_frames::{timestamp_s, PoseFault};

/// Longest time between the two samples a pose is interpolated across, s: a
/// quarter second (four frames at 16 frames/s), beyond which a hand-held probe
/// may have turned a degree or more between them.
pub const MAX_GAP_S: f64 = 0.25;

/// Two timestamps closer than this are the same instant, s.
pub const SAME_TIME_S: f64 = 1e-6;

/// One transform's samples, in time order: the frame they come from, its time,
/// and the pose or why it is unusable.
#[derive(Debug, Clone)]
pub struct Trajectory {
    name: String,
    samples: Vec<Sample>,
    /// Every frame's own sample, timed or not.
    own: std::collections::BTreeMap<usize, Result<Rigid, PoseFault>>,
}

#[derive(Debug, Clone)]
struct Sample {
    time_s: f64,
    pose: Result<Rigid, PoseFault>,
}

impl Trajectory {
    /// `name`'s samples in `sequence` (every frame with a timestamp), sorted by time.
    pub fn of(sequence: &Sequence, name: &str) -> Trajectory {
        Trajectory::from_samples(
            name,
            (0..sequence.frames.len()).map(|frame| {
                (
                    frame,
                    timestamp_s(sequence, frame),
                    sequence.transform(frame, name).map_err(PoseFault::from),
                )
            }),
        )
    }

    /// From `(frame, time, pose)` samples in any order.
    pub fn from_samples(
        name: &str,
        samples: impl IntoIterator<Item = (usize, Option<f64>, Result<Rigid, PoseFault>)>,
    ) -> Trajectory {
        let mut timed = Vec::new();
        let mut own = std::collections::BTreeMap::new();
        for (frame, time, pose) in samples {
            own.insert(frame, pose.clone());
            if let Some(time_s) = time.filter(|t| t.is_finite()) {
                timed.push(Sample { time_s, pose });
            }
        }
        timed.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        Trajectory {
            name: name.to_string(),
            samples: timed,
            own,
        }
    }

    /// Time span of the samples, s.
    pub fn span_s(&self) -> Option<(f64, f64)> {
        Some((self.samples.first()?.time_s, self.samples.last()?.time_s))
    }

    /// The transform's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Frame `frame`'s own sample, whatever its time (`None`: no such frame).
    pub fn own(&self, frame: usize) -> Option<Result<Rigid, PoseFault>> {
        self.own.get(&frame).cloned()
    }

    /// The pose at `time_s`, between the samples that bracket it; `frame` names
    /// the image it is wanted for (in the reasons).
    pub fn at(&self, time_s: f64, frame: usize) -> Result<Rigid, PoseFault> {
        let outside = |side: &'static str| PoseFault::OutsideTrajectory {
            frame,
            transform: self.name.clone(),
            time_s,
            side,
        };
        if !time_s.is_finite() {
            return Err(outside("at no time"));
        }
        let after = self.samples.partition_point(|s| s.time_s < time_s - SAME_TIME_S);
        if let Some(s) = self.samples.get(after) {
            if (s.time_s - time_s).abs() <= SAME_TIME_S {
                return s.pose.clone();
            }
        }
        let Some(before) = after.checked_sub(1) else {
            return Err(outside("before the first sample"));
        };
        let (Some(a), Some(b)) = (self.samples.get(before), self.samples.get(after)) else {
            return Err(outside("after the last sample"));
        };
        let gap_s = b.time_s - a.time_s;
        if gap_s > MAX_GAP_S {
            return Err(PoseFault::Gap {
                frame,
                transform: self.name.clone(),
                time_s,
                gap_s,
                limit_s: MAX_GAP_S,
            });
        }
        let (pa, pb) = (a.pose.clone()?, b.pose.clone()?);
        Ok(interpolate(&pa, &pb, (time_s - a.time_s) / gap_s))
    }
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
    fn steady(n: usize) -> Trajectory {
        Trajectory::from_samples(
            "ProbeToTracker",
            (0..n).map(|k| (k, Some(10.0 + 0.1 * k as f64), Ok(pose(0.1 * k as f64, k as f64)))),
        )
    }

    #[test]
    fn a_pose_is_read_between_the_samples_that_bracket_its_time() {
        let t = steady(10);
        // 0.35 s after frame 2 (five frame periods further than one neighbour).
        let p = t.at(10.0 + 0.2 + 0.35, 2).unwrap();
        assert!((p.translation.vector.x - 5.5).abs() < 1e-9, "{p:?}");
        assert!((p.rotation.angle() - 0.55).abs() < 1e-9);
        // Exactly at a sample: that sample.
        let q = t.at(10.3, 0).unwrap();
        assert!((q.translation.vector.x - 3.0).abs() < 1e-12);
    }

    #[test]
    fn outside_the_samples_or_across_a_gap_is_refused_with_its_reason() {
        let t = steady(5);
        let e = t.at(9.9, 0).unwrap_err().to_string();
        assert!(e.contains("before the first sample"), "{e}");
        let e = t.at(10.5, 4).unwrap_err().to_string();
        assert!(e.contains("after the last sample"), "{e}");
        let gappy = Trajectory::from_samples(
            "ProbeToTracker",
            [(0, Some(0.0), Ok(pose(0.0, 0.0))), (1, Some(0.3), Ok(pose(0.0, 1.0)))],
        );
        let e = gappy.at(0.1, 0).unwrap_err().to_string();
        assert!(e.contains("0.300 s apart") && e.contains("limit 0.25"), "{e}");
    }

    #[test]
    fn an_unusable_bracketing_sample_refuses_the_pose() {
        let fault = PoseFault::NoTimestamp {
            frame: 1,
            transform: "ProbeToTracker".into(),
        };
        let t = Trajectory::from_samples(
            "ProbeToTracker",
            [
                (0, Some(0.0), Ok(pose(0.0, 0.0))),
                (1, Some(0.1), Err(fault.clone())),
                (2, Some(0.2), Ok(pose(0.0, 2.0))),
            ],
        );
        assert_eq!(t.at(0.05, 0).unwrap_err(), fault);
        assert_eq!(t.at(0.15, 2).unwrap_err(), fault);
        assert!(t.at(0.0, 0).is_ok());
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
