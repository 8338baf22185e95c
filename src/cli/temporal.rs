//! `probecal temporal`: the tracker's lag behind the video (PLUS's temporal
//! calibration); 0 written, 1 when the inputs cannot be used or the outputs written.

use std::path::Path;

use super::failure::Failure;

pub fn command(video: &Path, tracker: &Path, out: &Path, force: bool) -> Result<(), Failure> {
    let folder = crate::io::output::OutputFolder::claim(out, "temporal", &[video, tracker], force)?;
    let run = crate::pipeline::tracked::time::temporal::run(video, tracker, "ProbeToTracker", "ReferenceToTracker")
        .map_err(Failure::failed)?;
    crate::report::plus_tools::temporal::write(&run, folder.path()).map_err(Failure::failed)?;
    folder.commit().map_err(Failure::failed)?;
    println!("tracker lag {:.4} s; written to {}", run.tracker_lag_s, out.display());
    Ok(())
}
