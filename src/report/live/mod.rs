//! `probecal live`: the terminal view while frames arrive (a line per frame, or
//! one updated line on a terminal) and the session's files: `live.csv` (per
//! frame: arrival, latency, work, rejection, predicted and running PRE3D,
//! frames used) and `summary.json` (the recorded rate, the latency, whether it
//! kept up, and the final calibration, the batch run's).

pub mod folder;
pub mod igtl;
pub mod timing;
use crate::report::error::OutputError;
use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use crate::pipeline::live::{LiveFrame, LiveRun, Replay};
use crate::pipeline::tracked::Role;
pub(crate) use crate::report::live::timing::{number, timing, write_session, Timing};

/// `live.csv`.
pub fn frames_csv(frames: &[LiveFrame]) -> String {
    let mut out = String::from(
        "frame,arrival_s,latency_ms,processing_ms,rejected,predicted_pre3d_mm,running_pre3d_mm,frames_used\n",
    );
    for f in frames {
        let reason = f.rejected.as_deref().unwrap_or("").replace(['"', ','], ";");
        let _ = writeln!(
            out,
            "{},{:.4},{:.3},{:.3},{reason},{},{},{}",
            f.index,
            f.arrival_s,
            f.latency_ms,
            f.processing_ms,
            number(f.predicted_pre3d_mm),
            number(f.running_pre3d_mm),
            f.frames_used
        );
    }
    out
}

#[derive(Serialize)]
pub struct LiveSummary {
    pub frames: usize,
    pub recorded_rate_hz: f64,
    pub replay_speed: f64,
    /// Per frame, ms.
    pub latency_ms: Timing,
    pub processing_ms: Timing,
    /// Every frame's work took less than the recording's frame interval at the
    /// replay speed.
    pub kept_up: bool,
    /// The running accuracy estimate at the last frame, mm.
    running_pre3d_mm: Option<f64>,
    /// The live fit at the last frame and the final (batch) calibration.
    pub last_live_matrix: Option<Vec<Vec<f64>>>,
    pub final_matrix: Vec<Vec<f64>>,
    pub final_validation_pre3d_mm: Option<f64>,
}

/// `summary.json`.
fn summary(run: &LiveRun, replay: Replay) -> LiveSummary {
    let latency: Vec<f64> = run.frames.iter().map(|f| f.latency_ms).collect();
    let processing: Vec<f64> = run.frames.iter().map(|f| f.processing_ms).collect();
    let speed = if replay.speed > 0.0 { replay.speed } else { 1.0 };
    let interval_ms = 1e3 / (run.recorded_rate_hz * speed).max(1e-9);
    let rows = |m: nalgebra::Matrix4<f64>| crate::report::tracked::rows(&m);
    LiveSummary {
        frames: run.frames.len(),
        recorded_rate_hz: run.recorded_rate_hz,
        replay_speed: replay.speed,
        kept_up: processing.iter().all(|p| *p < interval_ms),
        latency_ms: timing(&latency),
        processing_ms: timing(&processing),
        running_pre3d_mm: run.frames.last().and_then(|f| f.running_pre3d_mm),
        last_live_matrix: run.last_live.as_ref().map(|f| rows(f.image_to_probe.matrix())),
        final_matrix: rows(run.final_run.fit.image_to_probe.matrix()),
        final_validation_pre3d_mm: crate::core::stats::best_95(&run.final_run.pre3d(Role::Validation)).map(|s| s.mean),
    }
}

/// The terminal's line for one frame.
pub fn line(f: &LiveFrame) -> String {
    let mm = |v: Option<f64>| v.map(|v| format!("{v:.3} mm")).unwrap_or_else(|| "—".into());
    let status = match &f.rejected {
        Some(r) => format!("rejected: {}", r.chars().take(60).collect::<String>()),
        None => format!("predicted {}", mm(f.predicted_pre3d_mm)),
    };
    format!(
        "frame {:>4}/{}  t {:>6.2} s  used {:>4}  running PRE3D {}  {:>6.1} ms  {status}",
        f.index + 1,
        f.frames_total,
        f.arrival_s,
        f.frames_used,
        mm(f.running_pre3d_mm),
        f.processing_ms
    )
}

/// Writes `summary.json` and `live.csv` into `out` (whole, or nothing); the summary.
pub fn write(run: &LiveRun, replay: Replay, out: &Path) -> Result<LiveSummary, OutputError> {
    let s = summary(run, replay);
    write_session(out, &s, frames_csv(&run.frames))?;
    Ok(s)
}
