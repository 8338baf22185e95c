//! A tracked run's reconstruction of the sweep its manifest names
//! (`reconstruct:`), with the run's own `ImageToProbe`: the volume, its
//! pictures and page in the run's `reconstruction/` folder, and what the run's
//! summary and page say of it (the wires' figures beside PRE3D).

use std::path::Path;

use crate::io::fs::display_path;
use crate::pipeline::reconstruct::Reconstruction;
use crate::report::error::OutputError;
use crate::results::volume::{TrackedVolume, FOLDER};

/// Writes the reconstruction into `<run folder>/reconstruction/`; what the summary says of it.
pub fn write(volume: &Reconstruction, run_folder: &Path) -> Result<TrackedVolume, OutputError> {
    let dir = run_folder.join(FOLDER);
    std::fs::create_dir_all(&dir).map_err(|e| OutputError::io(&dir, e))?;
    let options = crate::report::reconstruct::WriteOptions {
        nrrd: false,
        compare: None,
    };
    crate::report::reconstruct::write(volume, &dir, &options)?;
    let grid = volume.volume.grid();
    Ok(TrackedVolume {
        folder: FOLDER.to_string(),
        sweep: display_path(&volume.inputs.sequence),
        config: display_path(&volume.inputs.config),
        frames_used: volume.frames_used.len(),
        frames_total: volume.frames_total,
        dims: grid.dims,
        spacing_mm: grid.spacing_mm,
        wires: volume.wires.clone(),
    })
}

/// The page's rows for the wires: (what, mm) as text; `null` without figures.
pub fn page_context(v: &TrackedVolume) -> serde_json::Value {
    let mm = |x: Option<f64>| x.map_or("—".to_string(), |x| format!("{x:.2}"));
    serde_json::json!({
        "folder": v.folder,
        "sweep": Path::new(&v.sweep).file_name().map_or(v.sweep.clone(), |n| n.to_string_lossy().to_string()),
        "frames": format!("{} of {}", v.frames_used, v.frames_total),
        "dims": format!("{}x{}x{}", v.dims[0], v.dims[1], v.dims[2]),
        "spacing": format!("{}", v.spacing_mm[0]),
        "wires": v.wires.as_ref().map(|w| serde_json::json!({
            "measured": format!("{} of {}", w.wires_measured, w.wires.len()),
            "position": mm(w.position_error_mm),
            "straightness": mm(w.straightness_rms_mm),
            "thickness": mm(w.thickness_fwhm_mm),
        })),
    })
}
