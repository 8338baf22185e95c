//! `probecal live <camera manifest> --watch <folder>`: the terminal view while
//! frames land in the folder, and the session's files: `live.csv` (per frame:
//! arrival, latency, work, rejection, predicted and running error, frames used,
//! all-frames BRE) and `summary.json` (latency and work, how the acquisition
//! ended, the live all-frames fit beside the batch run's, and the batch run's
//! reported calibration).

use crate::report::error::OutputError;
use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use crate::estimate::horn::HornFit;
use crate::pipeline::live::folder::{Ending, FolderFrame, FolderRun};
use crate::report::live::timing::{number, timing, write_session, Timing};

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

#[derive(Serialize)]
pub struct FolderSummary {
    pub frames: usize,
    pub frames_used: usize,
    /// `frame_list` (the frame list appeared and every frame it lists was taken)
    /// or `idle` (no new frame for the idle time).
    pub ended_by: &'static str,
    /// Per frame, ms.
    pub latency_ms: Timing,
    pub processing_ms: Timing,
    /// The running error estimate at the last frame, mm.
    pub running_error_mm: Option<f64>,
    /// The live all-frames fit at the last frame, and the batch run's.
    pub live_all_frames_matrix: Option<Vec<Vec<f64>>>,
    pub batch_all_frames_matrix: Option<Vec<Vec<f64>>>,
    /// Largest difference between their entries.
    pub live_minus_batch_max_abs: Option<f64>,
    /// The batch run's reported calibration (its cut-off) and its BRE means, mm.
    pub batch_reported_matrix: Option<Vec<Vec<f64>>>,
    pub batch_reported_bre_mean_mm: Option<[f64; 3]>,
}

fn matrix(fit: &HornFit) -> Vec<Vec<f64>> {
    crate::report::tracked::rows(&fit.target_T_source.to_homogeneous())
}

fn summary(run: &FolderRun) -> FolderSummary {
    let latency: Vec<f64> = run.frames.iter().map(|f| f.latency_ms).collect();
    let processing: Vec<f64> = run.frames.iter().map(|f| f.processing_ms).collect();
    let batch_all = run.batch.as_ref().map(|b| &b.all_frames_fit);
    let difference =
        run.last_fit.as_ref().zip(batch_all).map(|(live, batch)| {
            (live.target_T_source.to_homogeneous() - batch.target_T_source.to_homogeneous()).amax()
        });
    FolderSummary {
        frames: run.frames.len(),
        frames_used: run.frames.last().map(|f| f.frames_used).unwrap_or(0),
        ended_by: match run.ending {
            Ending::FrameList => "frame_list",
            Ending::Idle => "idle",
        },
        latency_ms: timing(&latency),
        processing_ms: timing(&processing),
        running_error_mm: run.frames.last().and_then(|f| f.running_error_mm),
        live_all_frames_matrix: run.last_fit.as_ref().map(matrix),
        batch_all_frames_matrix: batch_all.map(matrix),
        live_minus_batch_max_abs: difference,
        batch_reported_matrix: run.batch.as_ref().map(|b| matrix(b.primary_fit())),
        batch_reported_bre_mean_mm: run
            .batch
            .as_ref()
            .and_then(|b| b.thresholds[b.primary].stats.as_ref())
            .map(|s| s.axes().map(|a| a.mean)),
    }
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
    let s = summary(run);
    write_session(out, &s, frames_csv(run))?;
    Ok(s)
}
