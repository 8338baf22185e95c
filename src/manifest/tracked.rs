//! Manifests of tracker-sequence experiments: poses from a PLUS sequence file
//! instead of the camera stage, an N-wire phantom from a PLUS configuration.
//!
//! ```yaml
//! experiment: plus_fcal2_nwire
//! tracking:
//!   plus_sequence:
//!     dataset: fcal2_3nwires
//!     calibration: path/to/calibration.igs.mha
//!     validation: path/to/validation.igs.mha
//! phantom:
//!   nwire:
//!     plus_config: path/to/PlusDeviceSet.xml
//! ```
//!
//! or the phantom written out (each N: side, diagonal, side; phantom frame, mm):
//!
//! ```yaml
//! phantom:
//!   nwire:
//!     approximate_spacing_mm_per_px: 0.078
//!     patterns:
//!       - wires:
//!           - {name: w1, front_in_phantom_mm: [30, 0, 20], back_in_phantom_mm: [30, 40, 20]}
//!           - {name: w2, front_in_phantom_mm: [55, 0, 20], back_in_phantom_mm: [35, 40, 20]}
//!           - {name: w3, front_in_phantom_mm: [60, 0, 20], back_in_phantom_mm: [60, 40, 20]}
//!     reference_T_phantom: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
//! ```

use std::path::{Path, PathBuf};

use nalgebra::Matrix4;

pub use super::tracked_raw::{LiveStream, TrackedGates, TrackedRegression};
use super::tracked_raw::{OffsetSetting, PlusSequence, RawTrackedManifest, TrackedPhantom, Tracking};
use super::{deserialize_located, sha256_hex, Checker, ManifestErrors};
use nalgebra::Point3;

use crate::core::limits::MAX_FOLDS;
use crate::detect::nwire::Segmentation;
use crate::estimate::image_to_probe::{ConstraintModel, PixelModel};
use crate::io::plus::config::PlusConfig;
use crate::io::plus::xml_limits::{MAX_CLIP_PX, MAX_WIRE_COORDINATE_MM};
use crate::io::tracker_poses::{check_near_rigid, ORTHONORMAL_TOLERANCE};
use crate::spec::nwire::{NWire, WireSegment};

/// The tracker's time offset: fixed (s), or estimated from the calibration frames.
#[derive(Debug, Clone, PartialEq)]
pub enum TimeOffset {
    Fixed(f64),
    /// Estimated with the calibration from the calibration frames alone
    /// (`pipeline::time::lag`, `pipeline::time::lag_joint`), applied when
    /// cross-validation prefers it to no lag; the sweep's motion gives a second
    /// estimate beside it.
    Estimate,
    /// The lag `probecal temporal` finds in a recording of the probe over a flat
    /// reflector (PLUS's `TrackerLagSec`: a frame's pose is the tracker's at its
    /// time plus the lag).
    Temporal {
        tracker: PathBuf,
        video: PathBuf,
    },
}

/// A validated tracker-sequence experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedManifest {
    pub path: PathBuf,
    pub sha256: String,
    pub text: String,
    pub experiment: String,
    pub description: String,
    pub dataset: String,
    /// The PLUS device set the phantom came from (`None`: written in the manifest).
    pub plus_config: Option<PathBuf>,
    pub calibration_sequence: PathBuf,
    pub validation_sequence: Option<PathBuf>,
    pub probe_transform: String,
    pub reference_transform: String,
    pub time_offset: TimeOffset,
    pub nwires: Vec<NWire>,
    pub reference_T_phantom: Matrix4<f64>,
    pub spacing_guess_mm_per_px: f64,
    pub clip_rectangle_px: Option<[usize; 4]>,
    pub segmentation: Segmentation,
    /// Fixed by the manifest, or `None`: chosen by cross-validation.
    pub model: Option<ConstraintModel>,
    pub pixel_model: Option<PixelModel>,
    pub folds: usize,
    pub reject_sd: Option<f64>,
    pub refine_phantom: bool,
    pub min_frames: usize,
    pub gates: TrackedGates,
    pub regression: TrackedRegression,
    pub plus_result: Option<PathBuf>,
    pub live: LiveStream,
    /// A sweep to reconstruct with the calibration (`reconstruct:`).
    pub reconstruct: Option<TrackedReconstruct>,
}

/// The sweep a tracked run reconstructs with its own `ImageToProbe`, and the
/// device set whose `<VolumeReconstruction>` settings build the volume.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedReconstruct {
    pub sweep: PathBuf,
    pub config: PathBuf,
}

impl TrackedManifest {
    pub fn from_text(path: &Path, text: &str) -> Result<TrackedManifest, ManifestErrors> {
        let raw: RawTrackedManifest = deserialize_located(path, text)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut c = Checker {
            file: path,
            text,
            errors: Vec::new(),
        };
        c.name("experiment", &raw.experiment);
        let Tracking::PlusSequence(seq) = &raw.tracking;
        let f = "tracking.plus_sequence";
        c.name(&format!("{f}.dataset"), &seq.dataset);
        let calibration_sequence = c.existing(&format!("{f}.calibration"), &base, &seq.calibration, false);
        let validation_sequence = seq
            .validation
            .as_ref()
            .map(|v| c.existing(&format!("{f}.validation"), &base, v, false));
        let time_offset = time_offset(&mut c, &base, seq);
        check_pairing(&mut c, seq, &calibration_sequence, validation_sequence.as_deref());
        let PhantomParts {
            nwires,
            reference_T_phantom,
            config_spacing,
            clip_rectangle_px: config_clip_px,
            config_file,
            base_segmentation,
        } = phantom_parts(&mut c, &base, &raw.phantom);
        let spacing_guess_mm_per_px = match raw.bscan.approximate_spacing_mm_per_px.or(config_spacing) {
            Some(s) => {
                c.positive("bscan.approximate_spacing_mm_per_px", s);
                s
            }
            None => {
                c.fail(
                    "bscan.approximate_spacing_mm_per_px",
                    "is needed: neither the configuration nor the phantom gives `approximate_spacing_mm_per_px`",
                );
                1.0
            }
        };
        let seg = &raw.bscan.segmentation.apply(&base_segmentation);
        check_segmentation(&mut c, seg, nwires.len());
        let clip_rectangle_px = seg.clip_rectangle_px.or(config_clip_px);
        check_solve_and_thresholds(&mut c, &raw);
        let plus_result = raw
            .compare_with_plus_result
            .as_ref()
            .map(|p| c.existing("compare_with_plus_result", &base, p, false));
        let reconstruct = raw.reconstruct.as_ref().map(|r| TrackedReconstruct {
            sweep: match r.sweep.as_str() {
                "calibration" => calibration_sequence.clone(),
                "validation" => validation_sequence.clone().unwrap_or_else(|| {
                    c.fail(
                        "reconstruct.sweep",
                        "is `validation`, but `tracking.plus_sequence.validation` names no sequence",
                    );
                    PathBuf::new()
                }),
                path => c.existing("reconstruct.sweep", &base, path, false),
            },
            config: c.existing("reconstruct.config", &base, &r.config, false),
        });
        if !c.errors.is_empty() {
            return Err(ManifestErrors(c.errors));
        }
        Ok(TrackedManifest {
            path: path.to_path_buf(),
            sha256: sha256_hex(text.as_bytes()),
            text: text.to_string(),
            experiment: raw.experiment,
            description: raw.description,
            dataset: seq.dataset.clone(),
            plus_config: config_file,
            calibration_sequence,
            validation_sequence,
            probe_transform: seq.probe_transform.clone(),
            reference_transform: seq.reference_transform.clone(),
            time_offset,
            nwires,
            reference_T_phantom,
            spacing_guess_mm_per_px,
            clip_rectangle_px,
            segmentation: raw.bscan.segmentation.apply(&base_segmentation),
            model: raw.solve.constraints,
            pixel_model: raw.solve.pixel_model,
            folds: raw.solve.folds,
            reject_sd: raw.solve.reject_sd,
            refine_phantom: raw.solve.refine_phantom_registration,
            min_frames: raw.thresholds.min_frames,
            gates: raw.thresholds.gates,
            regression: raw.thresholds.regression,
            plus_result,
            live: raw.live,
            reconstruct,
        })
    }

    /// Every input file (those named inside the reconstruction's device set
    /// too), for hashing and for the output guard.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.plus_config.iter().cloned().collect();
        files.push(self.calibration_sequence.clone());
        files.extend(self.validation_sequence.clone());
        files.extend(self.plus_result.clone());
        if let Some(r) = &self.reconstruct {
            let mut named = vec![r.sweep.clone(), r.config.clone()];
            named.extend(crate::io::plus::volume_config::VolumeSettings::named_files(&r.config));
            for file in named {
                if !files.contains(&file) {
                    files.push(file);
                }
            }
        }
        if let TimeOffset::Temporal { tracker, video } = &self.time_offset {
            files.extend([tracker.clone(), video.clone()]);
        }
        files
    }
}

/// The two poses and the two recordings a run pairs must be two: a probe
/// transform that is the reference's, or a validation sequence that is the
/// calibration's, is refused at its key.
fn check_pairing(c: &mut Checker<'_>, seq: &PlusSequence, calibration: &Path, validation: Option<&Path>) {
    let f = "tracking.plus_sequence";
    if seq.probe_transform == seq.reference_transform {
        c.fail(
            &format!("{f}.reference_transform"),
            format!(
                "is `{}`, the probe's transform too: the phantom's pose relative to the probe would be the identity in every frame; name the reference marker's transform",
                seq.reference_transform
            ),
        );
    }
    if let (Some(v), false) = (validation, calibration.as_os_str().is_empty()) {
        if crate::io::fs::same_recording(calibration, v) {
            c.fail(
                &format!("{f}.validation"),
                "is the calibration sequence (the same file or the same bytes): its PRE3D would score the calibration on its own frames; give a held-out recording, or none",
            );
        }
    }
}

/// The tracker's time offset the manifest gives (a fixed value, `estimate`, or a
/// temporal-calibration recording).
fn time_offset(c: &mut Checker<'_>, base: &Path, seq: &PlusSequence) -> TimeOffset {
    let f = "tracking.plus_sequence";
    match &seq.time_offset_s {
        OffsetSetting::Seconds(s) if s.is_finite() && s.abs() <= 1.0 => TimeOffset::Fixed(*s),
        OffsetSetting::Word(w) if w == "estimate" => TimeOffset::Estimate,
        OffsetSetting::Temporal { temporal } => TimeOffset::Temporal {
            tracker: c.existing(
                &format!("{f}.time_offset_s.temporal.tracker"),
                base,
                &temporal.tracker,
                false,
            ),
            video: c.existing(
                &format!("{f}.time_offset_s.temporal.video"),
                base,
                &temporal.video,
                false,
            ),
        },
        other => {
            let got = match other {
                OffsetSetting::Seconds(s) => format!("{s} s"),
                OffsetSetting::Word(w) => format!("`{w}`"),
                OffsetSetting::Temporal { .. } => "a temporal calibration".into(),
            };
            c.fail(
                &format!("{f}.time_offset_s"),
                format!(
                    "must be `estimate`, seconds between -1 and 1, or `{{temporal: {{tracker, video}}}}`, got {got}"
                ),
            );
            TimeOffset::Fixed(0.0)
        }
    }
}

/// The phantom as the manifest gives it, from a device set or written out.
struct PhantomParts {
    nwires: Vec<NWire>,
    reference_T_phantom: Matrix4<f64>,
    config_spacing: Option<f64>,
    clip_rectangle_px: Option<[usize; 4]>,
    config_file: Option<PathBuf>,
    base_segmentation: Segmentation,
}

/// The N-wires, their pose on the reference and the segmentation's starting
/// settings: from `plus_config`, or from `patterns` and `reference_T_phantom`.
fn phantom_parts(c: &mut Checker<'_>, base: &Path, phantom: &TrackedPhantom) -> PhantomParts {
    let TrackedPhantom::Nwire {
        plus_config,
        patterns,
        reference_T_phantom: given_reference_T_phantom,
        approximate_spacing_mm_per_px: phantom_spacing,
        phantom_frame,
        reference_frame,
    } = phantom;
    let mut parts = PhantomParts {
        nwires: Vec::new(),
        reference_T_phantom: Matrix4::identity(),
        config_spacing: *phantom_spacing,
        clip_rectangle_px: None,
        config_file: None,
        base_segmentation: Segmentation::default(),
    };
    match (plus_config, patterns) {
        (Some(plus_config), None) => {
            let config_field = "phantom.nwire.plus_config";
            for (given, name) in [
                (given_reference_T_phantom.is_some(), "reference_T_phantom"),
                (phantom_spacing.is_some(), "approximate_spacing_mm_per_px"),
            ] {
                if given {
                    c.fail(
                        &format!("phantom.nwire.{name}"),
                        "comes from plus_config; give it only with `patterns`",
                    );
                }
            }
            let plus_config = c.existing(config_field, base, plus_config, false);
            if plus_config.is_file() {
                match PlusConfig::read(&plus_config) {
                    Ok(config) => {
                        if config.nwires.is_empty() {
                            c.fail(
                                config_field,
                                format!("{}: no N-wire `Pattern` in `PhantomDefinition`", plus_config.display()),
                            );
                        }
                        parts.nwires = config.nwires.clone();
                        match config.rigid_transform(phantom_frame, reference_frame) {
                            Ok(m) => parts.reference_T_phantom = m,
                            Err(e) => c.fail(config_field, e.to_string()),
                        }
                        parts.config_spacing = config.approximate_spacing_mm_per_px;
                        parts.clip_rectangle_px = config.clip_rectangle_px.map(|(o, s)| [o[0], o[1], s[0], s[1]]);
                        parts.base_segmentation = Segmentation::from_device_set(&config);
                    }
                    Err(e) => c.fail(config_field, e.to_string()),
                }
            }
            parts.config_file = Some(plus_config);
        }
        (None, Some(patterns)) => {
            if patterns.is_empty() {
                c.fail("phantom.nwire.patterns", "lists no N-wire");
            }
            for (i, p) in patterns.iter().enumerate() {
                let segments = p.wires.clone().map(|w| WireSegment {
                    name: w.name,
                    front_in_phantom_mm: Point3::from(w.front_in_phantom_mm),
                    back_in_phantom_mm: Point3::from(w.back_in_phantom_mm),
                });
                if segments.iter().any(|w| {
                    w.front_in_phantom_mm
                        .iter()
                        .chain(w.back_in_phantom_mm.iter())
                        .any(|v| !v.is_finite() || v.abs() > MAX_WIRE_COORDINATE_MM)
                }) {
                    c.fail(
                        &format!("phantom.nwire.patterns[{i}].wires"),
                        format!("has an end point not a finite number within ±{MAX_WIRE_COORDINATE_MM} mm of the phantom's origin"),
                    );
                    continue;
                }
                match NWire::new(segments) {
                    Ok(n) => parts.nwires.push(n),
                    Err(e) => c.fail(&format!("phantom.nwire.patterns[{i}].wires"), e.to_string()),
                }
            }
            match given_reference_T_phantom {
                Some(rows) => match check_near_rigid(rows, ORTHONORMAL_TOLERANCE) {
                    Ok(()) => parts.reference_T_phantom = Matrix4::from_fn(|r, k| rows[r][k]),
                    Err(e) => c.fail("phantom.nwire.reference_T_phantom", e.to_string()),
                },
                None => c.fail(
                    "phantom.nwire.reference_T_phantom",
                    "is needed with `patterns`: the phantom's pose on its reference marker (PLUS's PhantomToReference)",
                ),
            }
        }
        _ => c.fail(
            "phantom.nwire",
            "give exactly one of `plus_config` (a PLUS device set) or `patterns` with `reference_T_phantom`",
        ),
    }
    parts
}

/// The segmentation's settings within their ranges.
fn check_segmentation(c: &mut Checker<'_>, seg: &Segmentation, nwires: usize) {
    let sf = "bscan.segmentation";
    c.positive(&format!("{sf}.collinear_tolerance_mm"), seg.collinear_tolerance_mm);
    if !(seg.threshold_percent > 0.0 && seg.threshold_percent < 100.0) {
        c.fail(
            &format!("{sf}.threshold_percent"),
            format!("must be a percentage between 0 and 100, got {}", seg.threshold_percent),
        );
    }
    c.at_least(&format!("{sf}.opening_radius_mm"), seg.opening_radius_mm, 0.0);
    if !(0.0..=50.0).contains(&seg.opening_bar_size_mm) {
        c.fail(
            &format!("{sf}.opening_bar_size_mm"),
            format!("must be 0 (no bars) to 50 mm, got {}", seg.opening_bar_size_mm),
        );
    }
    if seg.opening_radius_px.is_some_and(|r| r > 50) {
        c.fail(&format!("{sf}.opening_radius_px"), "must be at most 50 px");
    }
    if !(0.0..1.0).contains(&seg.core_fraction) {
        c.fail(
            &format!("{sf}.core_fraction"),
            format!("must be a fraction in [0, 1), got {}", seg.core_fraction),
        );
    }
    if !(-90.0..=90.0).contains(&seg.min_row_angle_deg)
        || !(-90.0..=90.0).contains(&seg.max_row_angle_deg)
        || seg.min_row_angle_deg >= seg.max_row_angle_deg
    {
        c.fail(
            &format!("{sf}.max_row_angle_deg"),
            format!(
                "the row angles {}..{} must lie within ±90 degrees, the first below the second",
                seg.min_row_angle_deg, seg.max_row_angle_deg
            ),
        );
    }
    if !(seg.row_gap_tolerance_percent > 0.0 && seg.row_gap_tolerance_percent < 100.0) {
        c.fail(
            &format!("{sf}.row_gap_tolerance_percent"),
            format!(
                "must be a percentage between 0 and 100, got {}",
                seg.row_gap_tolerance_percent
            ),
        );
    }
    c.at_least(
        &format!("{sf}.max_row_angle_difference_deg"),
        seg.max_row_angle_difference_deg,
        0.0,
    );
    let most = crate::spec::nwire::MAX_DOT_CANDIDATES;
    if seg.max_candidates < 3 * nwires.max(1) || seg.max_candidates > most {
        c.fail(
            &format!("{sf}.max_candidates"),
            format!(
                "must be between {} (3 per N-wire) and {most}, got {}",
                3 * nwires.max(1),
                seg.max_candidates
            ),
        );
    }
    if let Some(r) = seg.clip_rectangle_px {
        if r[2] == 0 || r[3] == 0 {
            c.fail(&format!("{sf}.clip_rectangle_px"), "has zero width or height");
        } else if r.iter().any(|&v| v as f64 > MAX_CLIP_PX) {
            c.fail(
                &format!("{sf}.clip_rectangle_px"),
                format!("must be whole pixels up to {MAX_CLIP_PX}, got {r:?}"),
            );
        }
    }
}

/// The solve's settings and the thresholds within their ranges.
fn check_solve_and_thresholds(c: &mut Checker<'_>, raw: &RawTrackedManifest) {
    if let Some(k) = raw.solve.reject_sd {
        c.positive("solve.reject_sd", k);
    }
    if !(2..=MAX_FOLDS).contains(&raw.solve.folds) {
        c.fail(
            "solve.folds",
            format!("must be between 2 and {MAX_FOLDS}, got {}", raw.solve.folds),
        );
    }
    if raw.thresholds.min_frames < 3 {
        c.fail(
            "thresholds.min_frames",
            format!("at least 3 frames are needed, got {}", raw.thresholds.min_frames),
        );
    }
    if let Some(g) = raw.thresholds.gates.pre3d_mm {
        c.positive("thresholds.gates.pre3d_mm", g);
    }
    c.at_least(
        "thresholds.regression.pre3d_mm",
        raw.thresholds.regression.pre3d_mm,
        0.0,
    );
    c.at_least(
        "thresholds.regression.frames_rejected",
        raw.thresholds.regression.frames_rejected,
        0.0,
    );
    check_live(c, &raw.live);
}

/// Device names OpenIGTLink can carry, and times a session can wait.
fn check_live(c: &mut Checker<'_>, live: &LiveStream) {
    for (field, name) in [
        ("live.image_device", &live.image_device),
        ("live.end_device", &live.end_device),
        ("live.send_device", &live.send_device),
    ] {
        if name.is_empty() || name.len() > 20 || !name.bytes().all(|b| b.is_ascii_graphic()) {
            c.fail(
                field,
                format!("`{name}`: an OpenIGTLink device name is 1 to 20 printable ASCII characters"),
            );
        }
    }
    if !(live.silence_s.is_finite() && live.silence_s > 0.0 && live.silence_s <= 3600.0) {
        c.fail(
            "live.silence_s",
            format!("{}: seconds, above 0 and at most 3600", live.silence_s),
        );
    }
    let gap = live.max_transform_gap_s;
    if !(gap.is_finite() && gap > 0.0 && gap <= 1.0) {
        c.fail(
            "live.max_transform_gap_s",
            format!("{gap}: seconds, above 0 and at most 1"),
        );
    }
}
