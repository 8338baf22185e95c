//! Live calibration: a PLUS recording replayed at its recorded rate (or faster),
//! each frame processed as it arrives. After each frame: its dots segmented, its
//! pose attached, its error predicted by the calibration of the frames before
//! it (the running accuracy estimate: every frame is a held-out frame for the
//! calibration it did not enter), and the calibration refitted on every frame so
//! far. When the recording ends, the batch pipeline runs on the whole of it, so
//! the final calibration is the one `probecal run` gives.
//!
//! While frames arrive the model is fixed (the manifest's, or middle points with
//! an anisotropic pixel size) and so is the tracker's lag (the manifest's fixed
//! value or reflector recording; `estimate` uses 0 until the end, where it is
//! estimated). A positive lag needs the next frame's pose, so a frame is
//! finished when the next one arrives. The clip rectangle is the manifest's or
//! the whole image: a screen overlay is found only from the whole recording.

pub mod folder;
pub mod igtl;
pub mod igtl_pairing;
pub mod volume;
use std::time::{Duration, Instant};

use crate::core::stats::best_95;
use crate::estimate::image_to_probe::{ConstraintModel, Fit, PixelModel};
use crate::estimate::model_selection::{self, Candidate, FrameConstraints};
use crate::io::plus::sequence::Sequence;
use crate::manifest::tracked::TimeOffset;
use crate::pipeline::sequence_frames::{pattern_geometry, segment_frame, TrackedFrame};
use crate::pipeline::tracked::{
    self, attach_poses, constraints, fit_settings, segmentation_inputs, Role, TrackedError, TrackedInputs, TrackedRun,
};

/// Frames with dots and poses before the first calibration.
pub const FIRST_FIT_FRAMES: usize = 10;
/// Predictive errors the running accuracy estimate pools (the latest).
pub const RUNNING_WINDOW: usize = 30;

/// How the recording is replayed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Replay {
    /// Times the recorded rate; 0: every frame at once, as fast as it is processed.
    pub speed: f64,
}

/// One frame's outcome, as it was shown.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveFrame {
    pub index: usize,
    /// Frames in the recording.
    pub frames_total: usize,
    /// When it arrived, s after the first frame (wall clock).
    pub arrival_s: f64,
    /// From its arrival to its calibration update, ms (with a positive lag this
    /// includes the wait for the next frame).
    pub latency_ms: f64,
    /// The work for it: its segmentation, pose, prediction and refit, ms.
    pub processing_ms: f64,
    /// Why it was not used, if it was not.
    pub rejected: Option<String>,
    /// Its PRE3D (mean over its patterns) under the calibration before it, mm.
    pub predicted_pre3d_mm: Option<f64>,
    /// PLUS's best-95 % mean of the latest predicted PRE3Ds, mm.
    pub running_pre3d_mm: Option<f64>,
    /// Frames in the calibration after it.
    pub frames_used: usize,
    /// The calibration's translation after it, mm.
    pub translation_mm: Option<[f64; 3]>,
}

/// A live session.
#[derive(Debug, Clone)]
pub struct LiveRun {
    pub frames: Vec<LiveFrame>,
    /// The recording's frame rate, frames/s.
    pub recorded_rate_hz: f64,
    /// The calibration the live fit reached at the last frame.
    pub last_live: Option<Fit>,
    /// The batch pipeline on the whole recording.
    pub final_run: TrackedRun,
}

/// The live calibration between frames: the frames used, the predictions, the fit.
pub(super) struct State<'a> {
    inputs: &'a TrackedInputs,
    candidate: Candidate,
    used: Vec<FrameConstraints>,
    predicted: Vec<f64>,
    pub(super) fit: Option<Fit>,
}

impl<'a> State<'a> {
    /// No frames yet; the model is the manifest's, or middle points with an
    /// anisotropic pixel size.
    pub(super) fn new(inputs: &'a TrackedInputs) -> State<'a> {
        State {
            inputs,
            candidate: Candidate {
                constraints: inputs.model.unwrap_or(ConstraintModel::MiddlePoints),
                pixel_model: inputs.pixel_model.unwrap_or(PixelModel::Anisotropic),
            },
            used: Vec::new(),
            predicted: Vec::new(),
            fit: None,
        }
    }

    /// Attaches `frame`'s pose, predicts its error and refits.
    fn finish(&mut self, sequence: &Sequence, mut frame: TrackedFrame, offset_s: f64) -> LiveFrame {
        attach_poses(sequence, std::slice::from_mut(&mut frame), self.inputs, offset_s);
        let mut predicted = None;
        if frame.rejected.is_none() {
            if let Some(fit) = &self.fit {
                let errors = tracked::pre3d(
                    &frame,
                    &self.inputs.nwires,
                    |p| fit.image_to_probe.apply(p),
                    &fit.phantom_correction,
                );
                predicted = crate::core::stats::mean(errors.iter().copied());
                self.predicted.extend(errors);
            }
            self.used.push(constraints(&frame, &self.inputs.nwires));
            if self.used.len() >= FIRST_FIT_FRAMES {
                if let Ok(trained) = model_selection::fit(self.used.iter(), self.candidate, fit_settings(self.inputs)) {
                    self.fit = Some(trained.fit);
                }
            }
        }
        let window = self
            .predicted
            .len()
            .saturating_sub(RUNNING_WINDOW * self.inputs.nwires.len().max(1));
        LiveFrame {
            index: frame.index,
            frames_total: sequence.frames.len(),
            arrival_s: 0.0,
            latency_ms: 0.0,
            processing_ms: 0.0,
            rejected: frame.rejected.as_ref().map(|r| r.to_string()),
            predicted_pre3d_mm: predicted,
            running_pre3d_mm: best_95(&self.predicted[window..]).map(|s| s.mean),
            frames_used: self.used.len(),
            translation_mm: self.fit.as_ref().map(|f| {
                let t = f.image_to_probe.marker_T_image.translation.vector;
                [t.x, t.y, t.z]
            }),
        }
    }
}

/// A frame segmented on arrival.
pub(super) struct Arrived {
    pub(super) frame: TrackedFrame,
    pub(super) arrived: Instant,
    pub(super) segmentation_ms: f64,
}

/// Frames waiting for the tracker's samples at their time plus the lag: with a
/// positive lag a frame's pose lies in samples that arrive with later frames
/// (several frames later when the lag is longer than a frame period).
#[derive(Default)]
pub(super) struct LagQueue {
    pending: std::collections::VecDeque<Arrived>,
}

impl LagQueue {
    /// Queues `arrived`, then hands back every frame whose time plus `offset_s`
    /// the samples so far reach (the newest frame's time, `latest_s`).
    pub(super) fn push(&mut self, arrived: Arrived, offset_s: f64, latest_s: Option<f64>) -> Vec<Arrived> {
        self.pending.push_back(arrived);
        let mut ready = Vec::new();
        while let Some(front) = self.pending.front() {
            let reached = match (front.frame.timestamp_s, latest_s) {
                (Some(t), Some(latest)) => t + offset_s <= latest,
                // No time to wait for: its pose is refused with the reason.
                _ => true,
            };
            if !(reached || offset_s <= 0.0) {
                break;
            }
            ready.extend(self.pending.pop_front());
        }
        ready
    }

    /// Every frame still waiting (the stream or the replay has ended).
    pub(super) fn drain(&mut self) -> Vec<Arrived> {
        self.pending.drain(..).collect()
    }
}

/// Attaches `arrived`'s pose, predicts its error, refits, and shows the outcome.
pub(super) fn finish(
    state: &mut State<'_>,
    sequence: &Sequence,
    arrived: Arrived,
    offset_s: f64,
    start: Instant,
    show: &mut dyn FnMut(&LiveFrame),
) -> LiveFrame {
    let work = Instant::now();
    let mut live = state.finish(sequence, arrived.frame, offset_s);
    live.arrival_s = arrived.arrived.duration_since(start).as_secs_f64();
    live.processing_ms = arrived.segmentation_ms + work.elapsed().as_secs_f64() * 1e3;
    live.latency_ms = arrived.arrived.elapsed().as_secs_f64() * 1e3;
    show(&live);
    live
}

/// The tracker's lag while frames arrive: the manifest's fixed value or
/// reflector recording; 0 where it is estimated (at the end, from all frames).
pub(super) fn live_offset_s(inputs: &TrackedInputs) -> Result<f64, TrackedError> {
    Ok(match &inputs.time_offset {
        TimeOffset::Fixed(s) => *s,
        TimeOffset::Temporal { tracker, video } => {
            crate::pipeline::tracked::time::temporal::run(
                video,
                tracker,
                &inputs.probe_transform,
                &inputs.reference_transform,
            )?
            .tracker_lag_s
        }
        TimeOffset::Estimate => 0.0,
    })
}

/// Longest pause between two frames a paced replay waits out, s (of the
/// recording's own time).
pub const MAX_REPLAY_GAP_S: f64 = 10.0;

/// A paced replay waits for each frame's timestamp: a clock that stands still,
/// runs backwards or jumps (by years, or to a number no wait can hold) is
/// refused, naming the frame, before anything waits.
fn refuse_unpaced(sequence: &Sequence, times: &[Option<f64>]) -> Result<(), TrackedError> {
    let fault = crate::pipeline::sequence_frames::clock_fault(sequence).or_else(|| {
        times.windows(2).enumerate().find_map(|(i, w)| match (w[0], w[1]) {
            (Some(a), Some(b)) if b - a > MAX_REPLAY_GAP_S => Some(format!(
                "frame {} comes {:.3e} s after frame {i}, more than {MAX_REPLAY_GAP_S} s: a paced replay would wait that long (replay with --speed 0)",
                i + 1,
                b - a
            )),
            _ => None,
        })
    });
    match fault {
        None => Ok(()),
        Some(fault) => Err(TrackedError::Clock {
            sequence: sequence.path.clone(),
            fault,
        }),
    }
}

/// Replays the calibration sequence of `inputs` and calibrates as frames arrive;
/// `show` sees each frame's outcome. The batch run on the whole recording follows.
pub fn run(
    inputs: &TrackedInputs,
    min_frames: usize,
    replay: Replay,
    show: &mut dyn FnMut(&LiveFrame),
) -> Result<LiveRun, TrackedError> {
    let sequence = Sequence::read(&inputs.calibration_sequence)?;
    let clip = inputs
        .clip_rectangle_px
        .unwrap_or([0, 0, sequence.width, sequence.height]);
    let segmentation = segmentation_inputs(inputs, clip, None);
    let geometry = pattern_geometry(&segmentation);
    let offset_s = live_offset_s(inputs)?;
    let mut state = State::new(inputs);
    let n = sequence.frames.len();
    let times: Vec<Option<f64>> = (0..n).map(|i| tracked::timestamp_s(&sequence, i)).collect();
    if replay.speed > 0.0 {
        refuse_unpaced(&sequence, &times)?;
    }
    let first_time = times.iter().flatten().next().copied().unwrap_or(0.0);
    let recorded_rate_hz = match (times.first().copied().flatten(), times.last().copied().flatten()) {
        (Some(a), Some(b)) if b > a && n > 1 => (n - 1) as f64 / (b - a),
        _ => 0.0,
    };
    let start = Instant::now();
    let mut frames = Vec::with_capacity(n);
    let mut pending = LagQueue::default();
    for (index, time) in times.iter().enumerate() {
        if replay.speed > 0.0 {
            if let Some(t) = time {
                let due = Duration::from_secs_f64(((t - first_time) / replay.speed).max(0.0));
                if let Some(wait) = due.checked_sub(start.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
        }
        let arrived = Instant::now();
        let frame = segment_frame(&sequence, index, Role::Calibration, &segmentation, &geometry);
        let this = Arrived {
            frame,
            arrived,
            segmentation_ms: arrived.elapsed().as_secs_f64() * 1e3,
        };
        // A positive lag reads poses from later frames: a frame is finished once
        // the recording has reached its time plus the lag.
        for ready in pending.push(this, offset_s, *time) {
            frames.push(finish(&mut state, &sequence, ready, offset_s, start, show));
        }
    }
    for last in pending.drain() {
        frames.push(finish(&mut state, &sequence, last, offset_s, start, show));
    }
    drop(sequence);
    let final_run = tracked::run(inputs, min_frames)?;
    Ok(LiveRun {
        frames,
        recorded_rate_hz,
        last_live: state.fit,
        final_run,
    })
}
