//! A live session's outcome (`summary.json` of `probecal live`): the file
//! replay's ([`LiveSummary`]), a watched folder's ([`FolderSummary`]) and an
//! OpenIGTLink session's ([`IgtlSummary`]). The running figures (`running_…`)
//! are the estimate while frames arrived, from the frames so far; the final
//! ones (`final_…`, `batch_…`) are the batch run's on every frame at the end.

use serde::{Deserialize, Serialize};

use crate::core::stats::{mean_sd, percentile};
use crate::estimate::horn::HornFit;
use crate::pipeline::live::folder::{Ending, FolderRun};
use crate::pipeline::live::igtl::{StreamRun, StreamSettings};
use crate::pipeline::live::{LiveRun, Replay};
use crate::pipeline::tracked::Role;

/// A 4x4 matrix as rows.
fn rows(m: &nalgebra::Matrix4<f64>) -> Vec<Vec<f64>> {
    (0..4).map(|r| (0..4).map(|c| m[(r, c)]).collect()).collect()
}

/// Mean, 95th percentile and largest of per-frame times, ms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    pub mean: f64,
    pub p95: f64,
    pub max: f64,
}

pub fn timing(values: &[f64]) -> Timing {
    Timing {
        mean: mean_sd(values).mean,
        p95: if values.is_empty() {
            0.0
        } else {
            percentile(values, 0.95)
        },
        max: values.iter().copied().fold(0.0, f64::max),
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LiveSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
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
    pub running_pre3d_mm: Option<f64>,
    /// The live fit at the last frame and the final (batch) calibration.
    pub last_live_matrix: Option<Vec<Vec<f64>>>,
    pub final_matrix: Vec<Vec<f64>>,
    pub final_validation_pre3d_mm: Option<f64>,
}

impl LiveSummary {
    /// `probecal live`'s `summary.json`.
    pub fn of(run: &LiveRun, replay: Replay) -> LiveSummary {
        let latency: Vec<f64> = run.frames.iter().map(|f| f.latency_ms).collect();
        let processing: Vec<f64> = run.frames.iter().map(|f| f.processing_ms).collect();
        let speed = if replay.speed > 0.0 { replay.speed } else { 1.0 };
        let interval_ms = 1e3 / (run.recorded_rate_hz * speed).max(1e-9);
        let rows = |m: nalgebra::Matrix4<f64>| rows(&m);
        LiveSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            frames: run.frames.len(),
            recorded_rate_hz: run.recorded_rate_hz,
            replay_speed: replay.speed,
            kept_up: processing.iter().all(|p| *p < interval_ms),
            latency_ms: timing(&latency),
            processing_ms: timing(&processing),
            running_pre3d_mm: run.frames.last().and_then(|f| f.running_pre3d_mm),
            last_live_matrix: run.last_live.as_ref().map(|f| rows(f.image_to_probe.matrix())),
            final_matrix: rows(run.final_run.fit.image_to_probe.matrix()),
            final_validation_pre3d_mm: crate::core::stats::best_95(&run.final_run.pre3d(Role::Validation))
                .map(|s| s.mean),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FolderSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub frames: usize,
    pub frames_used: usize,
    /// `frame_list` (the frame list appeared and every frame it lists was taken)
    /// or `idle` (no new frame for the idle time).
    pub ended_by: String,
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
    rows(&fit.target_T_source.to_homogeneous())
}

impl FolderSummary {
    /// `probecal live --watch`'s `summary.json`.
    pub fn of(run: &FolderRun) -> FolderSummary {
        let latency: Vec<f64> = run.frames.iter().map(|f| f.latency_ms).collect();
        let processing: Vec<f64> = run.frames.iter().map(|f| f.processing_ms).collect();
        let batch_all = run.batch.as_ref().map(|b| &b.all_frames_fit);
        let difference = run.last_fit.as_ref().zip(batch_all).map(|(live, batch)| {
            (live.target_T_source.to_homogeneous() - batch.target_T_source.to_homogeneous()).amax()
        });
        FolderSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            frames: run.frames.len(),
            frames_used: run.frames.last().map(|f| f.frames_used).unwrap_or(0),
            ended_by: match run.ending {
                Ending::FrameList => "frame_list",
                Ending::Idle => "idle",
            }
            .into(),
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
}

/// Percentiles of per-frame times, ms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IgtlSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub kind: String,
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

impl IgtlSummary {
    /// `probecal live --igtl`'s `summary.json`.
    pub fn of(run: &StreamRun, settings: &StreamSettings) -> IgtlSummary {
        let latency: Vec<f64> = run.frames.iter().map(|f| f.latency_ms).collect();
        let processing: Vec<f64> = run.frames.iter().map(|f| f.processing_ms).collect();
        let gaps: Vec<f64> = run
            .frames
            .windows(2)
            .map(|w| (w[1].arrival_s - w[0].arrival_s) * 1e3)
            .collect();
        let interval_ms = (!gaps.is_empty()).then(|| percentile(&gaps, 0.5));
        let rows = |m: nalgebra::Matrix4<f64>| rows(&m);
        let c = &run.counts;
        let batch = run.final_run.as_ref().ok();
        IgtlSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            kind: "live_igtl".into(),
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
}
