//! `probecal segment`: the N-wire dots of a PLUS sequence segmented on their
//! own, optionally scored against PLUS's segmentation; 0 written, 1 when the
//! inputs cannot be read or the outputs written.

use super::failure::Failure;
use crate::results::segmentation::{against_plus, SegmentationSummary};

/// `probecal segment`'s arguments.
#[derive(Debug, clap::Args)]
pub struct SegmentArgs {
    /// A PLUS sequence file (.mha).
    pub sequence: std::path::PathBuf,
    /// The PLUS device set with the phantom (and its segmentation settings).
    #[arg(long)]
    pub config: std::path::PathBuf,
    /// The output folder (written whole on success).
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// PLUS's segmentation of the same sequence (a segmentation test baseline
    /// or a calibration result XML): recall, extra frames and point distances
    /// on the page and in summary.json.
    #[arg(long)]
    pub plus_baseline: Option<std::path::PathBuf>,
    /// Replace --out even when another command (or no command) wrote it.
    #[arg(long)]
    pub force: bool,
}

/// `probecal segment`: exit code 0 on success, 1 when the inputs cannot be read
/// or the outputs written.
pub fn command(args: &SegmentArgs) -> Result<(), Failure> {
    let (sequence, config, out) = (&args.sequence, &args.config, &args.out);
    let plus_baseline = args.plus_baseline.as_deref();
    let inputs: Vec<&std::path::Path> = [Some(sequence.as_path()), Some(config.as_path()), plus_baseline]
        .into_iter()
        .flatten()
        .collect();
    let folder = crate::io::output::OutputFolder::claim(out, "segment", &inputs, args.force)?;
    let run = crate::pipeline::tracked::segment::run(sequence, config).map_err(Failure::failed)?;
    let baseline = plus_baseline
        .map(|p| against_plus(&run, p))
        .transpose()
        .map_err(Failure::failed)?;
    let summary = SegmentationSummary::of(&run, baseline);
    crate::report::plus_tools::segment::write(&summary, &run, folder.path()).map_err(Failure::failed)?;
    folder.commit().map_err(Failure::failed)?;
    let found = run.frames.iter().filter(|f| f.rejected.is_none()).count();
    let role = crate::pipeline::sequence_frames::Role::Calibration;
    if let Some(w) = crate::pipeline::sequence_frames::rejection_warning(&run.frames, role, "sequence") {
        eprintln!("warning: {w}");
    }
    if let Some(b) = &summary.plus_baseline {
        let s = &b.score;
        println!(
            "against PLUS's segmentation ({}): {} of the {} frames PLUS segmented found here ({:.1} %), {} found here only; mean distance to PLUS's points {}",
            b.section,
            s.both_frames,
            s.plus_frames,
            100.0 * s.recall,
            s.extra_frames.len(),
            s.point_distance_px
                .map(|d| format!("{:.3} px", d.mean))
                .unwrap_or_else(|| "—".into())
        );
    }
    println!(
        "{found} of {} frames segmented; written to {}",
        run.frames.len(),
        out.display()
    );
    Ok(())
}
