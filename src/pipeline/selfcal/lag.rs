//! The sweeps' agreement against the tracker's lag, at the refined calibration:
//! the poses read again at each lag of a range around the start's, the pixels
//! the same. A peak inside the range gives the lag the sweeps prefer (the
//! vertex of a parabola through the peak and its neighbours); a peak at the
//! range's edge, or none, gives no lag. Nothing is applied: the calibration is
//! refined at the start's lag.

use nalgebra::Vector6;

use std::collections::BTreeSet;

use super::{load, Prepared, SelfcalError, SelfcalInputs};
use crate::estimate::selfcal::refine::{agreement, finest_grid};
use crate::estimate::selfcal::resample::{half_of, half_sample_standard_error};
use crate::io::plus::config::PlusConfig;

/// The lags scanned: the start's, and `steps` steps of `step_s` each side of it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LagScan {
    pub step_s: f64,
    pub steps: usize,
}

/// The most steps each side (a bound on the sequences read again).
pub const MAX_LAG_STEPS: usize = 20;

/// The agreement at each lag, and the lag the sweeps prefer when they have one.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LagProfile {
    /// Each lag, s, the mean normalised correlation there and the voxels it was taken over.
    pub points: Vec<(f64, f64, usize)>,
    /// The lag at the parabola's vertex through the peak and its neighbours, s.
    pub best_s: Option<f64>,
    /// Why there is no best lag (the peak at the range's edge, or no peak).
    pub no_best: Option<String>,
    /// The best lag's standard error from resampled sweeps, s (`None`: no
    /// best lag, no resamples, or fewer than half of them peak inside the range).
    #[serde(default)]
    pub standard_error_s: Option<f64>,
    /// Of the `resamples`, those whose agreement peaks inside the range.
    #[serde(default)]
    pub resamples_peaked: usize,
    #[serde(default)]
    pub resamples: usize,
}

/// Resamples of the sweeps the preferred lag's standard error comes from.
pub const LAG_RESAMPLES: usize = 8;

/// The profile at the correction `q` of the start, on the finest grid of the
/// sweeps as prepared (read at `centre_s`), over the lags `scan` sets around
/// `centre_s`. With `resamples`, the preferred lag is also found on that many
/// resamples of the sweeps (half of each sweep's 5-frame blocks, the same
/// frames at every lag): their spread, divided by √2, is its standard error.
pub fn profile(
    inputs: &SelfcalInputs,
    prepared: &Prepared,
    centre_s: f64,
    q: &Vector6<f64>,
    scan: &LagScan,
    resamples: usize,
) -> Result<LagProfile, SelfcalError> {
    let config = PlusConfig::read(&inputs.config)?;
    let steps = scan.steps.clamp(1, MAX_LAG_STEPS) as i32;
    let frame0 = &prepared.frame0;
    let grid = finest_grid(&prepared.sweeps, frame0, &inputs.settings)?;
    // Each resample as the sequence frames it keeps, per sweep.
    let halves: Vec<Vec<BTreeSet<usize>>> = (0..resamples)
        .map(|r| {
            half_of(&prepared.sweeps, None, 0x1a60_0000 + r as u64)
                .iter()
                .zip(&prepared.sweeps)
                .map(|(kept, sweep)| kept.iter().map(|&k| sweep.frames[k].index).collect())
                .collect()
        })
        .collect();
    let mut points = Vec::new();
    let mut resampled: Vec<Vec<(f64, f64, usize)>> = vec![Vec::new(); resamples];
    for k in -steps..=steps {
        let lag = centre_s + f64::from(k) * scan.step_s;
        let read_again;
        let sweeps = if k == 0 {
            // The centre's lag: the sweeps as prepared.
            &prepared.sweeps
        } else {
            read_again = inputs
                .sequences
                .iter()
                .map(|path| {
                    load::load(
                        path,
                        &config,
                        &inputs.framing,
                        prepared.block_px,
                        prepared.background_blocks,
                        lag,
                    )
                    .map(|(sweep, _)| sweep)
                })
                .collect::<Result<Vec<_>, _>>()?;
            &read_again
        };
        let (ncc, voxels) = agreement(&grid, sweeps, frame0, q, &inputs.settings, None);
        points.push((lag, ncc, voxels));
        for (half, out) in halves.iter().zip(&mut resampled) {
            let subsets: Vec<Vec<usize>> = sweeps
                .iter()
                .zip(half)
                .map(|(s, keep)| {
                    (0..s.frames.len())
                        .filter(|&i| keep.contains(&s.frames[i].index))
                        .collect()
                })
                .collect();
            let (ncc, voxels) = agreement(&grid, sweeps, frame0, q, &inputs.settings, Some(&subsets));
            out.push((lag, ncc, voxels));
        }
    }
    let (best_s, no_best) = peak(&points);
    let vertices: Vec<f64> = resampled.iter().filter_map(|p| peak(p).0).collect();
    let standard_error_s = (vertices.len() >= (resamples / 2).max(2))
        .then(|| half_sample_standard_error(&vertices))
        .flatten();
    Ok(LagProfile {
        points,
        best_s,
        no_best,
        standard_error_s: best_s.and(standard_error_s),
        resamples_peaked: vertices.len(),
        resamples,
    })
}

/// The vertex of the parabola through the highest point and its neighbours,
/// when the highest point is inside the range and the three bend down.
fn peak(points: &[(f64, f64, usize)]) -> (Option<f64>, Option<String>) {
    let finite = points.iter().all(|p| p.1.is_finite());
    let Some(top) = (0..points.len()).max_by(|&a, &b| points[a].1.total_cmp(&points[b].1)) else {
        return (None, Some("no lag was scanned".into()));
    };
    if !finite {
        return (None, Some("a correlation is not finite".into()));
    }
    if top == 0 || top + 1 == points.len() {
        return (
            None,
            Some(format!(
                "the highest correlation is at the range's edge ({:.1} ms)",
                points[top].0 * 1e3
            )),
        );
    }
    let (l, c, r) = (points[top - 1].1, points[top].1, points[top + 1].1);
    let bend = l - 2.0 * c + r;
    if bend >= 0.0 {
        return (
            None,
            Some("the correlation does not bend down at its highest point".into()),
        );
    }
    let step = points[top + 1].0 - points[top].0;
    (Some(points[top].0 + step * 0.5 * (l - r) / bend), None)
}

#[cfg(test)]
mod tests {
    use super::peak;

    #[test]
    fn the_peak_is_the_vertex_and_never_at_the_edge() {
        // A parabola with its vertex at 0.013 s, sampled every 10 ms.
        let at = |t: f64| 0.9 - 50.0 * (t - 0.013) * (t - 0.013);
        let points: Vec<(f64, f64, usize)> = (-3..=3)
            .map(|k| (f64::from(k) * 0.01, at(f64::from(k) * 0.01), 100))
            .collect();
        let (best, why) = peak(&points);
        assert!(why.is_none());
        assert!((best.unwrap() - 0.013).abs() < 1e-9, "{best:?}");
        // Rising to the last lag: no best, and the reason names the edge.
        let rising: Vec<(f64, f64, usize)> = (0..5).map(|k| (f64::from(k) * 0.01, f64::from(k), 100)).collect();
        let (best, why) = peak(&rising);
        assert!(best.is_none());
        assert!(why.unwrap().contains("edge"));
    }
}
