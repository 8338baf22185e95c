//! A sequence's B-scans as the N-wire pipeline sees them: each frame's wire
//! dots segmented (or why not), its timestamp, and the constraints its dots
//! give. Shared by `probecal segment` and the tracked pipeline.
//!
//! With no clip rectangle given, a screen grab's overlay (text, rulers, depth
//! markers: what is bright in every frame, [`crate::detect::overlay`]) is blacked
//! out before the dots are searched.

use nalgebra::Matrix4;
use rayon::prelude::*;
use serde::Serialize;

use crate::detect::nwire::{self, NWireRejection, PatternGeometry, Segmentation};
use crate::detect::overlay::Overlay;
use crate::estimate::image_to_probe::{Constraint, Target};
use crate::estimate::model_selection::FrameConstraints;
use crate::io::plus::sequence::{FrameFault, Sequence};
use crate::pipeline::record::Implausible;
use crate::spec::nwire::NWire;

/// Which sequence a frame comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Calibration,
    Validation,
}

/// One B-scan of a sequence, and what became of it.
#[derive(Debug, Clone, Serialize)]
pub struct TrackedFrame {
    pub role: Role,
    pub index: usize,
    pub timestamp_s: Option<f64>,
    /// Why the frame was not used (`None`: used).
    pub rejected: Option<TrackedRejection>,
    /// Per pattern: wire 1, 2, 3 dots (px).
    pub dots_px: Vec<[[f64; 2]; 3]>,
    /// `marker_T_phantom` of the frame (row-major), when the transforms were usable.
    #[serde(skip)]
    pub marker_T_phantom: Option<Matrix4<f64>>,
    /// The same with no tracker lag (each frame's own poses), when usable.
    #[serde(skip)]
    pub marker_T_phantom_no_lag: Option<Matrix4<f64>>,
    /// Per pattern: PRE3D of the middle dot under the result, mm.
    pub pre3d_mm: Vec<f64>,
    /// The bright spots the patterns were searched among, strongest first (px).
    #[serde(skip)]
    pub candidates_px: Vec<[f64; 2]>,
}

/// Why a tracked frame was not used; written as text only in tables and pages.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackedRejection {
    #[error("image status is {0}")]
    ImageStatus(String),
    #[error("segmentation: morphological opening failed: {0}")]
    Opening(String),
    #[error("segmentation: {0}")]
    Segmentation(NWireRejection),
    /// The tracker's poses cannot be had at the frame's time (re-evaluated for
    /// every tracker lag tried).
    #[error("pose: {0}")]
    Pose(PoseFault),
}

impl TrackedRejection {
    /// The check that rejected the frame, for summaries per check.
    pub fn check(&self) -> String {
        match self {
            TrackedRejection::ImageStatus(_) => "image status".into(),
            TrackedRejection::Opening(_) => "segmentation: opening".into(),
            TrackedRejection::Segmentation(e) => format!("segmentation: {}", e.check()),
            TrackedRejection::Pose(_) => "pose".into(),
        }
    }
}

/// How many frames each check rejected, most first (ties by name).
pub fn rejections_by_check<'a>(frames: impl IntoIterator<Item = &'a TrackedFrame>) -> Vec<(String, usize)> {
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    for r in frames.into_iter().filter_map(|f| f.rejected.as_ref()) {
        *counts.entry(r.check()).or_default() += 1;
    }
    let mut out: Vec<(String, usize)> = counts.into_iter().collect();
    out.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    out
}

/// Share of frames whose rejection is said loudly (on the console), not only
/// in the tables.
pub const LOUD_REJECTION_SHARE: f64 = 0.05;

/// The warning a sequence's rejections earn: more than
/// [`LOUD_REJECTION_SHARE`] of its frames, with the most common check.
pub fn rejection_warning(frames: &[TrackedFrame], role: Role, what: &str) -> Option<String> {
    let of_role: Vec<&TrackedFrame> = frames.iter().filter(|f| f.role == role).collect();
    let rejected = of_role.iter().filter(|f| f.rejected.is_some()).count();
    if of_role.is_empty() || (rejected as f64) <= LOUD_REJECTION_SHARE * of_role.len() as f64 {
        return None;
    }
    let by_check = rejections_by_check(of_role.iter().copied());
    let (check, count) = by_check.first()?;
    Some(format!(
        "{rejected} of {} {what} frames rejected ({:.0} %, more than {:.0} %); most common: {check} ({count} frames)",
        of_role.len(),
        100.0 * rejected as f64 / of_role.len() as f64,
        100.0 * LOUD_REJECTION_SHARE
    ))
}

/// Written as its text.
impl Serialize for TrackedRejection {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

/// Why a frame's pose cannot be had at its time plus the tracker's lag.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseFault {
    #[error("{0}")]
    Transform(#[from] FrameFault),
    #[error("frame {frame}: `{transform}` is wanted at {time_s:.6} s, {side} of the recorded trajectory")]
    OutsideTrajectory {
        frame: usize,
        transform: String,
        time_s: f64,
        side: &'static str,
    },
    #[error(
        "frame {frame}: the samples of `{transform}` around {time_s:.6} s are {gap_s:.3} s apart (limit {limit_s} s)"
    )]
    Gap {
        frame: usize,
        transform: String,
        time_s: f64,
        gap_s: f64,
        limit_s: f64,
    },
    #[error("frame {frame}: a timestamp is missing, cannot interpolate `{transform}`")]
    NoTimestamp { frame: usize, transform: String },
    /// Not finite, or a marker farther from the tracker than any tracker measures.
    #[error("{0}")]
    Implausible(Implausible),
}

/// What the dot segmentation of a sequence needs.
#[derive(Debug, Clone, Copy)]
pub struct SegmentationInputs<'a> {
    pub nwires: &'a [NWire],
    pub spacing_guess_mm_per_px: f64,
    pub segmentation: &'a Segmentation,
    pub clip: [usize; 4],
    /// A screen grab's overlay, blacked out before the search.
    pub overlay: Option<&'a Overlay>,
}

/// Each frame's segmented dots (or why not); poses are attached later.
pub fn segment_frames(sequence: &Sequence, role: Role, inputs: &SegmentationInputs<'_>) -> Vec<TrackedFrame> {
    let geometry = pattern_geometry(inputs);
    (0..sequence.frames.len())
        .into_par_iter()
        .map(|index| segment_frame(sequence, index, role, inputs, &geometry))
        .collect()
}

/// What the pattern search expects, in pixels, from the phantom and the pixel size.
pub fn pattern_geometry(inputs: &SegmentationInputs<'_>) -> PatternGeometry {
    let widths: Vec<f64> = inputs
        .nwires
        .iter()
        .map(|n| n.width_mm() / inputs.spacing_guess_mm_per_px)
        .collect();
    PatternGeometry {
        patterns: inputs.nwires.len(),
        widths_px: (
            widths.iter().copied().fold(f64::INFINITY, f64::min),
            widths.iter().copied().fold(0.0, f64::max),
        ),
        row_gaps_px: inputs
            .nwires
            .windows(2)
            .map(|pair| pair[0].distance_to(&pair[1]) / inputs.spacing_guess_mm_per_px)
            .collect(),
        plane_distances_px: plane_distances_px(inputs.nwires, inputs.spacing_guess_mm_per_px),
        spacing_mm_per_px: inputs.spacing_guess_mm_per_px,
        nwires: inputs.nwires.to_vec(),
    }
}

/// The smallest and largest distance between any two patterns' planes, px at
/// `spacing_mm_per_px` (PLUS's `PlusFidLabeling`; (0, 0) with one pattern).
fn plane_distances_px(nwires: &[NWire], spacing_mm_per_px: f64) -> (f64, f64) {
    let distances: Vec<f64> = (0..nwires.len())
        .flat_map(|i| (i + 1..nwires.len()).map(move |j| (i, j)))
        .map(|(i, j)| nwires[i].distance_to(&nwires[j]) / spacing_mm_per_px)
        .collect();
    if distances.is_empty() {
        return (0.0, 0.0);
    }
    (
        distances.iter().copied().fold(f64::INFINITY, f64::min),
        distances.iter().copied().fold(0.0, f64::max),
    )
}

/// Frame `index` of `sequence` segmented (or why not); its pose is attached later.
pub fn segment_frame(
    sequence: &Sequence,
    index: usize,
    role: Role,
    inputs: &SegmentationInputs<'_>,
    geometry: &PatternGeometry,
) -> TrackedFrame {
    let mut frame = TrackedFrame {
        role,
        index,
        timestamp_s: timestamp_s(sequence, index),
        rejected: None,
        dots_px: Vec::new(),
        marker_T_phantom: None,
        marker_T_phantom_no_lag: None,
        pre3d_mm: Vec::new(),
        candidates_px: Vec::new(),
    };
    if let Some(status) = sequence.frame_field(index, "ImageStatus") {
        if status != "OK" {
            frame.rejected = Some(TrackedRejection::ImageStatus(status.to_string()));
            return frame;
        }
    }
    let without_overlay;
    let mut pixels = sequence.pixels(index);
    if let Some(overlay) = inputs.overlay {
        without_overlay = overlay.remove(pixels);
        pixels = &without_overlay;
    }
    let cleaned = match nwire::clean(
        pixels,
        sequence.width,
        sequence.height,
        inputs.clip,
        inputs.segmentation.bar_px_for(inputs.spacing_guess_mm_per_px),
        inputs.segmentation.opening_radius_for(inputs.spacing_guess_mm_per_px) as usize,
    ) {
        Ok(c) => c,
        Err(e) => {
            frame.rejected = Some(TrackedRejection::Opening(e.to_string()));
            return frame;
        }
    };
    let spots = nwire::find_spots(
        &cleaned.pixels,
        pixels,
        sequence.width,
        sequence.height,
        cleaned.region_px,
        inputs.segmentation,
    );
    frame.candidates_px = spots.iter().map(|s| s.centre_px).collect();
    match nwire::segment(&spots, geometry, inputs.segmentation) {
        Ok(dots) => frame.dots_px = dots.patterns,
        Err(e) => frame.rejected = Some(TrackedRejection::Segmentation(e)),
    }
    frame
}

/// Why `sequence`'s clock cannot time its frames, if it cannot: a frame's
/// `Timestamp` not after the last timed frame before it (a clock that stands
/// still or runs backwards). A frame without a finite timestamp is its own
/// frame's fault (rejected with that reason where a time is needed), not the
/// clock's.
pub fn clock_fault(sequence: &Sequence) -> Option<String> {
    let mut previous: Option<(usize, f64)> = None;
    for index in 0..sequence.frames.len() {
        let Some(t) = timestamp_s(sequence, index) else {
            continue;
        };
        if let Some((before, t0)) = previous {
            if t <= t0 {
                return Some(format!(
                    "frame {index}'s `Timestamp` {t} s is not after frame {before}'s {t0} s: the clock {}",
                    if t == t0 { "stands still" } else { "runs backwards" }
                ));
            }
        }
        previous = Some((index, t));
    }
    None
}

/// A frame's timestamp, s; `None` when it is missing or not a finite number
/// (a `nan` parses as a number but times nothing).
pub fn timestamp_s(sequence: &Sequence, index: usize) -> Option<f64> {
    sequence.timestamp_s(index)
}

/// The constraints one frame gives: each N's middle dot on its point, each dot
/// on its wire.
pub fn constraints(frame: &TrackedFrame, nwires: &[NWire]) -> FrameConstraints {
    let mut out = FrameConstraints::default();
    let Some(marker_T_phantom) = frame.marker_T_phantom else {
        return out;
    };
    for (dots, nwire) in frame.dots_px.iter().zip(nwires) {
        out.points.push(Constraint {
            pixel: dots[1],
            elevation_mm: 0.0,
            marker_T_phantom,
            target_in_phantom: Target::Point(nwire.middle_in_phantom_mm(dots)),
        });
        for (dot, wire) in dots.iter().zip(&nwire.wires) {
            out.lines.push(Constraint {
                pixel: *dot,
                elevation_mm: 0.0,
                marker_T_phantom,
                target_in_phantom: Target::Line(wire.front_in_phantom_mm, wire.direction().normalize()),
            });
        }
    }
    out
}

/// A clip rectangle that reaches beyond its sequence's B-scans.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: the clip rectangle (origin {u} {v}, size {w} {h} px) reaches beyond the {width}x{height} px B-scans", sequence.display())]
pub struct ClipOutside {
    pub sequence: std::path::PathBuf,
    pub u: usize,
    pub v: usize,
    pub w: usize,
    pub h: usize,
    pub width: usize,
    pub height: usize,
}

/// A clip rectangle refused when it is empty or reaches beyond `sequence`'s images.
pub fn clip_inside(sequence: &Sequence, [u, v, w, h]: [usize; 4]) -> Result<(), ClipOutside> {
    let inside = u.checked_add(w).is_some_and(|r| r <= sequence.width)
        && v.checked_add(h).is_some_and(|b| b <= sequence.height)
        && w > 0
        && h > 0;
    if inside {
        return Ok(());
    }
    Err(ClipOutside {
        sequence: sequence.path.clone(),
        u,
        v,
        w,
        h,
        width: sequence.width,
        height: sequence.height,
    })
}

/// The clip rectangle given (refused when it reaches beyond the images), or the
/// whole image with the overlay of `sequence` found (when it has enough frames
/// to tell the drawn from the imaged).
pub fn clip_or_overlay(
    sequence: &Sequence,
    clip: Option<[usize; 4]>,
    segmentation: &Segmentation,
    spacing_guess_mm_per_px: f64,
) -> Result<([usize; 4], Option<Overlay>), ClipOutside> {
    Ok(match clip {
        Some(rectangle) => {
            clip_inside(sequence, rectangle)?;
            (rectangle, None)
        }
        None => (
            [0, 0, sequence.width, sequence.height],
            Overlay::find(
                (0..sequence.frames.len()).map(|i| sequence.pixels(i)),
                [sequence.width, sequence.height],
                segmentation.threshold_grey,
                segmentation.threshold_percent,
                segmentation.opening_radius_for(spacing_guess_mm_per_px).max(1) as usize,
            ),
        ),
    })
}
