//! Resamples of the sweeps: which frames of each sweep a search, a
//! standard error or a bootstrap uses, drawn in whole blocks of neighbouring
//! frames.

use super::Sweep;

/// Frames of each sweep to use (all when `None`): for resampling.
pub type Subsets<'a> = Option<&'a [Vec<usize>]>;

/// Consecutive frames that a resample keeps or leaves together (neighbouring
/// frames see nearly the same tissue).
pub const RESAMPLE_BLOCK_FRAMES: usize = 5;

/// Half of every sweep's blocks of frames (of the frames `subsets` keeps, all
/// when `None`), drawn from `seed`.
pub fn half_of(sweeps: &[Sweep], subsets: Subsets, seed: u64) -> Vec<Vec<usize>> {
    let mut rng = crate::core::rng::Rng::new(seed);
    sweeps
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let frames: Vec<usize> = match subsets {
                Some(f) => f[k].clone(),
                None => (0..s.frames.len()).collect(),
            };
            let blocks = frames.len().div_ceil(RESAMPLE_BLOCK_FRAMES);
            let mut order: Vec<usize> = (0..blocks).collect();
            for i in (1..blocks).rev() {
                order.swap(i, rng.below(i + 1));
            }
            let mut kept: Vec<usize> = order[..blocks.div_ceil(2)].to_vec();
            kept.sort_unstable();
            kept.iter()
                .flat_map(|b| &frames[b * RESAMPLE_BLOCK_FRAMES..((b + 1) * RESAMPLE_BLOCK_FRAMES).min(frames.len())])
                .copied()
                .collect()
        })
        .collect()
}

/// A block bootstrap of the sweeps: each sweep's 5-frame blocks drawn with
/// replacement, as many as it has (a frame drawn twice weighs twice), from
/// `seed`. A resampled recording of the same size, for the spread of anything
/// computed from the sweeps.
pub fn block_bootstrap(sweeps: &[Sweep], seed: u64) -> Vec<Vec<usize>> {
    let mut rng = crate::core::rng::Rng::new(seed);
    sweeps
        .iter()
        .map(|s| {
            let n = s.frames.len();
            let blocks = n.div_ceil(RESAMPLE_BLOCK_FRAMES);
            let mut drawn: Vec<usize> = (0..blocks).map(|_| rng.below(blocks)).collect();
            drawn.sort_unstable();
            drawn
                .iter()
                .flat_map(|b| b * RESAMPLE_BLOCK_FRAMES..((b + 1) * RESAMPLE_BLOCK_FRAMES).min(n))
                .collect()
        })
        .collect()
}

/// The standard error of an estimate over the whole sweeps from its values on
/// halves of them: their spread (n − 1 in the denominator) divided by √2, as a
/// half has twice the whole's variance. `None` with fewer than two values.
pub fn half_sample_standard_error(values: &[f64]) -> Option<f64> {
    if values.len() < 2 {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Some(variance.sqrt() / 2f64.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::selfcal::SweepFrame;
    use nalgebra::Matrix4;

    fn sweep(frames: usize) -> Sweep {
        Sweep {
            name: "s".into(),
            samples_px: vec![[0.0, 0.0]],
            frames: (0..frames)
                .map(|index| SweepFrame {
                    index,
                    reference_T_probe: Matrix4::identity(),
                    values: vec![0.0],
                })
                .collect(),
        }
    }

    #[test]
    fn a_half_of_resampled_sweeps_stays_within_their_frames() {
        let sweeps = vec![sweep(40), sweep(23)];
        let subsets = vec![(0..40).step_by(3).collect::<Vec<_>>(), (5..23).collect()];
        for seed in 0..20 {
            let half = half_of(&sweeps, Some(&subsets), seed);
            for (h, s) in half.iter().zip(&subsets) {
                assert!(h.iter().all(|f| s.contains(f)), "{h:?} outside {s:?}");
                assert!(h.len() * 2 >= s.len() - RESAMPLE_BLOCK_FRAMES && h.len() <= s.len());
            }
        }
        // On whole sweeps, the same as before resampling within subsets.
        let all: Vec<Vec<usize>> = sweeps.iter().map(|s| (0..s.frames.len()).collect()).collect();
        assert_eq!(half_of(&sweeps, None, 7), half_of(&sweeps, Some(&all), 7));
    }

    #[test]
    fn a_half_sample_standard_error_is_the_halves_spread_over_root_two() {
        assert_eq!(half_sample_standard_error(&[1.0]), None);
        // Spread of 1, 3: sample variance 2, so the whole's SE is 1.
        let se = half_sample_standard_error(&[1.0, 3.0]).unwrap_or(f64::NAN);
        assert!((se - 1.0).abs() < 1e-12, "{se}");
    }

    #[test]
    fn a_block_bootstrap_keeps_each_sweep_s_size_and_blocks() {
        let sweeps = vec![sweep(40), sweep(23)];
        for seed in 0..20 {
            let drawn = block_bootstrap(&sweeps, seed);
            assert_eq!(drawn[0].len(), 40);
            assert!(drawn[1].iter().all(|&f| f < 23));
            // Whole blocks: each drawn frame's block start is drawn with it.
            for d in &drawn {
                assert!(d.iter().all(|f| d.contains(&(f - f % RESAMPLE_BLOCK_FRAMES))));
            }
        }
    }
}
