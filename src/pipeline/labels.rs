//! What a run's summary, pages and provenance say of its manifest, read from
//! it once: the layers above (`results`, `report`) take these labels and never
//! read a manifest themselves.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::manifest::tracked::TrackedManifest;
use crate::manifest::{CameraSource, DatasetSource, Manifest, Regression, SolveVariant};
use crate::spec::nwire::NWire;
use crate::spec::phantom::Phantom;
use crate::spec::render::SessionOccluders;
use crate::spec::rig::Rig;

/// A camera-rig (or tracker-CSV) experiment's labels.
#[derive(Debug, Clone, PartialEq)]
pub struct RunLabels {
    pub manifest_path: PathBuf,
    pub manifest_sha256: String,
    pub experiment: String,
    pub description: String,
    pub phantom: Phantom,
    /// Where the poses come from, in full: the rig, or the tracker's file and
    /// the two transforms read from it.
    pub pose_source: String,
    /// The same in short (a comparison's column head).
    pub pose_source_short: String,
    pub solve_variant: SolveVariant,
    /// The estimator the truth gates check (`thresholds.gates.method`).
    pub gated_method: Option<String>,
    pub regression: Regression,
    /// The stated occluders of each rendered dataset that has them, by name.
    pub occluders: BTreeMap<String, SessionOccluders>,
}

impl RunLabels {
    pub fn of(m: &Manifest) -> RunLabels {
        let (pose_source, pose_source_short) = match &m.camera {
            CameraSource::TrackerCsv(t) => (
                format!(
                    "tracker poses from {} ({}, {})",
                    t.file, t.probe_transform, t.reference_transform
                ),
                format!("tracker poses from {}", t.file),
            ),
            _ => (rig_label(&m.rig), rig_label(&m.rig)),
        };
        RunLabels {
            manifest_path: m.path.clone(),
            manifest_sha256: m.sha256.clone(),
            experiment: m.experiment.clone(),
            description: m.description.clone(),
            phantom: m.phantom.clone(),
            pose_source,
            pose_source_short,
            solve_variant: m.solve_variant,
            gated_method: m.thresholds.gates.method.clone(),
            regression: m.thresholds.regression.clone(),
            occluders: m
                .datasets
                .iter()
                .filter_map(|d| match &d.source {
                    DatasetSource::Render(r) => r.occluders.clone().map(|o| (d.name.clone(), o)),
                    DatasetSource::Folder(_) => None,
                })
                .collect(),
        }
    }
}

/// The probe's rig in words.
pub fn rig_label(rig: &Rig) -> String {
    match rig {
        Rig::Checkerboard { probe_board, .. } => format!(
            "checkerboard {}x{} squares of {} mm",
            probe_board.inner_corners[0] + 1,
            probe_board.inner_corners[1] + 1,
            probe_board.square_mm
        ),
        Rig::Aruco {
            dictionary,
            probe_board,
            ..
        } => format!(
            "ArUco {} {}x{} markers of {} mm",
            dictionary, probe_board.markers[0], probe_board.markers[1], probe_board.marker_mm
        ),
        Rig::Charuco { probe_board, .. } => format!(
            "ChArUco {} {}x{} squares of {} mm",
            probe_board.dictionary, probe_board.squares[0], probe_board.squares[1], probe_board.square_mm
        ),
    }
}

/// A tracked (PLUS recording) experiment's labels.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedLabels {
    pub manifest_path: PathBuf,
    pub manifest_sha256: String,
    pub experiment: String,
    pub description: String,
    pub dataset: String,
    /// The PLUS device set the phantom came from, if any.
    pub plus_config: Option<PathBuf>,
    pub calibration_sequence: PathBuf,
    pub validation_sequence: Option<PathBuf>,
    /// The phantom's N-wires, in the phantom's frame (mm).
    pub nwires: Vec<NWire>,
    /// Every file the run reads.
    pub input_files: Vec<PathBuf>,
    /// `probecal check`'s tolerances: PRE3D (mm) and frames rejected.
    pub regression_pre3d_mm: f64,
    pub regression_frames_rejected: f64,
}

impl TrackedLabels {
    pub fn of(m: &TrackedManifest) -> TrackedLabels {
        TrackedLabels {
            manifest_path: m.path.clone(),
            manifest_sha256: m.sha256.clone(),
            experiment: m.experiment.clone(),
            description: m.description.clone(),
            dataset: m.dataset.clone(),
            plus_config: m.plus_config.clone(),
            calibration_sequence: m.calibration_sequence.clone(),
            validation_sequence: m.validation_sequence.clone(),
            nwires: m.nwires.clone(),
            input_files: m.input_files(),
            regression_pre3d_mm: m.regression.pre3d_mm,
            regression_frames_rejected: m.regression.frames_rejected,
        }
    }
}
