//! The experiment loop: every manifest's datasets (or tracked sequences) run in
//! turn into `--out`, each experiment into its own folder. What is written and
//! shown is a [`Reporter`]'s business: the loop tells it what happened.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use super::record::DatasetRun;
use super::tracked::{self, TrackedInputs, TrackedRun};
use crate::io::fs::write_atomic;
use crate::io::plus::result::PlusResult;
use crate::manifest::tracked::TrackedManifest;
use crate::manifest::{Experiment, Manifest};

/// What the loop tells as the experiments run (as criterion's reports are told).
/// Every hook but the errors' defaults to nothing.
pub trait Reporter {
    /// A dataset is about to run.
    fn dataset_started(&mut self, _experiment: &str, _dataset: &str) {}
    /// A camera experiment's dataset has run; its outputs go into `folder`.
    fn dataset_done(
        &mut self,
        _manifest: &Manifest,
        _run: &DatasetRun,
        _folder: &Path,
        _started: SystemTime,
    ) -> Result<(), String> {
        Ok(())
    }
    /// A tracked experiment has run (with PLUS's result, when the manifest names it).
    fn tracked_done(
        &mut self,
        _manifest: &TrackedManifest,
        _run: &TrackedRun,
        _plus: Option<&PlusResult>,
        _folder: &Path,
        _started: SystemTime,
    ) -> Result<(), String> {
        Ok(())
    }
    /// An accuracy gate failed (the line says which, its value and its limit).
    fn gate_failed(&mut self, _line: &str) {}
    /// Something failed; the loop goes on with the next dataset.
    fn error(&mut self, message: &str) {
        eprintln!("error: {message}");
    }
    /// Every experiment has run.
    fn finished(&mut self, _out: &Path) -> Result<(), String> {
        Ok(())
    }
}

/// What a `run` did: its exit code (0 success, 1 a dataset failed, 2 bad usage,
/// 3 a gate failed), the camera manifests, and each dataset run with its
/// manifest's index.
pub struct Outcome {
    pub code: u8,
    pub manifests: Vec<Manifest>,
    pub runs: Vec<(usize, DatasetRun)>,
}

impl Outcome {
    fn failed(code: u8) -> Outcome {
        Outcome {
            code,
            manifests: Vec::new(),
            runs: Vec::new(),
        }
    }
}

/// Loads every manifest; all their errors together when any fails.
pub fn load_all(paths: &[PathBuf]) -> Result<Vec<Experiment>, String> {
    let mut manifests = Vec::new();
    let mut errors = Vec::new();
    for p in paths {
        match Experiment::load(p) {
            Ok(m) => manifests.push(m),
            Err(e) => errors.push(e.to_string()),
        }
    }
    if errors.is_empty() {
        Ok(manifests)
    } else {
        Err(errors.join("\n"))
    }
}

/// The first free `runs/run-NNN`.
pub fn next_run_folder() -> PathBuf {
    (1..)
        .map(|i| Path::new("runs").join(format!("run-{i:03}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from("runs/run"))
}

/// Where the experiments go and where rendered datasets are cached.
pub struct RunOptions<'a> {
    pub out: &'a Path,
    pub datasets: &'a Path,
    /// Replace an experiment's earlier folder in `out`.
    pub force: bool,
}

/// Runs every experiment into `options.out`.
pub fn run_all(
    experiments: &[Experiment],
    options: &RunOptions<'_>,
    reporter: &mut dyn Reporter,
    log: &mut dyn FnMut(&str),
) -> Outcome {
    let out = options.out;
    for m in experiments {
        let folder = out.join(m.experiment());
        if folder.exists() && !options.force {
            reporter.error(&format!(
                "{} exists already; pass --force to replace it, or choose another --out",
                folder.display()
            ));
            return Outcome::failed(2);
        }
    }
    let mut failed = false;
    let mut gates_failed = false;
    let mut manifests = Vec::new();
    let mut runs = Vec::new();
    for experiment in experiments {
        let folder = out.join(experiment.experiment());
        if folder.exists() {
            if let Err(e) = std::fs::remove_dir_all(&folder) {
                reporter.error(&format!("cannot replace {}: {e}", folder.display()));
                return Outcome::failed(1);
            }
        }
        if let Err(e) = write_atomic(&folder.join("manifest.yaml"), experiment.text().as_bytes()) {
            reporter.error(&e.to_string());
            return Outcome::failed(1);
        }
        let m = match experiment {
            Experiment::Camera(m) => m.as_ref(),
            Experiment::Tracked(m) => {
                match run_tracked(m, &folder, reporter) {
                    Ok(passed) => gates_failed |= !passed,
                    Err(e) => {
                        reporter.error(&e);
                        failed = true;
                    }
                }
                continue;
            }
        };
        manifests.push(m.clone());
        let index = manifests.len() - 1;
        for d in &m.datasets {
            let started = SystemTime::now();
            reporter.dataset_started(&m.experiment, &d.name);
            let run = match super::run::run_dataset(m, d, options.datasets, log) {
                Ok(r) => r,
                Err(e) => {
                    reporter.error(&format!("{}: {e}", m.path.display()));
                    failed = true;
                    continue;
                }
            };
            if let Err(e) = reporter.dataset_done(m, &run, &folder.join(&d.name), started) {
                reporter.error(&e);
                failed = true;
                continue;
            }
            for g in run.gates.iter().filter(|g| !g.passed) {
                gates_failed = true;
                reporter.gate_failed(&format!(
                    "{} / {}: {} = {} exceeds {}",
                    m.experiment,
                    d.name,
                    g.name,
                    g.value.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
                    g.limit
                ));
            }
            runs.push((index, run));
        }
    }
    if let Err(e) = reporter.finished(out) {
        reporter.error(&e);
        failed = true;
    }
    let code = if failed {
        1
    } else if gates_failed {
        3
    } else {
        0
    };
    Outcome { code, manifests, runs }
}

/// Runs a tracked-sequence experiment into `folder`: whether its gates passed.
fn run_tracked(m: &TrackedManifest, folder: &Path, reporter: &mut dyn Reporter) -> Result<bool, String> {
    let started = SystemTime::now();
    reporter.dataset_started(&m.experiment, &m.dataset);
    let run = tracked::run(&TrackedInputs::from_manifest(m), m.min_frames)
        .map_err(|e| format!("{}: {e}", m.path.display()))?;
    let plus = match &m.plus_result {
        Some(p) => Some(PlusResult::read(p).map_err(|e| e.to_string())?),
        None => None,
    };
    reporter.tracked_done(m, &run, plus.as_ref(), &folder.join(&m.dataset), started)?;
    let gates = tracked::gates(&run, m);
    for g in gates.iter().filter(|g| !g.passed) {
        reporter.gate_failed(&format!(
            "{} / {}: {} = {} exceeds {}",
            m.experiment,
            m.dataset,
            g.name,
            g.value.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
            g.limit
        ));
    }
    Ok(gates.iter().all(|g| g.passed))
}
