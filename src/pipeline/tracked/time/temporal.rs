//! Temporal calibration: the tracker's lag behind the video from a probe moved
//! over a flat reflector (PLUS's method).
//!
//! - Video signal: the reflector's line in each B-scan ([`crate::detect::line`]),
//!   its signed distance from the image centre (px).
//! - Tracker signal: `ProbeToReference`'s position projected on its principal
//!   axis of motion (mm).
//! - Both are resampled on a 1 ms grid over their common time span and
//!   normalised (zero mean, unit SD); the normalised cross-correlation of the
//!   video signal with the tracker signal shifted by each lag within ±0.5 s is
//!   taken, its peak (of either sign: the line may move either way as the probe
//!   rises) refined by a parabola through the neighbouring lags.
//!
//! `tracker_lag_s` is PLUS's `TrackerLagSec`: how much the tracker lags the
//! video; the tracker's curve `p(t + lag)` lines up with the video's.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};

use crate::detect::line::{self, Line, LineRejection};
use crate::io::plus::sequence::{Sequence, SequenceError};

/// Resampling step, s.
pub const STEP_S: f64 = 0.001;
/// Largest lag searched, s.
pub const MAX_LAG_S: f64 = 0.5;
/// Fewest frames with a line and tracker samples the estimate needs.
const MIN_SAMPLES: usize = 10;

#[derive(Debug, thiserror::Error)]
pub enum TemporalError {
    #[error("{0}")]
    Sequence(#[from] SequenceError),
    #[error("{path}: frame {frame} has no usable `Timestamp`; the lag cannot be estimated without timestamps")]
    NoTimestamp { path: PathBuf, frame: usize },
    #[error("{path}: only {usable} frames are usable ({what}), at least {needed} are needed")]
    TooFew {
        path: PathBuf,
        usable: usize,
        needed: usize,
        what: &'static str,
    },
    #[error("the recordings overlap for {overlap_s:.2} s, too short to search lags of ±{MAX_LAG_S} s")]
    NoOverlap { overlap_s: f64 },
    /// The correlation peaks at (or next to) the end of the lags searched: the
    /// true lag may lie beyond, so none is reported.
    #[error(
        "unresolved: the correlation peaks at {lag_s:+.3} s, at the edge of the ±{MAX_LAG_S} s searched (correlation {peak_correlation:.3})"
    )]
    AtEdge { lag_s: f64, peak_correlation: f64 },
    /// A signal that does not vary (a probe held still) has no lag to find.
    #[error("unresolved: the {which} signal does not vary (SD {sd:.3e}): too little motion to tell the lag")]
    NoMotion { which: &'static str, sd: f64 },
    #[error("{path}: {fault}; the lag cannot be estimated on this clock")]
    Clock { path: PathBuf, fault: String },
    #[error(
        "{path}: frame {frame}'s probe is {distance_mm:.0} mm from the reference, beyond any tracker's workspace ({MAX_WORKSPACE_MM} mm)"
    )]
    OutsideWorkspace {
        path: PathBuf,
        frame: usize,
        distance_mm: f64,
    },
    #[error("unresolved: the correlation peaks at {peak_correlation:.3} (lag {lag_s:+.3} s), weaker than {MIN_PEAK_CORRELATION}: the two signals do not show one motion")]
    Weak { lag_s: f64, peak_correlation: f64 },
    /// A sample (or the correlation made of them) that is not a number.
    #[error("unresolved: the {which} signal's sample at {time_s} s is {value}, not a finite number")]
    NotFinite {
        which: &'static str,
        time_s: f64,
        value: f64,
    },
}

/// Farthest a tracked probe can be from its reference, mm.
pub const MAX_WORKSPACE_MM: f64 = 5000.0;

/// Weakest peak correlation taken as the same motion seen twice.
pub const MIN_PEAK_CORRELATION: f64 = 0.5;

/// The lag at which two signals of the same motion line up best.
#[derive(Debug, Clone)]
pub struct Correlation {
    /// How much the second signal lags the first, s: `second(t + lag)` lines up
    /// with `first(t)`.
    pub lag_s: f64,
    /// Correlation at the peak (its sign: whether the signals move alike).
    pub peak_correlation: f64,
    /// (lag, correlation) at every step searched.
    pub curve: Vec<(f64, f64)>,
}

/// The normalised cross-correlation of `first` with `second` shifted by each lag
/// within ±[`MAX_LAG_S`] in steps of [`STEP_S`], on a grid over `first`'s span
/// that leaves room for every lag; its peak (of either sign) refined by a
/// parabola. A peak at the edge of the search, or a signal that does not vary,
/// is refused: no estimate is made from there.
pub fn correlate(first: &[(f64, f64)], second: &[(f64, f64)]) -> Result<Correlation, TemporalError> {
    let (Some(f0), Some(f1), Some(s0), Some(s1)) = (first.first(), first.last(), second.first(), second.last()) else {
        return Err(TemporalError::NoOverlap { overlap_s: 0.0 });
    };
    for (which, signal) in [("first", first), ("second", second)] {
        if let Some(&(time_s, value)) = signal.iter().find(|(t, v)| !t.is_finite() || !v.is_finite()) {
            return Err(TemporalError::NotFinite { which, time_s, value });
        }
    }
    let start = f0.0.max(s0.0 + MAX_LAG_S);
    let end = f1.0.min(s1.0 - MAX_LAG_S);
    if end - start < 4.0 * MAX_LAG_S {
        return Err(TemporalError::NoOverlap {
            overlap_s: (end - start).max(0.0),
        });
    }
    let steps = ((end - start) / STEP_S) as usize;
    let times: Vec<f64> = (0..=steps).map(|k| start + k as f64 * STEP_S).collect();
    let v: Vec<f64> = times.iter().map(|t| interpolate(first, *t).unwrap_or(0.0)).collect();
    let sd = spread(&v);
    if sd.is_nan() || sd <= 1e-9 {
        return Err(TemporalError::NoMotion { which: "first", sd });
    }
    let v = normalised(&v);
    let max_k = (MAX_LAG_S / STEP_S).round() as i64;
    let mut curve = Vec::with_capacity(2 * max_k as usize + 1);
    for k in -max_k..=max_k {
        let lag = k as f64 * STEP_S;
        let p: Vec<f64> = times
            .iter()
            .map(|t| interpolate(second, t + lag).unwrap_or(0.0))
            .collect();
        let sd = spread(&p);
        if sd.is_nan() || sd <= 1e-9 {
            return Err(TemporalError::NoMotion { which: "second", sd });
        }
        let p = normalised(&p);
        let ncc = v.iter().zip(&p).map(|(a, b)| a * b).sum::<f64>() / v.len() as f64;
        if !ncc.is_finite() {
            return Err(TemporalError::NotFinite {
                which: "correlation",
                time_s: lag,
                value: ncc,
            });
        }
        curve.push((lag, ncc));
    }
    let found = peak(curve)?;
    if found.peak_correlation.abs() < MIN_PEAK_CORRELATION {
        return Err(TemporalError::Weak {
            lag_s: found.lag_s,
            peak_correlation: found.peak_correlation,
        });
    }
    Ok(found)
}

/// The peak (of either sign) of a correlation `curve` over evenly spaced lags,
/// refined by a parabola through its neighbours; refused at (or next to) the
/// curve's ends, where the true peak may lie beyond.
pub fn peak(curve: Vec<(f64, f64)>) -> Result<Correlation, TemporalError> {
    let Some(peak) = (0..curve.len()).max_by(|&a, &b| curve[a].1.abs().total_cmp(&curve[b].1.abs())) else {
        return Err(TemporalError::NoOverlap { overlap_s: 0.0 });
    };
    if peak <= 1 || peak + 2 >= curve.len() {
        return Err(TemporalError::AtEdge {
            lag_s: curve[peak].0,
            peak_correlation: curve[peak].1,
        });
    }
    let step = curve[peak + 1].0 - curve[peak].0;
    let mut lag = curve[peak].0;
    let (a, b, c) = (curve[peak - 1].1.abs(), curve[peak].1.abs(), curve[peak + 1].1.abs());
    let denominator = a - 2.0 * b + c;
    if denominator.abs() > 1e-12 {
        lag += step * 0.5 * (a - c) / denominator;
    }
    Ok(Correlation {
        lag_s: lag,
        peak_correlation: curve[peak].1,
        curve,
    })
}

/// The population SD of `values`.
fn spread(values: &[f64]) -> f64 {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// One B-scan's line, or why it has none.
#[derive(Debug, Clone)]
pub struct VideoFrame {
    pub index: usize,
    pub timestamp_s: f64,
    pub line: Result<Line, LineRejection>,
}

#[derive(Debug, Clone)]
pub struct TemporalRun {
    pub video: PathBuf,
    pub tracker: PathBuf,
    pub frames: Vec<VideoFrame>,
    pub tracker_samples: usize,
    pub tracker_lag_s: f64,
    /// Correlation at the peak (its sign: whether the line moves with the probe).
    pub peak_correlation: f64,
    /// (lag, correlation) at every millisecond searched.
    pub curve: Vec<(f64, f64)>,
}

fn timestamp(seq: &Sequence, index: usize) -> Result<f64, TemporalError> {
    seq.frame_field(index, "Timestamp")
        .and_then(|t| t.parse::<f64>().ok())
        .filter(|t| t.is_finite())
        .ok_or_else(|| TemporalError::NoTimestamp {
            path: seq.path.clone(),
            frame: index,
        })
}

/// Linear interpolation of `(t, value)` samples (sorted by t) at `t`.
pub fn interpolate(samples: &[(f64, f64)], t: f64) -> Option<f64> {
    let k = samples.partition_point(|(s, _)| *s < t);
    if k == 0 || k == samples.len() {
        return (k < samples.len() && samples[k].0 == t).then(|| samples[k].1);
    }
    let ((t0, v0), (t1, v1)) = (samples[k - 1], samples[k]);
    Some(if t1 > t0 {
        v0 + (v1 - v0) * (t - t0) / (t1 - t0)
    } else {
        v0
    })
}

fn normalised(values: &[f64]) -> Vec<f64> {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n)
        .sqrt()
        .max(1e-12);
    values.iter().map(|v| (v - mean) / sd).collect()
}

/// The tracker's positions projected on their principal axis, with their times.
fn tracker_signal(seq: &Sequence, probe: &str, reference: &str) -> Result<Vec<(f64, f64)>, TemporalError> {
    let mut positions = Vec::new();
    for i in 0..seq.frames.len() {
        let t = timestamp(seq, i)?;
        // Only the position is used: the matrices as written, not checked rigid.
        let (Ok(p), Ok(r)) = (seq.matrix(i, probe), seq.matrix(i, reference)) else {
            continue; // a transform missing or not OK: no sample
        };
        let Some(probe_to_reference) = r.try_inverse().map(|inv| inv * p) else {
            continue;
        };
        let position = Vector3::new(
            probe_to_reference[(0, 3)],
            probe_to_reference[(1, 3)],
            probe_to_reference[(2, 3)],
        );
        if position.iter().all(|v| v.is_finite()) {
            if position.norm() > MAX_WORKSPACE_MM {
                return Err(TemporalError::OutsideWorkspace {
                    path: seq.path.clone(),
                    frame: i,
                    distance_mm: position.norm(),
                });
            }
            positions.push((t, position));
        }
    }
    if positions.len() < MIN_SAMPLES {
        return Err(TemporalError::TooFew {
            path: seq.path.clone(),
            usable: positions.len(),
            needed: MIN_SAMPLES,
            what: "both transforms OK",
        });
    }
    let n = positions.len() as f64;
    let mean: Vector3<f64> = positions.iter().map(|(_, p)| *p).sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    for (_, p) in &positions {
        let d = p - mean;
        cov += d * d.transpose();
    }
    let eigen = cov.symmetric_eigen();
    let (k, _) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .fold((0, f64::MIN), |best, (k, v)| if *v > best.1 { (k, *v) } else { best });
    let axis = eigen.eigenvectors.column(k).into_owned();
    let mut out: Vec<(f64, f64)> = positions.iter().map(|(t, p)| (*t, (p - mean).dot(&axis))).collect();
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(out)
}

/// Estimates the tracker's lag from a video and a tracker recording.
pub fn run(video_path: &Path, tracker_path: &Path, probe: &str, reference: &str) -> Result<TemporalRun, TemporalError> {
    let video = Sequence::read(video_path)?;
    if let Some(fault) = crate::pipeline::sequence_frames::clock_fault(&video) {
        return Err(TemporalError::Clock {
            path: video_path.to_path_buf(),
            fault,
        });
    }
    let frames: Vec<VideoFrame> = (0..video.frames.len())
        .map(|index| {
            Ok(VideoFrame {
                index,
                timestamp_s: timestamp(&video, index)?,
                line: line::find_line(video.pixels(index), video.width, video.height),
            })
        })
        .collect::<Result<_, TemporalError>>()?;
    let centre = [video.width as f64 / 2.0, video.height as f64 / 2.0];
    let mut video_signal: Vec<(f64, f64)> = frames
        .iter()
        .filter_map(|f| {
            f.line
                .as_ref()
                .ok()
                .map(|l| (f.timestamp_s, line::signed_distance(l, centre)))
        })
        .collect();
    video_signal.sort_by(|a, b| a.0.total_cmp(&b.0));
    if video_signal.len() < MIN_SAMPLES {
        return Err(TemporalError::TooFew {
            path: video_path.to_path_buf(),
            usable: video_signal.len(),
            needed: MIN_SAMPLES,
            what: "a line found",
        });
    }
    let tracker = Sequence::read(tracker_path)?;
    if let Some(fault) = crate::pipeline::sequence_frames::clock_fault(&tracker) {
        return Err(TemporalError::Clock {
            path: tracker_path.to_path_buf(),
            fault,
        });
    }
    let tracker_signal = tracker_signal(&tracker, probe, reference)?;
    let found = correlate(&video_signal, &tracker_signal)?;
    Ok(TemporalRun {
        video: video_path.to_path_buf(),
        tracker: tracker_path.to_path_buf(),
        frames,
        tracker_samples: tracker_signal.len(),
        tracker_lag_s: found.lag_s,
        peak_correlation: found.peak_correlation,
        curve: found.curve,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sine seen twice, the second 120 ms late: the lag is found; late by
    /// 600 ms (beyond the search) it is refused as at the edge; a still second
    /// signal is refused as too little motion.
    #[test]
    fn correlation_finds_the_lag_and_refuses_the_edge() {
        let signal = |delay: f64| -> Vec<(f64, f64)> {
            (0..400)
                .map(|k| {
                    let t = k as f64 * 0.05;
                    (t, (0.9 * (t - delay)).sin() + 0.3 * (2.3 * (t - delay)).sin())
                })
                .collect()
        };
        let found = correlate(&signal(0.0), &signal(0.12)).unwrap();
        assert!((found.lag_s - 0.12).abs() < 0.005, "{}", found.lag_s);
        let e = correlate(&signal(0.0), &signal(0.6)).unwrap_err();
        assert!(matches!(e, TemporalError::AtEdge { .. }), "{e}");
        let still: Vec<(f64, f64)> = (0..400).map(|k| (k as f64 * 0.05, 3.0)).collect();
        let e = correlate(&signal(0.0), &still).unwrap_err();
        assert!(matches!(e, TemporalError::NoMotion { .. }), "{e}");
    }

    /// The same motion buried in noise three times its size peaks inside the
    /// search but too weakly to be taken; a sample that is not a number is
    /// named, not turned into a correlation.
    #[test]
    fn a_weak_peak_or_a_sample_not_a_number_is_unresolved() {
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let motion = |t: f64| (0.9 * t).sin() + 0.3 * (2.3 * t).sin();
        let first: Vec<(f64, f64)> = (0..400).map(|k| (k as f64 * 0.05, motion(k as f64 * 0.05))).collect();
        let buried: Vec<(f64, f64)> = (0..400)
            .map(|k| {
                let t = k as f64 * 0.05;
                (t, 0.3 * motion(t - 0.12) + 1.1 * noise())
            })
            .collect();
        match correlate(&first, &buried).unwrap_err() {
            TemporalError::Weak {
                lag_s,
                peak_correlation,
            } => {
                assert!(lag_s.abs() < MAX_LAG_S, "{lag_s}");
                assert!(
                    peak_correlation > 0.1 && peak_correlation < MIN_PEAK_CORRELATION,
                    "{peak_correlation}"
                );
            }
            e => panic!("not refused as weak: {e}"),
        }
        let mut gap = first.clone();
        gap[200].1 = f64::NAN;
        let e = correlate(&first, &gap).unwrap_err();
        assert!(
            e.to_string() == "unresolved: the second signal's sample at 10 s is NaN, not a finite number",
            "{e}"
        );
    }

    #[test]
    fn interpolation_stays_inside_the_samples() {
        let s = [(0.0, 0.0), (1.0, 10.0), (3.0, 30.0)];
        assert_eq!(interpolate(&s, 0.5), Some(5.0));
        assert_eq!(interpolate(&s, 2.0), Some(20.0));
        assert_eq!(interpolate(&s, 0.0), Some(0.0));
        assert_eq!(interpolate(&s, -0.1), None);
        assert_eq!(interpolate(&s, 3.1), None);
    }
}
