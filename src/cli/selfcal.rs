//! `probecal selfcal`: the correction of ImageToProbe that makes overlapping
//! tracked sweeps compound alike; 0 written, 2 when an input cannot be used,
//! 1 when the search or the outputs fail.

use std::path::PathBuf;

use super::failure::Failure;
use crate::estimate::selfcal::check::{CheckSettings, Verdict};
use crate::estimate::selfcal::refine::SearchSettings;
use crate::pipeline::selfcal::lag::LagScan;
use crate::pipeline::selfcal::load::Framing;
use crate::pipeline::selfcal::{SelfcalError, SelfcalInputs};
use crate::results::selfcal::SelfcalSummary;

/// The lag profile's step, s.
const LAG_STEP_S: f64 = 0.01;

/// `probecal selfcal`'s arguments.
#[derive(Debug, clap::Args)]
pub struct SelfcalArgs {
    /// Two or more PLUS sequence files (.mha, .igs.mha) of tracked 8-bit
    /// B-scans whose sweeps overlap.
    #[arg(required = true, num_args = 2..)]
    pub sequences: Vec<PathBuf>,
    /// The PLUS device set: the fixed transforms (CoordinateDefinitions) from
    /// Probe to Reference, and its <VolumeReconstruction> clip rectangle and
    /// frame names when it has one.
    #[arg(long)]
    pub config: PathBuf,
    /// The start: a probecal run folder of a PLUS recording or a PLUS
    /// calibration result (.xml).
    #[arg(long)]
    pub calibration: PathBuf,
    /// Output folder: summary.json, ImageToProbe.xml, report.html (written
    /// whole on success).
    #[arg(long)]
    pub out: PathBuf,
    /// The tracker's lag behind the images, s (-1 to 1). Default: the
    /// --calibration run folder's time_offset_s, else none.
    #[arg(long, allow_hyphen_values = true, value_parser = super::reconstruct::tracker_lag)]
    pub tracker_lag: Option<f64>,
    /// The finest voxel the sweeps are compared on, mm (coarser grids of 2 and
    /// 4 times it come first).
    #[arg(long, default_value_t = 1.0, value_parser = size_mm)]
    pub voxel_mm: f64,
    /// Pixels are averaged in squares of this side before compounding.
    /// Default: about half the voxel, by the start's pixel size.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub block_px: Option<u16>,
    /// Each block less the mean of the blocks within this distance, mm:
    /// slow changes of brightness left out (sparse echoes in water). Default: none.
    #[arg(long, value_parser = size_mm)]
    pub background_mm: Option<f64>,
    /// The start is consistent with the sweeps when their own calibration
    /// puts the image's corners at most this far from it, mm.
    #[arg(long, default_value_t = 1.0, value_parser = size_mm)]
    pub tolerance_mm: f64,
    /// Also profile the sweeps' agreement against the tracker's lag at the
    /// refined calibration, over this many ms each side of the start's lag in
    /// steps of 10 ms (10 to 200), and say the lag they prefer. Not applied.
    #[arg(long, value_parser = lag_range_ms)]
    pub lag_range_ms: Option<f64>,

    /// Check the start: exit 1 (outputs written) when it is not consistent
    /// with the sweeps, as after a bumped marker, or when the sweeps hold no
    /// direction to check it along.
    #[arg(long)]
    pub check: bool,
    /// Replace --out even when another command (or no command) wrote it.
    #[arg(long)]
    pub force: bool,
}

fn size_mm(text: &str) -> Result<f64, super::failure::ValueError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && (0.05..=20.0).contains(&v) => Ok(v),
        _ => Err(super::failure::ValueError::VoxelMm(text.to_string())),
    }
}

fn lag_range_ms(text: &str) -> Result<f64, super::failure::ValueError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && (10.0..=200.0).contains(&v) => Ok(v),
        _ => Err(super::failure::ValueError::LagRangeMs(text.to_string())),
    }
}

pub fn command(args: &SelfcalArgs) -> Result<(), Failure> {
    let mut read: Vec<&std::path::Path> = args.sequences.iter().map(PathBuf::as_path).collect();
    read.push(&args.config);
    read.push(&args.calibration);
    let folder = crate::io::output::OutputFolder::claim(&args.out, "selfcal", &read, args.force)?;
    let given = crate::results::calibration::read(&args.calibration).map_err(Failure::bad_input)?;
    let framing = match crate::io::plus::volume_config::VolumeSettings::read(&args.config) {
        Ok(v) => Framing {
            image_frame: v.image_frame,
            reference_frame: v.reference_frame,
            clip_px: (v.clip_size_px != [0, 0]).then_some([
                v.clip_origin_px[0],
                v.clip_origin_px[1],
                v.clip_size_px[0],
                v.clip_size_px[1],
            ]),
        },
        Err(_) => Framing {
            image_frame: "Image".into(),
            reference_frame: "Reference".into(),
            clip_px: None,
        },
    };
    let mut settings = SearchSettings::default();
    settings.comparison.voxel_mm = args.voxel_mm;
    settings.step_mm = 2.0 * args.voxel_mm;
    let lag = args
        .tracker_lag
        .or(given.tracker_lag_s.as_ref().map(|l| l.0))
        .unwrap_or(0.0);
    let inputs = SelfcalInputs {
        sequences: args.sequences.clone(),
        config: args.config.clone(),
        framing,
        start: (given.image_to_probe, given.source),
        tracker_lag_s: lag,
        block_px: args.block_px.map(usize::from),
        background_mm: args.background_mm,
        settings,
        check: CheckSettings {
            tolerance_mm: args.tolerance_mm,
            ..CheckSettings::default()
        },
        lag_scan: args.lag_range_ms.map(|ms| LagScan {
            step_s: LAG_STEP_S,
            steps: (ms / 1e3 / LAG_STEP_S).round() as usize,
        }),
    };
    let run = crate::pipeline::selfcal::run(&inputs).map_err(|e| match e {
        SelfcalError::Search(_) | SelfcalError::Grid(_) => Failure::failed(e),
        _ => Failure::bad_input(e),
    })?;
    let summary = crate::report::plus_tools::selfcal::write(&run, folder.path()).map_err(Failure::failed)?;
    folder.commit().map_err(Failure::failed)?;
    let verdict = say(&summary, &args.out);
    if args.check && summary.check.verdict != Verdict::Consistent {
        return Err(Failure::failed(verdict));
    }
    println!("{verdict}");
    Ok(())
}

/// Prints the refinement and the lag to the console; gives the check's line.
fn say(summary: &SelfcalSummary, out: &std::path::Path) -> String {
    let held: Vec<&str> = summary
        .directions
        .iter()
        .filter(|d| d.held)
        .map(|d| d.mostly.as_str())
        .collect();
    let left: Vec<&str> = summary
        .directions
        .iter()
        .filter(|d| !d.held)
        .map(|d| d.mostly.as_str())
        .collect();
    println!(
        "correlation {:.4} -> {:.4}; corners moved at most {:.2} mm; refined: {}; left at the start: {}; written to {}",
        summary.correlation_start,
        summary.correlation_end,
        summary.corner_change_mm,
        held.join(" | "),
        if left.is_empty() {
            "none".to_string()
        } else {
            left.join(" | ")
        },
        out.display()
    );
    let c = &summary.check;
    let verdict = format!(
        "the start is {}: their own calibration puts the corners {:.2} mm from it (tolerance {:.2} mm; noise alone goes past it {:.1} % of the time; not checked: {})",
        c.verdict.words(),
        c.offset_mm,
        c.tolerance_mm,
        c.false_alarm_rate * 100.0,
        if c.not_checked.is_empty() {
            "none".to_string()
        } else {
            c.not_checked.join(" | ")
        },
    );
    if let Some(p) = &summary.lag_profile {
        match (p.best_s, &p.no_best) {
            (Some(best), _) => println!(
                "lag: the sweeps agree best at {:.1} ms{} (refined at {:.1} ms; not applied)",
                best * 1e3,
                lag_error(summary),
                summary.tracker_lag_s * 1e3
            ),
            (None, why) => println!("lag: no lag preferred: {}", why.as_deref().unwrap_or("")),
        }
        if let Some(caution) = crate::report::plus_tools::selfcal::lag_caution(p, summary.tracker_lag_s) {
            println!("note: {caution}");
        }
    }
    verdict
}

/// " ± SE ms" of the lag profile's best lag, when it has one.
fn lag_error(summary: &SelfcalSummary) -> String {
    summary
        .lag_profile
        .as_ref()
        .and_then(|p| p.standard_error_s)
        .map_or(String::new(), |se| format!(" ± {:.1} ms", se * 1e3))
}
