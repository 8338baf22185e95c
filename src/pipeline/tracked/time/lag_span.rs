//! How much a tracked run's accuracy depends on its lag's uncertainty: the
//! calibration refitted on the calibration frames at lags across the lag's
//! 90 % interval, every frame's poses read at each of those lags. The report
//! scores them on the validation frames; nothing here chooses the lag.

use nalgebra::Matrix4;

use crate::estimate::image_to_probe::Fit;
use crate::estimate::model_selection::{self, Candidate};
use crate::pipeline::tracked::inputs::{attach_poses_along, fit_settings, usable_constraints, TrackerPaths};
use crate::pipeline::tracked::{Role, TrackedFrame, TrackedInputs};

/// Lags across the interval, both ends included.
pub const SPAN_LAGS: usize = 5;

/// The calibration at one lag of the span.
#[derive(Debug, Clone)]
pub struct SpanPoint {
    pub lag_s: f64,
    /// The chosen model refitted on the calibration frames at this lag.
    pub fit: Fit,
    /// Each of the run's frames' `marker_T_phantom` at this lag, in the run's
    /// frame order; `None` where the trajectory does not reach it.
    pub poses: Vec<Option<Matrix4<f64>>>,
}

/// `SPAN_LAGS` lags evenly across `interval_s`, ends included, and
/// `applied_s`, in order; none for an interval that is not finite or not
/// ordered.
pub fn lags(interval_s: [f64; 2], applied_s: f64) -> Vec<f64> {
    let [a, b] = interval_s;
    if !(a.is_finite() && b.is_finite() && a < b) {
        return Vec::new();
    }
    let mut out: Vec<f64> = (0..SPAN_LAGS)
        .map(|k| a + (b - a) * k as f64 / (SPAN_LAGS - 1) as f64)
        .chain([applied_s])
        .collect();
    out.sort_by(f64::total_cmp);
    out.dedup();
    out
}

/// The chosen model refitted at each lag, with every frame's poses there:
/// calibration frames from `calibration_paths`, validation frames from
/// `validation_paths`. A lag at which the fit fails is left out.
pub fn refit(
    frames: &[TrackedFrame],
    calibration_paths: &TrackerPaths,
    validation_paths: Option<&TrackerPaths>,
    inputs: &TrackedInputs,
    candidate: Candidate,
    lags_s: &[f64],
) -> Vec<SpanPoint> {
    lags_s
        .iter()
        .filter_map(|&lag_s| {
            let mut at: Vec<TrackedFrame> = frames.to_vec();
            for (role, paths) in [
                (Role::Calibration, Some(calibration_paths)),
                (Role::Validation, validation_paths),
            ] {
                let positions: Vec<usize> = (0..at.len()).filter(|&i| at[i].role == role).collect();
                let mut part: Vec<TrackedFrame> = positions.iter().map(|&i| at[i].clone()).collect();
                match paths {
                    Some(paths) => attach_poses_along(paths, &mut part, inputs, lag_s),
                    None => part.iter_mut().for_each(|f| f.marker_T_phantom = None),
                }
                for (i, f) in positions.into_iter().zip(part) {
                    at[i] = f;
                }
            }
            let usable = usable_constraints(&at, &inputs.nwires, Role::Calibration);
            let trained = model_selection::fit(usable.iter(), candidate, fit_settings(inputs)).ok()?;
            Some(SpanPoint {
                lag_s,
                fit: trained.fit,
                poses: at.iter().map(|f| f.marker_T_phantom).collect(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_span_covers_the_interval_and_the_lag_applied() {
        assert_eq!(lags([0.0, 0.5], 0.3), vec![0.0, 0.125, 0.25, 0.3, 0.375, 0.5]);
        // The applied lag on a grid point is not scored twice.
        assert_eq!(lags([0.0, 0.5], 0.25).len(), SPAN_LAGS);
        assert!(lags([0.08, 0.04], 0.06).is_empty());
        assert!(lags([f64::NAN, 0.04], 0.0).is_empty());
    }
}
