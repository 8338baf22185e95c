//! The manifest turned into each stage's settings: the one place where the
//! pipeline reads a manifest for the stages below it.

use crate::detect::arc::ArcSettings;
use crate::detect::ridge::RidgePeak;
use crate::detect::spot::SpotSettings;
use crate::estimate::horn::Variant;
use crate::estimate::sphere_fit::KnownSphere;
use crate::manifest::{CameraSource, EchoPeak, FitRadius, Manifest, SolveVariant};
use crate::pipeline::frames::{Detector, Targets};
use crate::pipeline::solve::SolveSettings;
use crate::spec::phantom::Phantom;
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

/// The arc detector's placement of an echo point on its ridge.
fn echo_peak(manifest: &Manifest) -> RidgePeak {
    match manifest.arc_detection.peak {
        EchoPeak::Column => RidgePeak::Column,
        EchoPeak::Normal => RidgePeak::Normal,
    }
}

/// The B-scan feature detector of the manifest's phantom, and where its features lie.
pub fn detector(manifest: &Manifest) -> (Detector, Targets<'_>) {
    let spacing = manifest.bscan_spacing_mm_per_px;
    match &manifest.phantom {
        Phantom::Hemisphere {
            centre_in_phantom_mm,
            radius_mm,
        } => (
            Detector::Arc(ArcSettings {
                spacing_mm_per_px: spacing,
                radius_mm: [
                    manifest.arc_detection.radius_fraction[0] * radius_mm,
                    manifest.arc_detection.radius_fraction[1] * radius_mm,
                ],
                min_span_deg: manifest.arc_detection.min_span_deg,
                max_rms_px: manifest.arc_detection.max_rms_px,
                min_points: manifest.arc_detection.min_points,
                fixed_radius_mm: (manifest.arc_detection.fit_radius == FitRadius::Known).then_some(*radius_mm),
                peak: echo_peak(manifest),
            }),
            Targets::Point(*centre_in_phantom_mm),
        ),
        Phantom::Point {
            position_in_phantom_mm,
            head_radius_mm,
        } => (
            Detector::PinHead(SpotSettings {
                spacing_mm_per_px: spacing,
                object_radius_mm: *head_radius_mm,
            }),
            Targets::Point(*position_in_phantom_mm),
        ),
        Phantom::Spheres { spheres } => {
            let radii = spheres.iter().map(|s| s.radius_mm);
            let (smallest, largest) = radii.fold((f64::INFINITY, 0.0f64), |(lo, hi), r| (lo.min(r), hi.max(r)));
            (
                Detector::Arcs(
                    ArcSettings {
                        spacing_mm_per_px: spacing,
                        radius_mm: [
                            manifest.arc_detection.radius_fraction[0] * smallest,
                            manifest.arc_detection.radius_fraction[1] * largest,
                        ],
                        min_span_deg: manifest.arc_detection.min_span_deg,
                        max_rms_px: manifest.arc_detection.max_rms_px,
                        min_points: manifest.arc_detection.min_points,
                        // A plane beside a centre cuts a smaller circle: the radius is fitted.
                        fixed_radius_mm: None,
                        peak: echo_peak(manifest),
                    },
                    spheres.len(),
                ),
                Targets::Spheres(spheres),
            )
        }
        Phantom::FourWire {
            wire_diameter_mm,
            wires,
        } => (
            Detector::WireDots(SpotSettings {
                spacing_mm_per_px: spacing,
                object_radius_mm: wire_diameter_mm / 2.0,
            }),
            Targets::Wires(wires),
        ),
    }
}

/// Horn's variant: rigid, or with a scale on the pixel spacing.
pub fn variant(manifest: &Manifest) -> Variant {
    match manifest.solve_variant {
        SolveVariant::Rigid => Variant::Rigid,
        SolveVariant::Similarity => Variant::Similarity,
    }
}

/// A dome phantom's spheres (a hemisphere is one); `None` for the others.
pub fn known_spheres(phantom: &Phantom) -> Option<Vec<KnownSphere>> {
    match phantom {
        Phantom::Spheres { spheres } => Some(
            spheres
                .iter()
                .map(|s| KnownSphere {
                    centre_in_phantom_mm: nalgebra::Point3::from(s.centre_in_phantom_mm),
                    radius_mm: s.radius_mm,
                })
                .collect(),
        ),
        Phantom::Hemisphere {
            centre_in_phantom_mm,
            radius_mm,
        } => Some(vec![KnownSphere {
            centre_in_phantom_mm: nalgebra::Point3::from(*centre_in_phantom_mm),
            radius_mm: *radius_mm,
        }]),
        Phantom::Point { .. } | Phantom::FourWire { .. } => None,
    }
}

/// The radius of the manifest's sphere, for the sphere fit (hemisphere phantoms).
pub fn sphere_radius_mm(manifest: &Manifest) -> Option<f64> {
    match &manifest.phantom {
        Phantom::Hemisphere { radius_mm, .. } => Some(*radius_mm),
        _ => None,
    }
}

/// How the manifest's pairs are solved.
pub fn solve(manifest: &Manifest) -> SolveSettings {
    SolveSettings {
        spacing_mm_per_px: manifest.bscan_spacing_mm_per_px,
        variant: variant(manifest),
        cutoffs_mm: manifest.thresholds.bre_cutoffs_mm.clone(),
        rule: manifest.thresholds.cutoff_rule,
        calibration_cutoff_mm: manifest.thresholds.calibration_cutoff_mm,
        min_frames: manifest.thresholds.min_frames,
        initial_marker_T_image: manifest.initial_marker_T_image,
    }
}
