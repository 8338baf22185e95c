//! The manifest turned into each stage's settings: the one place where the
//! pipeline reads a manifest for the stages below it.

use crate::manifest::{CameraSource, Manifest};
use crate::synth::Lab;

/// The lab a camera experiment's datasets are rendered in.
pub fn lab(manifest: &Manifest) -> Lab<'_> {
    Lab {
        rig: &manifest.rig,
        phantom: &manifest.phantom,
        spacing_mm_per_px: manifest.bscan_spacing_mm_per_px,
        calibration_board: match &manifest.camera {
            CameraSource::Calibrate { board, .. } => Some(board),
            CameraSource::IntrinsicsFile(_) | CameraSource::TrackerCsv(_) => None,
        },
        described_in: &manifest.path,
    }
}
