//! `probecal resolve <run folder>`: the run's calibration solved again from its
//! own folder, compared with the `marker_T_image` its `summary.json` reports.

use crate::report::error::ReadError;
use std::path::Path;

use crate::core::geometry::to_rows;
use crate::pipeline::run::resolve::{solve_again, SolveInputs};
use crate::results::summary::RunSummary;

/// Largest difference between two transforms' matrix entries that still counts
/// as the same calibration (mm for the translation, unitless for the rotation).
pub const SAME_CALIBRATION: f64 = 1e-9;

/// The largest entry-wise difference between the re-solved and the reported
/// `marker_T_image`, and the re-solved matrix.
pub fn resolve(run_folder: &Path) -> Result<(f64, [[f64; 4]; 4]), ResolveError> {
    let summary = match RunSummary::read(&run_folder.join("summary.json"))? {
        RunSummary::Camera(s) => s,
        RunSummary::Tracked(_) => {
            return Err(ResolveError::Summary(ReadError::new(
                run_folder,
                "a tracked-sequence run; its inputs are its sequence files: run its manifest again",
            )))
        }
    };
    let inputs = SolveInputs::read(run_folder)?;
    let solved = solve_again(&inputs)?;
    let again = to_rows(&solved.reported().target_T_source);
    let reported = summary.calibration.marker_T_image;
    let difference = (0..4)
        .flat_map(|r| (0..4).map(move |c| (r, c)))
        .map(|(r, c)| (again[r][c] - reported[r][c]).abs())
        .fold(0.0, f64::max);
    Ok((difference, again))
}

/// Why a run folder cannot be solved again.
#[derive(Debug, thiserror::Error)]
pub enum ResolveError {
    #[error("{0}")]
    Summary(#[from] ReadError),
    #[error("{0}")]
    Inputs(#[from] crate::pipeline::run::resolve::SolveInputsError),
}
