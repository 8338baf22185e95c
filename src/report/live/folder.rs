//! `probecal live <camera manifest> --watch <folder>`: the terminal view while
//! frames land in the folder, and the session's files: `live.csv` (per frame:
//! arrival, latency, work, rejection, predicted and running error, frames used,
//! all-frames BRE) and `summary.json` (latency and work, how the acquisition
//! ended, the live all-frames fit beside the batch run's, and the batch run's
//! reported calibration).

use crate::report::error::OutputError;
use std::fmt::Write as _;
use std::path::Path;

use crate::pipeline::live::folder::{FolderFrame, FolderRun};
use crate::report::live::timing::{number, write_session};
use crate::results::live::FolderSummary;

/// `live.csv`.
pub fn frames_csv(run: &FolderRun) -> String {
    let mut out = String::from(
        "frame,arrival_s,latency_ms,processing_ms,rejected,predicted_error_mm,running_error_mm,frames_used,bre_mean_x_mm,bre_mean_y_mm,bre_mean_z_mm\n",
    );
    for f in &run.frames {
        let reason = f.rejected.as_deref().unwrap_or("").replace(['"', ','], ";");
        let bre = |k: usize| number(f.bre_mean_mm.map(|b| b[k]));
        let _ = writeln!(
            out,
            "{},{:.4},{:.3},{:.3},{reason},{},{},{},{},{},{}",
            f.frame,
            f.arrival_s,
            f.latency_ms,
            f.processing_ms,
            number(f.predicted_error_mm),
            number(f.running_error_mm),
            f.frames_used,
            bre(0),
            bre(1),
            bre(2)
        );
    }
    out
}

/// The terminal's line for one frame.
pub fn line(f: &FolderFrame) -> String {
    let mm = |v: Option<f64>| v.map(|v| format!("{v:.3} mm")).unwrap_or_else(|| "—".into());
    let status = match &f.rejected {
        Some(r) => format!("rejected: {}", r.chars().take(60).collect::<String>()),
        None => format!("predicted {}", mm(f.predicted_error_mm)),
    };
    let bre = f
        .bre_mean_mm
        .map(|b| format!("{:.3}/{:.3}/{:.3} mm", b[0], b[1], b[2]))
        .unwrap_or_else(|| "—".into());
    format!(
        "frame {:>5}  t {:>6.2} s  used {:>4}  BRE x/y/z {bre}  running error {}  {:>6.1} ms  {status}",
        f.frame,
        f.arrival_s,
        f.frames_used,
        mm(f.running_error_mm),
        f.processing_ms
    )
}

/// Writes `summary.json` and `live.csv` into `out` (whole, or nothing); the summary.
pub fn write(run: &FolderRun, out: &Path) -> Result<FolderSummary, OutputError> {
    let s = FolderSummary::of(run);
    write_session(out, &s, frames_csv(run))?;
    Ok(s)
}
