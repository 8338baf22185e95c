//! `probecal phantom`: the printable model of a manifest's dome phantom as an STL.

use std::path::Path;

use crate::detect::board_pose::RigBoards;
use crate::manifest::{DatasetSource, Experiment, Manifest};
use nalgebra::Point3;
use serde::Serialize;

use crate::report::error::ReadError;
use crate::spec::render::RenderSpec;
use crate::synth::{board_seat, printable};

/// A camera experiment and the render spec of its first rendered dataset (the
/// lab its phantom stands in and the sweep over it), or why there is none.
pub fn rendered_lab(path: &Path) -> Result<(Box<Manifest>, RenderSpec), LabError> {
    let manifest = match Experiment::load(path)? {
        Experiment::Camera(m) => m,
        Experiment::Tracked(_) => {
            return Err(LabError::Missing(ReadError::new(
                path,
                "a tracked experiment has no rendered lab or sweep",
            )))
        }
    };
    let spec = manifest
        .datasets
        .iter()
        .find_map(|d| match &d.source {
            DatasetSource::Render(spec) => Some(spec.as_ref().clone()),
            DatasetSource::Folder(_) => None,
        })
        .ok_or_else(|| {
            LabError::Missing(ReadError::new(
                path,
                "field `datasets`: no rendered dataset gives the lab the phantom stands in",
            ))
        })?;
    Ok((manifest, spec))
}

/// Why a manifest gives no rendered lab.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    #[error("{0}")]
    Manifest(#[from] crate::manifest::ManifestErrors),
    #[error("{0}")]
    Missing(ReadError),
}

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

fn sheet(manifest: &Manifest, model: &printable::PrintableModel, stl: &Path, triangles: usize) -> ModelSheet {
    let mount = model.seat.mount;
    let corner = model.seat.upright_T_phantom * Point3::new(mount.left_x_mm, mount.bottom_y_mm, 0.0);
    let size = model.plate_max_mm - model.plate_min_mm;
    ModelSheet {
        experiment: manifest.experiment.clone(),
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

/// Writes the STL and its sheet (`<name>.json` beside it); prints the model's
/// size. Exit code: 0 written, 2 bad input, 1 failed write.
pub fn command(manifest: &Path, stl: &Path) -> u8 {
    let sheet_path = stl.with_extension("json");
    if sheet_path == stl {
        eprintln!(
            "error: --stl {}: the model's sheet would overwrite it; name the STL *.stl",
            stl.display()
        );
        return 2;
    }
    let (manifest, render) = match rendered_lab(manifest) {
        Ok(found) => found,
        Err(e) => {
            eprintln!("error: {e}");
            return 2;
        }
    };
    let rig = match RigBoards::from_rig(&manifest.rig) {
        Ok(rig) => rig,
        Err(e) => {
            eprintln!("error: {}: field `rig`: {e}", manifest.path.display());
            return 2;
        }
    };
    let model = match printable::model(&manifest.phantom, &rig.phantom, &render) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {}: {e}", manifest.path.display());
            return 2;
        }
    };
    let triangles = match model.triangles() {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: {e}", manifest.path.display());
            return 2;
        }
    };
    let header = format!("probecal phantom of {} (mm)", manifest.experiment);
    if let Err(e) = crate::io::stl::write(stl, &header, &triangles) {
        eprintln!("error: {e}");
        return 1;
    }
    let sheet = sheet(&manifest, &model, stl, triangles.len());
    let json = match serde_json::to_string_pretty(&sheet) {
        Ok(text) => text + "\n",
        Err(e) => {
            eprintln!("error: {}: {e}", sheet_path.display());
            return 1;
        }
    };
    if let Err(e) = crate::io::fs::write_atomic(&sheet_path, json.as_bytes()) {
        eprintln!("error: {e}");
        return 1;
    }
    let size = model.plate_max_mm - model.plate_min_mm;
    println!(
        "written {} and its sheet ({} triangles, {} shells): {:.1} x {:.1} mm on the bed, {:.1} mm tall; {} domes over a floor {:.1} mm up, the board's seat; {:.0} mm³",
        stl.display(),
        triangles.len(),
        model.shells(),
        size.x,
        size.y,
        model.top_mm(),
        model.domes.len(),
        model.floor_mm(),
        model.volume_mm3()
    );
    0
}
