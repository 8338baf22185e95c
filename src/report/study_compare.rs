//! Two Monte Carlo studies compared on the seeds they share: per method, the
//! mean difference of the seeds' errors (second minus first), its bootstrap
//! 90 % interval over the seeds, and on how many seeds each was the lower;
//! and the frames each kept. A difference whose interval holds zero is no
//! difference these seeds can show.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::study::StudyFile;
use crate::core::stats::mean_difference_interval;
use crate::pipeline::study::{MonteCarlo, INTERVAL_LEVEL};

/// One method's paired comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedMethod {
    pub method: String,
    /// Mean over the common seeds of each study's error, mm.
    pub mean_a_mm: f64,
    pub mean_b_mm: f64,
    /// Mean of (b − a) over the common seeds, mm: negative when b is the lower.
    pub mean_difference_mm: f64,
    /// Its 90 % interval (percentile bootstrap over the seeds), mm.
    pub interval_90_mm: [f64; 2],
    /// Seeds on which b's error is below a's, and above it.
    pub b_lower_seeds: usize,
    pub a_lower_seeds: usize,
    /// `lower`, `higher` (b against a) or `no difference shown` (the interval holds 0).
    pub verdict: String,
    /// Each study's RMS error over a's Cramér–Rao bound, `[a, b]`, on the common
    /// seeds a has a bound for: when a states the rig's true model and b
    /// misstates it (b's own ratio is over b's bound, which assumes b's model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_over_a_bound: Option<[f64; 2]>,
}

/// The frames each study kept per seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FramesKept {
    pub mean_a: f64,
    pub mean_b: f64,
    pub min_a: usize,
    pub min_b: usize,
}

/// `probecal study compare`'s result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedStudies {
    pub a: String,
    pub b: String,
    pub a_file: PathBuf,
    pub b_file: PathBuf,
    /// The seeds both studies ran.
    pub seeds: Vec<u64>,
    pub frames_kept: FramesKept,
    pub methods: Vec<PairedMethod>,
}

#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error("{0}")]
    Read(#[from] super::error::ReadError),
    #[error("{0}: no Monte Carlo study in it (a σ-table only)")]
    NoStudy(PathBuf),
    #[error("{a} and {b} share {n} seeds; a paired comparison needs at least 2")]
    FewSeeds { a: PathBuf, b: PathBuf, n: usize },
    #[error("{0}: method `{1}` is not in both studies")]
    NoMethod(PathBuf, String),
}

/// A study file, or the `study.json` of a folder.
fn study_of(path: &Path) -> Result<(PathBuf, MonteCarlo), CompareError> {
    let file = if path.is_dir() {
        path.join("study.json")
    } else {
        path.to_path_buf()
    };
    let study = StudyFile::read(&file)?;
    let mc = study.monte_carlo.ok_or_else(|| CompareError::NoStudy(file.clone()))?;
    Ok((file, mc))
}

/// Pairs the studies at `a` and `b` on their common seeds; every method they
/// share, or only `method`.
pub fn compare(a: &Path, b: &Path, method: Option<&str>) -> Result<PairedStudies, CompareError> {
    let (a_file, a_mc) = study_of(a)?;
    let (b_file, b_mc) = study_of(b)?;
    let pairs: Vec<_> = a_mc
        .seeds
        .iter()
        .filter_map(|sa| b_mc.seeds.iter().find(|sb| sb.seed == sa.seed).map(|sb| (sa, sb)))
        .collect();
    if pairs.len() < 2 {
        return Err(CompareError::FewSeeds {
            a: a_file,
            b: b_file,
            n: pairs.len(),
        });
    }
    let names: Vec<String> = a_mc
        .methods
        .iter()
        .map(|m| m.method.clone())
        .filter(|m| b_mc.methods.iter().any(|n| &n.method == m))
        .filter(|m| method.is_none_or(|want| want == m))
        .collect();
    if let Some(want) = method.filter(|_| names.is_empty()) {
        return Err(CompareError::NoMethod(b_file, want.to_string()));
    }
    let error_of =
        |r: &crate::pipeline::study::SeedResult, m: &str| r.rms_error_mm.iter().find(|(n, _)| n == m).map(|(_, e)| *e);
    let mut methods = Vec::new();
    for name in names {
        let both: Vec<(f64, f64)> = pairs
            .iter()
            .filter_map(|(sa, sb)| Some((error_of(sa, &name)?, error_of(sb, &name)?)))
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        // (a's error, b's error, a's bound) on the seeds a has a bound for.
        let bounded: Vec<(f64, f64, f64)> = pairs
            .iter()
            .filter_map(|(sa, sb)| Some((error_of(sa, &name)?, error_of(sb, &name)?, sa.crlb_rms_mm?)))
            .collect();
        let over_bound = |pick: fn(&(f64, f64, f64)) -> f64| {
            let ratio: Vec<(f64, f64)> = bounded.iter().map(|t| (pick(t), t.2)).collect();
            crate::core::stats::rms_ratio(&ratio)
        };
        let rms_over_a_bound = if bounded.len() == both.len() && bounded.len() >= 2 {
            over_bound(|t| t.0).zip(over_bound(|t| t.1)).map(|(a, b)| [a, b])
        } else {
            None
        };
        let diffs: Vec<f64> = both.iter().map(|(x, y)| y - x).collect();
        let Some(interval) = mean_difference_interval(&diffs, INTERVAL_LEVEL) else {
            continue;
        };
        let n = both.len() as f64;
        let verdict = if interval[1] < 0.0 {
            "lower"
        } else if interval[0] > 0.0 {
            "higher"
        } else {
            "no difference shown"
        };
        methods.push(PairedMethod {
            method: name,
            mean_a_mm: both.iter().map(|p| p.0).sum::<f64>() / n,
            mean_b_mm: both.iter().map(|p| p.1).sum::<f64>() / n,
            mean_difference_mm: diffs.iter().sum::<f64>() / n,
            interval_90_mm: interval,
            b_lower_seeds: diffs.iter().filter(|d| **d < 0.0).count(),
            a_lower_seeds: diffs.iter().filter(|d| **d > 0.0).count(),
            verdict: verdict.into(),
            rms_over_a_bound,
        });
    }
    let kept = |f: &dyn Fn(&(&crate::pipeline::study::SeedResult, &crate::pipeline::study::SeedResult)) -> usize| {
        let v: Vec<usize> = pairs.iter().map(f).collect();
        (
            v.iter().sum::<usize>() as f64 / v.len() as f64,
            v.iter().copied().min().unwrap_or_default(),
        )
    };
    let (mean_a, min_a) = kept(&|p| p.0.frames_used);
    let (mean_b, min_b) = kept(&|p| p.1.frames_used);
    Ok(PairedStudies {
        a: a_mc.experiment,
        b: b_mc.experiment,
        a_file,
        b_file,
        seeds: pairs.iter().map(|p| p.0.seed).collect(),
        frames_kept: FramesKept {
            mean_a,
            mean_b,
            min_a,
            min_b,
        },
        methods,
    })
}

/// The comparison as Markdown.
pub fn markdown(p: &PairedStudies) -> String {
    let mut md = format!(
        "# `{}` against `{}`, paired on {} common seeds ({}–{})\n\n\
         Error: the RMS distance of the image's four corners and centre from the truth, per seed. \
         Difference: `{}` minus `{}`; its 90 % interval is a percentile bootstrap over the seeds.\n\n\
         Frames kept per seed: `{}` {:.1} (fewest {}), `{}` {:.1} (fewest {}).\n\n\
         | method | {} mean (mm) | {} mean (mm) | difference (mm) | 90 % interval (mm) | seeds lower: {} / {} | verdict | RMS / {}'s bound: {} / {} |\n\
         |---|---|---|---|---|---|---|---|\n",
        p.b,
        p.a,
        p.seeds.len(),
        p.seeds.first().copied().unwrap_or_default(),
        p.seeds.last().copied().unwrap_or_default(),
        p.b,
        p.a,
        p.a,
        p.frames_kept.mean_a,
        p.frames_kept.min_a,
        p.b,
        p.frames_kept.mean_b,
        p.frames_kept.min_b,
        p.a,
        p.b,
        p.b,
        p.a,
        p.a,
        p.a,
        p.b,
    );
    for m in &p.methods {
        let bound = m
            .rms_over_a_bound
            .map_or("—".to_string(), |[a, b]| format!("{a:.2} / {b:.2}"));
        md.push_str(&format!(
            "| {} | {:.3} | {:.3} | {:+.3} | {:+.3} … {:+.3} | {} / {} | {} | {} |\n",
            m.method,
            m.mean_a_mm,
            m.mean_b_mm,
            m.mean_difference_mm,
            m.interval_90_mm[0],
            m.interval_90_mm[1],
            m.b_lower_seeds,
            m.a_lower_seeds,
            m.verdict,
            bound
        ));
    }
    md
}
