//! `probecal temporal`'s outcome: the tracker's lag behind the video (PLUS's
//! sign convention) from a reflector line's motion, and what it was read from.

use serde::{Deserialize, Serialize};

use crate::io::fs::display_path;
use crate::pipeline::tracked::time::temporal::{TemporalRun, MAX_LAG_S, STEP_S};

/// `summary.json` of `probecal temporal`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemporalSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub video: String,
    pub tracker: String,
    /// How far the tracker's clock runs behind the video's (s, PLUS's sign).
    pub tracker_lag_s: f64,
    /// The normalised cross-correlation at the peak.
    pub peak_correlation: f64,
    pub frames: usize,
    pub frames_with_line: usize,
    pub tracker_samples: usize,
    pub lag_step_s: f64,
    /// The lags searched: ± this (s).
    pub lag_range_s: f64,
}

impl TemporalSummary {
    pub fn of(run: &TemporalRun) -> TemporalSummary {
        TemporalSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            video: display_path(&run.video),
            tracker: display_path(&run.tracker),
            tracker_lag_s: run.tracker_lag_s,
            peak_correlation: run.peak_correlation,
            frames: run.frames.len(),
            frames_with_line: run.frames.iter().filter(|f| f.line.is_ok()).count(),
            tracker_samples: run.tracker_samples,
            lag_step_s: STEP_S,
            lag_range_s: MAX_LAG_S,
        }
    }
}
