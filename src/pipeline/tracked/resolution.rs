//! What a tracked run's validation score can tell: how much it moves with the
//! calibration frames fitted (a block bootstrap of the calibration sweep, each
//! refit scored on the same validation dots and poses), the lowest score the
//! chosen model reaches on those frames at all (fitted to the validation frames
//! themselves: a floor, never a result and never a choice), and whether the
//! validation sweep holds the probe at the calibration sweep's tilts.
//!
//! Runs after the calibration is chosen and fitted; nothing here feeds back
//! into it.

use nalgebra::{Matrix4, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::stats::{best_95, MeanSd};
use crate::estimate::image_to_probe::Fit;
use crate::estimate::model_selection;
use crate::evaluate::block_bootstrap::{self, BlockBootstrap, ScoreSpread};
use crate::evaluate::pose_coverage::{self, PoseCoverage};
use crate::pipeline::tracked::{self, fit_settings, Role, TrackedFrame, TrackedInputs, TrackedRun};
use crate::spec::nwire::NWire;

/// The bootstrap: blocks of 10 frames (under a second of a sweep at PLUS's
/// usual 10–30 frames/s, longer than the few frames a hand's motion keeps
/// alike), 200 resamples, a fixed seed.
pub const BOOTSTRAP: BlockBootstrap = BlockBootstrap {
    block_frames: 10,
    resamples: 200,
    seed: 0x5EED_B007,
};

/// What a tracked run adds once its calibration is fitted, never feeding back
/// into it: how far the validation score can tell calibrations apart, and the
/// sweep the manifest asks to reconstruct with the calibration.
#[derive(Debug, Clone, Default)]
pub struct TrackedAfter {
    pub resolution: ValidationResolution,
    /// The manifest's gates on the run.
    pub gates: Vec<crate::pipeline::record::GateResult>,
    pub volume: Option<crate::pipeline::reconstruct::Reconstruction>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ValidationResolution {
    /// Validation PRE3D (best-95 % mean, mm) of the chosen model refitted on
    /// block-bootstrap resamples of the calibration frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bootstrap_pre3d_mm: Option<ScoreSpread>,
    /// The chosen model fitted to the validation frames and scored on them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub own_fit_pre3d_mm: Option<MeanSd>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_coverage: Option<PoseCoverage>,
}

/// Validation PRE3D of `fit` on `run`'s validation frames (best-95 % mean and SD).
fn validation_pre3d(run: &TrackedRun, inputs: &TrackedInputs, fit: &Fit) -> Option<MeanSd> {
    let errors: Vec<f64> = used(&run.frames, Role::Validation)
        .flat_map(|f| {
            tracked::pre3d(
                f,
                &inputs.nwires,
                |pixel| fit.image_to_probe.apply(pixel),
                &fit.phantom_correction,
            )
        })
        .collect();
    best_95(&errors)
}

fn used(frames: &[TrackedFrame], role: Role) -> impl Iterator<Item = &TrackedFrame> {
    frames.iter().filter(move |f| f.role == role && f.rejected.is_none())
}

/// The phantom's wire direction in the image frame of each used frame of `role`.
pub fn wires_in_image(run: &TrackedRun, nwires: &[NWire], role: Role) -> Vec<Vector3<f64>> {
    let Some(wire) = nwires.first().map(|n| n.wires[0].direction()) else {
        return Vec::new();
    };
    let image_R_marker = run.fit.image_to_probe.marker_T_image.rotation.inverse();
    used(&run.frames, role)
        .filter_map(|f| f.marker_T_phantom)
        .map(|marker_T_phantom: Matrix4<f64>| {
            image_R_marker * (marker_T_phantom.fixed_view::<3, 3>(0, 0) * wire).normalize()
        })
        .collect()
}

/// The run's resolution; everything `None` without validation frames.
/// What is measured after a calibration of frames received live (no volume):
/// the validation score's resolution, with the received file as the
/// calibration sequence, and the manifest's gates.
pub fn after_received(
    run: &TrackedRun,
    manifest: &crate::manifest::tracked::TrackedManifest,
    received: &std::path::Path,
) -> TrackedAfter {
    let mut inputs = TrackedInputs::from_manifest(manifest);
    inputs.calibration_sequence = received.to_path_buf();
    TrackedAfter {
        resolution: evaluate(run, &inputs),
        gates: tracked::gates(run, manifest),
        volume: None,
    }
}

pub fn evaluate(run: &TrackedRun, inputs: &TrackedInputs) -> ValidationResolution {
    if used(&run.frames, Role::Validation).next().is_none() {
        return ValidationResolution::default();
    }
    let candidate = run.selection.chosen();
    let settings = fit_settings(inputs);
    let calibration = tracked::usable_constraints(&run.frames, &inputs.nwires, Role::Calibration);
    let bootstrap_pre3d_mm = block_bootstrap::spread(&calibration, &BOOTSTRAP, |picked| {
        let trained = model_selection::fit(picked.iter().copied(), candidate, settings).ok()?;
        validation_pre3d(run, inputs, &trained.fit).map(|s| s.mean)
    });
    let validation = tracked::usable_constraints(&run.frames, &inputs.nwires, Role::Validation);
    let own_fit_pre3d_mm = model_selection::fit(validation.iter(), candidate, settings)
        .ok()
        .and_then(|trained| validation_pre3d(run, inputs, &trained.fit));
    ValidationResolution {
        bootstrap_pre3d_mm,
        own_fit_pre3d_mm,
        pose_coverage: pose_coverage::coverage(
            &wires_in_image(run, &inputs.nwires, Role::Calibration),
            &wires_in_image(run, &inputs.nwires, Role::Validation),
        ),
    }
}
