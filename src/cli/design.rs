//! `probecal design`: the dome-phantom layouts of the manifest's lab ranked by
//! the Cramér–Rao bound of their calibration; 0 written, 2 bad input, 1 failed.

use std::path::Path;

use super::failure::Failure;

pub fn command(manifest: &Path, out: &Path, force: bool) -> Result<(), Failure> {
    let folder = crate::io::output::OutputFolder::claim(out, "design", &[manifest], force)?;
    let (manifest, spec) = crate::pipeline::run::lab::rendered_lab(manifest).map_err(Failure::bad_input)?;
    let rows = crate::pipeline::run::design::design(&manifest, &spec)
        .map_err(|e| Failure::bad_input(format!("{}: {e}", manifest.path.display())))?;
    let study = crate::pipeline::run::design::study(&manifest, &spec, &rows);
    let md = crate::report::study::design::write(&study, folder.path()).map_err(Failure::failed)?;
    folder.commit().map_err(Failure::failed)?;
    print!("{}", md.lines().take(12).collect::<Vec<_>>().join("\n"));
    println!("\nwritten to {} (design.json, design.md)", out.display());
    Ok(())
}
