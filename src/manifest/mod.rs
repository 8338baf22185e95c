//! Experiment manifests: YAML in, a validated [`Manifest`] out.
//!
//! Parsing happens in two steps. The `raw` structs mirror the YAML exactly and
//! refuse unknown keys; [`Manifest::load`] then checks what serde cannot (units,
//! positivity, ordering, files that must exist) and resolves paths relative to
//! the manifest's folder. Every error names the file, the dotted field path and
//! the line, and nothing is run before the whole manifest has passed.

mod checker;
pub mod init;
pub mod locate;
pub mod raw;
mod realism;
mod rig_check;
mod spheres;
pub mod tracked;
mod tracked_raw;
mod validate;

pub(crate) use checker::{deserialize_located, sha256_hex, Checker};
pub use checker::{name_fault, MAX_NAME_LEN, RESERVED_NAMES};
use validate::validate;

use std::fmt;
use std::path::{Path, PathBuf};

pub use raw::{ArcDetection, EchoPeak, FitRadius, Gates, Regression, SolveVariant, TrackerCsv};

use crate::evaluate::CutoffRule;
use crate::spec::phantom::Phantom;
use crate::spec::render::RenderSpec;
use crate::spec::rig::{CameraCalibrationBoard, Rig};

/// A manifest problem, located.
#[derive(Debug, Clone, PartialEq)]
pub struct ManifestError {
    pub file: PathBuf,
    /// Dotted field path, e.g. `phantom.hemisphere.radius_mm` (empty for the whole file).
    pub field: String,
    /// 1-based line, when the field (or its parent) could be found.
    pub line: Option<usize>,
    pub message: String,
}

impl fmt::Display for ManifestError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": field `{}`", self.field)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ManifestError {}

/// All problems found in one manifest (validation does not stop at the first).
#[derive(Debug, Clone, PartialEq)]
pub struct ManifestErrors(pub Vec<ManifestError>);

impl fmt::Display for ManifestErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for ManifestErrors {}

/// Where the poses come from: a camera (and its intrinsics), or a tracker.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraSource {
    /// An OpenCV FileStorage YAML/XML file (`camera_matrix`, `distortion_coefficients`).
    IntrinsicsFile(PathBuf),
    /// Calibrate from board images: a folder, or `None` for the dataset's own
    /// `camera_calibration/` folder.
    Calibrate {
        images: Option<PathBuf>,
        board: CameraCalibrationBoard,
    },
    /// No camera: each dataset folder has a CSV of tracker poses (`poses.tracker_csv`).
    TrackerCsv(TrackerCsv),
}

/// Where a dataset's frames come from.
#[derive(Debug, Clone, PartialEq)]
pub enum DatasetSource {
    Render(Box<RenderSpec>),
    Folder(PathBuf),
}

#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    pub name: String,
    pub source: DatasetSource,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Thresholds {
    /// Descending, the first one usually infinity (all frames).
    pub bre_cutoffs_mm: Vec<f64>,
    pub cutoff_rule: CutoffRule,
    /// The cut-off whose re-solved calibration is the run's result.
    pub calibration_cutoff_mm: f64,
    pub min_frames: usize,
    pub gates: Gates,
    pub regression: Regression,
}

/// A validated experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct Manifest {
    pub path: PathBuf,
    /// SHA-256 of the manifest text as read.
    pub sha256: String,
    pub text: String,
    pub experiment: String,
    pub description: String,
    pub phantom: Phantom,
    pub rig: Rig,
    pub camera: CameraSource,
    pub bscan_spacing_mm_per_px: [f64; 2],
    pub arc_detection: ArcDetection,
    pub thresholds: Thresholds,
    pub solve_variant: SolveVariant,
    /// A rough `marker_T_image` that starts the wire fit (`solve.initial_marker_T_image`).
    pub initial_marker_T_image: Option<crate::core::geometry::Rigid>,
    pub robust: crate::estimate::robust::RobustSettings,
    pub sphere_fit: raw::SphereFitOptions,
    pub validation: raw::ValidationOptions,
    pub datasets: Vec<Dataset>,
}

/// A manifest of either kind: camera-tracked (rendered or recorded photos and
/// B-scans) or tracker-sequence (`tracking:` names a PLUS sequence file).
#[derive(Debug, Clone, PartialEq)]
pub enum Experiment {
    Camera(Box<Manifest>),
    Tracked(Box<tracked::TrackedManifest>),
}

/// A manifest's text, bounded in size and depth before anything parses it.
fn read_manifest(path: &Path) -> Result<String, ManifestErrors> {
    crate::io::yaml_limits::read(path, "a manifest").map_err(|e| {
        ManifestErrors(vec![ManifestError {
            file: path.to_path_buf(),
            field: String::new(),
            line: e.line,
            message: match e.line {
                Some(_) => e.message,
                None => format!("cannot read the manifest: {}", e.message),
            },
        }])
    })
}

impl Experiment {
    /// Reads a manifest, telling the kinds apart by a top-level `tracking` key.
    pub fn load(path: &Path) -> Result<Experiment, ManifestErrors> {
        let text = read_manifest(path)?;
        // A manifest YAML cannot read (a key given twice, bad syntax) is told
        // apart by its top-level `tracking:` line, so that its own reader
        // gives the error.
        let is_tracked = match serde_yaml::from_str::<serde_yaml::Value>(&text) {
            Ok(v) => v.as_mapping().is_some_and(|m| m.contains_key("tracking")),
            Err(_) => text.lines().any(|l| l.trim_end().starts_with("tracking:")),
        };
        if is_tracked {
            tracked::TrackedManifest::from_text(path, &text).map(|m| Experiment::Tracked(Box::new(m)))
        } else {
            Manifest::from_text(path, &text).map(|m| Experiment::Camera(Box::new(m)))
        }
    }

    pub fn experiment(&self) -> &str {
        match self {
            Experiment::Camera(m) => &m.experiment,
            Experiment::Tracked(m) => &m.experiment,
        }
    }

    pub fn path(&self) -> &Path {
        match self {
            Experiment::Camera(m) => &m.path,
            Experiment::Tracked(m) => &m.path,
        }
    }

    pub fn text(&self) -> &str {
        match self {
            Experiment::Camera(m) => &m.text,
            Experiment::Tracked(m) => &m.text,
        }
    }
}

impl Manifest {
    /// Reads, parses and validates a manifest file.
    pub fn load(path: &Path) -> Result<Manifest, ManifestErrors> {
        let text = read_manifest(path)?;
        Manifest::from_text(path, &text)
    }

    /// Parses and validates manifest text; `path` names it in errors and anchors relative paths.
    pub fn from_text(path: &Path, text: &str) -> Result<Manifest, ManifestErrors> {
        let raw: raw::RawManifest = deserialize_located(path, text)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut c = Checker {
            file: path,
            text,
            errors: Vec::new(),
        };
        let manifest = validate(&mut c, &base, raw, path, text);
        if c.errors.is_empty() {
            Ok(manifest)
        } else {
            Err(ManifestErrors(c.errors))
        }
    }
}

#[cfg(test)]
mod tests;
