//! The lag refined with the calibration's own model, its uncertainty, and
//! whether to apply it (spatio-temporal calibration, after the coarse search of
//! [`crate::pipeline::tracked::time::lag`]).
//!
//! - **Joint refinement.** The lag and the calibration are fitted together by
//!   profiling: at each lag tried, the model chosen by cross-validation (its
//!   constraints and pixel model) is fitted to the calibration frames' poses at
//!   that lag, and the lag that leaves the smallest residual sum of squares is
//!   the joint minimum (golden-section search within two frame periods of the
//!   coarse minimum, to 0.1 ms). The constraints kept are those the fit at the
//!   coarse minimum kept (PLUS's outlier rule), so that the objective does not
//!   jump as a constraint crosses the rule's limit.
//! - **Uncertainty.** From the objective's curvature at the joint minimum
//!   (`SD = sqrt(2 s² / S'')`, `s²` the residual variance: as if the residuals
//!   were independent, which neighbouring frames are not), and from the coarse
//!   search's block-bootstrap refits (which keep neighbouring frames together).
//!   Both are reported; a resolved estimate is applied with them whatever their
//!   width.
//! - **Lag or no lag.** Cross-validation over contiguous blocks of the
//!   calibration frames, as the model is chosen: in each fold the lag is
//!   searched on the training frames alone, the model fitted there at that lag,
//!   and the held-out middle dots scored at that lag; the same folds score the
//!   model with no lag. The lag is applied when it lowers the held-out error by
//!   more than one standard error of the paired difference (blocks of ten
//!   frames); otherwise the simpler model, no lag, is kept. Validation frames
//!   never enter.
//! - **A second opinion.** The sweep's motion cross-correlation
//!   ([`crate::pipeline::tracked::time::sweep_lag`]) is reported beside it; where the two
//!   intervals do not overlap the disagreement is said, and which is applied.

use std::collections::HashSet;

use serde::{Deserialize, Serialize};

use crate::core::stats::{best_95, MeanSd};
use crate::estimate::model_selection::{self, Candidate, FrameConstraints};
use crate::pipeline::sequence_frames::{Role, TrackedFrame};
use crate::pipeline::tracked::inputs::{
    attach_poses_along, fit_settings, usable_constraints, TrackedInputs, TrackerPaths,
};
use crate::pipeline::tracked::time::lag::Coarse;
use crate::pipeline::tracked::time::sweep_lag::SweepLag;

/// Golden-section tolerance of the joint refinement, s.
const TOLERANCE_S: f64 = 1e-4;
/// Frames per block of the cross-validation's standard error.
const SE_BLOCK_FRAMES: usize = 10;

/// The joint minimum and its curvature-based uncertainty.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Joint {
    pub lag_s: f64,
    /// The residual sum of squares there, mm², and its residual variance.
    pub ssr_mm2: f64,
    pub residual_variance_mm2: f64,
    /// SD of the lag from the objective's curvature, s.
    pub curvature_sd_s: Option<f64>,
    /// Where the refinement stopped at its bracket's edge (the coarse lag is kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// Cross-validation of "lag" against "no lag" on the calibration frames.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LagCrossValidation {
    pub folds: usize,
    pub frames: usize,
    /// Held-out middle dots' PRE3D, PLUS's best-95 % mean, mm.
    pub no_lag_mm: Option<MeanSd>,
    pub lag_mm: Option<MeanSd>,
    /// Mean of (lag − no lag) over the held-out dots, and its standard error, mm.
    pub difference_mm: f64,
    pub standard_error_mm: f64,
    /// Each fold's lag, searched on its training frames, s.
    pub fold_lags_s: Vec<Option<f64>>,
    /// "lag" or "no lag".
    pub chosen: String,
}

/// The tracker's lag as the calibration estimated it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LagEstimate {
    /// The joint estimate, s; `None` where the data cannot tell the lag.
    pub lag_s: Option<f64>,
    /// Whether the lag is applied (cross-validation chose it).
    pub applied: bool,
    /// Which lag is applied, and why.
    pub decision: String,
    /// Curvature-based 90 % interval of the joint estimate, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_90_s: Option<[f64; 2]>,
    pub coarse: Coarse,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<Joint>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cross_validation: Option<LagCrossValidation>,
    /// The independent estimate from the sweep's motion.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<SweepLag>,
    /// Where the two estimates' intervals do not overlap.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disagreement: Option<String>,
    /// Why no lag was estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unresolved: Option<String>,
}

impl LagEstimate {
    /// The lag to apply, s.
    pub fn applied_s(&self) -> f64 {
        match (self.applied, self.lag_s) {
            (true, Some(lag)) => lag,
            _ => 0.0,
        }
    }

    /// Refused before any search (a clock that cannot be followed, …).
    pub fn refused(reason: String, motion: Option<SweepLag>) -> LagEstimate {
        LagEstimate {
            decision: format!("no lag applied: {reason}"),
            unresolved: Some(reason),
            motion,
            ..Default::default()
        }
    }

    /// The spatio-temporal estimate's interval: the wider of the curvature's and
    /// the bootstrap's, s.
    pub fn interval_s(&self) -> Option<[f64; 2]> {
        let boot = self.coarse.bootstrap_lag_s.map(|b| [b.p5, b.p95]);
        match (self.interval_90_s, boot) {
            (Some(a), Some(b)) => Some([a[0].min(b[0]), a[1].max(b[1])]),
            (a, b) => a.or(b),
        }
    }
}

/// The searched calibration frames (as the coarse search took them), in time order.
fn searched(frames: &[TrackedFrame], coarse: &Coarse) -> Vec<TrackedFrame> {
    let keep: HashSet<usize> = coarse.searched.iter().copied().collect();
    let mut out: Vec<TrackedFrame> = frames
        .iter()
        .filter(|f| f.role == Role::Calibration && keep.contains(&f.index))
        .cloned()
        .collect();
    out.sort_by(|a, b| a.timestamp_s.unwrap_or(0.0).total_cmp(&b.timestamp_s.unwrap_or(0.0)));
    out
}

/// The frames' constraints at `lag_s`, one entry per frame (empty where its
/// pose cannot be had).
fn constraints_at(
    paths: &TrackerPaths,
    frames: &mut [TrackedFrame],
    inputs: &TrackedInputs,
    lag_s: f64,
) -> Vec<FrameConstraints> {
    attach_poses_along(paths, frames, inputs, lag_s);
    frames
        .iter()
        .map(|f| {
            usable_constraints(std::slice::from_ref(f), &inputs.nwires, Role::Calibration)
                .pop()
                .unwrap_or_default()
        })
        .collect()
}

/// The constraints `inlier` kept (flags in the order a fit lists them: per
/// frame, its points, then its lines when the candidate fits them).
fn masked(frames: &[FrameConstraints], inlier: &[bool], candidate: Candidate) -> Vec<FrameConstraints> {
    let mut flags = inlier.iter();
    let wires = candidate.constraints == crate::estimate::image_to_probe::ConstraintModel::Wires;
    frames
        .iter()
        .map(|f| FrameConstraints {
            points: f
                .points
                .iter()
                .filter(|_| *flags.next().unwrap_or(&false))
                .copied()
                .collect(),
            lines: if wires {
                f.lines
                    .iter()
                    .filter(|_| *flags.next().unwrap_or(&false))
                    .copied()
                    .collect()
            } else {
                Vec::new()
            },
        })
        .collect()
}

/// Residual sum of squares (mm²) and residual components of `candidate`
/// fitted with no rejection.
fn ssr(frames: &[FrameConstraints], candidate: Candidate, inputs: &TrackedInputs) -> Option<(f64, usize)> {
    let settings = model_selection::FitSettings {
        reject_sd: None,
        ..fit_settings(inputs)
    };
    let fit = model_selection::fit(frames.iter(), candidate, settings).ok()?;
    let sum: f64 = fit.fit.residual_mm.iter().map(|r| r * r).sum();
    let components: usize = frames.iter().map(|f| 3 * f.points.len() + 2 * f.lines.len()).sum();
    sum.is_finite().then_some((sum, components))
}

/// The joint refinement (see the module's text); `None` when the coarse search
/// found no lag or the fits fail.
pub fn refine(
    paths: &TrackerPaths,
    frames: &[TrackedFrame],
    inputs: &TrackedInputs,
    coarse: &Coarse,
    candidate: Candidate,
) -> Option<Joint> {
    let start = coarse.lag_s?;
    let mut work = searched(frames, coarse);
    let at_start = constraints_at(paths, &mut work, inputs, start);
    let inlier = model_selection::fit(at_start.iter(), candidate, fit_settings(inputs))
        .ok()?
        .fit
        .inlier;
    let mut evaluate = |lag: f64| -> Option<(f64, usize)> {
        let c = constraints_at(paths, &mut work, inputs, lag);
        ssr(&masked(&c, &inlier, candidate), candidate, inputs)
    };
    let period = coarse.frame_period_s;
    let (lo, hi) = (
        (start - 2.0 * period).max(coarse.search_s[0]),
        (start + 2.0 * period).min(coarse.search_s[1]),
    );
    let lag = golden(&mut |lag| evaluate(lag).map_or(f64::INFINITY, |s| s.0), lo, hi);
    let at_edge = (lag - lo).abs() < 2.0 * TOLERANCE_S || (hi - lag).abs() < 2.0 * TOLERANCE_S;
    let (lag, note) = if at_edge {
        (
            start,
            Some(format!(
                "the joint refinement reached the edge of its bracket ({lo:+.3} to {hi:+.3} s): the coarse minimum is kept"
            )),
        )
    } else {
        (lag, None)
    };
    let (ssr_mm2, components) = evaluate(lag)?;
    let unknowns = 6 + 3 + 1;
    let variance = ssr_mm2 / components.saturating_sub(unknowns).max(1) as f64;
    let h = (period / 2.0).max(0.002);
    let mut objective = |lag: f64| evaluate(lag).map_or(f64::INFINITY, |s| s.0);
    let (below, above) = (objective(lag - h), objective(lag + h));
    let curvature = (below - 2.0 * ssr_mm2 + above) / (h * h);
    Some(Joint {
        lag_s: lag,
        ssr_mm2,
        residual_variance_mm2: variance,
        curvature_sd_s: (curvature > 0.0 && curvature.is_finite()).then(|| (2.0 * variance / curvature).sqrt()),
        note,
    })
}

/// Golden-section search for the minimum of `f` on `[a, b]`.
fn golden(f: &mut impl FnMut(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    while b - a > TOLERANCE_S {
        if fc <= fd {
            (b, d, fd) = (d, c, fc);
            c = b - r * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    (a + b) / 2.0
}

/// Held-out middle dots' errors of each fold, the model fitted on the others,
/// each fold's frames at `lag_of(fold)`.
fn held_out(
    paths: &TrackerPaths,
    work: &mut [TrackedFrame],
    inputs: &TrackedInputs,
    candidate: Candidate,
    folds: usize,
    lag_of: impl Fn(usize) -> f64,
) -> Option<Vec<Vec<f64>>> {
    let n = work.len();
    let mut per_frame = vec![Vec::new(); n];
    for fold in 0..folds {
        let c = constraints_at(paths, work, inputs, lag_of(fold));
        let training = c
            .iter()
            .enumerate()
            .filter(|(i, _)| i * folds / n != fold)
            .map(|(_, f)| f);
        let trained = model_selection::fit(training, candidate, fit_settings(inputs)).ok()?;
        for (i, frame) in c.iter().enumerate().filter(|(i, _)| i * folds / n == fold) {
            per_frame[i] = frame
                .points
                .iter()
                .map(|p| {
                    p.residual_with(&trained.fit.image_to_probe, &trained.fit.phantom_correction)
                        .norm()
                })
                .collect();
        }
    }
    Some(per_frame)
}

/// Cross-validation of "lag" against "no lag" (see the module's text).
pub fn cross_validate(
    paths: &TrackerPaths,
    frames: &[TrackedFrame],
    inputs: &TrackedInputs,
    coarse: &Coarse,
    candidate: Candidate,
) -> Option<LagCrossValidation> {
    let folds = coarse.fold_lags_s.len();
    let mut work = searched(frames, coarse);
    if folds < 2 || work.len() < 2 * folds {
        return None;
    }
    let fold_lag = |fold: usize| coarse.fold_lags_s[fold].unwrap_or(0.0);
    let with_lag = held_out(paths, &mut work, inputs, candidate, folds, fold_lag)?;
    let without = held_out(paths, &mut work, inputs, candidate, folds, |_| 0.0)?;
    // Paired per dot; the standard error from blocks of neighbouring frames.
    let mut blocks: Vec<(f64, usize)> = Vec::new();
    for (i, (a, b)) in with_lag.iter().zip(&without).enumerate() {
        if i % SE_BLOCK_FRAMES == 0 {
            blocks.push((0.0, 0));
        }
        let block = blocks.last_mut()?;
        for (x, y) in a.iter().zip(b) {
            block.0 += x - y;
            block.1 += 1;
        }
    }
    let total: usize = blocks.iter().map(|b| b.1).sum();
    let difference_mm = blocks.iter().map(|b| b.0).sum::<f64>() / total.max(1) as f64;
    let means: Vec<f64> = blocks.iter().filter(|b| b.1 > 0).map(|b| b.0 / b.1 as f64).collect();
    let m = means.len() as f64;
    let mean_of_means = means.iter().sum::<f64>() / m;
    let sd = (means.iter().map(|x| (x - mean_of_means).powi(2)).sum::<f64>() / (m - 1.0).max(1.0)).sqrt();
    let standard_error_mm = sd / m.sqrt();
    let chosen = if difference_mm + standard_error_mm < 0.0 {
        "lag"
    } else {
        "no lag"
    };
    let flat = |v: &[Vec<f64>]| best_95(&v.iter().flatten().copied().collect::<Vec<f64>>());
    Some(LagCrossValidation {
        folds,
        frames: work.len(),
        no_lag_mm: flat(&without),
        lag_mm: flat(&with_lag),
        difference_mm,
        standard_error_mm,
        fold_lags_s: coarse.fold_lags_s.clone(),
        chosen: chosen.into(),
    })
}

/// The estimate from its parts: which lag is applied and why, and how it
/// compares with the motion estimate.
pub fn assemble(
    coarse: Coarse,
    joint: Option<Joint>,
    cross_validation: Option<LagCrossValidation>,
    motion: Option<SweepLag>,
) -> LagEstimate {
    let lag_s = joint.as_ref().map(|j| j.lag_s).or(coarse.lag_s);
    let interval_90_s = joint
        .as_ref()
        .and_then(|j| j.curvature_sd_s.map(|sd| [j.lag_s - 1.645 * sd, j.lag_s + 1.645 * sd]));
    let mut out = LagEstimate {
        lag_s,
        interval_90_s,
        unresolved: coarse.unresolved.clone(),
        coarse,
        joint,
        motion,
        ..Default::default()
    };
    let ms = |s: f64| s * 1000.0;
    (out.applied, out.decision) = match (&out.unresolved, lag_s, cross_validation.as_ref()) {
        (Some(why), _, _) => (false, format!("no lag applied: the calibration frames cannot tell it ({why})")),
        (None, None, _) => (false, "no lag applied: the refinement failed".into()),
        (None, Some(lag), None) => (
            true,
            format!("{:+.0} ms applied: the calibration frames are too few to cross-validate it", ms(lag)),
        ),
        (None, Some(lag), Some(cv)) if cv.chosen == "lag" => (
            true,
            format!(
                "{:+.0} ms applied: on held-out calibration frames it lowers PRE3D by {:.3} mm (standard error {:.3} mm)",
                ms(lag),
                -cv.difference_mm,
                cv.standard_error_mm
            ),
        ),
        (None, Some(lag), Some(cv)) => (
            false,
            format!(
                "no lag applied: {:+.0} ms changes held-out calibration PRE3D by {:+.3} mm, within one standard error ({:.3} mm) of no lag",
                ms(lag),
                cv.difference_mm,
                cv.standard_error_mm
            ),
        ),
    };
    out.cross_validation = cross_validation;
    out.disagreement = disagreement(&out);
    out
}

/// Words for two estimates whose intervals do not overlap.
fn disagreement(e: &LagEstimate) -> Option<String> {
    let ours = e.interval_s()?;
    let motion = e.motion.as_ref()?;
    let m_lag = motion.lag_s?;
    let m = motion
        .bootstrap_lag_s
        .map_or([m_lag, m_lag], |b| [b.p5.min(m_lag), b.p95.max(m_lag)]);
    if ours[1] >= m[0] && m[1] >= ours[0] {
        return None;
    }
    let ms = |s: f64| s * 1000.0;
    Some(format!(
        "the two estimates disagree: the calibration's {:+.0} ms ({:+.0} to {:+.0} ms) against the motion's {:+.0} ms ({:+.0} to {:+.0} ms); {}",
        ms(e.lag_s.unwrap_or(f64::NAN)),
        ms(ours[0]),
        ms(ours[1]),
        ms(m_lag),
        ms(m[0]),
        ms(m[1]),
        if e.applied {
            "the calibration's is applied: it is the lag at which the dots and their poses agree best, and cross-validation chose it"
        } else {
            "neither is applied: cross-validation on the calibration frames kept no lag"
        }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_section_finds_a_parabolas_floor() {
        let mut calls = 0;
        let mut f = |x: f64| {
            calls += 1;
            (x - 0.1234).powi(2)
        };
        let x = golden(&mut f, 0.0, 0.3);
        assert!((x - 0.1234).abs() < TOLERANCE_S, "{x}");
        assert!(calls < 40, "{calls}");
    }

    fn spread(p5: f64, p95: f64) -> crate::evaluate::block_bootstrap::ScoreSpread {
        crate::evaluate::block_bootstrap::ScoreSpread {
            p5,
            p50: (p5 + p95) / 2.0,
            p95,
            resamples: 200,
            failed: 0,
            block_frames: 10,
        }
    }

    #[test]
    fn estimates_whose_intervals_do_not_overlap_are_said_to_disagree() {
        let coarse = Coarse {
            lag_s: Some(0.4),
            bootstrap_lag_s: Some(spread(0.38, 0.43)),
            ..Default::default()
        };
        let motion = |lag: f64, p5: f64, p95: f64| SweepLag {
            lag_s: Some(lag),
            bootstrap_lag_s: Some(spread(p5, p95)),
            ..Default::default()
        };
        let far = assemble(coarse.clone(), None, None, Some(motion(0.1, 0.05, 0.15)));
        let text = far.disagreement.clone().expect("disagree");
        assert!(text.contains("+400 ms") && text.contains("+100 ms"), "{text}");
        assert!(far.applied && (far.applied_s() - 0.4).abs() < 1e-12);
        let near = assemble(coarse, None, None, Some(motion(0.41, 0.36, 0.45)));
        assert_eq!(near.disagreement, None);
    }

    #[test]
    fn cross_validation_keeps_no_lag_within_one_standard_error() {
        let coarse = Coarse {
            lag_s: Some(0.05),
            ..Default::default()
        };
        let cv = |difference_mm: f64| LagCrossValidation {
            difference_mm,
            standard_error_mm: 0.01,
            chosen: if difference_mm + 0.01 < 0.0 { "lag" } else { "no lag" }.into(),
            ..Default::default()
        };
        let kept = assemble(coarse.clone(), None, Some(cv(-0.005)), None);
        assert!(!kept.applied && kept.applied_s() == 0.0, "{}", kept.decision);
        assert!(kept.decision.starts_with("no lag applied"), "{}", kept.decision);
        let applied = assemble(coarse, None, Some(cv(-0.05)), None);
        assert!(
            applied.applied && applied.decision.contains("+50 ms applied"),
            "{}",
            applied.decision
        );
        let refused = assemble(
            Coarse {
                unresolved: Some("flat".into()),
                ..Default::default()
            },
            None,
            None,
            None,
        );
        assert_eq!((refused.lag_s, refused.applied), (None, false));
    }
}
