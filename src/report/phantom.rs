//! `probecal phantom`: the printable model of a manifest's dome phantom as an STL.

use std::path::Path;

use crate::detect::board_pose::RigBoards;
use crate::manifest::{DatasetSource, Experiment};
use crate::synth::printable;

/// Writes the STL; prints the model's size. Exit code: 0 written, 2 bad input, 1 failed write.
pub fn command(manifest: &Path, stl: &Path) -> u8 {
    let manifest = match Experiment::load(manifest) {
        Ok(Experiment::Camera(m)) => m,
        Ok(Experiment::Tracked(_)) => {
            eprintln!(
                "error: {}: a tracked experiment has no rendered lab to place its phantom in",
                manifest.display()
            );
            return 2;
        }
        Err(e) => {
            eprintln!("error: {e}");
            return 2;
        }
    };
    let Some(render) = manifest.datasets.iter().find_map(|d| match &d.source {
        DatasetSource::Render(spec) => Some(spec),
        DatasetSource::Folder(_) => None,
    }) else {
        eprintln!(
            "error: {}: field `datasets`: no rendered dataset gives the lab the phantom stands in",
            manifest.path.display()
        );
        return 2;
    };
    let rig = match RigBoards::from_rig(&manifest.rig) {
        Ok(rig) => rig,
        Err(e) => {
            eprintln!("error: {}: field `rig`: {e}", manifest.path.display());
            return 2;
        }
    };
    let model = match printable::model(&manifest.phantom, &rig.phantom, render) {
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
