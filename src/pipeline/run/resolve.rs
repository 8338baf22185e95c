//! Results that carry their inputs: `solve_inputs.yaml` in a run's folder holds
//! every usable frame's poses and feature pixels (with where each feature lies in
//! the phantom) and the settings they were solved with, exactly (poses as unit
//! quaternions and translations, as the solver held them; YAML because its
//! numbers are read back to the last bit). [`solve_again`] solves
//! them through the same code as the run, so a run can be audited from its folder
//! alone.

use std::path::Path;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::geometry::Rigid;
use crate::estimate::correspondence::{Correspondence, Observed};
use crate::estimate::horn::Variant;
use crate::estimate::image_to_probe::Target;
use crate::evaluate::CutoffRule;
use crate::pipeline::error::RunError;
use crate::pipeline::solve::{self, Calibrations, SolveSettings};

/// The file a run's solve inputs are written to.
pub const SOLVE_INPUTS_FILE: &str = "solve_inputs.yaml";

/// A rigid transform as stored: unit quaternion `[x, y, z, w]` and translation (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub rotation_xyzw: [f64; 4],
    pub translation_mm: [f64; 3],
}

impl From<&Rigid> for Pose {
    fn from(t: &Rigid) -> Pose {
        let q = t.rotation.quaternion();
        let v = t.translation.vector;
        Pose {
            rotation_xyzw: [q.i, q.j, q.k, q.w],
            translation_mm: [v.x, v.y, v.z],
        }
    }
}

impl Pose {
    /// The transform; an error for a quaternion that is not of unit length.
    pub fn rigid(&self) -> Result<Rigid, PoseFault> {
        let [x, y, z, w] = self.rotation_xyzw;
        let q = Quaternion::new(w, x, y, z);
        if !(q.norm() - 1.0).abs().is_finite() || (q.norm() - 1.0).abs() > 1e-9 {
            return Err(PoseFault::NotUnit(self.rotation_xyzw));
        }
        if self.translation_mm.iter().any(|v| !v.is_finite()) {
            return Err(PoseFault::NotFinite(self.translation_mm));
        }
        Ok(Isometry3::from_parts(
            Translation3::from(Vector3::from(self.translation_mm)),
            UnitQuaternion::new_unchecked(q),
        ))
    }
}

/// Where a feature lies in the phantom frame (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TargetInPhantom {
    Point([f64; 3]),
    /// A point of the line and its unit direction.
    Line {
        point: [f64; 3],
        direction: [f64; 3],
    },
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FeatureInput {
    pub pixel: [f64; 2],
    /// Image z of the feature, mm (a sphere's centre beside the plane); absent: 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub elevation_mm: f64,
    pub target_in_phantom: TargetInPhantom,
}

/// One usable frame as the solver saw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameInput {
    pub frame: usize,
    pub camera_T_marker: Pose,
    pub camera_T_phantom: Pose,
    pub features: Vec<FeatureInput>,
}

/// `solve_inputs.yaml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolveInputs {
    pub experiment: String,
    pub dataset: String,
    pub spacing_mm_per_px: [f64; 2],
    /// `rigid` or `similarity`.
    pub variant: String,
    /// Descending; `.inf` (all frames) first.
    pub cutoffs_mm: Vec<f64>,
    pub cutoff_rule: CutoffRule,
    pub calibration_cutoff_mm: f64,
    pub min_frames: usize,
    pub initial_marker_T_image: Option<Pose>,
    pub frames: Vec<FrameInput>,
}

impl SolveInputs {
    /// The inputs of a run's solve.
    pub fn of(experiment: &str, dataset: &str, pairs: &[Correspondence], settings: &SolveSettings) -> SolveInputs {
        let target = |t: &Target| match t {
            Target::Point(p) => TargetInPhantom::Point([p.x, p.y, p.z]),
            Target::Line(q, d) => TargetInPhantom::Line {
                point: [q.x, q.y, q.z],
                direction: [d.x, d.y, d.z],
            },
        };
        SolveInputs {
            experiment: experiment.into(),
            dataset: dataset.into(),
            spacing_mm_per_px: settings.spacing_mm_per_px,
            variant: match settings.variant {
                Variant::Rigid => "rigid",
                Variant::Similarity => "similarity",
            }
            .into(),
            cutoffs_mm: settings.cutoffs_mm.clone(),
            cutoff_rule: settings.rule,
            calibration_cutoff_mm: settings.calibration_cutoff_mm,
            min_frames: settings.min_frames,
            initial_marker_T_image: settings.initial_marker_T_image.as_ref().map(Pose::from),
            frames: pairs
                .iter()
                .map(|c| FrameInput {
                    frame: c.frame,
                    camera_T_marker: Pose::from(&c.camera_T_marker),
                    camera_T_phantom: Pose::from(&c.camera_T_phantom),
                    features: c
                        .features
                        .iter()
                        .map(|o| FeatureInput {
                            pixel: o.pixel,
                            elevation_mm: o.elevation_mm,
                            target_in_phantom: target(&o.target_in_phantom),
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    /// The file's text.
    pub fn to_yaml(&self) -> Result<String, SolveInputsError> {
        serde_yaml::to_string(self).map_err(|e| SolveInputsError::Yaml(e.to_string()))
    }

    /// Reads a run folder's `solve_inputs.yaml`; an error names the file and field.
    pub fn read(run_folder: &Path) -> Result<SolveInputs, SolveInputsError> {
        let path = run_folder.join(SOLVE_INPUTS_FILE);
        let text = crate::io::fs::read_text_capped(&path, crate::core::limits::MAX_TEXT_FILE_BYTES).map_err(|e| {
            SolveInputsError::Read {
                path: path.clone(),
                message: e.to_string(),
            }
        })?;
        let de = serde_yaml::Deserializer::from_str(&text);
        serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            let line = inner.location().map(|l| format!(":{}", l.line())).unwrap_or_default();
            SolveInputsError::Read {
                path: path.clone(),
                message: format!("{line}: field `{field}`: {inner}")
                    .trim_start_matches(':')
                    .to_string(),
            }
        })
    }

    /// The pairs and settings back, checked.
    pub fn pairs_and_settings(&self) -> Result<(Vec<Correspondence>, SolveSettings), SolveInputsError> {
        let variant = match self.variant.as_str() {
            "rigid" => Variant::Rigid,
            "similarity" => Variant::Similarity,
            other => {
                return Err(SolveInputsError::Field {
                    field: "variant".into(),
                    message: format!("`{other}` is neither `rigid` nor `similarity`"),
                })
            }
        };
        let mut pairs = Vec::with_capacity(self.frames.len());
        for (i, f) in self.frames.iter().enumerate() {
            let at = |what: &str, e: PoseFault| SolveInputsError::Field {
                field: format!("frames[{i}].{what}"),
                message: format!("(frame {}) {e}", f.frame),
            };
            let features = f
                .features
                .iter()
                .map(|o| Observed {
                    pixel: o.pixel,
                    elevation_mm: o.elevation_mm,
                    target_in_phantom: match o.target_in_phantom {
                        TargetInPhantom::Point(p) => Target::Point(Point3::from(p)),
                        TargetInPhantom::Line { point, direction } => {
                            Target::Line(Point3::from(point), Vector3::from(direction))
                        }
                    },
                })
                .collect();
            pairs.push(Correspondence {
                frame: f.frame,
                features,
                camera_T_marker: f.camera_T_marker.rigid().map_err(|e| at("camera_T_marker", e))?,
                camera_T_phantom: f.camera_T_phantom.rigid().map_err(|e| at("camera_T_phantom", e))?,
            });
        }
        let settings = SolveSettings {
            spacing_mm_per_px: self.spacing_mm_per_px,
            variant,
            cutoffs_mm: self.cutoffs_mm.clone(),
            rule: self.cutoff_rule,
            calibration_cutoff_mm: self.calibration_cutoff_mm,
            min_frames: self.min_frames,
            initial_marker_T_image: match &self.initial_marker_T_image {
                Some(p) => Some(p.rigid().map_err(|e| SolveInputsError::Field {
                    field: "initial_marker_T_image".into(),
                    message: e.to_string(),
                })?),
                None => None,
            },
        };
        Ok((pairs, settings))
    }
}

/// Solves a run's inputs again, as the run did (no truth: nothing is scored).
pub fn solve_again(inputs: &SolveInputs) -> Result<Calibrations, SolveInputsError> {
    let (pairs, settings) = inputs.pairs_and_settings()?;
    solve::calibrate(&pairs, &settings, &inputs.dataset).map_err(|e: RunError| SolveInputsError::Solve(Box::new(e)))
}

/// Why a stored pose is not a rigid transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseFault {
    #[error("rotation {0:?} is not a unit quaternion")]
    NotUnit([f64; 4]),
    #[error("translation {0:?} is not finite")]
    NotFinite([f64; 3]),
}

/// Why a run's solve inputs cannot be read back or solved again.
#[derive(Debug, thiserror::Error)]
pub enum SolveInputsError {
    #[error("{}: {message}", path.display())]
    Read { path: std::path::PathBuf, message: String },
    #[error("field `{field}`: {message}")]
    Field { field: String, message: String },
    #[error("{0}")]
    Yaml(String),
    #[error("{0}")]
    Solve(Box<RunError>),
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}
