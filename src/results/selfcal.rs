//! `probecal selfcal`'s outcome: the correction of `ImageToProbe` that makes
//! overlapping sweeps compound alike, with the directions the sweeps hold.

use serde::{Deserialize, Serialize};

use crate::estimate::selfcal::check::Consistency;
use crate::estimate::selfcal::overlay::{OverlaySlice, AXES};
use crate::estimate::selfcal::profile::Profile;
use crate::estimate::selfcal::refine::{Direction, SearchSettings};
use crate::io::fs::display_path;
use crate::pipeline::selfcal::lag::LagProfile;
use crate::pipeline::selfcal::SelfcalRun;

/// One sweep as read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepRead {
    pub sequence: String,
    pub frames: usize,
    pub frames_used: usize,
    /// Why the first frame left out was (when any was).
    pub first_skipped: Option<String>,
    pub blocks: usize,
    /// Blocks touching the drawn overlay (bright in every frame).
    pub blocks_left_out: usize,
}

/// `summary.json`'s `kind`, which marks a folder as a refinement's.
pub const KIND: &str = "selfcal";

/// `summary.json` of `probecal selfcal`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SelfcalSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    /// Always [`KIND`].
    pub kind: String,
    pub sweeps: Vec<SweepRead>,
    pub config: String,
    /// Where the start came from, and the start: pixel to probe mm, row by row.
    pub start_source: String,
    pub start_image_to_probe: [[f64; 4]; 4],
    /// The refined calibration (written as ImageToProbe.xml).
    pub image_to_probe: [[f64; 4]; 4],
    /// The lag the poses were read at, s.
    pub tracker_lag_s: f64,
    /// The correction, in the probe's frame about the image's centre: moves
    /// (mm) along x, y, z and turns (degrees) about them.
    pub move_mm: [f64; 3],
    pub turn_deg: [f64; 3],
    /// The largest distance between where the start and the refined
    /// calibration put the image's corners, mm.
    pub corner_change_mm: f64,
    /// The image's half-diagonal, mm: a turn's unknown is its angle times it.
    pub radius_mm: f64,
    /// The directions at the solution, most curved first: `held` ones were refined,
    /// the others left at the start.
    pub directions: Vec<Direction>,
    /// Mean normalised correlation of the sweeps' volumes at the start and at the solution.
    pub correlation_start: f64,
    pub correlation_end: f64,
    pub voxels_compared: usize,
    pub iterations: usize,
    /// The resamples the standard errors came from (of `settings.resamples`).
    pub resamples_used: usize,
    /// Pixels averaged per block (a side), and the background's reach in
    /// blocks (0: none).
    pub block_px: usize,
    pub background_blocks: usize,
    pub settings: SearchSettings,
    /// The start checked against the sweeps: the corners' offset, the
    /// tolerance, the verdict and its false-alarm rate.
    pub check: Consistency,
    /// The agreement along each direction through the refined calibration
    /// (the page's figure).
    pub profiles: Vec<Profile>,
    /// The agreement against the tracker's lag at the refined calibration
    /// (`--lag-range-ms`), and the lag the sweeps prefer when they have one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lag_profile: Option<LagProfile>,
    /// The sweeps' agreement in the planes the page overlays, before and after
    /// the correction (empty when the sweeps share no voxel).
    #[serde(default)]
    pub overlays: Vec<OverlayAgreement>,
}

/// The agreement of the first sweep with the others in one plane of the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OverlayAgreement {
    /// The Reference axis the plane is normal to (`x`, `y` or `z`) and where
    /// it cuts it, mm.
    pub normal: char,
    pub position_mm: f64,
    /// The normalised correlation over the plane's pixels both cover, under
    /// the start and under the refined calibration (`None`: too few pixels).
    pub correlation_before: Option<f64>,
    pub correlation_after: Option<f64>,
    pub pixels_before: usize,
    pub pixels_after: usize,
}

impl OverlayAgreement {
    pub fn of(s: &OverlaySlice) -> OverlayAgreement {
        OverlayAgreement {
            normal: AXES[s.normal],
            position_mm: s.position_mm,
            correlation_before: s.before.correlation,
            correlation_after: s.after.correlation,
            pixels_before: s.before.pixels_compared,
            pixels_after: s.after.pixels_compared,
        }
    }
}

fn rows(m: &nalgebra::Matrix4<f64>) -> [[f64; 4]; 4] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
}

impl SelfcalSummary {
    pub fn of(run: &SelfcalRun) -> SelfcalSummary {
        let q = run.search.correction;
        let frame0 = &run.prepared.frame0;
        let refined = run.image_to_probe();
        SelfcalSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            kind: KIND.into(),
            sweeps: run
                .prepared
                .sources
                .iter()
                .zip(&run.prepared.sweeps)
                .map(|(s, sweep)| SweepRead {
                    sequence: display_path(&s.path),
                    frames: s.frames_total,
                    frames_used: sweep.frames.len(),
                    first_skipped: s.skipped.first().map(|k| format!("frame {}: {}", k.index, k.reason)),
                    blocks: s.blocks,
                    blocks_left_out: s.blocks_left_out,
                })
                .collect(),
            config: display_path(&run.inputs.config),
            start_source: run.inputs.start.1.clone(),
            start_image_to_probe: rows(&frame0.probe_T_pixel),
            image_to_probe: rows(&refined),
            tracker_lag_s: run.inputs.tracker_lag_s,
            move_mm: [q[0], q[1], q[2]],
            turn_deg: [3, 4, 5].map(|k| (q[k] / frame0.radius_mm).to_degrees()),
            corner_change_mm: frame0.corner_error_mm(&refined, &frame0.probe_T_pixel),
            radius_mm: frame0.radius_mm,
            directions: run.search.directions.clone(),
            correlation_start: run.search.start_correlation,
            correlation_end: run.search.end.correlation(),
            voxels_compared: run.search.end.voxels,
            iterations: run.search.iterations,
            resamples_used: run.search.resamples_used,
            block_px: run.prepared.block_px,
            background_blocks: run.prepared.background_blocks,
            settings: run.inputs.settings,
            check: run.check.clone(),
            profiles: run.profiles.clone(),
            lag_profile: run.lag_profile.clone(),
            overlays: run.overlays.iter().map(OverlayAgreement::of).collect(),
        }
    }
}
