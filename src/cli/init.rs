//! `probecal init`: a commented manifest for one's own recording.

use std::path::PathBuf;

use crate::manifest::init::{folder_manifest, folder_name, plus_manifest, InitError, PlusRecording};

/// Write a commented manifest for a recording: a PLUS recording (`--plus-config`,
/// `--calibration`), or a folder of frames (`--folder`).
#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["plus_config", "folder"])))]
pub struct InitArgs {
    /// PLUS device-set configuration (.xml) the recording was made with: the
    /// N-wire phantom, the pixel size and the segmentation settings.
    #[arg(long, requires = "calibration", conflicts_with = "folder")]
    pub plus_config: Option<PathBuf>,
    /// PLUS sequence file (.igs.mha / .mha) of the calibration frames.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// PLUS sequence file of held-out validation frames (PRE3D is reported on them).
    #[arg(long, requires = "plus_config")]
    pub validation: Option<PathBuf>,
    /// The probe marker's transform in the sequence (e.g. ProbeToTracker), when
    /// the device set's frames do not tell it.
    #[arg(long, requires = "reference_transform")]
    pub probe_transform: Option<String>,
    /// The phantom's reference marker's transform (e.g. ReferenceToTracker).
    #[arg(long, requires = "probe_transform")]
    pub reference_transform: Option<String>,
    /// PLUS's own calibration result of this recording (fCal's
    /// ProbeCalibrationResult .xml): the report compares it like for like.
    #[arg(long, requires = "plus_config")]
    pub plus_result: Option<PathBuf>,
    /// A recorded folder: frames.csv, the photos and B-scans, and
    /// camera_calibration/ or tracker_poses.csv.
    #[arg(long)]
    pub folder: Option<PathBuf>,
    /// The experiment's name (names the run folder). Default: the manifest file's name.
    #[arg(long)]
    pub experiment: Option<String>,
    /// The manifest to write (YAML); an existing file is replaced only with --force.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing manifest at --out.
    #[arg(long)]
    pub force: bool,
}

/// Writes the manifest; 0 when written, 2 when an input or the manifest is wrong.
pub fn command(args: &InitArgs) -> u8 {
    match write(args) {
        Ok(()) => {
            eprintln!(
                "wrote {}: check it with `probecal validate {0}`, run it with `probecal run {0} --out runs/{}`",
                args.out.display(),
                folder_name(&args.out, "experiment")
            );
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// A tracked manifest's text, once its recordings pass the checks `run` makes
/// before it uses a frame (what `init` writes, `validate` and `run` accept).
fn preflighted(text: String, out: &std::path::Path) -> Result<String, InitError> {
    let refused = |message: String| InitError::Input {
        path: out.to_path_buf(),
        message,
    };
    let manifest =
        crate::manifest::tracked::TrackedManifest::from_text(out, &text).map_err(|e| refused(e.to_string()))?;
    let inputs = crate::pipeline::tracked::TrackedInputs::from_manifest(&manifest);
    crate::pipeline::tracked::preflight(&inputs).map_err(|e| refused(format!("not written: {e}")))?;
    Ok(text)
}

fn write(args: &InitArgs) -> Result<(), InitError> {
    // Even with --force, the manifest never replaces the recording it describes.
    let read: Vec<&std::path::Path> = [
        &args.plus_config,
        &args.calibration,
        &args.validation,
        &args.plus_result,
        &args.folder,
    ]
    .into_iter()
    .flatten()
    .map(|p| p.as_path())
    .collect();
    if let Some(why) = crate::io::output::file_refusal(&args.out, "init", &read, args.force) {
        return Err(InitError::Input {
            path: args.out.clone(),
            message: why,
        });
    }
    let experiment = args
        .experiment
        .clone()
        .unwrap_or_else(|| folder_name(&args.out, "experiment"));
    let text = match (&args.plus_config, &args.calibration, &args.folder) {
        (Some(config), Some(calibration), None) => preflighted(
            plus_manifest(
                &PlusRecording {
                    config,
                    calibration,
                    validation: args.validation.as_deref(),
                    probe_transform: args.probe_transform.as_deref(),
                    reference_transform: args.reference_transform.as_deref(),
                    plus_result: args.plus_result.as_deref(),
                },
                &args.out,
                &experiment,
            )?,
            &args.out,
        )?,
        (None, None, Some(folder)) => folder_manifest(folder, &args.out, &experiment)?,
        _ => {
            return Err(InitError::Input {
                path: args.out.clone(),
                message: "give --plus-config with --calibration, or --folder".into(),
            })
        }
    };
    crate::io::fs::write_atomic(&args.out, text.as_bytes()).map_err(|e| InitError::Read(e.to_string()))
}
