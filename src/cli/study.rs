//! `probecal study` and `probecal study merge`: the σ-table and the Monte Carlo
//! study of a manifest (whole, or one slice of its seeds as a shard file), and
//! a study joined from its shards; 0 written, 2 bad input, 1 failed.

use std::path::{Path, PathBuf};

use super::failure::Failure;
use crate::core::limits::MAX_SEEDS;
use crate::io::output::OutputFiles;
use crate::pipeline::study::shard::{self, Shard, ShardFile};
use crate::pipeline::study::BoundModel;
use crate::report::study::{sigma_table, write, STUDY_FILES};

/// `probecal study`'s arguments.
#[derive(Debug, Clone, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct StudyArgs {
    #[command(subcommand)]
    pub merge: Option<StudyMerge>,
    /// A manifest of a rendered rig (its first dataset is rendered once per seed).
    #[arg(required = true)]
    pub manifest: Option<PathBuf>,
    /// Run every N-th seed from the K-th only (1-based), into
    /// <out>/shard_K_of_N.yaml; `study merge` joins the slices.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Seeds rendered (0: the σ-table only).
    #[arg(long, default_value_t = 50)]
    pub seeds: u64,
    /// The first seed rendered; the study renders seeds first_seed.. first_seed+seeds-1.
    #[arg(long, default_value_t = 1000)]
    pub first_seed: u64,
    /// Output folder: study.json, study.md, study.html, the σ-table.
    #[arg(long, default_value = "reports/study")]
    pub out: PathBuf,
    /// Where rendered datasets are cached.
    #[arg(long, default_value = "datasets")]
    pub datasets: PathBuf,
    /// Keep the rendered datasets (they are removed after each seed's run).
    #[arg(long)]
    pub keep_datasets: bool,
    /// Replace study files (or a shard file) in --out that another command, or
    /// none, wrote.
    #[arg(long)]
    pub force: bool,
}

/// `probecal study merge`.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum StudyMerge {
    /// Join the shard files of one study into the study.json and pages one run writes.
    Merge {
        /// The shard files (`shard_K_of_N.yaml`) of one study, every K once.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Output folder of the joined study.
        #[arg(long, default_value = "reports/study")]
        out: PathBuf,
        /// Replace study files in --out that another command, or none, wrote.
        #[arg(long)]
        force: bool,
    },
    /// Pair two studies on the seeds they share: per method the mean difference
    /// of the seeds' errors (B minus A), its 90 % interval (Student's t below 30
    /// seeds, a percentile bootstrap from 30) and the seeds each was the lower
    /// on; the frames each kept. Printed, and written as JSON with --out
    Compare {
        /// The first study: its study.json or its folder.
        a: PathBuf,
        /// The second study, compared against the first.
        b: PathBuf,
        /// Only this method (by its name in the studies' tables).
        #[arg(long)]
        method: Option<String>,
        /// Pair --method of the first study with this method of the second
        /// (the two may be the same study): one method against another on the
        /// same seeds.
        #[arg(long, requires = "method")]
        method_b: Option<String>,
        /// Write the comparison here as JSON (and beside it the Markdown, .md).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace --out (and its .md) when they exist already.
        #[arg(long, requires = "out")]
        force: bool,
    },
}

/// `probecal study` or `probecal study merge`; the exit code.
pub fn dispatch(args: StudyArgs) -> Result<(), Failure> {
    match &args.merge {
        Some(StudyMerge::Merge { shards, out, force }) => merge(shards, out, *force),
        Some(StudyMerge::Compare {
            a,
            b,
            method,
            method_b,
            out,
            force,
        }) => compare(a, b, [method.as_deref(), method_b.as_deref()], out.as_deref(), *force),
        None => command(&args),
    }
}

/// `probecal study`: the σ-table and, for `seeds` seeds from `first_seed`, the
/// Monte Carlo study of the manifest, written to `out` (or one slice of the
/// seeds, written as a shard file); the exit code.
pub fn command(request: &StudyArgs) -> Result<(), Failure> {
    let path = request.manifest.as_deref().unwrap_or(Path::new(""));
    let manifest = crate::manifest::Manifest::load(path).map_err(Failure::bad_input)?;
    crate::core::progress::set_quiet(true);
    let (seeds, first_seed) = (request.seeds, request.first_seed);
    let last = first_seed.checked_add(seeds).filter(|_| seeds <= MAX_SEEDS);
    let Some(last) = last else {
        return Err(Failure::bad_input(format!(
            "--seeds {seeds} from --first-seed {first_seed}: at most {MAX_SEEDS} seeds, and the last below 2^64"
        )));
    };
    let all: Vec<u64> = (first_seed..last).collect();
    let mut log = |l: &str| eprintln!("{l}");
    if let Some(shard) = request.shard {
        let (_, manifest_sha256) =
            crate::io::fs::file_sha256(path).map_err(|e| Failure::bad_input(format!("{}: {e}", path.display())))?;
        let name = shard.file_name();
        let claim = claim(&request.out, &[&name], &[path, &request.datasets], request.force, false)?;
        let mine = shard.seeds_of(&all);
        let results =
            crate::pipeline::study::seed_results(&manifest, &mine, &request.datasets, request.keep_datasets, &mut log)
                .map_err(Failure::failed)?;
        let file = ShardFile {
            experiment: manifest.experiment.clone(),
            manifest_sha256,
            first_seed,
            seeds,
            shard,
            bound: BoundModel::of(&manifest),
            results,
        };
        let written = shard::write(&request.out, &file)
            .map_err(|e| Failure::failed(format!("{}: {e}", request.out.display())))?;
        claim.commit().map_err(Failure::failed)?;
        eprintln!(
            "shard {}/{}: {} seeds; written to {}",
            shard.index,
            shard.count,
            mine.len(),
            written.display()
        );
        return Ok(());
    }
    let claim = claim(
        &request.out,
        &STUDY_FILES,
        &[path, &request.datasets],
        request.force,
        true,
    )?;
    let sigma = sigma_table();
    let monte_carlo = if all.is_empty() {
        None
    } else {
        Some(
            crate::pipeline::study::monte_carlo(&manifest, &all, &request.datasets, request.keep_datasets, &mut log)
                .map_err(Failure::failed)?,
        )
    };
    write(&request.out, &sigma, monte_carlo.as_ref()).map_err(Failure::failed)?;
    claim.commit().map_err(Failure::failed)?;
    eprintln!("written to {}", request.out.display());
    Ok(())
}

/// `probecal study merge`: the study from its shard files, written to `out`.
pub fn merge(files: &[PathBuf], out: &Path, force: bool) -> Result<(), Failure> {
    let inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let claim = claim(out, &STUDY_FILES, &inputs, force, true)?;
    let mut shards = Vec::new();
    for path in files {
        shards.push((path.clone(), shard::read(path).map_err(Failure::bad_input)?));
    }
    let (experiment, bound, results) = shard::join(&shards).map_err(Failure::bad_input)?;
    let monte_carlo = crate::pipeline::study::summarise(&experiment, bound, results);
    let sigma = sigma_table();
    write(out, &sigma, Some(&monte_carlo)).map_err(|e| Failure::failed(format!("{}: {e}", out.display())))?;
    claim.commit().map_err(Failure::failed)?;
    eprintln!("{} shards merged; written to {}", shards.len(), out.display());
    Ok(())
}

/// `out` claimed for a study's `names`; refused before any seed is rendered.
fn claim(out: &Path, names: &[&str], inputs: &[&Path], force: bool, exclusive: bool) -> Result<OutputFiles, Failure> {
    Ok(OutputFiles::claim(out, "study", names, inputs, force, exclusive)?)
}

/// `probecal study compare`: the paired comparison, printed and written to `out`.
/// `methods`: only this method, and the method of `b` it is paired with.
pub fn compare(a: &Path, b: &Path, methods: [Option<&str>; 2], out: Option<&Path>, force: bool) -> Result<(), Failure> {
    use crate::report::study::compare as study_compare;
    if let Some(out) = out {
        if out.extension().is_none_or(|e| e != "json") {
            return Err(Failure::bad_input(format!(
                "{}: --out is the comparison's JSON file (name it .json; the Markdown goes beside it as .md)",
                out.display()
            )));
        }
        for written in [out.to_path_buf(), out.with_extension("md")] {
            if let Some(why) = crate::io::output::file_refusal(&written, "study compare", &[a, b], force) {
                return Err(Failure::bad_input(format!("{}: {why}", written.display())));
            }
        }
    }
    let paired = study_compare::compare(a, b, methods[0], methods[1]).map_err(Failure::bad_input)?;
    let markdown = study_compare::markdown(&paired);
    println!("{markdown}");
    if let Some(out) = out {
        let json = serde_json::to_string_pretty(&paired).map_err(|e| Failure::failed(e.to_string()))?;
        let write = |path: &Path, bytes: &[u8]| {
            crate::io::fs::write_atomic(path, bytes).map_err(|e| Failure::failed(format!("{}: {e}", path.display())))
        };
        write(out, format!("{json}\n").as_bytes())?;
        write(&out.with_extension("md"), markdown.as_bytes())?;
    }
    Ok(())
}
