//! `probecal ablate`: the error budget of a rendered rig; 0 written, 2 bad
//! input, 1 failed.

use std::path::PathBuf;

use super::failure::Failure;
use crate::pipeline::run::RunError;

/// `probecal ablate`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct AblateArgs {
    /// A manifest of a rendered rig (its first dataset and `render.realism`).
    pub manifest: PathBuf,
    /// Output folder: ablation.json, ablation.md, ablation.html.
    #[arg(long)]
    pub out: PathBuf,
    /// Where rendered datasets are cached.
    #[arg(long, default_value = "datasets")]
    pub datasets: PathBuf,
    /// Keep the variants' rendered datasets.
    #[arg(long)]
    pub keep_datasets: bool,
    /// Run only these variants (e.g. "only speed_of_sound"; repeatable).
    #[arg(long)]
    pub only: Vec<String>,
    /// Replace --out even when another command (or no command) wrote it.
    #[arg(long)]
    pub force: bool,
}

pub fn command(args: &AblateArgs) -> Result<(), Failure> {
    let (manifest_path, out) = (&args.manifest, &args.out);
    let manifest = crate::manifest::Manifest::load(manifest_path).map_err(Failure::bad_input)?;
    let folder = crate::io::output::OutputFolder::claim(out, "ablate", &[manifest_path, &args.datasets], args.force)?;
    let result = crate::pipeline::study::ablation::ablate(
        &manifest,
        &args.datasets,
        args.keep_datasets,
        &args.only,
        &mut |line| eprintln!("{line}"),
    );
    let a = match result {
        Ok(a) => a,
        Err(RunError::Unsupported(why)) => {
            return Err(Failure::bad_input(format!("{}: {why}", manifest_path.display())))
        }
        Err(e) => return Err(Failure::failed(e)),
    };
    let md = crate::report::study::ablation::write(&a, folder.path()).map_err(Failure::failed)?;
    folder.commit().map_err(Failure::failed)?;
    print!("{md}");
    println!(
        "\nwritten to {} (ablation.json, ablation.md, ablation.html)",
        out.display()
    );
    Ok(())
}
