//! The command line: arguments (clap) and dispatch to the commands. The work is
//! done by [`crate::pipeline`] (running) and [`crate::report`] (writing, checking);
//! `docs/cli.md` is generated from these definitions (`tests/cli_help.rs`).

mod ablate;
mod camera;
mod check;
mod design;
pub mod docs;
mod failure;
mod init;
mod live;
mod live_igtl;
mod manifests;
mod phantom;
mod reconstruct;
mod resolve;
mod segment;
mod selfcal;
mod study;
mod temporal;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::manifest::Experiment;
use crate::pipeline::experiment::{load_all, next_run_folder, run_all, Outcome, RunOptions};
use crate::report::writer::ReportWriter;
use live::LiveSource;

#[derive(Parser)]
#[command(
    name = "probecal",
    version,
    about = "Freehand ultrasound probe calibration from camera images and B-scans"
)]
pub struct Cli {
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
    /// Write a commented manifest for one's own recording: a PLUS recording
    /// (device set and sequence files) or a folder of frames.
    Init(init::InitArgs),
    /// Run experiments end to end: render or read each dataset, calibrate, evaluate, report.
    Run {
        #[command(flatten)]
        args: RunArgs,
        /// Worker threads (0: one per core; at most 256). Outputs do not depend on it.
        #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=crate::core::limits::MAX_THREADS as i64))]
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
    /// Check manifests, and a tracked manifest's recordings as run checks them, without running anything.
    Validate {
        /// Experiment manifests (YAML); every one is checked and every error printed.
        #[arg(required = true)]
        manifests: Vec<PathBuf>,
    },
    /// Render the datasets of experiments (camera images, B-scans, ground truth) only.
    Synth {
        /// Experiment manifests (YAML) whose rendered datasets to write.
        #[arg(required = true)]
        manifests: Vec<PathBuf>,
        /// Where rendered datasets are cached.
        #[arg(long, default_value = "datasets")]
        datasets: PathBuf,
    },
    /// The thesis's σ-table and a Monte Carlo accuracy study of every estimator
    /// (renders the manifest's first dataset once per seed).
    Study(study::StudyArgs),
    /// Calibrate while a tracked manifest's calibration sequence is replayed at its
    /// recorded rate: a line per frame (predicted error, running accuracy, work),
    /// then the batch calibration of the whole recording; summary.json, live.csv.
    Live {
        /// A tracked manifest (its calibration sequence is replayed), or a camera
        /// manifest with --watch.
        manifest: PathBuf,
        /// Output folder: summary.json (with the batch calibration of the whole
        /// recording) and live.csv; with --igtl also received.igs.mha and the batch
        /// run's folder, calibration/.
        #[arg(long)]
        out: PathBuf,
        /// Times the recorded rate (0: every frame at once).
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
        /// A camera manifest: take its frames from this folder as they are written.
        #[arg(long)]
        watch: Option<PathBuf>,
        /// With --watch: no new frame for this long ends the acquisition, s.
        #[arg(long, default_value_t = 10.0, value_parser = live::parse_idle_s)]
        idle_s: f64,
        /// A tracked manifest: take the frames from an OpenIGTLink server
        /// (PlusServer) at HOST:PORT instead of its sequence file, and send the
        /// calibration back (device names and the stream's end in the
        /// manifest's `live:`).
        #[arg(long, value_name = "HOST:PORT", conflicts_with_all = ["watch", "speed"], value_parser = live::parse_address)]
        igtl: Option<String>,
        /// With --igtl: reconstruct a volume while the frames arrive, with this
        /// PLUS device set's <VolumeReconstruction> (OutputOrigin and
        /// OutputExtent given), and send it as an IMAGE message `Volume`.
        #[arg(long, value_name = "DEVICE_SET", requires = "igtl")]
        reconstruct: Option<PathBuf>,
        /// With --reconstruct: send the volume every this many inserted frames.
        #[arg(long, default_value_t = 10, requires = "reconstruct", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
        volume_every: u32,
        /// Replace --out even when another command (or no command) wrote it.
        #[arg(long)]
        force: bool,
    },
    /// Solve a run again from its own folder (the frames' poses and feature pixels
    /// in `solve_inputs.yaml`, the manifest it ran with) and compare with its summary.
    Resolve {
        /// A dataset's run folder (`<out>/<experiment>/<dataset>`).
        run: PathBuf,
    },
    /// Segment the N-wire dots of a PLUS sequence on their own: segmentation.csv,
    /// summary.json and report.html in --out.
    Segment(segment::SegmentArgs),
    /// The tracker's lag behind the video from a probe moved over a flat reflector
    /// (PLUS's temporal calibration): summary.json, lines.csv, report.html in --out.
    Temporal {
        /// PLUS sequence file of the tracker's poses (`*TrackerBuffer*.igs.mha`).
        #[arg(long)]
        tracker: PathBuf,
        /// PLUS sequence file of the B-scans of the reflector (`*VideoBuffer*.igs.mha`).
        #[arg(long)]
        video: PathBuf,
        /// Output folder: summary.json, lines.csv, report.html.
        #[arg(long)]
        out: PathBuf,
        /// Replace --out even when another command (or no command) wrote it.
        #[arg(long)]
        force: bool,
    },
    /// Error budget of a rendered rig: its dataset rendered with its error sources
    /// (render.realism) all on, all off, each left out and each alone;
    /// ablation.json, ablation.md and ablation.html in --out.
    Ablate(ablate::AblateArgs),
    /// Dome-phantom layouts for the manifest's lab and sweep, ranked by the
    /// Cramér–Rao bound of their calibration: design.json and design.md in --out.
    Design {
        /// A manifest with a dome (spheres) phantom: its lab and sweep.
        manifest: PathBuf,
        /// Output folder: design.json, design.md.
        #[arg(long)]
        out: PathBuf,
        /// Replace --out even when another command (or no command) wrote it.
        #[arg(long)]
        force: bool,
    },
    /// A dome phantom's printable model (plate, riser, domes, board seat) as a
    /// binary STL in mm, and its sheet (sizes, domes, seat) as <name>.json.
    Phantom {
        /// A manifest with a dome (spheres) phantom.
        manifest: PathBuf,
        /// The STL file to write (binary, mm); its sheet goes beside it as <name>.json.
        #[arg(long)]
        stl: PathBuf,
        /// Replace the STL or its sheet when they exist already.
        #[arg(long)]
        force: bool,
    },
    /// Reconstruct a 3D volume from a tracked PLUS sequence as PLUS's
    /// VolumeReconstructor does (the device set's <VolumeReconstruction>):
    /// volume.mha, summary.json, report.html with slices in --out.
    Reconstruct(reconstruct::ReconstructArgs),
    /// Refine ImageToProbe from the images: the correction that makes two or
    /// more overlapping tracked sweeps compound alike, refined only in the
    /// directions they hold: summary.json, ImageToProbe.xml, report.html in --out.
    Selfcal(selfcal::SelfcalArgs),
    /// Calibrate a camera from chessboard or ChArUco images; writes OpenCV FileStorage YAML.
    #[command(group = clap::ArgGroup::new("pattern").required(true).args(["board", "charuco"]))]
    CalibrateCamera {
        /// Image files and/or folders of images.
        #[arg(required = true)]
        images: Vec<PathBuf>,
        /// A chessboard's inner corners, COLSxROWS (e.g. 9x6).
        #[arg(long, value_parser = crate::detect::board_grid::parse_board)]
        board: Option<[u32; 2]>,
        /// A ChArUco board's squares, XxY (e.g. 5x7); with --marker-mm and --dictionary.
        #[arg(long, value_parser = crate::detect::board_grid::parse_squares, requires_all = ["marker_mm", "dictionary"])]
        charuco: Option<[u32; 2]>,
        /// Square size in millimetres (or any unit: the translations come out in it).
        #[arg(long, value_parser = camera::parse_square_mm)]
        square_mm: f64,
        /// A ChArUco board's marker size, in the unit of --square-mm.
        #[arg(long, requires = "charuco")]
        marker_mm: Option<f64>,
        /// A ChArUco board's dictionary: an OpenCV name (DICT_6X6_250) or a dictionary file.
        #[arg(long, requires = "charuco")]
        dictionary: Option<String>,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
        /// Replace an existing output file.
        #[arg(long)]
        force: bool,
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
    let labels: Vec<_> = manifests.iter().map(crate::pipeline::labels::RunLabels::of).collect();
    if let Err(e) = writer.write_comparison(&out, &labels, &runs, args.quiet) {
        eprintln!("error: {e}");
        return 1;
    }
    if runs.is_empty() {
        return code.max(1);
    }
    code
}

/// Parses the command line, runs the command, and gives its exit code.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Command::Run { args, .. } | Command::Compare { args } = &cli.command {
        crate::core::progress::set_quiet(args.quiet);
    }
    // Every command runs with the same thread setting (OpenCV's included).
    crate::core::parallel::set_threads(match &cli.command {
        Command::Run { threads, .. } => usize::from(*threads),
        _ => 0,
    });
    ExitCode::from(match cli.command {
        Command::Init(args) => init::command(&args),
        Command::Run { args, .. } => run(args, false),
        Command::Compare { args } => run(args, true),
        Command::Check {
            runs,
            baselines,
            update,
            allow_drop,
        } => failure::exit_code(check::command(&runs, &baselines, update, allow_drop)),
        Command::Validate { manifests } => failure::exit_code(manifests::validate(&manifests)),
        Command::Temporal {
            tracker,
            video,
            out,
            force,
        } => failure::exit_code(temporal::command(&video, &tracker, &out, force)),
        Command::Segment(args) => failure::exit_code(segment::command(&args)),
        Command::Live {
            manifest,
            out,
            speed,
            watch,
            idle_s,
            igtl,
            reconstruct,
            volume_every,
            force,
        } => match igtl {
            Some(address) => {
                let volume = reconstruct.map(|config| crate::pipeline::live::volume::VolumeRequest {
                    config,
                    every: volume_every as usize,
                    device: "Volume".into(),
                });
                failure::exit_code(live_igtl::command(&manifest, &address, volume, &out, force))
            }
            None => failure::exit_code(live::command(
                &manifest,
                &out,
                &LiveSource {
                    speed,
                    watch,
                    idle_s,
                    force,
                },
            )),
        },
        Command::Study(args) => failure::exit_code(study::dispatch(args)),
        Command::Synth { manifests, datasets } => failure::exit_code(manifests::synth(&manifests, &datasets)),
        Command::Resolve { run } => failure::exit_code(resolve::command(&run)),
        Command::Ablate(args) => failure::exit_code(ablate::command(&args)),
        Command::Design { manifest, out, force } => failure::exit_code(design::command(&manifest, &out, force)),
        Command::Phantom { manifest, stl, force } => failure::exit_code(phantom::command(&manifest, &stl, force)),
        Command::Reconstruct(args) => failure::exit_code(reconstruct::command(&args)),
        Command::Selfcal(args) => failure::exit_code(selfcal::command(&args)),
        Command::CalibrateCamera {
            images,
            board,
            charuco,
            square_mm,
            marker_mm,
            dictionary,
            out,
            force,
        } => failure::exit_code(match (board, charuco, marker_mm, dictionary) {
            (_, Some(squares), Some(marker_mm), Some(dictionary)) => {
                let spec = crate::detect::charuco_calibration::CharucoSpec {
                    squares,
                    square_mm,
                    marker_mm,
                    dictionary,
                };
                camera::charuco_command(&images, &spec, &out, force)
            }
            (Some(board), ..) => camera::command(&images, board, square_mm, &out, force),
            _ => Err(failure::Failure::bad_input(
                "--board COLSxROWS, or --charuco XxY with --marker-mm and --dictionary".to_string(),
            )),
        }),
    })
}
