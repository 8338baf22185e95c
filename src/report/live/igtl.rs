//! `probecal live --igtl`: the session's files. `summary.json` (how the
//! acquisition ended, every message's fate, the latency percentiles, the
//! calibration sent back), `live.csv` (per frame, as the file replay writes it),
//! `received.igs.mha` (written by the session) and, when the batch calibration
//! succeeded, its usual run folder in `calibration/`.

use std::path::Path;

use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::live::igtl::{StreamRun, StreamSettings};
use crate::report::error::OutputError;
use crate::results::live::IgtlSummary;

/// Writes the session's files into `folder` (the staged output, which already
/// holds `received.igs.mha`), with the batch calibration's page when there is
/// one (`after`: what was measured after it); the summary.
pub fn write(
    run: &StreamRun,
    settings: &StreamSettings,
    labels: &TrackedLabels,
    after: Option<&crate::pipeline::tracked::resolution::TrackedAfter>,
    folder: &Path,
) -> Result<IgtlSummary, OutputError> {
    let s = IgtlSummary::of(run, settings);
    crate::io::fs::write_atomic(
        &folder.join("summary.json"),
        crate::results::summary::to_text(&s)?.as_bytes(),
    )?;
    crate::io::fs::write_atomic(
        &folder.join("live.csv"),
        crate::report::live::frames_csv(&run.frames).as_bytes(),
    )?;
    if let (Ok(batch), Some(after)) = (&run.final_run, after) {
        crate::report::tracked::write(batch, after, labels, None, &folder.join("calibration"))?;
    }
    Ok(s)
}
