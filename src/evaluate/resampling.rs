//! How good and how repeatable a calibration is, from the data alone.
//!
//! - PRE (point reconstruction error) by leave-one-out: each frame is held out,
//!   the calibration solved from the others, and the held-out feature
//!   reconstructed in the phantom frame; PRA is their mean.
//! - CR (calibration reproducibility, Lindseth 2003): the image's corners and
//!   centre mapped by calibrations from different halves of the frames; CR is the
//!   mean distance of each mapped point from its mean position.
//! - Bootstrap: frames resampled with replacement; percentile intervals (2.5 %,
//!   97.5 %) of `marker_T_image`'s translation and Euler angles and of the BRE
//!   means per axis.
//!
//! Resamples and halves come from a seeded generator: reproducible.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::core::geometry::{euler_zyx_deg, image_probe_points, Rigid};
use crate::core::rng::Rng;
use crate::core::stats::{mean_sd, percentile, MeanSd};
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::{HornError, HornFit, Variant};

/// What every resampled fit needs.
#[derive(Debug, Clone, Copy)]
pub struct FitInputs<'a> {
    pub spacing: [f64; 2],
    pub variant: Variant,
    /// Start of the line fits (wire phantoms).
    pub start: Option<&'a Rigid>,
    pub image_size_px: [usize; 2],
}

impl FitInputs<'_> {
    fn solve(&self, frames: &[Correspondence]) -> Result<HornFit, HornError> {
        correspondence::solve(frames, self.spacing, self.variant, self.start)
    }

    /// The image's four corners and centre, mm in the image frame.
    fn probe_points(&self) -> [Point3<f64>; 5] {
        image_probe_points(self.image_size_px, self.spacing)
    }
}

/// Leave-one-out PRE per frame (mm), and their mean (PRA) and SD.
#[derive(Debug, Clone, Serialize)]
pub struct LeaveOneOut {
    pub pre_mm: Vec<(usize, f64)>,
    pub summary: MeanSd,
}

pub fn leave_one_out(frames: &[Correspondence], inputs: &FitInputs<'_>) -> Result<LeaveOneOut, HornError> {
    let mut pre_mm = Vec::new();
    for i in 0..frames.len() {
        let rest: Vec<Correspondence> = frames
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != i)
            .map(|(_, f)| f.clone())
            .collect();
        let fit = inputs.solve(&rest)?;
        pre_mm.push((frames[i].frame, correspondence::bre(&frames[i], &fit, inputs.spacing).1));
    }
    let values: Vec<f64> = pre_mm.iter().map(|(_, v)| *v).collect();
    Ok(LeaveOneOut {
        summary: mean_sd(&values),
        pre_mm,
    })
}

/// CR over `halves` random half-splits (each split gives two calibrations).
#[derive(Debug, Clone, Serialize)]
pub struct Reproducibility {
    pub calibrations: usize,
    /// Mean distance of the mapped corners and centre from their mean, mm.
    pub cr_mm: f64,
    /// The same, per probe point (four corners, then the centre).
    pub per_point_mm: Vec<f64>,
}

fn shuffled(n: usize, rng: &mut Rng) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = rng.below(i + 1);
        order.swap(i, j);
    }
    order
}

pub fn reproducibility(
    frames: &[Correspondence],
    inputs: &FitInputs<'_>,
    halves: usize,
    seed: u64,
) -> Result<Reproducibility, HornError> {
    let mut rng = Rng::new(seed);
    let probes = inputs.probe_points();
    let mut mapped: Vec<[Point3<f64>; 5]> = Vec::new();
    for _ in 0..halves {
        let order = shuffled(frames.len(), &mut rng);
        let (a, b) = order.split_at(frames.len() / 2);
        for half in [a, b] {
            let subset: Vec<Correspondence> = half.iter().map(|&i| frames[i].clone()).collect();
            let fit = inputs.solve(&subset)?;
            mapped.push(probes.map(|p| fit.apply(&p)));
        }
    }
    let per_point_mm: Vec<f64> = (0..5)
        .map(|k| {
            let mean = mapped.iter().map(|m| m[k].coords).sum::<nalgebra::Vector3<f64>>() / mapped.len() as f64;
            mapped.iter().map(|m| (m[k].coords - mean).norm()).sum::<f64>() / mapped.len() as f64
        })
        .collect();
    Ok(Reproducibility {
        calibrations: mapped.len(),
        cr_mm: per_point_mm.iter().sum::<f64>() / 5.0,
        per_point_mm,
    })
}

/// A 95 % percentile interval.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub low: f64,
    pub high: f64,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Bootstrap {
    pub resamples: usize,
    pub translation_mm: [Interval; 3],
    pub euler_zyx_deg: [Interval; 3],
    /// Mean BRE per axis (x, y, z) of the resampled frames under their calibration.
    pub bre_mean_mm: [Interval; 3],
    /// Distance of the mapped corners and centre from the full-data calibration's:
    /// 95th percentile, mm.
    pub corner_shift_p95_mm: f64,
}

/// The 95 % percentile interval (2.5 %, 97.5 %) of non-empty `values`.
fn interval(values: &[f64]) -> Interval {
    Interval {
        low: percentile(values, 0.025),
        high: percentile(values, 0.975),
    }
}

pub fn bootstrap(
    frames: &[Correspondence],
    full: &HornFit,
    inputs: &FitInputs<'_>,
    resamples: usize,
    seed: u64,
) -> Result<Bootstrap, HornError> {
    let mut rng = Rng::new(seed);
    let probes = inputs.probe_points();
    let mut translation = [Vec::new(), Vec::new(), Vec::new()];
    let mut euler = [Vec::new(), Vec::new(), Vec::new()];
    let mut bre = [Vec::new(), Vec::new(), Vec::new()];
    let mut shifts = Vec::new();
    let mut done = 0;
    for _ in 0..resamples {
        let sample: Vec<Correspondence> = (0..frames.len())
            .map(|_| frames[rng.below(frames.len())].clone())
            .collect();
        // A resample may repeat one frame too often to be solvable; it is skipped.
        let Ok(fit) = inputs.solve(&sample) else { continue };
        done += 1;
        let t = fit.target_T_source.translation.vector;
        let e = euler_zyx_deg(&fit.target_T_source);
        let mut sums = [0.0; 3];
        for f in &sample {
            let (axes, _) = correspondence::bre(f, &fit, inputs.spacing);
            for k in 0..3 {
                sums[k] += axes[k];
            }
        }
        for k in 0..3 {
            translation[k].push(t[k]);
            euler[k].push(e[k]);
            bre[k].push(sums[k] / sample.len() as f64);
        }
        shifts.extend(probes.iter().map(|p| (fit.apply(p) - full.apply(p)).norm()));
    }
    if done < 10 {
        return Err(HornError::TooFewPairs(done));
    }
    Ok(Bootstrap {
        resamples: done,
        translation_mm: [0, 1, 2].map(|k| interval(&translation[k])),
        euler_zyx_deg: [0, 1, 2].map(|k| interval(&euler[k])),
        bre_mean_mm: [0, 1, 2].map(|k| interval(&bre[k])),
        corner_shift_p95_mm: percentile(&shifts, 0.95),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::correspondence::test_frames::frames;

    #[test]
    fn metrics_grow_with_the_noise_and_cover_the_truth() {
        let inputs = FitInputs {
            spacing: [0.2, 0.2],
            variant: Variant::Rigid,
            start: None,
            image_size_px: [800, 600],
        };
        let (_, _, quiet) = frames(30, 0.2, &[], 4);
        let (truth, _, noisy) = frames(30, 2.0, &[], 4);
        let loo_quiet = leave_one_out(&quiet, &inputs).unwrap();
        let loo_noisy = leave_one_out(&noisy, &inputs).unwrap();
        assert_eq!(loo_noisy.pre_mm.len(), 30);
        assert!(
            loo_noisy.summary.mean > 5.0 * loo_quiet.summary.mean,
            "{loo_quiet:?} {loo_noisy:?}"
        );
        let cr_quiet = reproducibility(&quiet, &inputs, 10, 1).unwrap();
        let cr_noisy = reproducibility(&noisy, &inputs, 10, 1).unwrap();
        assert_eq!(cr_noisy.calibrations, 20);
        assert!(cr_noisy.cr_mm > 5.0 * cr_quiet.cr_mm);
        let full = correspondence::solve(&noisy, [0.2, 0.2], Variant::Rigid, None).unwrap();
        let boot = bootstrap(&noisy, &full, &inputs, 300, 3).unwrap();
        // The true translation lies within (or very near) the 95 % intervals.
        for k in 0..3 {
            let t = truth.translation.vector[k];
            let i = boot.translation_mm[k];
            let margin = 0.25 * (i.high - i.low);
            assert!(
                i.low - margin <= t && t <= i.high + margin,
                "axis {k}: {t} not in {i:?}"
            );
            assert!(i.high > i.low);
        }
    }
}
