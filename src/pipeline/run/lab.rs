//! The rendered lab of a camera experiment: what `probecal phantom` and
//! `probecal design` start from.

use std::path::{Path, PathBuf};

use crate::manifest::{DatasetSource, Experiment, Manifest};
use crate::spec::render::RenderSpec;

/// A camera experiment and the render spec of its first rendered dataset (the
/// lab its phantom stands in and the sweep over it), or why there is none.
pub fn rendered_lab(path: &Path) -> Result<(Box<Manifest>, RenderSpec), LabError> {
    let manifest = match Experiment::load(path)? {
        Experiment::Camera(m) => m,
        Experiment::Tracked(_) => {
            return Err(LabError::Missing {
                path: path.to_path_buf(),
                message: "a tracked experiment has no rendered lab or sweep".into(),
            })
        }
    };
    let spec = manifest
        .datasets
        .iter()
        .find_map(|d| match &d.source {
            DatasetSource::Render(spec) => Some(spec.as_ref().clone()),
            DatasetSource::Folder(_) => None,
        })
        .ok_or_else(|| LabError::Missing {
            path: path.to_path_buf(),
            message: "field `datasets`: no rendered dataset gives the lab the phantom stands in".into(),
        })?;
    Ok((manifest, spec))
}

/// Why a manifest gives no rendered lab.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    #[error("{0}")]
    Manifest(#[from] crate::manifest::ManifestErrors),
    #[error("{}: {message}", path.display())]
    Missing { path: PathBuf, message: String },
}
