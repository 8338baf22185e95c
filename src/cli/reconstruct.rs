//! `probecal reconstruct`: a tracked sequence into a 3D volume as PLUS's
//! `VolumeReconstructor` makes it; 0 written, 2 when an input cannot be used,
//! 1 when the outputs cannot be written.

use std::path::PathBuf;

use super::failure::Failure;
use crate::pipeline::reconstruct::ReconstructInputs;

/// `probecal reconstruct`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ReconstructArgs {
    /// A PLUS sequence file (.mha, .igs.mha) of tracked B-scans, 8-bit or float.
    pub sequence: PathBuf,
    /// The PLUS device set: its <VolumeReconstruction> settings and the fixed
    /// transforms (CoordinateDefinitions) that lead from Image to Reference.
    #[arg(long)]
    pub config: PathBuf,
    /// Output folder: volume.mha, summary.json, report.html and the pictures
    /// (written whole on success; an existing folder must be a reconstruction's).
    #[arg(long)]
    pub out: PathBuf,
    /// A probecal run folder of a PLUS recording (a run's --out folder at any
    /// level: the one tracked run below it), or a PLUS calibration result
    /// (.xml): its ImageToProbe replaces the device set's.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// The tracker's lag behind the images, s (-1 to 1): every tracked transform
    /// is read along its recorded trajectory at the image's time plus the lag
    /// (PLUS's LocalTimeOffsetSec of the tracker). Default: the --calibration
    /// run folder's time_offset_s, else none.
    #[arg(long, allow_hyphen_values = true, value_parser = tracker_lag)]
    pub tracker_lag: Option<f64>,
    /// A PLUS device set with the phantom's N-wires (<PhantomDefinition>) and
    /// its registration (PhantomToReference): each wire's position error,
    /// straightness and thickness in the volume, in summary.json and on the page.
    #[arg(long)]
    pub wires: Option<PathBuf>,
    /// Worker threads (0: one per core; the device set's NumberOfThreads is not
    /// used). The volume does not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u16).range(0..=crate::core::limits::MAX_THREADS as i64))]
    pub threads: Option<u16>,
    /// Also write volume.nrrd.
    #[arg(long)]
    pub nrrd: bool,
    /// A reference volume (e.g. PLUS's output for the same inputs): agreement.json
    /// gives the geometry's differences, the share of voxels within one grey
    /// level, the Dice of the nonzero masks and whether the files are identical.
    #[arg(long)]
    pub compare: Option<PathBuf>,
    /// Leave the run times out of summary.json and report.html, so that the
    /// same inputs give byte-identical outputs.
    #[arg(long)]
    pub no_times: bool,
    /// Replace --out even when another command (or no command) wrote it.
    #[arg(long)]
    pub force: bool,
}

pub fn command(args: &ReconstructArgs) -> Result<(), Failure> {
    let mut read: Vec<&std::path::Path> = vec![&args.sequence, &args.config];
    read.extend(args.calibration.as_deref());
    read.extend(args.compare.as_deref());
    read.extend(args.wires.as_deref());
    let named = crate::io::plus::volume_config::VolumeSettings::named_files(&args.config);
    read.extend(named.iter().map(PathBuf::as_path));
    // A folder of an earlier reconstruction (before folders were marked) is this command's.
    let replace = args.force || crate::report::reconstruct::holds_reconstruction(&args.out);
    let folder = crate::io::output::OutputFolder::claim(&args.out, "reconstruct", &read, replace)?;
    let given = args
        .calibration
        .as_deref()
        .map(crate::results::calibration::read)
        .transpose()
        .map_err(Failure::bad_input)?;
    let given_lag = given.as_ref().and_then(|g| g.tracker_lag_s.clone());
    let inputs = ReconstructInputs {
        sequence: args.sequence.clone(),
        config: args.config.clone(),
        threads: args.threads.map(usize::from),
        wires: args.wires.clone(),
        image_to_probe: given.map(|g| (g.image_to_probe, g.source)),
        tracker_lag_s: args.tracker_lag.map(|s| (s, "--tracker-lag".to_string())).or(given_lag),
    };
    let mut run = crate::pipeline::reconstruct::run(&inputs).map_err(Failure::bad_input)?;
    if args.no_times {
        run.timings.clear();
    }
    let reference = args
        .compare
        .as_deref()
        .map(crate::io::volume_file::read_metaimage)
        .transpose()
        .map_err(Failure::bad_input)?;
    let options = crate::report::reconstruct::WriteOptions {
        nrrd: args.nrrd,
        compare: args.compare.as_deref().zip(reference.as_ref()),
    };
    crate::report::reconstruct::write(&run, folder.path(), &options).map_err(Failure::failed)?;
    folder.commit().map_err(Failure::failed)?;
    if !run.skipped.is_empty() {
        eprintln!(
            "warning: {} of {} frames skipped (first: frame {}: {}); see summary.json",
            run.skipped.len(),
            run.frames_total,
            run.skipped[0].index,
            run.skipped[0].reason
        );
    }
    let g = run.volume.grid();
    println!(
        "{} of {} frames into {}x{}x{} voxels ({} filled, {} by hole filling); written to {}",
        run.frames_used.len(),
        run.frames_total,
        g.dims[0],
        g.dims[1],
        g.dims[2],
        run.voxels_filled_after_holes,
        run.voxels_filled_after_holes - run.voxels_filled_before_holes,
        args.out.display()
    );
    Ok(())
}

/// A lag in seconds within ±1 s.
pub(super) fn tracker_lag(text: &str) -> Result<f64, super::failure::ValueError> {
    let s: f64 = text
        .parse()
        .map_err(|e: std::num::ParseFloatError| super::failure::ValueError::NotSeconds(e.to_string()))?;
    if s.is_finite() && s.abs() <= 1.0 {
        Ok(s)
    } else {
        Err(super::failure::ValueError::Lag(s))
    }
}
