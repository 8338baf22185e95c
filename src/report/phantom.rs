//! `probecal phantom`: the printable model of a manifest's dome phantom as an STL.

use std::path::Path;

use crate::detect::board_pose::RigBoards;
use crate::manifest::{DatasetSource, Experiment, Manifest};
use crate::spec::render::RenderSpec;
use crate::synth::printable;

/// A camera experiment and the render spec of its first rendered dataset (the
/// lab its phantom stands in and the sweep over it), or why there is none.
pub fn rendered_lab(path: &Path) -> Result<(Box<Manifest>, RenderSpec), String> {
    let manifest = match Experiment::load(path).map_err(|e| e.to_string())? {
        Experiment::Camera(m) => m,
        Experiment::Tracked(_) => {
            return Err(format!(
                "{}: a tracked experiment has no rendered lab or sweep",
                path.display()
            ))
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
            format!(
                "{}: field `datasets`: no rendered dataset gives the lab the phantom stands in",
                path.display()
            )
        })?;
    Ok((manifest, spec))
}

/// Writes the STL; prints the model's size. Exit code: 0 written, 2 bad input, 1 failed write.
pub fn command(manifest: &Path, stl: &Path) -> u8 {
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
    let triangles = model.triangles();
    let header = format!("probecal phantom of {} (mm)", manifest.experiment);
    if let Err(e) = crate::io::stl::write(stl, &header, &triangles) {
        eprintln!("error: {e}");
        return 1;
    }
    let size = model.plate_max_mm - model.plate_min_mm;
    let top = model
        .domes
        .iter()
        .map(|d| d.centre_mm.z + d.radius_mm)
        .fold(0.0, f64::max);
    println!(
        "written {} ({} triangles): plate {:.1} x {:.1} x {:.1} mm, {} domes, {:.1} mm tall, {:.0} mm³",
        stl.display(),
        triangles.len(),
        size.x,
        size.y,
        size.z,
        model.domes.len(),
        top,
        model.volume_mm3()
    );
    0
}
