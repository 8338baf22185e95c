//! Two Monte Carlo studies compared on the seeds they share: per method, the
//! mean difference of the seeds' errors (second minus first), its 90 %
//! interval over the seeds (Student's t below 30 seeds, the percentile
//! bootstrap from 30, [`crate::core::stats::mean_interval`]), and on how many
//! seeds each was the lower;
//! and the frames each kept. A difference whose interval holds zero is no
//! difference these seeds can show. Two methods of one study (or of two) are
//! paired the same way: each seed's error of the one against the other's.

use std::path::{Path, PathBuf};

use crate::core::stats::{mean_interval, IntervalMethod};
use crate::pipeline::study::{MonteCarlo, SeedResult, INTERVAL_LEVEL};
use crate::report::study::StudyFile;
pub use crate::results::comparison::{FramesKept, PairedMethod, PairedStudies, Ratio};

/// The geometric mean of `b / a` over the pairs and its interval (the mean of
/// the logarithms' interval, exponentiated); `None` when an error is zero.
fn ratio(both: &[(f64, f64)]) -> Option<Ratio> {
    let logs: Vec<f64> = both.iter().map(|(a, b)| (b / a).ln()).collect();
    let (_, [lo, hi]) = mean_interval(&logs, INTERVAL_LEVEL)?;
    let mean = logs.iter().sum::<f64>() / logs.len() as f64;
    Some(Ratio {
        geometric_mean: mean.exp(),
        interval_90: [lo.exp(), hi.exp()],
    })
}

#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error("{0}")]
    Read(#[from] crate::report::error::ReadError),
    #[error("{0}: no Monte Carlo study in it (a σ-table only)")]
    NoStudy(PathBuf),
    #[error("{a} and {b} share {n} seeds; a paired comparison needs at least 2")]
    FewSeeds { a: PathBuf, b: PathBuf, n: usize },
    #[error("{0}: method `{1}` is not in both studies")]
    NoMethod(PathBuf, String),
    #[error("{0}: method `{1}` is not in it")]
    NoMethodIn(PathBuf, String),
    #[error("--method-b needs --method: the method of the first study it is paired with")]
    MethodBAlone,
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
/// share, or only `method`; or, with `method_b`, a's `method` against b's
/// `method_b`.
pub fn compare(
    a: &Path,
    b: &Path,
    method: Option<&str>,
    method_b: Option<&str>,
) -> Result<PairedStudies, CompareError> {
    let (a_file, a_mc) = study_of(a)?;
    let (b_file, b_mc) = study_of(b)?;
    let methods_paired = match (method, method_b) {
        (None, Some(_)) => return Err(CompareError::MethodBAlone),
        (Some(m), Some(n)) => {
            for (file, mc, name) in [(&a_file, &a_mc, m), (&b_file, &b_mc, n)] {
                if !mc.methods.iter().any(|x| x.method == name) {
                    return Err(CompareError::NoMethodIn(file.clone(), name.to_string()));
                }
            }
            Some([m.to_string(), n.to_string()])
        }
        _ => None,
    };
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
    // (a's method, b's method) pairs.
    let names: Vec<(String, String)> = match &methods_paired {
        Some([m, n]) => vec![(m.clone(), n.clone())],
        None => a_mc
            .methods
            .iter()
            .map(|m| m.method.clone())
            .filter(|m| b_mc.methods.iter().any(|n| &n.method == m))
            .filter(|m| method.is_none_or(|want| want == m))
            .map(|m| (m.clone(), m))
            .collect(),
    };
    if let Some(want) = method.filter(|_| names.is_empty()) {
        return Err(CompareError::NoMethod(b_file, want.to_string()));
    }
    // a's bound is b's too only for the same rig: one study, or one method
    // in two studies of which a states the model.
    let same_rig = methods_paired.is_none() || a_file == b_file;
    let methods = names
        .into_iter()
        .filter_map(|(name, name_b)| pair_method(&pairs, name, &name_b, same_rig))
        .collect();
    let kept = |f: &dyn Fn(&SeedPair) -> usize| {
        let v: Vec<usize> = pairs.iter().map(f).collect();
        (
            v.iter().sum::<usize>() as f64 / v.len() as f64,
            v.iter().copied().min().unwrap_or_default(),
        )
    };
    let (mean_a, min_a) = kept(&|p| p.0.frames_used);
    let (mean_b, min_b) = kept(&|p| p.1.frames_used);
    Ok(PairedStudies {
        schema_version: crate::results::SCHEMA_VERSION,
        a: a_mc.experiment,
        b: b_mc.experiment,
        a_file,
        b_file,
        methods_paired,
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

type SeedPair<'s> = (&'s SeedResult, &'s SeedResult);

/// a's method `name` against b's `name_b` over the seed pairs; `None` when too
/// few seeds have both errors for an interval.
fn pair_method(pairs: &[SeedPair], name: String, name_b: &str, same_rig: bool) -> Option<PairedMethod> {
    let error_of = |r: &SeedResult, m: &str| r.rms_error_mm.iter().find(|(n, _)| n == m).map(|(_, e)| *e);
    let both: Vec<(f64, f64)> = pairs
        .iter()
        .filter_map(|(sa, sb)| Some((error_of(sa, &name)?, error_of(sb, name_b)?)))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    // (a's error, b's error, a's bound) on the seeds a has a bound for.
    let bounded: Vec<(f64, f64, f64)> = pairs
        .iter()
        .filter_map(|(sa, sb)| Some((error_of(sa, &name)?, error_of(sb, name_b)?, sa.crlb_rms_mm?)))
        .collect();
    let over_bound = |pick: fn(&(f64, f64, f64)) -> f64| {
        let ratio: Vec<(f64, f64)> = bounded.iter().map(|t| (pick(t), t.2)).collect();
        crate::core::stats::rms_ratio(&ratio)
    };
    let rms_over_a_bound = if same_rig && bounded.len() == both.len() && bounded.len() >= 2 {
        over_bound(|t| t.0).zip(over_bound(|t| t.1)).map(|(a, b)| [a, b])
    } else {
        None
    };
    let diffs: Vec<f64> = both.iter().map(|(x, y)| y - x).collect();
    let (interval_method, interval) = mean_interval(&diffs, INTERVAL_LEVEL)?;
    let side = |pick: fn(&(f64, f64)) -> f64| {
        let v: Vec<f64> = both.iter().map(pick).collect();
        mean_interval(&v, INTERVAL_LEVEL).map(|(_, i)| i)
    };
    let (mean_a_interval_90_mm, mean_b_interval_90_mm) = (side(|p| p.0)?, side(|p| p.1)?);
    let n = both.len() as f64;
    let verdict = if interval[1] < 0.0 {
        "lower"
    } else if interval[0] > 0.0 {
        "higher"
    } else {
        "no difference shown"
    };
    Some(PairedMethod {
        method: name,
        mean_a_mm: both.iter().map(|p| p.0).sum::<f64>() / n,
        mean_b_mm: both.iter().map(|p| p.1).sum::<f64>() / n,
        mean_difference_mm: diffs.iter().sum::<f64>() / n,
        interval_90_mm: interval,
        interval_method,
        ratio_b_over_a: ratio(&both),
        mean_a_interval_90_mm,
        mean_b_interval_90_mm,
        b_lower_seeds: diffs.iter().filter(|d| **d < 0.0).count(),
        a_lower_seeds: diffs.iter().filter(|d| **d > 0.0).count(),
        verdict: verdict.into(),
        rms_over_a_bound,
    })
}

/// How the comparison's intervals were made, in words (one method, or each).
fn interval_words(p: &PairedStudies) -> String {
    let mut methods: Vec<IntervalMethod> = p.methods.iter().map(|m| m.interval_method).collect();
    methods.dedup();
    match methods.as_slice() {
        [one] => one.words().to_string(),
        _ => "Student's t below 30 seeds, a percentile bootstrap from 30".to_string(),
    }
}

/// The comparison as Markdown.
pub fn markdown(p: &PairedStudies) -> String {
    // Each side's name: the study, and when methods are paired, its method.
    let (a, b) = match &p.methods_paired {
        Some([m, n]) => (format!("{} {m}", p.a), format!("{} {n}", p.b)),
        None => (p.a.clone(), p.b.clone()),
    };
    let mut md = format!(
        "# `{b}` against `{a}`, paired on {} common seeds ({}–{})\n\n\
         Error: the RMS distance of the image's four corners and centre from the truth, per seed. \
         Difference: `{b}` minus `{a}`; its 90 % interval is {}. A verdict needs an interval clear of zero; \
         each interval is at 90 % on its own, with no correction for the other comparisons made with it.\n\n\
         Frames kept per seed: `{a}` {:.1} (fewest {}), `{b}` {:.1} (fewest {}).\n\n\
         | method | {a} mean (mm) | {b} mean (mm) | difference (mm) | 90 % interval (mm) | {b} / {a}: geometric mean of the seeds' ratios (90 % interval) | seeds lower: {b} / {a} | verdict | RMS / {a}'s bound: {a} / {b} |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        p.seeds.len(),
        p.seeds.first().copied().unwrap_or_default(),
        p.seeds.last().copied().unwrap_or_default(),
        interval_words(p),
        p.frames_kept.mean_a,
        p.frames_kept.min_a,
        p.frames_kept.mean_b,
        p.frames_kept.min_b,
    );
    for m in &p.methods {
        let bound = m
            .rms_over_a_bound
            .map_or("—".to_string(), |[a, b]| format!("{a:.2} / {b:.2}"));
        md.push_str(&format!(
            "| {} | {:.3} | {:.3} | {:+.3} | {:+.3} … {:+.3} | {} | {} / {} | {} | {} |\n",
            m.method,
            m.mean_a_mm,
            m.mean_b_mm,
            m.mean_difference_mm,
            m.interval_90_mm[0],
            m.interval_90_mm[1],
            m.ratio_b_over_a.map_or("—".to_string(), |r| format!(
                "{:.2} ({:.2} … {:.2})",
                r.geometric_mean, r.interval_90[0], r.interval_90[1]
            )),
            m.b_lower_seeds,
            m.a_lower_seeds,
            m.verdict,
            bound
        ));
    }
    md
}
