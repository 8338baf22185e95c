//! `probecal live --igtl`: the session's files. `summary.json` (how the
//! acquisition ended, every message's fate, the latency percentiles, the
//! calibration sent back), `live.csv` (per frame, as the file replay writes it),
//! `received.igs.mha` (written by the session) and, when the batch calibration
//! succeeded, its usual run folder in `calibration/`.

use std::path::Path;

use serde::Serialize;

use crate::core::stats::percentile;
use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::live::igtl::{StreamRun, StreamSettings};
use crate::pipeline::tracked::Role;
use crate::report::error::OutputError;
use crate::report::live::timing::{timing, Timing};

/// Percentiles of per-frame times, ms.
#[derive(Serialize)]
pub struct Percentiles {
    pub p50: f64,
    pub p90: f64,
    pub p99: f64,
    pub max: f64,
}

fn percentiles(values: &[f64]) -> Option<Percentiles> {
    (!values.is_empty()).then(|| Percentiles {
        p50: percentile(values, 0.5),
        p90: percentile(values, 0.9),
        p99: percentile(values, 0.99),
        max: values.iter().copied().fold(0.0, f64::max),
    })
}

#[derive(Serialize)]
pub struct Messages {
    pub bytes: u64,
    /// Read, by `TYPE device`.
    pub by_device: std::collections::BTreeMap<String, usize>,
    /// Of other devices or types, by `TYPE device`.
    pub ignored: std::collections::BTreeMap<String, usize>,
    pub skipped: usize,
    pub skip_reasons: Vec<String>,
    pub statuses: Vec<String>,
}

#[derive(Serialize)]
pub struct IgtlSummary {
    pub kind: &'static str,
    pub address: String,
    pub ended_by: String,
    pub images_received: usize,
    /// Images paired with transforms: the frames of `received.igs.mha`.
    pub frames: usize,
    pub frames_without_pose: usize,
    /// Frames the live fit used.
    pub frames_used_live: usize,
    pub received_rate_hz: f64,
    /// Median time between two images' arrivals (wall clock), ms.
    pub arrival_interval_ms: Option<f64>,
    /// From an image's arrival to its calibration update, ms.
    pub latency_ms: Option<Percentiles>,
    pub processing_ms: Timing,
    /// Every frame's work took less than the median interval between arrivals.
    pub kept_up: bool,
    pub messages: Messages,
    pub running_pre3d_mm: Option<f64>,
    pub last_live_matrix: Option<Vec<Vec<f64>>>,
    /// The batch calibration of the received frames (as `probecal run` on
    /// `received.igs.mha`), or why there is none.
    pub image_to_probe_matrix: Option<Vec<Vec<f64>>>,
    pub calibration_error: Option<String>,
    /// The tracker lag used while frames arrived, s (0 where the manifest asks
    /// for it to be estimated: that is done on all frames at the end).
    pub live_time_offset_s: f64,
    /// The batch calibration's lag, s.
    pub time_offset_s: Option<f64>,
    pub final_validation_pre3d_mm: Option<f64>,
    /// The TRANSFORM sent back: its device, and the matrix or why not.
    pub sent_device: String,
    pub sent_matrix: Option<Vec<Vec<f64>>>,
    pub sent_error: Option<String>,
    /// The live reconstruction, when asked for.
    pub live_volume: Option<crate::pipeline::live::igtl::VolumeOutcome>,
}

pub fn summary(run: &StreamRun, settings: &StreamSettings) -> IgtlSummary {
    let latency: Vec<f64> = run.frames.iter().map(|f| f.latency_ms).collect();
    let processing: Vec<f64> = run.frames.iter().map(|f| f.processing_ms).collect();
    let gaps: Vec<f64> = run
        .frames
        .windows(2)
        .map(|w| (w[1].arrival_s - w[0].arrival_s) * 1e3)
        .collect();
    let interval_ms = (!gaps.is_empty()).then(|| percentile(&gaps, 0.5));
    let rows = |m: nalgebra::Matrix4<f64>| crate::report::tracked::rows(&m);
    let c = &run.counts;
    let batch = run.final_run.as_ref().ok();
    IgtlSummary {
        kind: "live_igtl",
        address: settings.address.clone(),
        ended_by: run.ending.describe(&settings.stream),
        images_received: c.images_received,
        frames: c.frames,
        frames_without_pose: c.frames_without_pose,
        frames_used_live: run.frames.last().map(|f| f.frames_used).unwrap_or(0),
        received_rate_hz: run.received_rate_hz,
        arrival_interval_ms: interval_ms,
        latency_ms: percentiles(&latency),
        processing_ms: timing(&processing),
        kept_up: interval_ms.is_some_and(|i| processing.iter().all(|p| *p < i)),
        messages: Messages {
            bytes: c.bytes,
            by_device: c.messages.clone(),
            ignored: c.ignored.clone(),
            skipped: c.skipped,
            skip_reasons: c.skip_reasons.clone(),
            statuses: c.statuses.clone(),
        },
        running_pre3d_mm: run.frames.last().and_then(|f| f.running_pre3d_mm),
        last_live_matrix: run.last_live.as_ref().map(|f| rows(f.image_to_probe.matrix())),
        image_to_probe_matrix: batch.map(|b| rows(b.fit.image_to_probe.matrix())),
        calibration_error: run.final_run.as_ref().err().map(|e| e.to_string()),
        live_time_offset_s: run.live_time_offset_s,
        time_offset_s: batch.map(|b| b.time_offset_s),
        final_validation_pre3d_mm: batch
            .and_then(|b| crate::core::stats::best_95(&b.pre3d(Role::Validation)))
            .map(|s| s.mean),
        sent_device: settings.stream.send_device.clone(),
        sent_matrix: run.sent.as_ref().ok().map(|m| rows(*m)),
        sent_error: run.sent.as_ref().err().map(|e| e.to_string()),
        live_volume: run.volume.clone(),
    }
}

/// Writes the session's files into `folder` (the staged output, which already
/// holds `received.igs.mha`), with the batch calibration's page when there is
/// one (`after`: what was measured after it); the summary.
pub fn write(
    run: &StreamRun,
    settings: &StreamSettings,
    labels: &TrackedLabels,
    after: Option<&crate::pipeline::tracked::resolution::TrackedAfter>,
    folder: &Path,
) -> Result<IgtlSummary, OutputError> {
    let s = summary(run, settings);
    crate::io::fs::write_atomic(
        &folder.join("summary.json"),
        crate::results::summary::to_text(&s)?.as_bytes(),
    )?;
    crate::io::fs::write_atomic(
        &folder.join("live.csv"),
        crate::report::live::frames_csv(&run.frames).as_bytes(),
    )?;
    if let (Ok(batch), Some(after)) = (&run.final_run, after) {
        crate::report::tracked::write(batch, after, labels, None, &folder.join("calibration"))?;
    }
    Ok(s)
}
