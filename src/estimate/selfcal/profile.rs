//! The agreement around a solution along each direction: what the page draws
//! to show which directions the sweeps hold (a peak) and which they do not (flat).

use nalgebra::Vector6;

use super::refine::{correlations_over, finest_grid, Direction, SearchFault, SearchSettings};
use super::{Frame0, Sweep};

/// Points each side of the solution along a direction.
pub const PROFILE_SIDE_POINTS: i32 = 4;

/// The mean correlation along one direction through the solution.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Profile {
    /// The direction's unknowns, largest first (as [`Direction::mostly`]).
    pub mostly: String,
    pub held: bool,
    /// Distance from the solution along the direction, mm, and the mean
    /// normalised correlation of the sweeps there (all over the same voxels).
    pub points: Vec<(f64, f64)>,
}

/// The agreement at `q` and at up to two finite-difference steps each side of
/// it along each direction, on the finest grid, all over the voxels every
/// sweep covers at each of these points.
pub fn profiles(
    sweeps: &[Sweep],
    frame0: &Frame0,
    q: &Vector6<f64>,
    directions: &[Direction],
    settings: &SearchSettings,
) -> Result<Vec<Profile>, SearchFault> {
    let finest = finest_grid(sweeps, frame0, settings)?;
    let offsets: Vec<f64> = (-PROFILE_SIDE_POINTS..=PROFILE_SIDE_POINTS)
        .map(|k| f64::from(k) * settings.step_mm / 2.0)
        .collect();
    let points: Vec<Vector6<f64>> = directions
        .iter()
        .flat_map(|d| {
            let v = Vector6::from_column_slice(&d.vector);
            offsets.iter().map(move |t| q + v * *t)
        })
        .collect();
    let (ncc, _) = correlations_over(&finest, sweeps, frame0, q, &points, settings, None)?;
    Ok(directions
        .iter()
        .zip(ncc.chunks(offsets.len()))
        .map(|(d, values)| Profile {
            mostly: d.mostly.clone(),
            held: d.held,
            points: offsets.iter().copied().zip(values.iter().copied()).collect(),
        })
        .collect())
}
