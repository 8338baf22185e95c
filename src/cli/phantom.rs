//! `probecal phantom`: the printable model of a manifest's dome phantom as an
//! STL, with its sheet; 0 written, 2 bad input, 1 failed write.

use std::path::Path;

use super::failure::Failure;
use crate::detect::board_pose::RigBoards;
use crate::pipeline::run::lab::rendered_lab;
use crate::synth::printable;

/// Writes the STL and its sheet (`<name>.json` beside it); prints the model's
/// size. Exit code: 0 written, 2 bad input, 1 failed write.
pub fn command(manifest: &Path, stl: &Path, force: bool) -> Result<(), Failure> {
    let sheet_path = stl.with_extension("json");
    if sheet_path == stl {
        return Err(Failure::bad_input(format!(
            "--stl {}: the model's sheet would overwrite it; name the STL *.stl",
            stl.display()
        )));
    }
    for written in [stl, sheet_path.as_path()] {
        if let Some(why) = crate::io::output::file_refusal(written, "phantom", &[manifest], force) {
            return Err(Failure::bad_input(format!("{}: {why}", written.display())));
        }
    }
    let (manifest, render) = rendered_lab(manifest).map_err(Failure::bad_input)?;
    let at = |e: &dyn std::fmt::Display| Failure::bad_input(format!("{}: {e}", manifest.path.display()));
    let rig = RigBoards::from_rig(&manifest.rig).map_err(|e| at(&format!("field `rig`: {e}")))?;
    let model = printable::model(&manifest.phantom, &rig.phantom, &render).map_err(|e| at(&e))?;
    let triangles = model.triangles().map_err(|e| at(&e))?;
    let header = format!("probecal phantom of {} (mm)", manifest.experiment);
    crate::io::stl::write(stl, &header, &triangles).map_err(Failure::failed)?;
    let sheet = crate::report::thesis::phantom::sheet(&manifest.experiment, &model, stl, triangles.len());
    let json = serde_json::to_string_pretty(&sheet)
        .map_err(|e| Failure::failed(format!("{}: {e}", sheet_path.display())))?
        + "\n";
    crate::io::fs::write_atomic(&sheet_path, json.as_bytes()).map_err(Failure::failed)?;
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
    Ok(())
}
