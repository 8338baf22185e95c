//! `probecal reconstruct`'s outcome: what went into the volume (the sequence,
//! the device set's settings, `ImageToProbe` and the lag with where each came
//! from), what came out (the grid, the frames used and skipped with their
//! reasons, the voxels filled, the accumulator's saturated cells, the wires'
//! figures), and, with `--compare`, how it agrees with a reference volume.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::evaluate::wire_profile::WireFigures;
use crate::io::fs::display_path;
use crate::io::plus::volume_config::VolumeSettings;
use crate::io::volume_file::VolumeHeader;
use crate::pipeline::reconstruct::{AnyVolume, Reconstruction};
use crate::reconstruct::poses::SkippedFrame;

/// `summary.json`'s `kind`, which marks a folder as a reconstruction's.
pub const KIND: &str = "reconstruction";

/// `summary.json` of `probecal reconstruct` (and of a tracked run's `reconstruction/`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReconstructionSummary {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    /// Always [`KIND`].
    pub kind: String,
    pub sequence: String,
    pub config: String,
    /// Where `ImageToProbe` came from: the device set or a run folder.
    pub image_to_probe_source: String,
    /// Row-major, image pixels (mm after the pixel spacing) to the probe's frame.
    pub image_to_probe: Option<[[f64; 4]; 4]>,
    /// The tracker's lag applied (s) and where it came from.
    pub tracker_lag_s: f64,
    pub tracker_lag_source: String,
    pub settings: VolumeSettings,
    pub volume: VolumeGrid,
    pub frames: VolumeFrames,
    pub pixels_inserted: u64,
    /// Accumulator cells that reached their ceiling (PLUS's 16-bit sums).
    pub accumulator_saturated: u64,
    pub voxels_filled: VoxelsFilled,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wires: Option<VolumeWires>,
    /// Only where the run kept its times.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threads: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_s: Option<BTreeMap<String, f64>>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VolumeGrid {
    pub file: String,
    pub dims: [usize; 3],
    pub origin_mm: [f64; 3],
    pub spacing_mm: [f64; 3],
    pub element_type: String,
    pub voxels: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VolumeFrames {
    pub total: usize,
    pub used: usize,
    pub used_indices: Vec<usize>,
    /// Each frame left out, with its reason.
    pub skipped: Vec<SkippedFrame>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VoxelsFilled {
    pub before_hole_filling: u64,
    pub after_hole_filling: u64,
    /// In the settings' order of hole-filling elements.
    pub holes_filled_by_element: Vec<u64>,
    pub holes_left: u64,
}

/// The phantom's wires measured in the volume.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VolumeWires {
    pub device_set: Option<String>,
    pub figures: WireFigures,
}

impl ReconstructionSummary {
    pub fn of(r: &Reconstruction) -> ReconstructionSummary {
        let g = r.volume.grid();
        ReconstructionSummary {
            schema_version: crate::results::SCHEMA_VERSION,
            kind: KIND.into(),
            sequence: display_path(&r.inputs.sequence),
            config: display_path(&r.inputs.config),
            image_to_probe_source: r.image_to_probe_source.clone(),
            image_to_probe: r
                .image_to_probe
                .map(|m| std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))),
            tracker_lag_s: r.tracker_lag_s,
            tracker_lag_source: r.tracker_lag_source.clone(),
            settings: r.settings.clone(),
            volume: VolumeGrid {
                file: "volume.mha".into(),
                dims: g.dims,
                origin_mm: g.origin_mm,
                spacing_mm: g.spacing_mm,
                element_type: r.volume.element_type().into(),
                voxels: g.voxels(),
            },
            frames: VolumeFrames {
                total: r.frames_total,
                used: r.frames_used.len(),
                used_indices: r.frames_used.clone(),
                skipped: r.skipped.clone(),
            },
            pixels_inserted: r.pixels_inserted,
            accumulator_saturated: r.accumulator_saturated,
            voxels_filled: VoxelsFilled {
                before_hole_filling: r.voxels_filled_before_holes,
                after_hole_filling: r.voxels_filled_after_holes,
                holes_filled_by_element: r.holes.filled_by_element.clone(),
                holes_left: r.holes.holes_after,
            },
            wires: r.wires.clone().map(|figures| VolumeWires {
                device_set: r.inputs.wires.as_deref().map(display_path),
                figures,
            }),
            threads: (!r.timings.is_empty()).then_some(r.threads),
            time_s: (!r.timings.is_empty()).then(|| r.timings.iter().cloned().collect()),
        }
    }
}

/// Whether a `summary.json` is a reconstruction's (`kind: reconstruction`), not a
/// calibration run's.
pub fn is_reconstruction(summary: &Path) -> bool {
    super::kind_of(summary).as_deref() == Some(KIND)
}

/// The header a volume is written with.
pub fn header(volume: &AnyVolume) -> VolumeHeader {
    let g = volume.grid();
    VolumeHeader {
        dims: g.dims,
        origin_mm: g.origin_mm,
        spacing_mm: g.spacing_mm,
        element_type: volume.element_type().to_string(),
    }
}

/// `agreement.json`: how a volume agrees with a reference of the same inputs
/// (PLUS's, say).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Agreement {
    pub reference: String,
    pub dims: OursAndReference<[usize; 3]>,
    pub element_type: OursAndReference<String>,
    /// The largest difference of the two origins along an axis (mm).
    pub offset_max_difference_mm: f64,
    pub spacing_equal: bool,
    /// The reference file is byte for byte the volume written.
    pub identical_file: bool,
    /// Voxel by voxel, where both are 8-bit volumes on the same grid.
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub voxels: Option<VoxelAgreement>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OursAndReference<T> {
    pub ours: T,
    pub reference: T,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VoxelAgreement {
    pub voxels: usize,
    pub voxels_equal: u64,
    pub nonzero_in_either: u64,
    /// Of the voxels nonzero in either, the fraction within one grey level.
    pub within_one_grey_level: f64,
    /// Dice coefficient of the two volumes' nonzero voxels.
    pub dice_nonzero: f64,
}

impl Agreement {
    /// How `r` (written as the bytes `written`) agrees with the reference at `path`.
    pub fn of(r: &Reconstruction, written: &[u8], path: &Path, reference: &(VolumeHeader, Vec<u8>)) -> Agreement {
        let (theirs, their_voxels) = reference;
        let ours = header(&r.volume);
        let same_grid = ours.dims == theirs.dims && ours.element_type == theirs.element_type;
        let offset_mm = (0..3)
            .map(|a| (ours.origin_mm[a] - theirs.origin_mm[a]).abs())
            .fold(0.0, f64::max);
        let voxels =
            (same_grid && ours.element_type == "MET_UCHAR").then(|| voxel_agreement(&r.volume.bytes(), their_voxels));
        Agreement {
            reference: display_path(path),
            dims: OursAndReference {
                ours: ours.dims,
                reference: theirs.dims,
            },
            element_type: OursAndReference {
                ours: ours.element_type.clone(),
                reference: theirs.element_type.clone(),
            },
            offset_max_difference_mm: offset_mm,
            spacing_equal: ours.spacing_mm == theirs.spacing_mm,
            identical_file: crate::io::fs::read_capped(path, written.len() as u64)
                .map(|b| b == written)
                .unwrap_or(false),
            voxels,
        }
    }
}

fn voxel_agreement(mine: &[u8], theirs: &[u8]) -> VoxelAgreement {
    let (mut union, mut close, mut a, mut b, mut both, mut equal) = (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
    for (&o, &t) in mine.iter().zip(theirs) {
        a += u64::from(o > 0);
        b += u64::from(t > 0);
        both += u64::from(o > 0 && t > 0);
        equal += u64::from(o == t);
        if o > 0 || t > 0 {
            union += 1;
            close += u64::from(o.abs_diff(t) <= 1);
        }
    }
    VoxelAgreement {
        voxels: mine.len(),
        voxels_equal: equal,
        nonzero_in_either: union,
        within_one_grey_level: close as f64 / union.max(1) as f64,
        dice_nonzero: 2.0 * both as f64 / (a + b).max(1) as f64,
    }
}
