//! Robust estimation over frames: RANSAC (MSAC) and LMedS with Horn's closed form
//! inside: two methods, each with its own sample choice and threshold.
//!
//! The thesis drops frames by hand-set BRE cut-offs; its future work asks for
//! RANSAC or LMedS. A minimal sample is 3 frames (3 point pairs fix a rigid
//! transform); each sample's calibration scores every frame by its residual in the
//! phantom frame (mm):
//! - RANSAC keeps the sample of least MSAC cost `Σ min(r², t²)` (Torr &
//!   Zisserman), with the inlier threshold `t` from a stated noise model: a
//!   pair's residual has SD `σ` per axis, so `|r|² / σ²` is χ² with 3 degrees of
//!   freedom and `t = √11.34 σ = 3.37 σ` keeps 99 % of good frames. `σ` is the
//!   manifest's `solve.robust.noise_sd_mm` (or `t` its `threshold_mm`), never
//!   taken from the data it judges;
//! - LMedS keeps the sample with the least median squared residual and derives
//!   the threshold from it: 2.5 robust SDs, `σ = 1.4826 (1 + 5 / (n − 3)) √median`
//!   (Rousseeuw & Leroy).
//!
//! The consensus is then refitted on its inliers and the inliers taken again until
//! they no longer change. Samples are drawn from a seeded generator, so a run is
//! reproducible.

use serde::{Deserialize, Serialize};

use crate::core::rng::Rng;
use crate::core::stats::median;
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::{HornError, HornFit, Variant};

/// Which robust estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RobustMethod {
    Ransac,
    Lmeds,
}

/// `√χ²₃(0.99)`: a 3D residual of per-axis SD σ is below this many σ with
/// probability 0.99.
pub const CHI3_99_SIGMAS: f64 = 3.368;

/// Settings of a robust fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobustSettings {
    pub method: RobustMethod,
    /// RANSAC's inlier threshold on a frame's residual (mm); absent:
    /// `3.37 noise_sd_mm`. LMedS always takes its own from the data.
    pub threshold_mm: Option<f64>,
    /// The stated SD of a good frame's residual per axis (mm), RANSAC's noise model.
    pub noise_sd_mm: f64,
    /// Random minimal samples drawn.
    pub samples: usize,
    pub seed: u64,
}

impl Default for RobustSettings {
    fn default() -> Self {
        // 500 samples of 3: with 30 % outlier frames the chance of never drawing an
        // all-inlier sample is 0.657^500 ≈ 1e-91.
        RobustSettings {
            method: RobustMethod::Ransac,
            threshold_mm: None,
            // A pair's residual per axis: 1 px of feature localisation at
            // 0.2 mm/px (0.2 mm) and each of the two tracked boards' pose error at
            // the feature, about 0.25 mm (printed boards seen by a webcam at half a
            // metre are tracked to a few tenths of a millimetre):
            // √(0.2² + 2 · 0.25²) ≈ 0.4 mm.
            noise_sd_mm: 0.4,
            samples: 500,
            seed: 1,
        }
    }
}

/// A robust fit and the frames it chose.
#[derive(Debug, Clone)]
pub struct RobustFit {
    pub fit: HornFit,
    /// Per input frame: inside the consensus.
    pub inliers: Vec<bool>,
    pub threshold_mm: f64,
    pub method: RobustMethod,
    /// Median squared residual of the best sample (LMedS's criterion), mm².
    pub median_squared_mm2: f64,
}

impl RobustSettings {
    /// RANSAC's inlier threshold, mm.
    pub fn ransac_threshold_mm(&self) -> f64 {
        self.threshold_mm.unwrap_or(CHI3_99_SIGMAS * self.noise_sd_mm)
    }
}

impl RobustFit {
    pub fn inlier_frames(&self, frames: &[Correspondence]) -> Vec<usize> {
        frames
            .iter()
            .zip(&self.inliers)
            .filter(|(_, k)| **k)
            .map(|(f, _)| f.frame)
            .collect()
    }
}

/// A frame's residual under a calibration: the distance of its feature's
/// reconstruction from the feature, mm (the mean over features of a frame).
fn frame_residual(frame: &Correspondence, fit: &HornFit, spacing: [f64; 2]) -> f64 {
    correspondence::bre(frame, fit, spacing).1
}

/// Three distinct indices below `n`.
fn draw3(rng: &mut Rng, n: usize) -> [usize; 3] {
    let a = rng.below(n);
    let mut b = rng.below(n - 1);
    if b >= a {
        b += 1;
    }
    let (lo, hi) = (a.min(b), a.max(b));
    let mut c = rng.below(n - 2);
    if c >= lo {
        c += 1;
    }
    if c >= hi {
        c += 1;
    }
    [a, b, c]
}

/// Robust calibration from point-feature frames.
pub fn solve(
    frames: &[Correspondence],
    spacing: [f64; 2],
    variant: Variant,
    settings: &RobustSettings,
) -> Result<RobustFit, HornError> {
    let n = frames.len();
    if n < 4 {
        return Err(HornError::TooFewPairs(n));
    }
    let mut rng = Rng::new(settings.seed);
    let t = settings.ransac_threshold_mm();
    // The best sample's calibration and its criterion: MSAC's cost, or LMedS's
    // median squared residual.
    let mut best: Option<(f64, HornFit)> = None;
    let mut best_median = f64::INFINITY;
    for _ in 0..settings.samples.max(1) {
        let sample = draw3(&mut rng, n);
        let subset: Vec<Correspondence> = sample.iter().map(|&i| frames[i].clone()).collect();
        let Ok(fit) = correspondence::solve(&subset, spacing, variant, None) else {
            continue; // a degenerate sample (e.g. collinear centres)
        };
        let mut squared: Vec<f64> = frames
            .iter()
            .map(|f| frame_residual(f, &fit, spacing).powi(2))
            .collect();
        let criterion = match settings.method {
            RobustMethod::Ransac => squared.iter().map(|r2| r2.min(t * t)).sum::<f64>(),
            RobustMethod::Lmeds => median(&mut squared),
        };
        // A NaN criterion never wins.
        if criterion < best.as_ref().map_or(f64::INFINITY, |(c, _)| *c) {
            if settings.method == RobustMethod::Lmeds {
                best_median = criterion;
            }
            best = Some((criterion, fit));
        }
    }
    let Some((_, start)) = best else {
        return Err(HornError::Degenerate("all sampled frame triples'"));
    };
    let median_squared_mm2 = match settings.method {
        RobustMethod::Lmeds => best_median,
        RobustMethod::Ransac => {
            let mut squared: Vec<f64> = frames
                .iter()
                .map(|f| frame_residual(f, &start, spacing).powi(2))
                .collect();
            median(&mut squared)
        }
    };
    let threshold_mm = match settings.method {
        RobustMethod::Ransac => t,
        RobustMethod::Lmeds => {
            let robust_sd = 1.4826 * (1.0 + 5.0 / (n as f64 - 3.0)) * median_squared_mm2.sqrt();
            (2.5 * robust_sd).max(1e-9)
        }
    };
    // Refit on the consensus until it is stable.
    let mut inliers: Vec<bool> = frames
        .iter()
        .map(|f| frame_residual(f, &start, spacing) < threshold_mm)
        .collect();
    let mut fit = start;
    for _ in 0..10 {
        let kept: Vec<Correspondence> = frames
            .iter()
            .zip(&inliers)
            .filter(|(_, k)| **k)
            .map(|(f, _)| f.clone())
            .collect();
        if kept.len() < 3 {
            return Err(HornError::TooFewPairs(kept.len()));
        }
        fit = correspondence::solve(&kept, spacing, variant, None)?;
        let next: Vec<bool> = frames
            .iter()
            .map(|f| frame_residual(f, &fit, spacing) < threshold_mm)
            .collect();
        if next == inliers {
            break;
        }
        inliers = next;
    }
    Ok(RobustFit {
        fit,
        inliers,
        threshold_mm,
        method: settings.method,
        median_squared_mm2,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::correspondence::test_frames::frames;
    use crate::evaluate;

    #[test]
    fn ransac_and_lmeds_find_the_planted_inliers() {
        let outliers = [1, 5, 6, 12, 17, 20, 28];
        let (truth, _, frames) = frames(30, 0.5, &outliers, 9);
        for settings in [
            RobustSettings {
                method: RobustMethod::Ransac,
                threshold_mm: Some(1.0),
                ..RobustSettings::default()
            },
            RobustSettings {
                method: RobustMethod::Ransac,
                noise_sd_mm: 0.5,
                ..RobustSettings::default()
            },
            RobustSettings {
                method: RobustMethod::Lmeds,
                ..RobustSettings::default()
            },
        ] {
            let robust = solve(&frames, [0.2, 0.2], Variant::Rigid, &settings).unwrap();
            let chosen_out: Vec<usize> = (0..30).filter(|k| !robust.inliers[*k]).collect();
            assert_eq!(chosen_out, outliers, "{settings:?}: threshold {}", robust.threshold_mm);
            let cmp = evaluate::compare_with_truth(&robust.fit, &truth, [800, 600], [0.2, 0.2]);
            assert!(cmp.corner_error_max_mm < 0.5, "{settings:?}: {cmp:?}");
        }
        // Horn on every frame is pulled far off by the same outliers.
        let all = correspondence::solve(&frames, [0.2, 0.2], Variant::Rigid, None).unwrap();
        let cmp = evaluate::compare_with_truth(&all, &truth, [800, 600], [0.2, 0.2]);
        assert!(cmp.corner_error_max_mm > 2.0, "{cmp:?}");
    }

    #[test]
    fn same_seed_same_choice() {
        let (_, _, frames) = frames(20, 0.5, &[3, 4], 2);
        let s = RobustSettings::default();
        let a = solve(&frames, [0.2, 0.2], Variant::Rigid, &s).unwrap();
        let b = solve(&frames, [0.2, 0.2], Variant::Rigid, &s).unwrap();
        assert_eq!(a.inliers, b.inliers);
        assert_eq!(a.fit.target_T_source, b.fit.target_T_source);
    }

    /// Two methods, two thresholds: RANSAC's follows the stated noise model and
    /// not the data; LMedS's follows the data's spread.
    #[test]
    fn ransac_threshold_is_the_noise_models_and_lmeds_the_datas() {
        let ransac = RobustSettings {
            noise_sd_mm: 0.3,
            ..RobustSettings::default()
        };
        let lmeds = RobustSettings {
            method: RobustMethod::Lmeds,
            ..RobustSettings::default()
        };
        let mut lmeds_thresholds = Vec::new();
        for noise_px in [1.0, 3.0] {
            let (_, _, frames) = frames(40, noise_px, &[2, 9], 6);
            let r = solve(&frames, [0.2, 0.2], Variant::Rigid, &ransac).unwrap();
            assert!(
                (r.threshold_mm - CHI3_99_SIGMAS * 0.3).abs() < 1e-12,
                "{}",
                r.threshold_mm
            );
            assert!(!r.inliers[2] && !r.inliers[9]);
            let l = solve(&frames, [0.2, 0.2], Variant::Rigid, &lmeds).unwrap();
            lmeds_thresholds.push(l.threshold_mm);
        }
        // Three times the pixel noise: LMedS's threshold grows about threefold.
        let ratio = lmeds_thresholds[1] / lmeds_thresholds[0];
        assert!((2.0..4.5).contains(&ratio), "{lmeds_thresholds:?}");
    }
}
