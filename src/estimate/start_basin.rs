//! How far off the 4-wire phantom's start guess may be: the basin of
//! convergence of [`wire_matching::match_and_solve`], measured on a run's own
//! frames.
//!
//! The reference is the calibration the manifest's start converged to. For each
//! offset of the grid, starts are drawn that far from it (the image origin moved
//! by the offset's millimetres along a random direction, the image turned by its
//! degrees about a random axis), the pairing is run again from each, and a
//! start counts as converged when it ends within 0.05 mm and 0.01° of the
//! reference. No ground truth is used: the table is what a user with real data
//! would see.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::core::geometry::{rigid_from_axis_angle, rotation_angle_between_deg, Rigid};
use crate::core::rng::Rng;
use crate::estimate::wire_matching::{self, FrameWireDots, WireAxis};

/// Offsets tried: (mm, degrees).
pub const OFFSETS: [(f64, f64); 7] = [
    (2.0, 1.0),
    (5.0, 2.0),
    (10.0, 3.0),
    (15.0, 5.0),
    (20.0, 8.0),
    (30.0, 12.0),
    (45.0, 20.0),
];
/// Random starts per offset.
pub const TRIALS: usize = 10;
const SAME_MM: f64 = 0.05;
const SAME_DEG: f64 = 0.01;

/// One offset of the grid and how many of its starts converged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BasinRow {
    pub translation_mm: f64,
    pub rotation_deg: f64,
    pub trials: usize,
    pub converged: usize,
}

/// The manifest's start, its distance from where it converged, and the basin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StartGuess {
    /// The start's image origin from the converged one's, mm.
    pub offset_translation_mm: f64,
    /// The start's rotation from the converged one's, degrees.
    pub offset_rotation_deg: f64,
    pub basin: Vec<BasinRow>,
}

/// A rotation axis or direction, uniform on the sphere.
fn unit(rng: &mut Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0));
        if v.norm() > 1e-6 {
            return v.normalize();
        }
    }
}

/// Whether two calibrations are the same within the basin's tolerance.
fn same(a: &Rigid, b: &Rigid) -> bool {
    (a.translation.vector - b.translation.vector).norm() < SAME_MM && rotation_angle_between_deg(a, b) < SAME_DEG
}

/// Measures the basin around `converged` (what `start` gave).
pub fn measure(
    frames: &[FrameWireDots],
    wires: &[WireAxis],
    start: &Rigid,
    converged: &Rigid,
    spacing: [f64; 2],
    min_frames: usize,
    seed: u64,
) -> StartGuess {
    let mut rng = Rng::new(seed);
    let basin = OFFSETS
        .iter()
        .map(|&(mm, deg)| {
            let converged_count = (0..TRIALS)
                .filter(|_| {
                    let turn = unit(&mut rng) * deg.to_radians();
                    let shift = unit(&mut rng) * mm;
                    // Turned about the image origin, then the origin moved.
                    let rotated = *converged * rigid_from_axis_angle(turn, Vector3::zeros());
                    let trial = Rigid::from_parts((rotated.translation.vector + shift).into(), rotated.rotation);
                    wire_matching::match_and_solve(frames, wires, &trial, spacing, min_frames)
                        .is_ok_and(|m| same(&m.fit.target_T_source, converged))
                })
                .count();
            BasinRow {
                translation_mm: mm,
                rotation_deg: deg,
                trials: TRIALS,
                converged: converged_count,
            }
        })
        .collect();
    StartGuess {
        offset_translation_mm: (start.translation.vector - converged.translation.vector).norm(),
        offset_rotation_deg: rotation_angle_between_deg(start, converged),
        basin,
    }
}
