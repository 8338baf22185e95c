//! A calibration named on the command line (`reconstruct --calibration`): a
//! probecal run's folder, at any level of a `run --out` folder, read through
//! the typed summary ([`RunSummary`]), or a PLUS calibration result (.xml).

use std::path::{Path, PathBuf};

use nalgebra::Matrix4;

use super::summary::RunSummary;
use super::ReadError;
use crate::io::fs::display_path;

/// `ImageToProbe` and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenCalibration {
    pub image_to_probe: Matrix4<f64>,
    /// The file it was read from, as the page names it.
    pub source: String,
    /// A run folder's lag (`time_offset_s`, the lag its calibration was
    /// fitted with), and where it is said; none for a PLUS result.
    pub tracker_lag_s: Option<(f64, String)>,
}

/// Why a `--calibration` cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GivenCalibrationError {
    /// The folder holds no run, several, or a run without `ImageToProbe`.
    #[error("{}: {message}", display_path(path))]
    Folder { path: PathBuf, message: String },
    /// The summary or the PLUS result could not be read, or its matrix is unusable.
    #[error(transparent)]
    Read(#[from] ReadError),
}

/// The calibration `given` names: a PLUS calibration result, or the one
/// tracked run in the folder (the folder itself, or up to three levels below).
pub fn read(given: &Path) -> Result<GivenCalibration, GivenCalibrationError> {
    if given.is_file() && given.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml")) {
        let result = crate::io::plus::result::PlusResult::read(given).map_err(|e| ReadError::new(given, e))?;
        return Ok(GivenCalibration {
            image_to_probe: result.image_to_probe,
            source: display_path(given),
            tracker_lag_s: None,
        });
    }
    if given.is_file() {
        return Err(GivenCalibrationError::Folder {
            path: given.to_path_buf(),
            message: "neither a PLUS calibration result (.xml) nor a probecal run's folder".into(),
        });
    }
    let folder = run_folder(given)?;
    let path = folder.join("summary.json");
    let summary = match RunSummary::read(&path)? {
        RunSummary::Tracked(s) => s,
        RunSummary::Camera(_) => {
            return Err(ReadError::new(
                &path,
                "a camera-rig run: it has no `image_to_probe.matrix` (only a tracked (PLUS recording) run has one)",
            )
            .into())
        }
    };
    let rows = &summary.image_to_probe.matrix;
    if rows.len() != 4 || rows.iter().any(|r| r.len() != 4 || r.iter().any(|v| !v.is_finite())) {
        return Err(ReadError::new(&path, "`image_to_probe.matrix` must be 4 rows of 4 finite numbers").into());
    }
    let matrix = Matrix4::from_fn(|r, c| rows[r][c]);
    if let Some(why) = crate::io::plus::xml_limits::affine_fault(&matrix) {
        return Err(ReadError::new(&path, format!("`image_to_probe.matrix`: {why}")).into());
    }
    let lag = Some(summary.time_offset_s).filter(|v| v.is_finite() && v.abs() <= 1.0);
    Ok(GivenCalibration {
        image_to_probe: matrix,
        source: format!("{}/summary.json", display_path(&folder)),
        tracker_lag_s: Some((lag.unwrap_or(0.0), format!("{} (time_offset_s)", display_path(&path)))),
    })
}

/// The folder of the one tracked run `given` names: the folder itself when it
/// holds a `summary.json`, or the one tracked run's folder below it (a
/// `run --out` folder holds its runs two levels down, `<experiment>/<dataset>`).
/// Several are refused with their names; none, with what was looked for.
fn run_folder(given: &Path) -> Result<PathBuf, GivenCalibrationError> {
    let tracked = |dir: &Path| matches!(RunSummary::read(&dir.join("summary.json")), Ok(RunSummary::Tracked(_)));
    if given.join("summary.json").is_file() {
        return Ok(given.to_path_buf());
    }
    let mut found = Vec::new();
    let mut level = vec![given.to_path_buf()];
    // Three levels down at most, folders in name order (hidden ones, such as a
    // failed run's, left out).
    for _ in 0..3 {
        let mut next = Vec::new();
        for dir in &level {
            let Ok(entries) = std::fs::read_dir(dir) else { continue };
            let mut children: Vec<PathBuf> = entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.is_dir() && !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.')))
                .collect();
            children.sort();
            for child in children {
                if tracked(&child) {
                    found.push(child);
                } else {
                    next.push(child);
                }
            }
        }
        level = next;
    }
    let fail = |message: String| GivenCalibrationError::Folder {
        path: given.to_path_buf(),
        message,
    };
    match found.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(fail(
            "holds no probecal run with an ImageToProbe (a tracked run's summary.json, here or up to three levels below); give a run's folder or a PLUS calibration result (.xml)".into(),
        )),
        many => Err(fail(format!(
            "holds {} tracked runs: {}; give the one whose calibration places the sweep",
            many.len(),
            many.iter().map(|p| display_path(p)).collect::<Vec<_>>().join(", ")
        ))),
    }
}
