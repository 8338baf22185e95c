//! `probecal phantom`: the printable model of a manifest's dome phantom as an
//! STL, and its sheet.

use std::path::Path;

use nalgebra::Point3;
use serde::Serialize;

use crate::synth::{board_seat, printable};

/// The model's sheet, written beside its STL (`<name>.json`): its size, its
/// domes and where the seat holds the board, for checking a print with calipers
/// (upright frame: z up from the bed, mm; x and y centred on the domes).
#[derive(Debug, Serialize)]
pub struct ModelSheet {
    pub experiment: String,
    pub stl: String,
    pub triangles: usize,
    pub shells: usize,
    pub footprint_mm: [f64; 2],
    pub height_mm: f64,
    pub floor_mm: f64,
    pub volume_cm3: f64,
    pub domes: Vec<SheetDome>,
    pub board_seat: SheetSeat,
}

#[derive(Debug, Serialize)]
pub struct SheetDome {
    pub name: String,
    pub centre_mm: [f64; 3],
    pub radius_mm: f64,
}

/// The seat: the mount it holds, where the pattern's origin lies from its fence
/// and ledge, and the front corner where fence, ledge and print plane meet.
#[derive(Debug, Serialize)]
pub struct SheetSeat {
    pub mount_mm: [f64; 2],
    pub mount_thickness_mm: f64,
    pub origin_from_fence_mm: f64,
    pub origin_above_ledge_mm: f64,
    pub front_corner_mm: [f64; 3],
}

pub fn sheet(experiment: &str, model: &printable::PrintableModel, stl: &Path, triangles: usize) -> ModelSheet {
    let mount = model.seat.mount;
    let corner = model.seat.upright_T_phantom * Point3::new(mount.left_x_mm, mount.bottom_y_mm, 0.0);
    let size = model.plate_max_mm - model.plate_min_mm;
    ModelSheet {
        experiment: experiment.to_string(),
        stl: stl
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        triangles,
        shells: model.shells(),
        footprint_mm: [size.x, size.y],
        height_mm: model.top_mm(),
        floor_mm: model.floor_mm(),
        volume_cm3: model.volume_mm3() / 1000.0,
        domes: model
            .domes
            .iter()
            .map(|d| SheetDome {
                name: d.name.clone(),
                centre_mm: d.centre_mm.coords.into(),
                radius_mm: d.radius_mm,
            })
            .collect(),
        board_seat: SheetSeat {
            mount_mm: [mount.right_x_mm - mount.left_x_mm, mount.bottom_y_mm - mount.top_y_mm],
            mount_thickness_mm: board_seat::MOUNT_MM,
            origin_from_fence_mm: -mount.left_x_mm,
            origin_above_ledge_mm: mount.bottom_y_mm,
            front_corner_mm: corner.coords.into(),
        },
    }
}
