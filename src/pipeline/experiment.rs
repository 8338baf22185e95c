//! The experiment loop: every manifest's datasets (or tracked sequences) run in
//! turn into `--out`, each experiment into its own folder. What is written and
//! shown is a [`Reporter`]'s business: the loop tells it what happened.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use crate::io::fs::{write_atomic, Lock, Staged};
use crate::io::plus::result::PlusResult;
use crate::manifest::tracked::TrackedManifest;
use crate::manifest::{CameraSource, DatasetSource, Experiment, Manifest, ManifestErrors};
use crate::pipeline::error::ReporterError;
use crate::pipeline::record::DatasetRun;
use crate::pipeline::tracked::resolution::{self as tracked_resolution, TrackedAfter};
use crate::pipeline::tracked::{self, TrackedInputs, TrackedRun};

/// Where a dataset's outputs are written now, and where they will be once its
/// experiment's folder is swapped in.
#[derive(Debug, Clone, Copy)]
pub struct RunFolder<'a> {
    pub write_to: &'a Path,
    pub final_path: &'a Path,
}

/// What the loop tells as the experiments run (as criterion's reports are told).
/// Every hook but the errors' defaults to nothing.
pub trait Reporter {
    /// A dataset is about to run.
    fn dataset_started(&mut self, _experiment: &str, _dataset: &str) {}
    /// A camera experiment's dataset has run; its outputs go into `folder.write_to`
    /// (the experiment's folder is swapped in when all its datasets are written).
    fn dataset_done(
        &mut self,
        _labels: &crate::pipeline::labels::RunLabels,
        _run: &DatasetRun,
        _folder: &RunFolder<'_>,
        _started: SystemTime,
    ) -> Result<(), ReporterError> {
        Ok(())
    }
    /// A tracked experiment has run (with PLUS's result, when the manifest names it).
    fn tracked_done(
        &mut self,
        _labels: &crate::pipeline::labels::TrackedLabels,
        _run: &TrackedRun,
        _after: &TrackedAfter,
        _plus: Option<&PlusResult>,
        _folder: &RunFolder<'_>,
        _started: SystemTime,
    ) -> Result<(), ReporterError> {
        Ok(())
    }
    /// An accuracy gate failed (the line says which, its value and its limit).
    fn gate_failed(&mut self, _line: &str) {}
    /// Something failed; the loop goes on with the next dataset.
    fn error(&mut self, message: &str) {
        eprintln!("error: {message}");
    }
    /// Every experiment has run.
    fn finished(&mut self, _out: &Path) -> Result<(), ReporterError> {
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
pub fn load_all(paths: &[PathBuf]) -> Result<Vec<Experiment>, ManifestErrors> {
    let mut manifests = Vec::new();
    let mut errors = Vec::new();
    for p in paths {
        match Experiment::load(p) {
            Ok(m) => manifests.push(m),
            Err(e) => errors.extend(e.0),
        }
    }
    if errors.is_empty() {
        Ok(manifests)
    } else {
        Err(ManifestErrors(errors))
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

/// Every file or folder an experiment reads (the rendered datasets' cache aside).
fn inputs_of(experiment: &Experiment) -> Vec<PathBuf> {
    match experiment {
        Experiment::Tracked(m) => {
            let mut inputs = m.input_files();
            inputs.push(m.path.clone());
            inputs
        }
        Experiment::Camera(m) => {
            let mut inputs = vec![m.path.clone()];
            match &m.camera {
                CameraSource::IntrinsicsFile(p) => inputs.push(p.clone()),
                CameraSource::Calibrate { images: Some(p), .. } => inputs.push(p.clone()),
                CameraSource::Calibrate { images: None, .. } | CameraSource::TrackerCsv(_) => {}
            }
            inputs.extend(m.datasets.iter().filter_map(|d| match &d.source {
                DatasetSource::Folder(f) => Some(f.clone()),
                DatasetSource::Render(_) => None,
            }));
            inputs
        }
    }
}

/// Why the experiments cannot be written into `out` as they are: two of them
/// with one folder, an existing folder without `--force`, or a folder that would
/// be replaced while it holds an input of the run (or the datasets' cache).
fn refusal(experiments: &[Experiment], options: &RunOptions<'_>) -> Option<String> {
    // Run folders and cached datasets are named alike: one folder for both
    // would let each replace the other.
    let (out, cache) = (
        crate::io::output::resolved(options.out),
        crate::io::output::resolved(options.datasets),
    );
    if out.starts_with(&cache) || cache.starts_with(&out) {
        return Some(format!(
            "--out {} and --datasets {} overlap: a run's folder and a cached dataset could replace each other; give them separate folders",
            options.out.display(),
            options.datasets.display()
        ));
    }
    for (i, m) in experiments.iter().enumerate() {
        if let Some(other) = experiments[..i].iter().find(|o| o.experiment() == m.experiment()) {
            return Some(format!(
                "{} and {} both name experiment `{}`: one would replace the other's folder in {}",
                other.path().display(),
                m.path().display(),
                m.experiment(),
                options.out.display()
            ));
        }
    }
    if let Some(reason) = pages_refusal(experiments, options.out) {
        return Some(reason);
    }
    for m in experiments {
        let folder = options.out.join(m.experiment());
        if !folder.exists() {
            continue;
        }
        if !options.force {
            return Some(format!(
                "{} exists already; pass --force to replace it, or choose another --out",
                folder.display()
            ));
        }
        let Ok(replaced) = folder.canonicalize() else { continue };
        let mut guarded = inputs_of(m);
        guarded.push(options.datasets.to_path_buf());
        for input in guarded {
            if input.canonicalize().is_ok_and(|p| p.starts_with(&replaced)) {
                return Some(format!(
                    "{} would be replaced, and it holds {}, which the run reads; choose another --out",
                    folder.display(),
                    input.display()
                ));
            }
        }
    }
    None
}

/// The pages a run or a comparison writes at the top of `--out`.
pub const TOP_PAGES: [&str; 6] = [
    "index.html",
    "compare.html",
    "compare.md",
    "compare.tex",
    "thesis.html",
    "thesis.tex",
];

/// Why `out` cannot hold the experiments' top pages, if it cannot: it lies
/// inside a folder the run reads, or one of the pages would replace an input.
fn pages_refusal(experiments: &[Experiment], out: &Path) -> Option<String> {
    if out.is_file() {
        return Some(format!(
            "--out {} is a file, not a folder; choose another --out",
            out.display()
        ));
    }
    let target = crate::io::output::resolved(out);
    for input in experiments.iter().flat_map(inputs_of) {
        let input_path = crate::io::output::resolved(&input);
        if input.is_dir() && target.starts_with(&input_path) {
            return Some(format!(
                "--out {} lies inside {}, which the run reads; choose another --out",
                out.display(),
                input.display()
            ));
        }
        if let Some(page) = TOP_PAGES.iter().find(|p| target.join(p) == input_path) {
            return Some(format!(
                "--out {}: its {page} would replace {}, which the run reads; choose another --out",
                out.display(),
                input.display()
            ));
        }
    }
    None
}

/// The file that claims an output folder for one run at a time.
pub const OUT_LOCK: &str = ".probecal.lock";

/// Runs every experiment into `options.out`. Each experiment's folder is written
/// beside the old one and swapped in when all its datasets are written; a failed
/// experiment leaves the old folder as it was.
pub fn run_all(
    experiments: &[Experiment],
    options: &RunOptions<'_>,
    reporter: &mut dyn Reporter,
    log: &mut dyn FnMut(&str),
) -> Outcome {
    let out = options.out;
    if let Some(reason) = refusal(experiments, options) {
        reporter.error(&reason);
        return Outcome::failed(2);
    }
    let _lock = match Lock::acquire(&out.join(OUT_LOCK)) {
        Ok(locks) => locks,
        Err(e) => {
            reporter.error(&e.to_string());
            return Outcome::failed(2);
        }
    };
    let mut failed = false;
    let mut gates_failed = false;
    let mut manifests = Vec::new();
    let mut runs = Vec::new();
    for experiment in experiments {
        let target = out.join(experiment.experiment());
        let staged = match Staged::begin(&target) {
            Ok(s) => s,
            Err(e) => {
                reporter.error(&e.to_string());
                return Outcome::failed(1);
            }
        };
        let folder = staged.path().to_path_buf();
        if let Err(e) = write_atomic(&folder.join("manifest.yaml"), experiment.text().as_bytes()) {
            reporter.error(&e.to_string());
            return Outcome::failed(1);
        }
        let mut written = true;
        let m = match experiment {
            Experiment::Camera(m) => m.as_ref(),
            Experiment::Tracked(m) => {
                match run_tracked(m, &folder, &target, reporter) {
                    Ok(passed) => gates_failed |= !passed,
                    Err(e) => {
                        reporter.error(&e.to_string());
                        written = false;
                    }
                }
                failed |= !swap_in(staged, written, reporter);
                continue;
            }
        };
        manifests.push(m.clone());
        let index = manifests.len() - 1;
        for d in &m.datasets {
            let started = SystemTime::now();
            reporter.dataset_started(&m.experiment, &d.name);
            let run = match crate::pipeline::run::run_dataset(m, d, options.datasets, log) {
                Ok(r) => r,
                Err(e) => {
                    reporter.error(&format!("{}: {e}", m.path.display()));
                    written = false;
                    continue;
                }
            };
            let write_to = folder.join(&d.name);
            let final_path = target.join(&d.name);
            let run_folder = RunFolder {
                write_to: &write_to,
                final_path: &final_path,
            };
            if let Err(e) =
                reporter.dataset_done(&crate::pipeline::labels::RunLabels::of(m), &run, &run_folder, started)
            {
                reporter.error(&e.to_string());
                written = false;
                continue;
            }
            for g in run.gates.iter().filter(|g| !g.passed) {
                gates_failed = true;
                reporter.gate_failed(&failed_gate(&m.experiment, &d.name, g));
            }
            runs.push((index, run));
        }
        failed |= !swap_in(staged, written, reporter);
    }
    if let Err(e) = reporter.finished(out) {
        reporter.error(&e.to_string());
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

/// A failed gate in words: which, its value and its limit.
fn failed_gate(experiment: &str, dataset: &str, g: &crate::pipeline::record::GateResult) -> String {
    format!(
        "{experiment} / {dataset}: {} = {} exceeds {}",
        g.name,
        g.value.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
        g.limit
    )
}

/// Swaps a written experiment in, or keeps the old folder when any of its
/// datasets failed (what was written goes to `.<experiment>.failed`); whether
/// the experiment's folder is now the new one.
fn swap_in(staged: Staged, written: bool, reporter: &mut dyn Reporter) -> bool {
    if written {
        return match staged.commit() {
            Ok(()) => true,
            Err(e) => {
                reporter.error(&e.to_string());
                false
            }
        };
    }
    match staged.abandon() {
        Ok(kept) => reporter.error(&format!(
            "the experiment's previous folder is kept; what this run wrote is in {}",
            kept.display()
        )),
        Err(e) => reporter.error(&e.to_string()),
    }
    false
}

/// Why a tracked experiment wrote no run.
#[derive(Debug, thiserror::Error)]
pub enum TrackedExperimentError {
    #[error("{}: {source}", manifest.display())]
    Run {
        manifest: PathBuf,
        source: tracked::TrackedError,
    },
    #[error("{0}")]
    PlusResult(#[from] crate::io::plus::config::ConfigError),
    #[error("{manifest}: reconstruct: {message}")]
    Volume { manifest: PathBuf, message: String },
    #[error("{0}")]
    Reporter(#[from] ReporterError),
}

/// The sweep the manifest names, reconstructed with the run's own
/// `ImageToProbe`, its wires measured when the phantom came from a device set.
fn tracked_volume(
    m: &TrackedManifest,
    run: &TrackedRun,
) -> Result<Option<crate::pipeline::reconstruct::Reconstruction>, TrackedExperimentError> {
    let Some(r) = &m.reconstruct else {
        return Ok(None);
    };
    let inputs = crate::pipeline::reconstruct::ReconstructInputs {
        sequence: r.sweep.clone(),
        config: r.config.clone(),
        threads: None,
        wires: m.plus_config.clone(),
        image_to_probe: Some((run.fit.image_to_probe.matrix(), "this run's calibration".to_string())),
        tracker_lag_s: Some((run.time_offset_s, "this run's tracker lag".to_string())),
    };
    let mut volume = crate::pipeline::reconstruct::run(&inputs).map_err(|e| TrackedExperimentError::Volume {
        manifest: m.path.clone(),
        message: e.to_string(),
    })?;
    // Times would make the page differ run to run.
    volume.timings.clear();
    Ok(Some(volume))
}

/// Runs a tracked-sequence experiment into `folder`: whether its gates passed.
fn run_tracked(
    m: &TrackedManifest,
    folder: &Path,
    target: &Path,
    reporter: &mut dyn Reporter,
) -> Result<bool, TrackedExperimentError> {
    let started = SystemTime::now();
    reporter.dataset_started(&m.experiment, &m.dataset);
    let inputs = TrackedInputs::from_manifest(m);
    let run = tracked::run(&inputs, m.min_frames).map_err(|source| TrackedExperimentError::Run {
        manifest: m.path.clone(),
        source,
    })?;
    // After the calibration is fitted, and never feeding back into it.
    let after = TrackedAfter {
        resolution: tracked_resolution::evaluate(&run, &inputs),
        gates: tracked::gates(&run, m),
        volume: tracked_volume(m, &run)?,
    };
    let plus = match &m.plus_result {
        Some(p) => Some(PlusResult::read(p)?),
        None => None,
    };
    let (write_to, final_path) = (folder.join(&m.dataset), target.join(&m.dataset));
    let run_folder = RunFolder {
        write_to: &write_to,
        final_path: &final_path,
    };
    let labels = crate::pipeline::labels::TrackedLabels::of(m);
    reporter.tracked_done(&labels, &run, &after, plus.as_ref(), &run_folder, started)?;
    for g in after.gates.iter().filter(|g| !g.passed) {
        reporter.gate_failed(&failed_gate(&m.experiment, &m.dataset, g));
    }
    Ok(after.gates.iter().all(|g| g.passed))
}
