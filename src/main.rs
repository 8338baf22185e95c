//! The `probecal` command line: arguments and dispatch. The work is done by
//! [`probecal::pipeline`] (running) and [`probecal::report`] (writing, checking).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use probecal::manifest::Experiment;
use probecal::pipeline::experiment::{load_all, next_run_folder, run_all, Outcome, RunOptions};
use probecal::report::live::LiveSource;
use probecal::report::writer::ReportWriter;

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
        /// Worker threads (0: one per core; at most 256). Outputs do not depend on it.
        #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=probecal::core::limits::MAX_THREADS as i64))]
        threads: u16,
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
        /// With --update: let a run that lacks a metric drop it from the baseline.
        #[arg(long)]
        allow_drop: bool,
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
    Study(probecal::report::study::StudyArgs),
    /// Calibrate while a tracked manifest's calibration sequence is replayed at its
    /// recorded rate: a line per frame (predicted error, running accuracy, work),
    /// then the batch calibration of the whole recording; summary.json, live.csv.
    Live {
        manifest: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Times the recorded rate (0: every frame at once).
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
        /// A camera manifest: take its frames from this folder as they are written.
        #[arg(long)]
        watch: Option<PathBuf>,
        /// With --watch: no new frame for this long ends the acquisition, s.
        #[arg(long, default_value_t = 10.0)]
        idle_s: f64,
    },
    /// Solve a run again from its own folder (the frames' poses and feature pixels
    /// in `inputs.csv`, the manifest it ran with) and compare with its summary.
    Resolve {
        /// A dataset's run folder (`<out>/<experiment>/<dataset>`).
        run: PathBuf,
    },
    /// Segment the N-wire dots of a PLUS sequence on their own: segmentation.csv,
    /// summary.json and report.html in --out.
    Segment(probecal::report::segment::SegmentArgs),
    /// The tracker's lag behind the video from a probe moved over a flat reflector
    /// (PLUS's temporal calibration): summary.json, lines.csv, report.html in --out.
    Temporal {
        #[arg(long)]
        tracker: PathBuf,
        #[arg(long)]
        video: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// Error budget of a rendered rig: its dataset rendered with its error sources
    /// (render.realism) all on, all off, each left out and each alone;
    /// ablation.json, ablation.md and ablation.html in --out.
    Ablate(probecal::report::ablation::AblateArgs),
    /// Dome-phantom layouts for the manifest's lab and sweep, ranked by the
    /// Cramér–Rao bound of their calibration: design.json and design.md in --out.
    Design {
        manifest: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// A dome phantom's printable model (plate, riser, domes, board seat) as a
    /// binary STL in mm, and its sheet (sizes, domes, seat) as <name>.json.
    Phantom {
        manifest: PathBuf,
        #[arg(long)]
        stl: PathBuf,
    },
    /// Calibrate a camera from chessboard images; writes OpenCV FileStorage YAML.
    CalibrateCamera {
        /// Image files and/or folders of images.
        #[arg(required = true)]
        images: Vec<PathBuf>,
        /// Inner corners, COLSxROWS (e.g. 9x6).
        #[arg(long, value_parser = probecal::detect::camera_calibration::parse_board)]
        board: [u32; 2],
        /// Square size in millimetres (or any unit: the translations come out in it).
        #[arg(long)]
        square_mm: f64,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Every manifest, or `None` after printing all their errors.
fn loaded(paths: &[PathBuf]) -> Option<Vec<Experiment>> {
    load_all(paths).map_err(|e| eprintln!("error: {e}")).ok()
}

/// `run` and `compare`: every experiment into `--out`; `compare` lays them side by side.
fn run(args: RunArgs, side_by_side: bool) -> u8 {
    let Some(experiments) = loaded(&args.manifests) else {
        return 2;
    };
    let out = args.out.unwrap_or_else(next_run_folder);
    let quiet = args.quiet || side_by_side;
    let mut writer = ReportWriter::new(quiet);
    writer.index_later = side_by_side;
    let mut log = |line: &str| {
        if !quiet {
            eprintln!("{line}");
        }
    };
    let options = RunOptions {
        out: &out,
        datasets: &args.datasets,
        force: args.force,
    };
    let Outcome { code, manifests, runs } = run_all(&experiments, &options, &mut writer, &mut log);
    if !side_by_side {
        return code;
    }
    if let Err(e) = writer.write_comparison(&out, &manifests, &runs, args.quiet) {
        eprintln!("error: {e}");
        return 1;
    }
    if runs.is_empty() {
        return code.max(1);
    }
    code
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Command::Run { args, .. } | Command::Compare { args } = &cli.command {
        probecal::core::progress::set_quiet(args.quiet);
    }
    // Every command runs with the same thread setting (OpenCV's included).
    probecal::core::parallel::set_threads(match &cli.command {
        Command::Run { threads, .. } => usize::from(*threads),
        _ => 0,
    });
    ExitCode::from(match cli.command {
        Command::Run { args, .. } => run(args, false),
        Command::Compare { args } => run(args, true),
        Command::Check {
            runs,
            baselines,
            update,
            allow_drop,
        } => probecal::report::check::run(&runs, &baselines, update, allow_drop),
        Command::Validate { manifests } => probecal::report::console::validate(&manifests),
        Command::Temporal { tracker, video, out } => probecal::report::temporal::command(&video, &tracker, &out),
        Command::Segment(args) => probecal::report::segment::command(&args),
        Command::Live {
            manifest,
            out,
            speed,
            watch,
            idle_s,
        } => probecal::report::live::command(&manifest, &out, &LiveSource { speed, watch, idle_s }),
        Command::Study(args) => probecal::report::study::dispatch(args),
        Command::Synth { manifests, datasets } => probecal::report::console::synth(&manifests, &datasets),
        Command::Resolve { run } => probecal::report::resolve::command(&run),
        Command::Ablate(args) => probecal::report::ablation::command(&args),
        Command::Design { manifest, out } => probecal::report::design::command(&manifest, &out),
        Command::Phantom { manifest, stl } => probecal::report::phantom::command(&manifest, &stl),
        Command::CalibrateCamera {
            images,
            board,
            square_mm,
            out,
        } => probecal::report::console::calibrate_camera(&images, board, square_mm, &out),
    })
}
