//! The `probecal` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use probecal::evaluate::cutoff_label;
use probecal::io::fs::write_atomic;
use probecal::manifest::tracked::TrackedManifest;
use probecal::manifest::{Experiment, Manifest};
use probecal::report::write::{bre_table_text, threshold_table_text, write_dataset_run};
use probecal::report::{render_index, IndexEntry};

#[derive(Parser)]
#[command(
    name = "probecal",
    version,
    about = "Freehand ultrasound probe calibration from camera images and B-scans"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// What `run` and `compare` share.
#[derive(clap::Args)]
struct RunArgs {
    /// Experiment manifests (YAML).
    #[arg(required = true)]
    manifests: Vec<PathBuf>,
    /// Output folder: a subfolder per experiment and dataset, index.html (and for
    /// `compare`, compare.md and compare.html). Default: a new runs/run-NNN.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Where rendered datasets are cached.
    #[arg(long, default_value = "datasets")]
    datasets: PathBuf,
    /// Replace an experiment's earlier output in --out.
    #[arg(long)]
    force: bool,
    /// Print only errors and gate failures; no progress bars.
    #[arg(long)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Run experiments end to end: render or read each dataset, calibrate, evaluate, report.
    Run {
        #[command(flatten)]
        args: RunArgs,
        /// Worker threads (0: one per core). Outputs do not depend on it.
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
    /// Run several experiments and lay them side by side (rigs as columns).
    Compare {
        #[command(flatten)]
        args: RunArgs,
    },
    /// Compare runs with the committed accuracy baselines; fail on regressions.
    Check {
        /// Run folders (as written by `run --out`) or summary.json files.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// Folder of baseline files, one `<experiment>.yaml` per experiment.
        #[arg(long, default_value = "experiments/baselines")]
        baselines: PathBuf,
        /// Write the baselines from these runs instead of comparing.
        #[arg(long)]
        update: bool,
    },
    /// Check manifests without running anything.
    Validate {
        #[arg(required = true)]
        manifests: Vec<PathBuf>,
    },
    /// Render the datasets of experiments (camera images, B-scans, ground truth) only.
    Synth {
        #[arg(required = true)]
        manifests: Vec<PathBuf>,
        #[arg(long, default_value = "datasets")]
        datasets: PathBuf,
    },
    /// The thesis's σ-table and a Monte Carlo accuracy study of every estimator
    /// (renders the manifest's first dataset once per seed).
    Study {
        manifest: PathBuf,
        /// Seeds rendered (0: the σ-table only).
        #[arg(long, default_value_t = 50)]
        seeds: u64,
        #[arg(long, default_value_t = 1000)]
        first_seed: u64,
        #[arg(long, default_value = "reports/study")]
        out: PathBuf,
        #[arg(long, default_value = "datasets")]
        datasets: PathBuf,
        /// Keep the rendered datasets (they are removed after each seed's run).
        #[arg(long)]
        keep_datasets: bool,
    },
    /// Calibrate a camera from chessboard images; writes OpenCV FileStorage YAML.
    CalibrateCamera {
        /// Image files and/or folders of images.
        #[arg(required = true)]
        images: Vec<PathBuf>,
        /// Inner corners, COLSxROWS (e.g. 9x6).
        #[arg(long, value_parser = parse_board)]
        board: [u32; 2],
        /// Square size in millimetres (or any unit: the translations come out in it).
        #[arg(long)]
        square_mm: f64,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
    },
}

fn study(manifest: &Path, seeds: u64, first_seed: u64, out: &Path, datasets: &Path, keep: bool) -> ExitCode {
    let manifest = match probecal::manifest::Manifest::load(manifest) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    probecal::core::progress::set_quiet(true);
    let sigma = probecal::pipeline::study::sigma_table(50, 200, 1);
    let seeds: Vec<u64> = (first_seed..first_seed + seeds).collect();
    let monte_carlo = if seeds.is_empty() {
        None
    } else {
        match probecal::pipeline::study::monte_carlo(&manifest, &seeds, datasets, keep, &mut |l| eprintln!("{l}")) {
            Ok(m) => Some(m),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    };
    match probecal::pipeline::study::write(out, &sigma, monte_carlo.as_ref()) {
        Ok(()) => {
            eprintln!("written to {}", out.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn parse_board(text: &str) -> Result<[u32; 2], String> {
    let (c, r) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{text}` is not COLSxROWS (e.g. 9x6)"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<u32>()
            .map_err(|_| format!("`{text}` is not COLSxROWS (e.g. 9x6)"))
    };
    let (c, r) = (parse(c)?, parse(r)?);
    if c < 2 || r < 2 {
        return Err(format!("a board needs at least 2x2 inner corners, got {c}x{r}"));
    }
    Ok([c, r])
}

fn load_all(paths: &[PathBuf]) -> Result<Vec<Experiment>, String> {
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

fn next_run_folder() -> PathBuf {
    (1..)
        .map(|i| Path::new("runs").join(format!("run-{i:03}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from("runs/run"))
}

fn check(runs: Vec<PathBuf>, baselines: PathBuf, update: bool) -> ExitCode {
    let summaries = match probecal::report::check::find_summaries(&runs) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if update {
        return match probecal::report::check::update(&summaries, &baselines) {
            Ok(written) => {
                for path in written {
                    println!("baseline written: {}", path.display());
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let comparisons = match probecal::report::check::compare(&summaries, &baselines) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    print!("{}", probecal::report::check::table(&comparisons));
    let mut failed = false;
    for c in &comparisons {
        if matches!(
            c.verdict,
            probecal::report::check::Verdict::Regressed | probecal::report::check::Verdict::Missing
        ) {
            failed = true;
            eprintln!(
                "{}: {} / {}: {} is {} (baseline {:.3} + tolerance {:.3}); look at {}",
                c.verdict.label(),
                c.experiment,
                c.dataset,
                c.metric,
                c.current.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
                c.baseline.value,
                c.baseline.tolerance,
                c.report.display()
            );
        }
    }
    for gate in probecal::report::check::failed_gates(&summaries) {
        failed = true;
        eprintln!("GATE FAILED: {gate}");
    }
    if failed {
        ExitCode::FAILURE
    } else {
        println!(
            "{} metrics of {} runs: no regression",
            comparisons.len(),
            summaries.len()
        );
        ExitCode::SUCCESS
    }
}

/// What a `run` did: its exit code, the manifests, and each dataset run (with its manifest's index).
type RunOutcome = (u8, Vec<Manifest>, Vec<(usize, probecal::pipeline::run::DatasetRun)>);

/// The index's words for a study folder: its experiment and seed count from
/// `study.json`, or the folder's name when that cannot be read.
fn study_label(study_json: &Path, folder: &str) -> String {
    let monte_carlo = std::fs::read_to_string(study_json)
        .ok()
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok())
        .map(|v| v["monte_carlo"].clone());
    match monte_carlo
        .as_ref()
        .and_then(|mc| Some((mc["experiment"].as_str()?, mc)))
    {
        Some((experiment, mc)) => format!(
            "Monte Carlo accuracy study of {experiment} ({} seeds)",
            mc["seeds"].as_array().map_or(0, Vec::len)
        ),
        None => format!("Study: {}", folder.replace('_', " ")),
    }
}

fn run(manifests: Vec<PathBuf>, out: Option<PathBuf>, datasets: PathBuf, force: bool, quiet: bool) -> RunOutcome {
    let experiments = match load_all(&manifests) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return (2, Vec::new(), Vec::new());
        }
    };
    let out = out.unwrap_or_else(next_run_folder);
    for m in &experiments {
        let folder = out.join(m.experiment());
        if folder.exists() && !force {
            eprintln!(
                "error: {} exists already; pass --force to replace it, or choose another --out",
                folder.display()
            );
            return (2, Vec::new(), Vec::new());
        }
    }
    let mut log = |line: &str| {
        if !quiet {
            eprintln!("{line}");
        }
    };
    let mut entries = Vec::new();
    let mut runs = Vec::new();
    let mut failed = false;
    let mut gates_failed = false;
    let mut manifests = Vec::new();
    for experiment in &experiments {
        let folder = out.join(experiment.experiment());
        if folder.exists() {
            if let Err(e) = std::fs::remove_dir_all(&folder) {
                eprintln!("error: cannot replace {}: {e}", folder.display());
                return (1, Vec::new(), Vec::new());
            }
        }
        if let Err(e) = write_atomic(&folder.join("manifest.yaml"), experiment.text().as_bytes()) {
            eprintln!("error: {e}");
            return (1, Vec::new(), Vec::new());
        }
        let m = match experiment {
            Experiment::Camera(m) => m.as_ref(),
            Experiment::Tracked(m) => {
                match run_tracked(m, &folder, quiet) {
                    Ok((entry, passed)) => {
                        gates_failed |= !passed;
                        entries.push(entry);
                    }
                    Err(e) => {
                        eprintln!("error: {e}");
                        failed = true;
                    }
                }
                continue;
            }
        };
        manifests.push(m.clone());
        let index = manifests.len() - 1;
        for d in &m.datasets {
            let started = std::time::SystemTime::now();
            log(&format!("== {} / {}", m.experiment, d.name));
            let run = match probecal::pipeline::run::run_dataset(m, d, &datasets, &mut log) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("error: {}: {e}", m.path.display());
                    failed = true;
                    continue;
                }
            };
            let run_folder = folder.join(&d.name);
            if let Err(e) = write_dataset_run(&run, m, &run_folder) {
                eprintln!("error: {e}");
                failed = true;
                continue;
            }
            if let Err(e) = write_provenance(&run, m, &run_folder, started) {
                eprintln!("error: {e}");
                failed = true;
            }
            let primary = &run.thresholds[run.primary];
            if !quiet {
                for (stage, seconds) in &run.timings_s {
                    eprintln!("  {stage}: {seconds:.1} s");
                }
                println!(
                    "\n{} / {}: {} of {} frames used; calibration at cut-off {} mm from {} frames",
                    m.experiment,
                    d.name,
                    run.used_frames(),
                    run.frames.len(),
                    cutoff_label(primary.cutoff_mm),
                    primary.frames.len()
                );
                if let Some(stats) = &primary.stats {
                    println!("BRE along axes (mm)\n{}", bre_table_text(stats));
                }
                println!(
                    "BRE after removing frames above each cut-off (mm, frames)\n{}",
                    threshold_table_text(&run)
                );
                if let Some(t) = &run.truth {
                    println!(
                        "ground truth: image corners {:.3} mm mean, {:.3} mm max; rotation {:.3}°; translation {:.3} mm",
                        t.calibration.corner_error_mean_mm, t.calibration.corner_error_max_mm, t.calibration.rotation_error_deg, t.calibration.translation_error_mm
                    );
                }
                println!("written to {}", run_folder.display());
            }
            for g in &run.gates {
                if !g.passed {
                    gates_failed = true;
                    eprintln!(
                        "GATE FAILED: {} / {}: {} = {} exceeds {}",
                        m.experiment,
                        d.name,
                        g.name,
                        g.value.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
                        g.limit
                    );
                }
            }
            let stats = primary.stats.as_ref();
            entries.push(IndexEntry {
                experiment: m.experiment.clone(),
                dataset: d.name.clone(),
                link: format!("{}/{}/report.html", m.experiment, d.name),
                frames: format!("{} / {}", run.used_frames(), run.frames.len()),
                bre_mean: stats
                    .map(|s| format!("{:.3}", s.max_mean()))
                    .unwrap_or_else(|| "—".into()),
                truth_corner: run
                    .truth
                    .as_ref()
                    .map(|t| format!("{:.3}", t.calibration.corner_error_mean_mm))
                    .unwrap_or_else(|| "—".into()),
                passed: run.gates_passed(),
            });
            runs.push((index, run));
        }
    }
    // A study written into the same folder (`probecal study --out <out>/study`) is linked too.
    let mut studies: Vec<(String, String)> = Vec::new();
    // The thesis's results chapter, from whichever of its experiments are in `out`.
    match probecal::report::thesis::write(&out) {
        Ok(Some(_)) => studies.push((
            "thesis.html".into(),
            "The thesis's results chapter, regenerated (also thesis.tex)".into(),
        )),
        Ok(None) => {}
        Err(e) => {
            eprintln!("error: thesis chapter: {e}");
            failed = true;
        }
    }
    if out.join("study/study.html").is_file() {
        studies.push((
            "study/study.html".into(),
            "The thesis's σ-table and the Monte Carlo accuracy study of every estimator".into(),
        ));
    }
    // Further studies (`probecal study <manifest> --out <out>/study/<name>`), e.g. the
    // error budget of `experiments/studies/`.
    let mut more: Vec<String> = std::fs::read_dir(out.join("study"))
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().join("study.html").is_file())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .collect();
    more.sort();
    for name in more {
        studies.push((
            format!("study/{name}/study.html"),
            study_label(&out.join("study").join(&name).join("study.json"), &name),
        ));
    }
    match render_index(&entries, &studies) {
        Ok(html) => {
            if let Err(e) = write_atomic(&out.join("index.html"), html.as_bytes()) {
                eprintln!("error: {e}");
                failed = true;
            }
        }
        Err(e) => {
            eprintln!("error: index page: {e}");
            failed = true;
        }
    }
    let code = if failed {
        1
    } else if gates_failed {
        3
    } else {
        0
    };
    (code, manifests, runs)
}

/// Runs a tracker-sequence experiment into `folder`: its index entry and whether its gates passed.
fn run_tracked(m: &TrackedManifest, folder: &Path, quiet: bool) -> Result<(IndexEntry, bool), String> {
    let started = std::time::SystemTime::now();
    if !quiet {
        eprintln!("== {} / {}", m.experiment, m.dataset);
    }
    let run = probecal::pipeline::tracked::run(
        &probecal::pipeline::tracked::TrackedInputs::from_manifest(m),
        m.min_frames,
    )
    .map_err(|e| format!("{}: {e}", m.path.display()))?;
    let plus = match &m.plus_result {
        Some(p) => Some(probecal::io::plus::result::PlusResult::read(p).map_err(|e| e.to_string())?),
        None => None,
    };
    let run_folder = folder.join(&m.dataset);
    let summary = probecal::report::tracked::write(&run, m, plus.as_ref(), &run_folder).map_err(|e| e.to_string())?;
    probecal::report::provenance::Provenance::new(
        &m.path,
        &m.sha256,
        &m.dataset,
        &m.calibration_sequence,
        &m.input_files(),
        started,
    )
    .write(&run_folder)
    .map_err(|e| e.to_string())?;
    let gates = probecal::report::tracked::gates(&run, m);
    for g in gates.iter().filter(|g| !g.passed) {
        eprintln!(
            "GATE FAILED: {} / {}: {} = {} exceeds {}",
            m.experiment,
            m.dataset,
            g.name,
            g.value.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
            g.limit
        );
    }
    let f3 = |v: &serde_json::Value| v.as_f64().map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into());
    if !quiet {
        println!(
            "\n{} / {}: calibration frames segmented {}/{}, validation {}/{}; tracker offset {:.0} ms",
            m.experiment,
            m.dataset,
            summary["frames"]["calibration"]["segmented"],
            summary["frames"]["calibration"]["total"],
            summary["frames"]["validation"]["segmented"],
            summary["frames"]["validation"]["total"],
            run.time_offset_s * 1000.0
        );
        println!("ImageToProbe\n{}", run.fit.image_to_probe.matrix());
        println!(
            "validation PRE3D: {} ± {} mm (best 95 %, n = {}); all points {} ± {} mm (n = {})",
            f3(&summary["validation"]["pre3d_mm"]["mean"]),
            f3(&summary["validation"]["pre3d_mm"]["std"]),
            summary["validation"]["pre3d_mm"]["n"],
            f3(&summary["validation"]["pre3d_all_mm"]["mean"]),
            f3(&summary["validation"]["pre3d_all_mm"]["std"]),
            summary["validation"]["pre3d_all_mm"]["n"],
        );
        if !summary["plus_result"].is_null() {
            println!(
                "PLUS's result: published {} mm; on our dots {} mm",
                f3(&summary["plus_result"]["published_validation_pre3d_mm"]["mean"]),
                f3(&summary["plus_result"]["validation_pre3d_on_our_dots_mm"]["mean"]),
            );
        }
        println!("written to {}", run_folder.display());
    }
    let passed = gates.iter().all(|g| g.passed);
    Ok((
        IndexEntry {
            experiment: m.experiment.clone(),
            dataset: m.dataset.clone(),
            link: format!("{}/{}/report.html", m.experiment, m.dataset),
            frames: format!(
                "{} / {}",
                summary["frames"]["calibration"]["segmented"], summary["frames"]["calibration"]["total"]
            ),
            bre_mean: format!("PRE3D {}", f3(&summary["validation"]["pre3d_mm"]["mean"])),
            truth_corner: "—".into(),
            passed,
        },
        passed,
    ))
}

fn compare(manifests: Vec<PathBuf>, out: Option<PathBuf>, datasets: PathBuf, force: bool, quiet: bool) -> ExitCode {
    let out = out.unwrap_or_else(next_run_folder);
    let (code, manifests, runs) = run(manifests, Some(out.clone()), datasets, force, true);
    if runs.is_empty() {
        return ExitCode::from(code.max(1));
    }
    let columns: Vec<probecal::report::compare::Column> = runs
        .iter()
        .map(|(i, r)| probecal::report::compare::column(&manifests[*i], r))
        .collect();
    let markdown = probecal::report::compare::markdown(&columns);
    if !quiet {
        println!("{markdown}");
    }
    let mut ok = write_atomic(&out.join("compare.md"), markdown.as_bytes()).map_err(|e| e.to_string());
    if ok.is_ok() {
        ok = probecal::report::compare::render_html(&columns)
            .and_then(|html| write_atomic(&out.join("compare.html"), html.as_bytes()).map_err(|e| e.to_string()));
    }
    if ok.is_ok() {
        ok = probecal::report::compare::render_tex(&columns)
            .and_then(|tex| write_atomic(&out.join("compare.tex"), tex.as_bytes()).map_err(|e| e.to_string()));
    }
    if let Err(e) = ok {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    println!("written to {} (compare.md, compare.html, compare.tex)", out.display());
    ExitCode::from(code)
}

fn write_provenance(
    run: &probecal::pipeline::run::DatasetRun,
    manifest: &Manifest,
    folder: &Path,
    started: std::time::SystemTime,
) -> Result<(), probecal::report::write::OutputError> {
    let mut provenance = probecal::report::provenance::Provenance::new(
        &manifest.path,
        &manifest.sha256,
        &run.dataset,
        &run.dataset_folder,
        &run.input_files,
        started,
    );
    provenance.seed = run.seed;
    provenance.timings_s = run.timings_s.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    provenance.write(folder)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Command::Run { args, .. } | Command::Compare { args } = &cli.command {
        probecal::core::progress::set_quiet(args.quiet);
    }
    // Every command runs with the same thread setting (OpenCV's included).
    probecal::core::parallel::set_threads(match &cli.command {
        Command::Run { threads, .. } => *threads,
        _ => 0,
    });
    match cli.command {
        Command::Run { args, .. } => {
            ExitCode::from(run(args.manifests, args.out, args.datasets, args.force, args.quiet).0)
        }
        Command::Compare { args } => compare(args.manifests, args.out, args.datasets, args.force, args.quiet),
        Command::Check {
            runs,
            baselines,
            update,
        } => check(runs, baselines, update),
        Command::Validate { manifests } => match load_all(&manifests) {
            Ok(ms) => {
                for m in ms {
                    match m {
                        Experiment::Camera(m) => println!("{}: ok ({} dataset(s))", m.path.display(), m.datasets.len()),
                        Experiment::Tracked(m) => println!(
                            "{}: ok (tracked sequence, {} N-wires)",
                            m.path.display(),
                            m.nwires.len()
                        ),
                    }
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(2)
            }
        },
        Command::Study {
            manifest,
            seeds,
            first_seed,
            out,
            datasets,
            keep_datasets,
        } => study(&manifest, seeds, first_seed, &out, &datasets, keep_datasets),
        Command::Synth { manifests, datasets } => {
            let manifests = match load_all(&manifests) {
                Ok(m) => m,
                Err(e) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(2);
                }
            };
            for m in manifests.iter().filter_map(|m| match m {
                Experiment::Camera(m) => Some(m),
                Experiment::Tracked(_) => None,
            }) {
                if let Err(e) = probecal::pipeline::run::synth_only(m, &datasets, &mut |l| eprintln!("{l}")) {
                    eprintln!("error: {}: {e}", m.path.display());
                    return ExitCode::FAILURE;
                }
            }
            ExitCode::SUCCESS
        }
        Command::CalibrateCamera {
            images,
            board,
            square_mm,
            out,
        } => {
            if !(square_mm.is_finite() && square_mm > 0.0) {
                eprintln!("error: --square-mm must be a positive number, got {square_mm}");
                return ExitCode::from(2);
            }
            match probecal::detect::camera_calibration::calibrate_from(&images, board, square_mm) {
                Ok(cal) => {
                    for v in &cal.views {
                        match (&v.reason, v.rms_px) {
                            (None, Some(rms)) => eprintln!("  {}: used, RMS {rms:.3} px", v.image.display()),
                            (Some(r), _) => eprintln!("  {}: not used: {r}", v.image.display()),
                            _ => {}
                        }
                    }
                    let k = &cal.intrinsics;
                    println!(
                        "fx {:.4} fy {:.4} cx {:.4} cy {:.4} px; distortion {:?}; RMS {:.6} px",
                        k.fx(),
                        k.fy(),
                        k.cx(),
                        k.cy(),
                        k.distortion,
                        k.rms_px.unwrap_or(f64::NAN)
                    );
                    if let Err(e) = k.save(&out, Some((board, square_mm))) {
                        eprintln!("error: {e}");
                        return ExitCode::FAILURE;
                    }
                    println!("written to {}", out.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}
