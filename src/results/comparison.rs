//! `probecal study compare`'s outcome: two Monte Carlo studies (or two
//! methods) paired on the seeds they share, as `study compare --out` writes it.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::core::stats::IntervalMethod;

/// One method's paired comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedMethod {
    pub method: String,
    /// Mean over the common seeds of each study's error, mm.
    pub mean_a_mm: f64,
    pub mean_b_mm: f64,
    /// Mean of (b − a) over the common seeds, mm: negative when b is the lower.
    pub mean_difference_mm: f64,
    /// Its 90 % interval over the seeds, mm, made by `interval_method`.
    pub interval_90_mm: [f64; 2],
    /// Student's t below 30 seeds, the percentile bootstrap from 30.
    pub interval_method: IntervalMethod,
    /// Each mean's own 90 % interval over the same seeds (same method), mm.
    pub mean_a_interval_90_mm: [f64; 2],
    pub mean_b_interval_90_mm: [f64; 2],
    /// b's error over a's: the geometric mean of the per-seed ratios and its
    /// 90 % interval (`interval_method` on the logarithms); absent when an
    /// error is zero.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratio_b_over_a: Option<Ratio>,
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

/// A ratio of errors over the seeds: geometric mean and interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ratio {
    pub geometric_mean: f64,
    pub interval_90: [f64; 2],
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
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub a: String,
    pub b: String,
    pub a_file: PathBuf,
    pub b_file: PathBuf,
    /// When one method is paired with another (`--method` of a against
    /// `--method-b` of b, a and b perhaps the same study): the two methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub methods_paired: Option<[String; 2]>,
    /// The seeds both studies ran.
    pub seeds: Vec<u64>,
    pub frames_kept: FramesKept,
    pub methods: Vec<PairedMethod>,
}
