//! The results model: `summary.json`, typed. The runner's record of a dataset
//! becomes a [`Summary`] (a tracked sequence's run a [`TrackedSummary`]); the
//! regression gate, the thesis chapter, the index and the console read them back
//! through the same types, never through string keys.
//!
//! Millimetres and degrees throughout; a cut-off of infinity is written `"inf"`.
//! Objects are written with their keys sorted, so the file is stable.

use super::ReadError;
use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::core::geometry::{euler_zyx_deg, to_rows};
use crate::core::stats::MeanSd;
use crate::estimate::edge_offset::EdgeOffset;
use crate::estimate::start_basin::StartGuess;
use crate::evaluate::resampling::Bootstrap;
use crate::evaluate::{cutoff_label, AxisStats, BreStats, TruthComparison};
use crate::manifest::{Regression, SolveVariant};
use crate::pipeline::labels::RunLabels;
use crate::pipeline::record::{DatasetRun, GateResult, Method, MethodResult};

/// A BRE cut-off in mm; infinity (all frames) is written `"inf"`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CutoffMm(pub f64);

impl Serialize for CutoffMm {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if self.0.is_infinite() {
            s.serialize_str("inf")
        } else {
            s.serialize_f64(self.0)
        }
    }
}

impl<'de> Deserialize<'de> for CutoffMm {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<CutoffMm, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Written {
            Number(f64),
            Text(String),
        }
        match Written::deserialize(d)? {
            Written::Number(v) => Ok(CutoffMm(v)),
            Written::Text(t) if t == "inf" => Ok(CutoffMm(f64::INFINITY)),
            Written::Text(t) => Err(serde::de::Error::custom(format!(
                "a cut-off is a number of mm or \"inf\", got \"{t}\""
            ))),
        }
    }
}

impl CutoffMm {
    /// As `summary.json` writes it: `inf`, or the number as JSON writes it (`2.0`).
    pub fn written(&self) -> String {
        serde_json::to_value(self)
            .map(|v| match v {
                serde_json::Value::String(s) => s,
                other => other.to_string(),
            })
            .unwrap_or_default()
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameCounts {
    pub total: usize,
    pub used: usize,
    pub rejected: usize,
    /// Stage label → frames it rejected.
    #[serde(deserialize_with = "crate::io::unique_keys::map")]
    pub rejected_by_stage: BTreeMap<String, usize>,
}

/// The camera's intrinsics (none with a tracker) and their calibration.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraSummary {
    pub source: String,
    pub fx_px: Option<f64>,
    pub fy_px: Option<f64>,
    pub cx_px: Option<f64>,
    pub cy_px: Option<f64>,
    /// OpenCV order: k1, k2, p1, p2, k3.
    pub distortion: Option<[f64; 5]>,
    pub rms_px: Option<f64>,
    pub views_used: Option<usize>,
    pub views_total: Option<usize>,
}

/// The reported calibration.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CalibrationSummary {
    pub marker_T_image: [[f64; 4]; 4],
    pub scale_mm_per_px: [f64; 2],
    pub solve_variant: SolveVariant,
    pub euler_zyx_deg: [f64; 3],
    pub translation_mm: [f64; 3],
    pub cutoff_mm: CutoffMm,
    pub frames_used: usize,
    pub horn_rms_residual_mm: f64,
}

/// The thesis's BRE table: Std./Mean/Min/Max per axis of the phantom frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct BreSummary {
    pub x: AxisStats,
    pub y: AxisStats,
    pub z: AxisStats,
}

impl BreSummary {
    pub fn axes(&self) -> [AxisStats; 3] {
        [self.x, self.y, self.z]
    }
    /// The largest mean over the axes.
    pub fn max_mean(&self) -> f64 {
        self.x.mean.max(self.y.mean).max(self.z.mean)
    }
}

impl From<&BreStats> for BreSummary {
    fn from(s: &BreStats) -> BreSummary {
        BreSummary { x: s.x, y: s.y, z: s.z }
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MeanMax {
    pub mean: f64,
    pub max: f64,
}

impl MeanMax {
    fn of(v: Option<(f64, f64)>) -> Option<MeanMax> {
        v.map(|(mean, max)| MeanMax { mean, max })
    }
}

/// A calibration against the truth: the image's corners and centre, the rotation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TruthError {
    pub corner_error_mm: MeanMax,
    pub rotation_error_deg: f64,
    #[serde(default)]
    pub in_image: crate::evaluate::ImageFrameError,
}

impl From<TruthComparison> for TruthError {
    fn from(t: TruthComparison) -> TruthError {
        TruthError {
            corner_error_mm: MeanMax {
                mean: t.corner_error_mean_mm,
                max: t.corner_error_max_mm,
            },
            rotation_error_deg: t.rotation_error_deg,
            in_image: t.in_image,
        }
    }
}

/// One row of the thesis's threshold table.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ThresholdSummary {
    pub cutoff_mm: CutoffMm,
    pub frames: usize,
    pub bre_mm: Option<BreSummary>,
    pub error: Option<String>,
    pub truth: Option<TruthError>,
}

/// One estimator's calibration.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MethodSummary {
    pub name: String,
    pub description: String,
    pub frames_used: usize,
    pub frames_left_out: Vec<usize>,
    pub marker_T_image: [[f64; 4]; 4],
    pub spacing_mm_per_px: [f64; 2],
    pub truth: Option<TruthError>,
}

/// Leave-one-out PRE, CR and bootstrap intervals.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ValidationSummary {
    pub protocol: String,
    pub pre_loo_mm: MeanSd,
    pub cr_mm: f64,
    pub cr_calibrations: usize,
    pub bootstrap: Bootstrap,
}

/// The run against the rendered truth.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TruthSummaryJson {
    pub corner_error_mm: MeanMax,
    pub rotation_error_deg: f64,
    pub translation_error_mm: f64,
    pub camera_focal_error_px: Option<f64>,
    pub camera_principal_point_error_px: Option<f64>,
    /// The camera's intrinsics against the truth in the uncertainty its
    /// calibration states (χ², nine degrees of freedom, when that is honest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_intrinsics_nees: Option<f64>,
    pub arc_centre_error_px: Option<MeanMax>,
    pub probe_pose_error_mm: Option<MeanMax>,
    pub probe_pose_error_deg: Option<MeanMax>,
    pub phantom_pose_error_mm: Option<MeanMax>,
    /// Dome phantoms: the arcs' errors against their true cuts, set against the
    /// bound's noise model (`evaluate::arc_noise`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arc_noise: Option<crate::evaluate::arc_noise::ArcNoiseCheck>,
}

/// `summary.json` of a camera (or tracker-CSV) run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub experiment: String,
    pub dataset: String,
    pub rendered: bool,
    pub probecal_version: String,
    pub manifest_sha256: String,
    pub frames: FrameCounts,
    pub camera: CameraSummary,
    pub calibration: CalibrationSummary,
    /// At the calibration cut-off.
    pub bre_mm: Option<BreSummary>,
    pub thresholds: Vec<ThresholdSummary>,
    pub gates: Vec<GateResult>,
    /// The estimator the truth gates check (`thresholds.gates.method`), when
    /// it is not the reported calibration: the one the phantom is for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gated_method: Option<String>,
    pub regression_tolerances: Regression,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub methods: Vec<MethodSummary>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<ValidationSummary>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<TruthSummaryJson>,
    /// Wire phantoms: the start guess's offset and basin of convergence.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_guess: Option<StartGuess>,
    /// A rendered handheld session's stated occluders (`render.occluders`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluders: Option<crate::spec::render::SessionOccluders>,
}

impl Summary {
    /// The truth error of the estimator the gates check, with its name, when
    /// that is not the reported calibration.
    pub fn gated_truth(&self) -> Option<(&str, TruthError)> {
        let name = self.gated_method.as_deref()?;
        let m = self.methods.iter().find(|m| m.name == name)?;
        Some((name, m.truth?))
    }
}

/// The pixel size a sphere fit mapped pixels with, when it was not the manifest's.
fn fitted_pixel_size(fitted: bool, m: &MethodResult, how: &str) -> String {
    if !fitted {
        return String::new();
    }
    let [x, y] = m.spacing_mm_per_px;
    format!(", the pixel size {how} ({x:.4} x {y:.4} mm/px)")
}

/// What the report says an estimator did.
pub fn describe(m: &MethodResult) -> String {
    match m.method {
        Method::CutoffWorstFirst { cutoff_mm } => format!(
            "the reported calibration: Horn on the feature centres, frames above {} mm removed worst first, re-solving after each",
            cutoff_label(cutoff_mm)
        ),
        Method::ThesisOneShot { cutoff_mm } => format!(
            "the thesis's procedure: Horn on all frames, every frame above {} mm dropped at once, Horn again",
            cutoff_label(cutoff_mm)
        ),
        Method::Ransac {
            threshold_mm,
            noise_sd_mm,
        } => format!(
            "RANSAC (MSAC) over frames (samples of 3, Horn inside), inlier threshold {threshold_mm:.3} mm{}",
            match noise_sd_mm {
                Some(sd) => format!(" (χ² 99 % of a stated {sd:.2} mm noise SD per axis)"),
                None => " (manifest)".into(),
            }
        ),
        Method::Lmeds { threshold_mm } => format!(
            "LMEDS over frames (samples of 3, Horn inside), inlier threshold {threshold_mm:.3} mm (from the data)"
        ),
        Method::RansacLmScales => format!(
            "RANSAC's frames, Levenberg–Marquardt with the pixel size as unknowns ({:.4} x {:.4} mm/px)",
            m.spacing_mm_per_px[0], m.spacing_mm_per_px[1]
        ),
        Method::RansacSphereFit {
            elevation_prior_sd_mm,
            edge_offset_mm,
        } => format!(
            "RANSAC's frames, every arc edge point on the sphere (LM; elevation prior {}, edge offset {edge_offset_mm:.3} mm)",
            elevation_prior_sd_mm
                .map(|s| format!("{s:.2} mm"))
                .unwrap_or_else(|| "none".into())
        ),
        Method::SphereFit {
            arcs,
            rms_mm,
            rms_limit_mm,
            pixel_size_fitted,
        } => format!(
            "the reported calibration's frames, the edge points of every arc ({arcs}) on their own sphere (LM, no prior: the spheres cut at different offsets observe the planes' elevation){}, frames whose RMS exceeds {rms_limit_mm:.3} mm (median + 3 robust SD) left out and the fit repeated; RMS {rms_mm:.3} mm",
            fitted_pixel_size(pixel_size_fitted, m, "solved with it")
        ),
        Method::SphereFitPosePrior {
            arcs,
            rms_mm,
            noise,
            pixel_size_fitted,
        } => format!(
            "the sphere fit's arcs ({arcs}){}, every frame's phantom_T_marker free under its prior (board corners {:.4} px probe, {:.4} px phantom: the run's median reprojection RMS; the hand between photo and B-scan {:.3} mm, {:.3}° per axis: solve.sphere_fit.pose_prior), edge points {:.3} mm (the arcs' median RMS){}, {}{}; RMS {rms_mm:.3} mm",
            fitted_pixel_size(pixel_size_fitted, m, "the sphere fit's"),
            noise.probe_corner_sd_px,
            noise.phantom_corner_sd_px,
            noise.tremor_sd_mm,
            noise.tremor_sd_deg,
            noise.edge_sd_mm,
            match noise.slice_blur {
                None => String::new(),
                Some(b) => format!(
                    " with their variance grown by 1 + (σ_e·|d|/(r·σ_a))² for an arc cut d from its dome's centre (pulse σ_a {:.3} mm, slice σ_e {:.3} mm: the pose prior's slice_blur)",
                    b.axial_sd_mm, b.elevation_sd_mm
                ),
            },
            match noise.intrinsics_fx_sd_px {
                Some(sd) => format!(
                    "the camera's nine intrinsics solved too, one error every frame's pose shares, under what the calibration's views know of them (fx SD {sd:.3} px)"
                ),
                None => "the camera's intrinsics taken as exact (no calibration views)".into(),
            },
            match noise.edge_offset {
                EdgeOffset::None => String::new(),
                model => format!(
                    ", the echo edge's offset outside its sphere solved with it ({}: a + b·(d/R)² + c·d²/(R·r), a = {:.3} mm, b = {:.3} mm, c = {:.3} mm)",
                    model.name(),
                    noise.edge_offset_mm[0],
                    noise.edge_offset_mm[1],
                    noise.edge_offset_mm[2]
                ),
            }
        ),
    }
}

impl CameraSummary {
    /// The camera stage's intrinsics and views.
    fn of(camera: &crate::pipeline::record::CameraStage) -> CameraSummary {
        let k = camera.intrinsics.as_ref();
        CameraSummary {
            source: camera.source.clone(),
            fx_px: k.map(|k| k.fx()),
            fy_px: k.map(|k| k.fy()),
            cx_px: k.map(|k| k.cx()),
            cy_px: k.map(|k| k.cy()),
            distortion: k.map(|k| k.distortion),
            rms_px: k.and_then(|k| k.rms_px),
            views_used: camera
                .calibration
                .as_ref()
                .map(|c| c.views.iter().filter(|v| v.used).count()),
            views_total: camera.calibration.as_ref().map(|c| c.views.len()),
        }
    }
}

impl Summary {
    /// The summary of a dataset's run.
    pub fn of(run: &DatasetRun, labels: &RunLabels) -> Summary {
        let primary = &run.thresholds[run.primary];
        let fit = run.primary_fit();
        let used = run.used_frames();
        let mut rejected_by_stage = BTreeMap::new();
        for f in &run.frames {
            if let Some(r) = &f.rejection {
                *rejected_by_stage.entry(r.stage().label().to_string()).or_insert(0) += 1;
            }
        }
        let t = fit.target_T_source.translation.vector;
        Summary {
            schema_version: crate::results::SCHEMA_VERSION,
            experiment: run.experiment.clone(),
            dataset: run.dataset.clone(),
            rendered: run.rendered,
            probecal_version: env!("CARGO_PKG_VERSION").into(),
            manifest_sha256: labels.manifest_sha256.clone(),
            frames: FrameCounts {
                total: run.frames.len(),
                used,
                rejected: run.frames.len() - used,
                rejected_by_stage,
            },
            camera: CameraSummary::of(&run.camera),
            calibration: CalibrationSummary {
                marker_T_image: to_rows(&fit.target_T_source),
                scale_mm_per_px: [
                    run.spacing_mm_per_px[0] * fit.scale,
                    run.spacing_mm_per_px[1] * fit.scale,
                ],
                solve_variant: labels.solve_variant,
                euler_zyx_deg: euler_zyx_deg(&fit.target_T_source),
                translation_mm: [t.x, t.y, t.z],
                cutoff_mm: CutoffMm(primary.cutoff_mm),
                frames_used: primary.frames.len(),
                horn_rms_residual_mm: fit.rms_residual_mm,
            },
            bre_mm: primary.stats.as_ref().map(BreSummary::from),
            thresholds: run
                .thresholds
                .iter()
                .map(|r| ThresholdSummary {
                    cutoff_mm: CutoffMm(r.cutoff_mm),
                    frames: r.frames.len(),
                    bre_mm: r.stats.as_ref().map(BreSummary::from),
                    error: r.fit.as_ref().err().map(|e| e.to_string()),
                    truth: r.truth.map(TruthError::from),
                })
                .collect(),
            gates: run.gates.clone(),
            gated_method: labels.gated_method.clone(),
            regression_tolerances: labels.regression.clone(),
            methods: run
                .methods
                .iter()
                .map(|m| MethodSummary {
                    name: m.method.name().into(),
                    description: describe(m),
                    frames_used: m.frames_used,
                    frames_left_out: m.frames_left_out.clone(),
                    marker_T_image: to_rows(&m.marker_T_image),
                    spacing_mm_per_px: m.spacing_mm_per_px,
                    truth: m.truth.map(TruthError::from),
                })
                .collect(),
            start_guess: run.start_guess.clone(),
            occluders: labels.occluders.get(&run.dataset).cloned(),
            validation: run.validation.as_ref().map(|v| ValidationSummary {
                protocol: "frames of the calibration cut-off; PRE by leave-one-out; CR over random half-splits; bootstrap percentile intervals (2.5 %, 97.5 %)".into(),
                pre_loo_mm: v.leave_one_out.summary,
                cr_mm: v.reproducibility.cr_mm,
                cr_calibrations: v.reproducibility.calibrations,
                bootstrap: v.bootstrap.clone(),
            }),
            truth: run.truth.as_ref().map(|t| TruthSummaryJson {
                corner_error_mm: MeanMax {
                    mean: t.calibration.corner_error_mean_mm,
                    max: t.calibration.corner_error_max_mm,
                },
                rotation_error_deg: t.calibration.rotation_error_deg,
                translation_error_mm: t.calibration.translation_error_mm,
                camera_focal_error_px: t.camera_focal_error_px,
                camera_principal_point_error_px: t.camera_principal_error_px,
                camera_intrinsics_nees: t.camera_intrinsics_nees,
                arc_centre_error_px: MeanMax::of(t.arc_centre_error_px),
                probe_pose_error_mm: MeanMax::of(t.probe_pose_translation_error_mm),
                probe_pose_error_deg: MeanMax::of(t.probe_pose_rotation_error_deg),
                phantom_pose_error_mm: MeanMax::of(t.phantom_pose_translation_error_mm),
                arc_noise: t.arc_noise.clone(),
            }),
        }
    }
}

/// Either kind of run summary, as read back from disk.
#[derive(Debug, Clone, PartialEq)]
pub enum RunSummary {
    Camera(Box<Summary>),
    Tracked(Box<TrackedSummary>),
}

impl RunSummary {
    pub fn experiment(&self) -> &str {
        match self {
            RunSummary::Camera(s) => &s.experiment,
            RunSummary::Tracked(s) => &s.experiment,
        }
    }
    pub fn dataset(&self) -> &str {
        match self {
            RunSummary::Camera(s) => &s.dataset,
            RunSummary::Tracked(s) => &s.dataset,
        }
    }
    pub fn gates(&self) -> &[GateResult] {
        match self {
            RunSummary::Camera(s) => &s.gates,
            RunSummary::Tracked(s) => &s.gates,
        }
    }

    /// Reads a `summary.json`; an error names the file, the field and the line.
    pub fn read(path: &Path) -> Result<RunSummary, ReadError> {
        let text = crate::io::fs::read_text_capped(path, crate::core::limits::MAX_TEXT_FILE_BYTES)
            .map_err(|e| ReadError::new(path, e))?;
        RunSummary::parse(&text, path)
    }

    /// Parses a summary's text read from `path` (the kind from its `kind` field).
    pub fn parse(text: &str, path: &Path) -> Result<RunSummary, ReadError> {
        let value = crate::io::unique_keys::json_value(text).map_err(|e| ReadError::new(path, e))?;
        if let Some(fault) = crate::results::schema_version_fault(&value) {
            return Err(ReadError::new(path, fault));
        }
        let tracked = value.get("kind").and_then(|k| k.as_str()) == Some(TRACKED_KIND);
        let described = |e: serde_path_to_error::Error<serde_json::Error>| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            let message = format!(
                "line {}: field `{field}`: {inner}: not a probecal summary",
                inner.line()
            );
            ReadError::new(path, message)
        };
        let de = &mut serde_json::Deserializer::from_str(text);
        let summary = if tracked {
            serde_path_to_error::deserialize(de)
                .map(|s| RunSummary::Tracked(Box::new(s)))
                .map_err(described)
        } else {
            serde_path_to_error::deserialize(de)
                .map(|s| RunSummary::Camera(Box::new(s)))
                .map_err(described)
        }?;
        // The experiment's name names folders and baseline files: a plain name only.
        if let Some(fault) = crate::manifest::name_fault(summary.experiment()) {
            return Err(ReadError::new(path, format!("field `experiment`: {fault}")));
        }
        Ok(summary)
    }
}

pub use crate::io::json::to_text;
pub use crate::results::tracked::*;
