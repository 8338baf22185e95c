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

use crate::pipeline::live::{LiveFrame, LiveRun, Replay};
pub(crate) use crate::report::live::timing::{number, write_session};
use crate::results::live::LiveSummary;

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
    let s = LiveSummary::of(run, replay);
    write_session(out, &s, frames_csv(&run.frames))?;
    Ok(s)
}
