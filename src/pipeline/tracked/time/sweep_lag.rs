//! The tracker's lag behind the images from an N-wire calibration sweep's own
//! motion (PLUS's temporal calibration, [`crate::pipeline::tracked::time::temporal`], with the
//! phantom's wires in place of a flat reflector):
//!
//! - Video signal: the mean of each frame's segmented wire dots (px).
//! - Tracker signal: where the same wires cross the image plane under the
//!   frame's poses and a calibration fitted with no lag (px).
//! - Both projected on the principal axis of the video signal's motion. The
//!   tracker signal is taken at each frame's time plus each lag within ±0.5 s
//!   (1 ms steps, Catmull-Rom between frames: a straight line between frames
//!   smooths a shifted signal more than an unshifted one and pulls the peak
//!   to whole frame periods), correlated with the video signal at the frames'
//!   own times, and the peak found as PLUS's temporal calibration finds it
//!   ([`crate::pipeline::tracked::time::temporal::peak`]).
//! - Its spread over block-bootstrap resamples of the frames must lie within
//!   one frame period (90 %), or the lag is unresolved.
//!
//! One round: the calibration fitted with no lag takes up part of a lag, but
//! refitting it at the lag found and searching again did not settle on PLUS's
//! fCal 2.0 sweep (it went 48, 81, 50, 82 ms), whose dots' motion leaves the lag
//! only loosely held (its bootstrap interval is 41–115 ms).
//!
//! The calibration fitted with no lag only maps poses into pixels; the lag comes
//! from when the two motions line up, not from which lag fits the calibration
//! best. A sweep whose dots barely move, a peak at the edge of the search, or a
//! weak correlation leaves the lag unresolved, and it is not applied.

use nalgebra::{Matrix2, Matrix3, Point3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::estimate::image_to_probe::Fit;
use crate::pipeline::sequence_frames::{Role, TrackedFrame};
use crate::pipeline::tracked::time::temporal;
use crate::spec::nwire::NWire;

/// Fewest frames with dots, poses and timestamps the estimate needs.
const MIN_FRAMES: usize = 20;
/// The weakest peak correlation taken as the two motions lining up: below it
/// the poses explain under half the dots' motion (r² < 0.5).
pub const MIN_PEAK_CORRELATION: f64 = 0.71;
/// Least motion of the dots along their principal axis, px: ten times the
/// scale of a dot's localisation error (under a pixel).
pub const MIN_MOTION_SD_PX: f64 = 10.0;

/// The lag found from a sweep's motion, or why none was.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SweepLag {
    /// How much the tracker lags the images, s; `None`: unresolved.
    pub lag_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_correlation: Option<f64>,
    /// SD of the dots' motion along its principal axis, px.
    pub motion_sd_px: f64,
    /// The lag's spread over block-bootstrap resamples of the frames, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bootstrap_lag_s: Option<crate::evaluate::block_bootstrap::ScoreSpread>,
    /// The widest 90 % bootstrap interval taken as resolving the lag: one frame
    /// period of the sweep, s.
    #[serde(default)]
    pub resolution_limit_s: f64,
    pub frames: usize,
    /// Why no lag was taken.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unresolved: Option<String>,
}

/// Where the line `point + t direction` (marker frame) crosses the image plane
/// of `image_to_marker` (pixel `(u, v, 0, 1)` to marker mm), as a pixel.
fn crossing(image_to_marker: &nalgebra::Matrix4<f64>, point: Point3<f64>, direction: Vector3<f64>) -> Option<[f64; 2]> {
    let origin = image_to_marker.fixed_view::<3, 1>(0, 3).into_owned();
    let a_u = image_to_marker.fixed_view::<3, 1>(0, 0).into_owned();
    let a_v = image_to_marker.fixed_view::<3, 1>(0, 1).into_owned();
    let m = Matrix3::from_columns(&[a_u, a_v, -direction]);
    let x = m.lu().solve(&(point.coords - origin))?;
    (x[0].is_finite() && x[1].is_finite()).then_some([x[0], x[1]])
}

/// A frame's measured and predicted mean dot (px), at its timestamp.
fn samples(frames: &[TrackedFrame], nwires: &[NWire], fit: &Fit) -> Vec<(f64, Vector2<f64>, Vector2<f64>)> {
    let image_to_marker = fit.image_to_probe.matrix();
    let correction = fit.phantom_correction.to_homogeneous();
    frames
        .iter()
        .filter(|f| f.role == Role::Calibration && f.rejected.is_none())
        .filter_map(|f| {
            let (t, marker_T_phantom) = (f.timestamp_s?, f.marker_T_phantom? * correction);
            let dots: Vec<[f64; 2]> = f.dots_px.iter().flatten().copied().collect();
            let wires = nwires.iter().flat_map(|n| n.wires.iter());
            let predicted: Option<Vec<[f64; 2]>> = wires
                .map(|w| {
                    let point = marker_T_phantom.transform_point(&w.front_in_phantom_mm);
                    let direction = marker_T_phantom.transform_vector(&w.direction());
                    crossing(&image_to_marker, point, direction)
                })
                .collect();
            let predicted = predicted?;
            if dots.is_empty() || predicted.len() != dots.len() {
                return None;
            }
            let mean =
                |p: &[[f64; 2]]| p.iter().fold(Vector2::zeros(), |s, q| s + Vector2::new(q[0], q[1])) / p.len() as f64;
            Some((t, mean(&dots), mean(&predicted)))
        })
        .collect()
}

/// The lag of the tracker behind the images in `frames` (their poses attached
/// with no lag), with `fit` fitted to them.
pub fn estimate(frames: &[TrackedFrame], nwires: &[NWire], fit: &Fit) -> SweepLag {
    let mut s = samples(frames, nwires, fit);
    s.sort_by(|a, b| a.0.total_cmp(&b.0));
    let unresolved = |reason: String, motion_sd_px: f64, frames: usize| SweepLag {
        lag_s: None,
        motion_sd_px,
        frames,
        unresolved: Some(reason),
        ..Default::default()
    };
    if s.len() < MIN_FRAMES {
        return unresolved(
            format!(
                "{} frames with dots, poses and timestamps, {MIN_FRAMES} needed",
                s.len()
            ),
            0.0,
            s.len(),
        );
    }
    if s.windows(2).any(|w| w[1].0 <= w[0].0) {
        return unresolved("the frames' timestamps repeat or run backwards".into(), 0.0, s.len());
    }
    let (video, tracker, motion_sd_px) = on_principal_axis(&s);
    if motion_sd_px < MIN_MOTION_SD_PX {
        return unresolved(
            format!("the dots move {motion_sd_px:.1} px (SD), less than {MIN_MOTION_SD_PX} px: too little motion to tell the lag"),
            motion_sd_px,
            s.len(),
        );
    }
    let max_k = (temporal::MAX_LAG_S / temporal::STEP_S).round() as i64;
    let lags: Vec<f64> = (-max_k..=max_k).map(|k| k as f64 * temporal::STEP_S).collect();
    // Per frame: its video value, and the tracker's at its time plus each lag.
    let rows: Vec<(f64, Vec<Option<f64>>)> = video
        .iter()
        .map(|(t, v)| (*v, lags.iter().map(|lag| cubic(&tracker, t + lag)).collect()))
        .collect();
    let all: Vec<&(f64, Vec<Option<f64>>)> = rows.iter().collect();
    let curve = |picked: &[&(f64, Vec<Option<f64>>)]| -> Vec<(f64, f64)> {
        lags.iter()
            .enumerate()
            .map(|(k, lag)| (*lag, ncc(picked.iter().filter_map(|(v, p)| p[k].map(|p| (*v, p))))))
            .collect()
    };
    let full = curve(&all);
    if full.iter().any(|(_, r)| !r.is_finite()) {
        return unresolved(
            "the tracker's signal does not vary over the frames: too little motion to tell the lag".into(),
            motion_sd_px,
            s.len(),
        );
    }
    let mut intervals: Vec<f64> = s.windows(2).map(|w| w[1].0 - w[0].0).collect();
    intervals.sort_by(f64::total_cmp);
    let resolution_limit_s = intervals[intervals.len() / 2];
    let bootstrap_lag_s = crate::evaluate::block_bootstrap::spread(&rows, &BOOTSTRAP, |picked| {
        temporal::peak(curve(picked)).ok().map(|c| c.lag_s)
    });
    let base = SweepLag {
        motion_sd_px,
        frames: s.len(),
        bootstrap_lag_s,
        resolution_limit_s,
        ..Default::default()
    };
    decide(temporal::peak(full), base)
}

/// `(time s, value)` samples of one signal.
type Signal = Vec<(f64, f64)>;

/// The video and tracker signals (time, px) projected on the video signal's
/// principal axis of motion, and its SD along that axis, px.
fn on_principal_axis(s: &[(f64, Vector2<f64>, Vector2<f64>)]) -> (Signal, Signal, f64) {
    let n = s.len() as f64;
    let mean = s.iter().fold(Vector2::zeros(), |a, x| a + x.1) / n;
    let cov = s.iter().fold(Matrix2::zeros(), |c, x| {
        let d = x.1 - mean;
        c + d * d.transpose()
    }) / n;
    let eigen = cov.symmetric_eigen();
    let k = usize::from(eigen.eigenvalues[0] < eigen.eigenvalues[1]);
    let axis = eigen.eigenvectors.column(k).into_owned();
    let video = s.iter().map(|x| (x.0, (x.1 - mean).dot(&axis))).collect();
    let tracker = s.iter().map(|x| (x.0, (x.2 - mean).dot(&axis))).collect();
    (video, tracker, eigen.eigenvalues[k].max(0.0).sqrt())
}

/// The lag from the correlation's peak, unless the peak is unresolved (at the
/// edge, weak, or spread over resamples wider than a frame period).
fn decide(peak: Result<temporal::Correlation, temporal::TemporalError>, base: SweepLag) -> SweepLag {
    match peak {
        Err(e) => SweepLag {
            unresolved: Some(e.to_string()),
            ..base
        },
        Ok(c) if c.peak_correlation < MIN_PEAK_CORRELATION => SweepLag {
            peak_correlation: Some(c.peak_correlation),
            unresolved: Some(format!(
                "the motions correlate at most {:.3} (at {:+.3} s), less than {MIN_PEAK_CORRELATION}",
                c.peak_correlation, c.lag_s
            )),
            ..base
        },
        Ok(c) => match base.bootstrap_lag_s {
            Some(b) if b.p95 - b.p5 <= base.resolution_limit_s => SweepLag {
                lag_s: Some(c.lag_s),
                peak_correlation: Some(c.peak_correlation),
                ..base
            },
            _ => SweepLag {
                peak_correlation: Some(c.peak_correlation),
                unresolved: Some(match base.bootstrap_lag_s {
                    Some(b) => format!(
                        "the peak at {:+.3} s is not resolved: over resamples of the sweep it moves from {:+.3} to {:+.3} s (90 %), wider than a frame period ({:.3} s)",
                        c.lag_s, b.p5, b.p95, base.resolution_limit_s
                    ),
                    None => format!("the peak at {:+.3} s could not be resampled to tell its spread", c.lag_s),
                }),
                ..base
            },
        },
    }
}

/// The bootstrap of the lag: blocks of 10 frames (under a second of a sweep at
/// PLUS's usual 10–30 frames/s), 200 resamples, a fixed seed.
const BOOTSTRAP: crate::evaluate::block_bootstrap::BlockBootstrap = crate::evaluate::block_bootstrap::BlockBootstrap {
    block_frames: 10,
    resamples: 200,
    seed: 0x1A6_5EED,
};

/// The correlation of pairs; NaN when either side does not vary.
fn ncc(pairs: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
    let n = pairs.clone().count() as f64;
    let (ma, mb) = pairs.clone().fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        sab += (a - ma) * (b - mb);
        saa += (a - ma).powi(2);
        sbb += (b - mb).powi(2);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        f64::NAN
    }
}

/// Catmull-Rom interpolation of `(t, value)` samples at `t`.
fn cubic(samples: &[(f64, f64)], t: f64) -> Option<f64> {
    let k = samples.partition_point(|(s, _)| *s <= t);
    if k < 2 || k + 1 >= samples.len() {
        return None;
    }
    let (p0, p1, p2, p3) = (samples[k - 2], samples[k - 1], samples[k], samples[k + 1]);
    let x = (t - p1.0) / (p2.0 - p1.0);
    let m1 = (p2.1 - p0.1) / (p2.0 - p0.0) * (p2.0 - p1.0);
    let m2 = (p3.1 - p1.1) / (p3.0 - p1.0) * (p2.0 - p1.0);
    let (x2, x3) = (x * x, x * x * x);
    Some((2.0 * x3 - 3.0 * x2 + 1.0) * p1.1 + (x3 - 2.0 * x2 + x) * m1 + (-2.0 * x3 + 3.0 * x2) * p2.1 + (x3 - x2) * m2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_crosses_the_image_plane_at_its_pixel() {
        // Pixels of 0.1 mm, the image plane z = 0 of the marker frame.
        let mut m = nalgebra::Matrix4::identity();
        m[(0, 0)] = 0.1;
        m[(1, 1)] = 0.1;
        let p = crossing(&m, Point3::new(2.0, 3.0, 5.0), Vector3::new(0.0, 0.0, 1.0)).unwrap();
        assert!((p[0] - 20.0).abs() < 1e-9 && (p[1] - 30.0).abs() < 1e-9);
        assert!(crossing(&m, Point3::new(2.0, 3.0, 5.0), Vector3::new(1.0, 0.0, 0.0)).is_none());
    }
}
