//! How much one held-out score moves when the calibration is fitted on other
//! frames of the same sweep: a moving-block bootstrap (Künsch 1989).
//!
//! The calibration frames are cut into contiguous blocks of `block_frames`
//! (neighbouring frames of a sweep are alike, so single frames would resample
//! as if they were independent and understate the spread); each resample draws
//! as many blocks as there are, with replacement, refits, and scores the fit.
//! The percentiles of the scores say how far apart two calibrations' scores
//! must be before the recording can tell them apart. Resample `k` draws from its
//! own stream `Rng::fork(seed, k)`: the result does not depend on the order the
//! resamples run in.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::core::rng::Rng;
use crate::core::stats::percentile;

/// How the frames are resampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockBootstrap {
    pub block_frames: usize,
    pub resamples: usize,
    pub seed: u64,
}

/// The scores' 5th, 50th and 95th percentiles over the resamples that could be
/// fitted and scored, mm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ScoreSpread {
    pub p5: f64,
    pub p50: f64,
    pub p95: f64,
    /// Resamples scored.
    pub resamples: usize,
    /// Resamples whose fit or score failed (not in the percentiles).
    pub failed: usize,
    pub block_frames: usize,
}

/// The frame indices of resample `k`: whole blocks, drawn with replacement.
pub fn resample(frames: usize, settings: &BlockBootstrap, k: usize) -> Vec<usize> {
    let block = settings.block_frames.max(1);
    let blocks = frames.div_ceil(block);
    let mut rng = Rng::fork(settings.seed, k as u64);
    (0..blocks)
        .flat_map(|_| {
            let start = rng.below(blocks) * block;
            start..(start + block).min(frames)
        })
        .collect()
}

/// `score` of each resample of `frames` (it fits on the frames given and scores
/// the fit; `None` when either fails), summarised; `None` when fewer than two
/// blocks or fewer than 20 scored resamples.
pub fn spread<T: Sync>(
    frames: &[T],
    settings: &BlockBootstrap,
    score: impl Fn(&[&T]) -> Option<f64> + Sync,
) -> Option<ScoreSpread> {
    if frames.len() < 2 * settings.block_frames.max(1) {
        return None;
    }
    let scores: Vec<Option<f64>> = (0..settings.resamples)
        .into_par_iter()
        .map(|k| {
            let picked: Vec<&T> = resample(frames.len(), settings, k)
                .into_iter()
                .map(|i| &frames[i])
                .collect();
            score(&picked).filter(|s| s.is_finite())
        })
        .collect();
    let scored: Vec<f64> = scores.iter().flatten().copied().collect();
    if scored.len() < 20 {
        return None;
    }
    Some(ScoreSpread {
        p5: percentile(&scored, 0.05),
        p50: percentile(&scored, 0.5),
        p95: percentile(&scored, 0.95),
        resamples: scored.len(),
        failed: settings.resamples - scored.len(),
        block_frames: settings.block_frames,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SETTINGS: BlockBootstrap = BlockBootstrap {
        block_frames: 10,
        resamples: 200,
        seed: 7,
    };

    #[test]
    fn a_resample_is_made_of_whole_blocks_and_as_long_as_the_frames() {
        for k in 0..20 {
            let picked = resample(95, &SETTINGS, k);
            // 10 blocks: nine of 10 frames and the last of 5.
            let mut i = 0;
            let mut blocks = 0;
            while i < picked.len() {
                let start = picked[i];
                assert_eq!(start % 10, 0, "resample {k} starts a block at {start}");
                let len = if start == 90 { 5 } else { 10 };
                assert_eq!(&picked[i..i + len], &(start..start + len).collect::<Vec<_>>()[..]);
                i += len;
                blocks += 1;
            }
            assert_eq!(blocks, 10);
        }
        assert_ne!(resample(95, &SETTINGS, 0), resample(95, &SETTINGS, 1));
    }

    #[test]
    fn the_spread_of_a_mean_follows_the_blocks_noise() {
        // Each block of 10 frames shares one offset (SD 1): the block means are
        // what varies, so the resampled mean of 20 blocks has SD 1/sqrt(20).
        let mut rng = Rng::new(3);
        let frames: Vec<f64> = (0..20)
            .flat_map(|_| {
                let offset = rng.normal(0.0, 1.0);
                (0..10).map(move |_| offset)
            })
            .collect();
        let mean = |picked: &[&f64]| Some(picked.iter().copied().sum::<f64>() / picked.len() as f64);
        let s = spread(&frames, &SETTINGS, mean).unwrap();
        let sample_sd = {
            let blocks: Vec<f64> = frames.chunks(10).map(|c| c[0]).collect();
            let m = blocks.iter().sum::<f64>() / 20.0;
            (blocks.iter().map(|b| (b - m).powi(2)).sum::<f64>() / 20.0).sqrt()
        };
        let expected_half_width = 1.645 * sample_sd / 20f64.sqrt();
        let half_width = (s.p95 - s.p5) / 2.0;
        assert!(
            (half_width / expected_half_width - 1.0).abs() < 0.25,
            "{half_width} against {expected_half_width}"
        );
        assert_eq!((s.resamples, s.failed), (200, 0));
        assert!(s.p5 < s.p50 && s.p50 < s.p95);
        // The same settings give the same spread.
        assert_eq!(spread(&frames, &SETTINGS, mean), Some(s));
    }

    #[test]
    fn failed_resamples_are_counted_and_too_few_frames_give_nothing() {
        let frames: Vec<f64> = (0..100).map(f64::from).collect();
        let odd = |picked: &[&f64]| (!(*picked[0] as usize).is_multiple_of(20)).then_some(1.0);
        let s = spread(&frames, &SETTINGS, odd).unwrap();
        assert_eq!(s.resamples + s.failed, 200);
        assert!(s.failed > 0);
        assert_eq!(spread(&frames[..15], &SETTINGS, odd), None);
    }
}
