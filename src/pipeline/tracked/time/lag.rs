//! The tracker's lag as a parameter of the calibration (spatio-temporal
//! calibration), from the calibration frames alone: the lag at which the
//! frames' wire dots and their poses agree best.
//!
//! The coarse search, here: at each lag of a grid over ±1 s (or a quarter of
//! the sweep when it is shorter than 4 s), every calibration frame's poses are
//! read along the recorded trajectories at the image's time plus the lag
//! ([`crate::core::trajectory`]), each N's middle dot is placed in the
//! probe's frame, and PLUS's least-squares `ImageToProbe` (the general affine
//! map of pixel `(u, v, 1)` to probe millimetres, 12 unknowns) is fitted in
//! closed form. Its residual sum of squares against the lag is the objective.
//! Each frame's share of the normal equations is kept per lag, so that a
//! block-bootstrap resample of the frames, or a fold of the cross-validation,
//! refits every lag by adding the shares of the frames it holds: 200 refits
//! over the whole grid cost about as much as one.
//!
//! Only frames whose poses can be read at every lag of the grid enter (the
//! frames within the search range of either end of the sweep, or next to a
//! tracker dropout, do not), so every lag is scored on the same dots. Outliers
//! are dropped by PLUS's rule (residual above mean + 3 SD) at the first
//! search's minimum and the search repeated without them.
//!
//! Refused, with the reason: too few frames, an objective that does not tell
//! one lag from another (flat: the lags within the grid are all within the
//! noise of the best; or a minimum whose curvature-based 90 % interval spans the
//! grid), many minima (over resamples of the sweep more than a tenth of the
//! minima fall in another valley of the objective), and a minimum at or next to
//! the edge of the grid (within one frame period).
//!
//! The refinement with the model, the curvature and the cross-validation of
//! "lag" against "no lag": `pipeline::time::lag_joint`.

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::core::stats::percentile;
use crate::evaluate::block_bootstrap::{self, BlockBootstrap, ScoreSpread};
use crate::pipeline::sequence_frames::{Role, TrackedFrame, TrackedRejection};
use crate::pipeline::tracked::inputs::{TrackedInputs, TrackerPaths};
use crate::spec::nwire::NWire;

/// Fewest frames the search needs.
pub const MIN_FRAMES: usize = 20;
/// Half-width of the search, s, unless a quarter of the sweep is shorter.
pub const SEARCH_HALF_WIDTH_S: f64 = 1.0;
/// Finest grid step, s.
pub const STEP_S: f64 = 0.001;
/// Most frame-lag pairs one search evaluates: a longer sweep gets a coarser
/// grid (the refinement is not on the grid).
pub const MAX_FRAME_LAGS: usize = 400_000;
/// The chi-square 90 % point of one parameter: two lags whose residual sums of
/// squares differ by less than this many residual variances are not told apart.
pub const CHI2_90_ONE: f64 = 2.706;
/// Least motion of the dots' targets over the sweep (RMS about their means),
/// in multiples of the affine fit's RMS error: below it the poses move about as
/// much as their noise.
pub const MIN_MOTION_OVER_NOISE: f64 = 3.0;
/// Spacing of the objective as reported (summary and page), s.
pub const REPORT_STEP_S: f64 = 0.005;
/// Largest share of resamples whose minimum may fall in another valley.
pub const MAX_OTHER_VALLEY_SHARE: f64 = 0.1;

/// The bootstrap: blocks of 10 frames, 200 resamples, a fixed seed.
pub const BOOTSTRAP: BlockBootstrap = BlockBootstrap {
    block_frames: 10,
    resamples: 200,
    seed: 0x1A6_5EED,
};

/// One frame's middle dots: pixel `(u, v)` and position in the phantom, per N.
#[derive(Debug, Clone)]
struct FramePoints {
    index: usize,
    time_s: f64,
    pixels: Vec<[f64; 2]>,
    in_phantom: Vec<Point3<f64>>,
}

/// A frame's share of the affine fit's normal equations at one lag.
#[derive(Debug, Clone, Copy)]
struct Share {
    /// `sum x x^T` over its kept dots, `x = (u, v, 1)`.
    g: Matrix3<f64>,
    /// `sum x p^T`, `p` the dot's target in the probe frame (centred).
    b: Matrix3<f64>,
    /// `sum |p|^2`.
    c: f64,
    n: f64,
}

impl Share {
    const ZERO: Share = Share {
        g: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        b: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        c: 0.0,
        n: 0.0,
    };

    fn add(&mut self, other: &Share, w: f64) {
        self.g += other.g * w;
        self.b += other.b * w;
        self.c += other.c * w;
        self.n += other.n * w;
    }

    /// The fitted map (rows: u, v, 1) and the residual sum of squares.
    fn solve(&self) -> Option<(Matrix3<f64>, f64)> {
        let inverse = self.g.try_inverse()?;
        let a = inverse * self.b;
        let ssr = (self.c - (self.b.transpose() * a).trace()).max(0.0);
        ssr.is_finite().then_some((a, ssr))
    }
}

/// What the coarse search found.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Coarse {
    /// The lags searched, s: first, last, step.
    pub search_s: [f64; 2],
    pub step_s: f64,
    /// The sweep's median frame period, s.
    pub frame_period_s: f64,
    /// Calibration frames scored at every lag, and their middle dots kept.
    pub frames: usize,
    pub points: usize,
    /// Middle dots dropped as outliers.
    pub outliers: usize,
    /// The objective's minimum (parabola through the grid's lowest three), s;
    /// `None` when refused.
    pub lag_s: Option<f64>,
    /// `(lag s, RMS residual mm)` of the affine fit, every grid step.
    pub objective: Vec<[f64; 2]>,
    /// The minimum's spread over block-bootstrap refits of the frames.
    pub bootstrap_lag_s: Option<ScoreSpread>,
    /// Share of resamples whose minimum lies in another valley.
    pub other_valley_share: f64,
    /// How far the dots' targets (probe frame, no lag) move over the sweep:
    /// RMS about each N's mean, mm.
    pub motion_rms_mm: f64,
    /// The RMS residual at lag 0 and at the minimum, mm.
    pub rms_at_zero_mm: Option<f64>,
    pub rms_at_minimum_mm: Option<f64>,
    /// Why no lag was found.
    pub unresolved: Option<String>,
    /// Each cross-validation fold's training minimum, s (`None`: unresolved).
    #[serde(skip)]
    pub fold_lags_s: Vec<Option<f64>>,
    /// The frames searched (their indices) and each one's fold.
    #[serde(skip)]
    pub searched: Vec<usize>,
    /// Per searched frame and N: kept (not an outlier).
    #[serde(skip)]
    pub kept: Vec<Vec<bool>>,
}

/// The searched frames and grid, or why there is none.
struct Setup {
    points: Vec<FramePoints>,
    lags: Vec<f64>,
    period_s: f64,
}

fn refused(reason: String) -> Coarse {
    Coarse {
        unresolved: Some(reason),
        ..Default::default()
    }
}

/// The calibration frames with dots and a timestamp, in time order.
fn frame_points(frames: &[TrackedFrame], nwires: &[NWire]) -> Vec<FramePoints> {
    let mut out: Vec<FramePoints> = frames
        .iter()
        .filter(|f| f.role == Role::Calibration && !f.dots_px.is_empty())
        .filter(|f| matches!(f.rejected, None | Some(TrackedRejection::Pose(_))))
        .filter_map(|f| {
            Some(FramePoints {
                index: f.index,
                time_s: f.timestamp_s?,
                pixels: f.dots_px.iter().map(|d| d[1]).collect(),
                in_phantom: f
                    .dots_px
                    .iter()
                    .zip(nwires)
                    .map(|(d, n)| n.middle_in_phantom_mm(d))
                    .collect(),
            })
        })
        .collect();
    out.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    out
}

/// Why the search cannot start; said as the estimate's reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum NoSearch {
    #[error("{found} calibration frames with dots and a timestamp, {MIN_FRAMES} needed")]
    TooFewFrames { found: usize },
    #[error("the frames' timestamps do not advance")]
    StoppedClock,
    #[error("the sweep lasts {duration_s:.3} s: too short to search a lag")]
    TooShort { duration_s: f64 },
    #[error("{found} calibration frames have poses at every lag within ±{half_s:.3} s, {MIN_FRAMES} needed")]
    TooFewPosed { found: usize, half_s: f64 },
}

fn setup(paths: &TrackerPaths, frames: &[TrackedFrame], inputs: &TrackedInputs) -> Result<Setup, NoSearch> {
    let all = frame_points(frames, &inputs.nwires);
    if all.len() < MIN_FRAMES {
        return Err(NoSearch::TooFewFrames { found: all.len() });
    }
    let mut gaps: Vec<f64> = all.windows(2).map(|w| w[1].time_s - w[0].time_s).collect();
    gaps.sort_by(f64::total_cmp);
    let period_s = gaps[gaps.len() / 2];
    let duration_s = all[all.len() - 1].time_s - all[0].time_s;
    if period_s.is_nan() || period_s <= 0.0 {
        return Err(NoSearch::StoppedClock);
    }
    let half = SEARCH_HALF_WIDTH_S.min(duration_s / 4.0);
    // The grid: whole milliseconds, as fine as the budget of frame-lags allows.
    let most_lags = (MAX_FRAME_LAGS / all.len()).max(3);
    let step_s = ((2.0 * half / (most_lags - 1) as f64 / STEP_S).ceil() * STEP_S).max(STEP_S);
    let k = (half / step_s).floor() as i64;
    if k < 2 {
        return Err(NoSearch::TooShort { duration_s });
    }
    let lags: Vec<f64> = (-k..=k).map(|i| i as f64 * step_s).collect();
    // Only frames with poses at every lag: each is scored on the same dots.
    let points: Vec<FramePoints> = all
        .into_par_iter()
        .filter(|f| {
            lags.iter().all(|lag| {
                paths
                    .marker_T_phantom(f.index, Some(f.time_s), *lag, &inputs.reference_T_phantom)
                    .is_ok()
            })
        })
        .collect();
    if points.len() < MIN_FRAMES {
        return Err(NoSearch::TooFewPosed {
            found: points.len(),
            half_s: half,
        });
    }
    Ok(Setup { points, lags, period_s })
}

/// Each frame's share at `lag_s` over its kept dots, targets centred on `centre`.
fn shares(
    s: &Setup,
    paths: &TrackerPaths,
    inputs: &TrackedInputs,
    kept: &[Vec<bool>],
    lag_s: f64,
    centre: &Vector3<f64>,
) -> Vec<Share> {
    s.points
        .iter()
        .zip(kept)
        .map(|(f, keep)| {
            let mut share = Share::ZERO;
            let Ok(m) = paths.marker_T_phantom(f.index, Some(f.time_s), lag_s, &inputs.reference_T_phantom) else {
                return share;
            };
            for ((pixel, q), _) in f.pixels.iter().zip(&f.in_phantom).zip(keep).filter(|(_, k)| **k) {
                let x = Vector3::new(pixel[0], pixel[1], 1.0);
                let p = m.transform_point(q).coords - centre;
                share.g += x * x.transpose();
                share.b += x * p.transpose();
                share.c += p.norm_squared();
                share.n += 1.0;
            }
            share
        })
        .collect()
}

/// Residual sum of squares of each weighting of the frames at one lag.
fn weighted_ssr(shares: &[Share], weights: &[Vec<f64>]) -> Vec<f64> {
    weights
        .iter()
        .map(|w| {
            let mut total = Share::ZERO;
            for (share, w) in shares.iter().zip(w) {
                if *w != 0.0 {
                    total.add(share, *w);
                }
            }
            total.solve().map_or(f64::NAN, |(_, ssr)| ssr)
        })
        .collect()
}

/// The minimum of a curve on the grid: its index, and the vertex of the
/// parabola through it and its neighbours (s); `None` for no finite point.
fn minimum(lags: &[f64], curve: &[f64]) -> Option<(usize, f64)> {
    let k = (0..curve.len())
        .filter(|&i| curve[i].is_finite())
        .min_by(|&a, &b| curve[a].total_cmp(&curve[b]))?;
    if k == 0 || k + 1 == curve.len() {
        return Some((k, lags[k]));
    }
    let (a, b, c) = (curve[k - 1], curve[k], curve[k + 1]);
    let denominator = a - 2.0 * b + c;
    let shift = if denominator > 0.0 {
        (0.5 * (a - c) / denominator).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    Some((k, lags[k] + shift * (lags[1] - lags[0])))
}

/// Whether grid points `k` and `r` lie in different valleys of the curve: a
/// ridge between them rises above the higher of the two by more than `barrier`.
fn separated(curve: &[f64], k: usize, r: usize, barrier: f64) -> bool {
    let (a, b) = (k.min(r), k.max(r));
    let ridge = curve[a..=b]
        .iter()
        .copied()
        .filter(|c| c.is_finite())
        .fold(f64::MIN, f64::max);
    ridge - curve[k].max(curve[r]) > barrier
}

/// Drops dots above mean + `k` SD of the affine fit's residuals at `lag_s`
/// (until none is dropped, at most 10 rounds).
fn outliers(
    s: &Setup,
    paths: &TrackerPaths,
    inputs: &TrackedInputs,
    lag_s: f64,
    k: f64,
    centre: &Vector3<f64>,
) -> Vec<Vec<bool>> {
    let mut kept: Vec<Vec<bool>> = s.points.iter().map(|f| vec![true; f.pixels.len()]).collect();
    let residuals: Vec<Vec<Option<Vector3<f64>>>> = s
        .points
        .iter()
        .map(|f| {
            let m = paths
                .marker_T_phantom(f.index, Some(f.time_s), lag_s, &inputs.reference_T_phantom)
                .ok();
            f.in_phantom
                .iter()
                .map(|q| m.map(|m| m.transform_point(q).coords - centre))
                .collect()
        })
        .collect();
    for _ in 0..10 {
        let mut total = Share::ZERO;
        for share in shares(s, paths, inputs, &kept, lag_s, centre) {
            total.add(&share, 1.0);
        }
        let Some((a, _)) = total.solve() else { break };
        let norm = |f: &FramePoints, j: usize, p: &Vector3<f64>| {
            let x = Vector3::new(f.pixels[j][0], f.pixels[j][1], 1.0);
            (a.transpose() * x - p).norm()
        };
        let norms: Vec<Vec<f64>> = s
            .points
            .iter()
            .zip(&residuals)
            .map(|(f, ps)| {
                ps.iter()
                    .enumerate()
                    .map(|(j, p)| p.map_or(f64::INFINITY, |p| norm(f, j, &p)))
                    .collect()
            })
            .collect();
        let kept_norms: Vec<f64> = norms
            .iter()
            .flatten()
            .zip(kept.iter().flatten())
            .filter(|(_, k)| **k)
            .map(|(n, _)| *n)
            .collect();
        let n = kept_norms.len() as f64;
        let mean = kept_norms.iter().sum::<f64>() / n;
        let sd = (kept_norms.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        let next: Vec<Vec<bool>> = norms
            .iter()
            .map(|f| f.iter().map(|x| *x <= mean + k * sd).collect())
            .collect();
        if next == kept {
            break;
        }
        kept = next;
    }
    kept
}

/// RMS distance of each N's middle-dot target (probe frame, no lag) from its
/// mean over the searched frames, mm.
fn motion_rms_mm(s: &Setup, paths: &TrackerPaths, inputs: &TrackedInputs) -> f64 {
    let mut by_pattern: Vec<Vec<Vector3<f64>>> = Vec::new();
    for f in &s.points {
        let Ok(m) = paths.marker_T_phantom(f.index, Some(f.time_s), 0.0, &inputs.reference_T_phantom) else {
            continue;
        };
        for (j, q) in f.in_phantom.iter().enumerate() {
            if by_pattern.len() <= j {
                by_pattern.resize(j + 1, Vec::new());
            }
            by_pattern[j].push(m.transform_point(q).coords);
        }
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for targets in &by_pattern {
        let mean = targets.iter().sum::<Vector3<f64>>() / targets.len().max(1) as f64;
        sum += targets.iter().map(|p| (p - mean).norm_squared()).sum::<f64>();
        n += targets.len();
    }
    (sum / n.max(1) as f64).sqrt()
}

/// Frame weights: the full set, each bootstrap resample, then each fold's
/// training frames (`folds` contiguous blocks).
fn weightings(frames: usize, folds: usize) -> Vec<Vec<f64>> {
    let mut out = vec![vec![1.0; frames]];
    for r in 0..BOOTSTRAP.resamples {
        let mut w = vec![0.0; frames];
        for i in block_bootstrap::resample(frames, &BOOTSTRAP, r) {
            w[i] += 1.0;
        }
        out.push(w);
    }
    for fold in 0..folds {
        out.push((0..frames).map(|i| f64::from(i * folds / frames != fold)).collect());
    }
    out
}

/// The coarse search (see the module's text).
pub fn search(paths: &TrackerPaths, frames: &[TrackedFrame], inputs: &TrackedInputs) -> Coarse {
    let s = match setup(paths, frames, inputs) {
        Ok(s) => s,
        Err(reason) => return refused(reason.to_string()),
    };
    let n = s.points.len();
    let centre = {
        let sum: Vector3<f64> = s
            .points
            .iter()
            .flat_map(|f| f.in_phantom.iter())
            .map(|p| p.coords)
            .sum();
        let count = s.points.iter().map(|f| f.in_phantom.len()).sum::<usize>().max(1);
        let mean_in_phantom = Point3::from(sum / count as f64);
        paths
            .marker_T_phantom(
                s.points[0].index,
                Some(s.points[0].time_s),
                0.0,
                &inputs.reference_T_phantom,
            )
            .map(|m| m.transform_point(&mean_in_phantom).coords)
            .unwrap_or_else(|_| Vector3::zeros())
    };
    let all: Vec<Vec<bool>> = s.points.iter().map(|f| vec![true; f.pixels.len()]).collect();
    let first: Vec<f64> = s
        .lags
        .par_iter()
        .map(|lag| weighted_ssr(&shares(&s, paths, inputs, &all, *lag, &centre), &[vec![1.0; n]])[0])
        .collect();
    let Some((_, first_lag)) = minimum(&s.lags, &first) else {
        return refused("the affine fit failed at every lag (the dots do not span the image)".into());
    };
    let kept = outliers(&s, paths, inputs, first_lag, inputs.reject_sd.unwrap_or(3.0), &centre);
    let folds = inputs.folds.max(2);
    let weights = weightings(n, folds);
    // Per lag: the full set's, each resample's and each fold's residual sum of squares.
    let by_lag: Vec<Vec<f64>> = s
        .lags
        .par_iter()
        .map(|lag| weighted_ssr(&shares(&s, paths, inputs, &kept, *lag, &centre), &weights))
        .collect();
    let curve = |w: usize| -> Vec<f64> { by_lag.iter().map(|row| row[w]).collect() };
    let full = curve(0);
    let points: usize = kept.iter().flatten().filter(|k| **k).count();
    let rms = |ssr: f64| (ssr / points.max(1) as f64).sqrt();
    let zero = s.lags.iter().position(|l| l.abs() < 1e-12);
    let mut out = Coarse {
        search_s: [s.lags[0], s.lags[s.lags.len() - 1]],
        step_s: s.lags[1] - s.lags[0],
        frame_period_s: s.period_s,
        frames: n,
        points,
        outliers: kept.iter().flatten().filter(|k| !**k).count(),
        objective: objective(&s.lags, &full, rms),
        rms_at_zero_mm: zero.map(|k| rms(full[k])),
        searched: s.points.iter().map(|f| f.index).collect(),
        motion_rms_mm: motion_rms_mm(&s, paths, inputs),
        kept,
        ..Default::default()
    };
    let fold_curves: Vec<Vec<f64>> = (0..folds).map(|f| curve(1 + BOOTSTRAP.resamples + f)).collect();
    let fold_lags_s = fold_curves
        .iter()
        .map(|c| minimum(&s.lags, c).and_then(|(k, lag)| away_from_edge(k, c.len(), &out).then_some(lag)))
        .collect();
    out.fold_lags_s = fold_lags_s;
    let resampled: Vec<Option<(usize, f64)>> = (1..=BOOTSTRAP.resamples).map(|r| minimum(&s.lags, &curve(r))).collect();
    decide(&mut out, &s.lags, &full, &resampled, points);
    out
}

/// The objective to report, every [`REPORT_STEP_S`] (or grid step), as
/// `(lag, RMS)`: the decisions use the whole grid.
fn objective(lags: &[f64], full: &[f64], rms: impl Fn(f64) -> f64) -> Vec<[f64; 2]> {
    let stride = ((REPORT_STEP_S / (lags[1] - lags[0])).round() as usize).max(1);
    let centre = lags.len() / 2;
    lags.iter()
        .zip(full)
        .enumerate()
        .filter(|(i, _)| i.abs_diff(centre) % stride == 0)
        .map(|(_, (l, c))| [*l, rms(*c)])
        .collect()
}

/// Whether grid index `k` of `len` is more than a frame period from either edge.
fn away_from_edge(k: usize, len: usize, c: &Coarse) -> bool {
    let margin = ((c.frame_period_s / c.step_s).ceil() as usize).max(1);
    k >= margin && k + margin < len
}

/// The minimum, its bootstrap spread, and the refusals (see the module's text).
fn decide(out: &mut Coarse, lags: &[f64], full: &[f64], resampled: &[Option<(usize, f64)>], points: usize) {
    let Some((k, lag)) = minimum(lags, full) else {
        out.unresolved = Some("the affine fit failed at every lag".into());
        return;
    };
    let ssr_min = full[k];
    out.rms_at_minimum_mm = Some((ssr_min / points.max(1) as f64).sqrt());
    let found: Vec<f64> = resampled.iter().flatten().map(|r| r.1).collect();
    if found.len() >= 20 {
        out.bootstrap_lag_s = Some(ScoreSpread {
            p5: percentile(&found, 0.05),
            p50: percentile(&found, 0.5),
            p95: percentile(&found, 0.95),
            resamples: found.len(),
            failed: resampled.len() - found.len(),
            block_frames: BOOTSTRAP.block_frames,
        });
    }
    // Residual variance of the affine fit: 3 coordinates a dot, 12 unknowns.
    let variance = (ssr_min / (3 * points).saturating_sub(13).max(1) as f64).max(1e-12);
    let other: Vec<f64> = resampled
        .iter()
        .flatten()
        .filter(|(r, _)| separated(full, k, *r, CHI2_90_ONE * variance))
        .map(|(_, lag)| *lag)
        .collect();
    out.other_valley_share = other.len() as f64 / resampled.len().max(1) as f64;
    let worst = full.iter().copied().filter(|c| c.is_finite()).fold(f64::MIN, f64::max);
    let curvature = if k > 0 && k + 1 < full.len() {
        (full[k - 1] - 2.0 * ssr_min + full[k + 1]) / out.step_s.powi(2)
    } else {
        0.0
    };
    let sd_s = (curvature > 0.0).then(|| (2.0 * variance / curvature).sqrt());
    let half_width = (out.search_s[1] - out.search_s[0]) / 2.0;
    let noise_mm = (ssr_min / points.max(1) as f64).sqrt();
    out.unresolved = if out.motion_rms_mm < MIN_MOTION_OVER_NOISE * noise_mm {
        Some(format!(
            "too little motion to tell the lag: the dots' targets move {:.2} mm (RMS about their means) over the sweep, less than {MIN_MOTION_OVER_NOISE} times the fit's RMS error {noise_mm:.2} mm",
            out.motion_rms_mm
        ))
    } else if (worst - ssr_min) / variance < CHI2_90_ONE {
        Some(format!(
            "the objective is flat: every lag within ±{half_width:.3} s fits within {CHI2_90_ONE} residual variances of the best (too little motion to tell the lag)"
        ))
    } else if sd_s.is_some_and(|sd| 1.645 * sd > half_width) {
        Some(format!(
            "the objective is flat: its curvature at {lag:+.3} s gives a 90 % interval of ±{:.3} s, wider than the search",
            1.645 * sd_s.unwrap_or(f64::NAN)
        ))
    } else if !away_from_edge(k, full.len(), out) {
        Some(format!(
            "the minimum at {lag:+.3} s is at the edge of the search ({:+.3} to {:+.3} s)",
            out.search_s[0], out.search_s[1]
        ))
    } else if out.other_valley_share > MAX_OTHER_VALLEY_SHARE {
        let median = crate::core::stats::percentile(&other, 0.5);
        Some(format!(
            "the objective has more than one minimum: over resamples of the sweep {:.0} % of the minima lie beyond a ridge from {lag:+.3} s (their median {median:+.3} s)",
            100.0 * out.other_valley_share
        ))
    } else {
        None
    };
    if out.unresolved.is_none() {
        out.lag_s = Some(lag);
    }
}

#[cfg(test)]
mod tests;
