//! Robust estimation over frames: RANSAC and LMedS with Horn's closed form inside.
//!
//! The thesis drops frames by hand-set BRE cut-offs; its future work asks for
//! RANSAC or LMedS. A minimal sample is 3 frames (3 point pairs fix a rigid
//! transform); each sample's calibration scores every frame by its residual in the
//! phantom frame (mm):
//! - RANSAC keeps the sample with most frames within the inlier threshold (ties:
//!   the smaller sum of inlier residuals, MSAC's rule);
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

/// Settings of a robust fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobustSettings {
    pub method: RobustMethod,
    /// Inlier threshold on a frame's residual (mm); absent: derived from the data
    /// by LMedS's robust scale.
    pub threshold_mm: Option<f64>,
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
    // (RANSAC score: inliers, then -sum) / (LMedS: median squared residual).
    let mut best_ransac: Option<(usize, f64, HornFit)> = None;
    let mut best_lmeds: Option<(f64, HornFit)> = None;
    for _ in 0..settings.samples.max(1) {
        let sample = draw3(&mut rng, n);
        let subset: Vec<Correspondence> = sample.iter().map(|&i| frames[i].clone()).collect();
        let Ok(fit) = correspondence::solve(&subset, spacing, variant, None) else {
            continue; // a degenerate sample (e.g. collinear centres)
        };
        let residuals: Vec<f64> = frames.iter().map(|f| frame_residual(f, &fit, spacing)).collect();
        let mut squared: Vec<f64> = residuals.iter().map(|r| r * r).collect();
        let med = median(&mut squared);
        if best_lmeds.as_ref().is_none_or(|(m, _)| med < *m) {
            best_lmeds = Some((med, fit.clone()));
        }
        if let Some(t) = settings.threshold_mm {
            let inside: Vec<f64> = residuals.iter().copied().filter(|r| *r < t).collect();
            let score = (inside.len(), inside.iter().sum::<f64>());
            let better = match &best_ransac {
                None => true,
                Some((count, sum, _)) => score.0 > *count || (score.0 == *count && score.1 < *sum),
            };
            if better {
                best_ransac = Some((score.0, score.1, fit));
            }
        }
    }
    let Some((median_squared_mm2, lmeds_fit)) = best_lmeds else {
        return Err(HornError::Degenerate("all sampled frame triples'"));
    };
    let robust_sd = 1.4826 * (1.0 + 5.0 / (n as f64 - 3.0)) * median_squared_mm2.sqrt();
    let (threshold_mm, start) = match (settings.method, settings.threshold_mm, best_ransac) {
        (RobustMethod::Ransac, Some(t), Some((_, _, fit))) => (t, fit),
        // RANSAC without a threshold: the data's robust scale gives it.
        _ => ((2.5 * robust_sd).max(1e-9), lmeds_fit),
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
                threshold_mm: None,
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
}
