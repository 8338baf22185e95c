//! `probecal validate` and `probecal synth`: manifests checked, or their
//! rendered datasets written, with nothing run; 0 done, 2 a bad manifest, 1 a
//! dataset that could not be rendered.

use std::path::{Path, PathBuf};

use super::failure::Failure;
use crate::manifest::Experiment;

/// Every manifest checked; all their errors together.
pub fn validate(manifests: &[PathBuf]) -> Result<(), Failure> {
    let experiments = crate::pipeline::experiment::load_all(manifests).map_err(Failure::bad_input)?;
    let mut refused = Vec::new();
    for m in experiments {
        match m {
            Experiment::Camera(m) => println!("{}: ok ({} dataset(s))", m.path.display(), m.datasets.len()),
            Experiment::Tracked(m) => {
                // The recordings are checked as `run` checks them before it uses a frame.
                let inputs = crate::pipeline::tracked::TrackedInputs::from_manifest(&m);
                match crate::pipeline::tracked::preflight(&inputs) {
                    Ok(()) => println!(
                        "{}: ok (tracked sequence, {} N-wires)",
                        m.path.display(),
                        m.nwires.len()
                    ),
                    Err(e) => refused.push(format!("{}: {e}", m.path.display())),
                }
            }
        }
    }
    if refused.is_empty() {
        return Ok(());
    }
    Err(Failure::bad_input(refused.join("\n")))
}

/// The camera experiments' datasets rendered into `datasets`.
pub fn synth(manifests: &[PathBuf], datasets: &Path) -> Result<(), Failure> {
    let experiments = crate::pipeline::experiment::load_all(manifests).map_err(Failure::bad_input)?;
    for m in experiments.iter().filter_map(|m| match m {
        Experiment::Camera(m) => Some(m),
        Experiment::Tracked(_) => None,
    }) {
        crate::pipeline::run::synth_only(m, datasets, &mut |l| eprintln!("{l}"))
            .map_err(|e| Failure::failed(format!("{}: {e}", m.path.display())))?;
    }
    Ok(())
}
