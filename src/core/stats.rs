//! Summary statistics, written once: mean and sample SD, mean and maximum,
//! median, percentiles (interpolated, or nearest rank on sorted values), the
//! bootstrap interval of a ratio of RMS values, and the interval of a mean
//! (Student's t on few values, the bootstrap on many).

use serde::{Deserialize, Serialize};

/// Mean, sample SD (n − 1; 0 for fewer than two values) and count.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MeanSd {
    pub mean: f64,
    pub std: f64,
    pub n: usize,
}

/// Mean and sample SD of `values`; all zero when there are none.
pub fn mean_sd(values: &[f64]) -> MeanSd {
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n.max(1) as f64;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n.max(2) - 1) as f64;
    MeanSd {
        mean,
        std: var.sqrt(),
        n,
    }
}

/// Mean and sample SD, `None` for no values.
pub fn mean_sd_of(values: &[f64]) -> Option<MeanSd> {
    (!values.is_empty()).then(|| mean_sd(values))
}

/// PLUS's convention: mean and SD of the best `round(0.95 n)` values.
pub fn best_95(values: &[f64]) -> Option<MeanSd> {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let keep = (0.95 * sorted.len() as f64).round() as usize;
    mean_sd_of(&sorted[..keep])
}

/// The mean, `None` for no values.
pub fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = values.collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Mean and largest value (the largest at least 0), `None` for no values.
pub fn mean_max(values: &[f64]) -> Option<(f64, f64)> {
    (!values.is_empty()).then(|| {
        (
            values.iter().sum::<f64>() / values.len() as f64,
            values.iter().cloned().fold(0.0, f64::max),
        )
    })
}

/// The median (sorts `values` in place); the mean of the middle two for an even count.
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(|a, b| a.total_cmp(b));
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    }
}

/// The `q` quantile (0..=1) by linear interpolation between the sorted values.
/// `values` must not be empty.
pub fn percentile(values: &[f64], q: f64) -> f64 {
    let mut values = values.to_vec();
    values.sort_by(|a, b| a.total_cmp(b));
    let pos = q * (values.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    values[lo] + (values[hi] - values[lo]) * (pos - lo as f64)
}

/// The median and the `q` quantile of `values` by nearest rank, as
/// [`percentile_sorted_nearest`] gives them on the sorted values (in
/// `f32::total_cmp` order), found in linear time: by selection for few values
/// (`values` is reordered), by a two-level radix count of the values' order
/// keys for many (a B-scan's fan, where selection was the detector's slowest
/// step). 0 for no values.
pub fn median_and_quantile_nearest(values: &mut [f32], q: f64) -> (f32, f32) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let rank = |q: f64| ((values.len() - 1) as f64 * q).round() as usize;
    let (m, k) = (rank(0.5), rank(q));
    if values.len() >= RADIX_MIN_VALUES {
        let [median, quantile] = nth_pair_by_radix(values, [m, k]);
        return (median, quantile);
    }
    let (_, median, _) = values.select_nth_unstable_by(m, |a, b| a.total_cmp(b));
    let median = *median;
    // The k-th smallest lies on the side of the median it ranks on.
    let quantile = match k.cmp(&m) {
        std::cmp::Ordering::Equal => median,
        std::cmp::Ordering::Greater => {
            *values[m + 1..]
                .select_nth_unstable_by(k - m - 1, |a, b| a.total_cmp(b))
                .1
        }
        std::cmp::Ordering::Less => *values[..m].select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1,
    };
    (median, quantile)
}

/// Below this many values selection is faster than two passes of counting.
const RADIX_MIN_VALUES: usize = 1 << 14;

/// An unsigned key that orders like `f32::total_cmp`.
fn order_key(v: f32) -> u32 {
    let bits = v.to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

fn from_order_key(key: u32) -> f32 {
    f32::from_bits(if key & 0x8000_0000 != 0 {
        key & 0x7fff_ffff
    } else {
        !key
    })
}

/// The `n[0]`-th and `n[1]`-th smallest values (0-based, below `values.len()`):
/// the high 16 bits of their keys from one count over all values, the low 16
/// from a count over the values that share them (one pass for both).
fn nth_pair_by_radix(values: &[f32], n: [usize; 2]) -> [f32; 2] {
    const BUCKETS: usize = 1 << 16;
    let bucket = |counts: &[u32], mut left: usize| -> (usize, usize) {
        for (b, c) in counts.iter().enumerate() {
            if left < *c as usize {
                return (b, left);
            }
            left -= *c as usize;
        }
        (counts.len() - 1, 0)
    };
    let mut high_counts = vec![0u32; BUCKETS];
    for v in values {
        high_counts[(order_key(*v) >> 16) as usize] += 1;
    }
    let found = n.map(|n| bucket(&high_counts, n));
    let highs = found.map(|(high, _)| high as u32);
    // Low-half counts of the first bucket, then of the second (if another).
    let mut low_counts = vec![0u32; 2 * BUCKETS];
    let second = usize::from(highs[1] != highs[0]) * BUCKETS;
    for v in values {
        let key = order_key(*v);
        let (high, low) = (key >> 16, (key & 0xffff) as usize);
        if high == highs[0] {
            low_counts[low] += 1;
        } else if high == highs[1] {
            low_counts[second + low] += 1;
        }
    }
    let mut out = [0f32; 2];
    for (i, (high, left)) in found.iter().enumerate() {
        let offset = if i == 1 { second } else { 0 };
        let (low, _) = bucket(&low_counts[offset..offset + BUCKETS], *left);
        out[i] = from_order_key(((*high as u32) << 16) | low as u32);
    }
    out
}

/// The `q` quantile of already sorted grey levels, nearest rank; 0 for none.
pub fn percentile_sorted_nearest(sorted: &[f32], q: f64) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Resamples of [`rms_ratio_interval`]'s bootstrap.
pub const BOOTSTRAP_RESAMPLES: usize = 10_000;

/// `√(Σ aᵢ² / Σ bᵢ²)` of paired values (e.g. each seed's error and its bound).
pub fn rms_ratio(pairs: &[(f64, f64)]) -> Option<f64> {
    let (a, b) = pairs.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x * x, b + y * y));
    let ratio = (a / b).sqrt();
    (b > 0.0 && ratio.is_finite()).then_some(ratio)
}

/// The central `level` (e.g. 0.9) interval of [`rms_ratio`] over the pairs'
/// population, by the percentile bootstrap: the pairs (not their members
/// apart) are drawn with replacement, [`BOOTSTRAP_RESAMPLES`] times, from a
/// fixed seed, so the same pairs give the same interval. `None` for fewer than
/// two pairs, a value that is not finite, or a level outside (0, 1).
pub fn rms_ratio_interval(pairs: &[(f64, f64)], level: f64) -> Option<[f64; 2]> {
    let finite = pairs.iter().all(|(a, b)| a.is_finite() && b.is_finite());
    if pairs.len() < 2 || !finite || !(level > 0.0 && level < 1.0) {
        return None;
    }
    rms_ratio(pairs)?;
    let mut rng = crate::core::rng::Rng::new(0x0b00_7572_a900);
    let mut sample = vec![(0.0, 0.0); pairs.len()];
    let mut ratios = Vec::with_capacity(BOOTSTRAP_RESAMPLES);
    for _ in 0..BOOTSTRAP_RESAMPLES {
        for s in sample.iter_mut() {
            *s = pairs[rng.below(pairs.len())];
        }
        // A resample of only zero bounds has no ratio: it counts as unbounded.
        ratios.push(rms_ratio(&sample).unwrap_or(f64::INFINITY));
    }
    let tail = (1.0 - level) / 2.0;
    let interval = [percentile(&ratios, tail), percentile(&ratios, 1.0 - tail)];
    interval.iter().all(|v| v.is_finite()).then_some(interval)
}

/// A percentile-bootstrap interval at `level` of the mean of paired
/// differences (one per seed), resampling the seeds with a fixed stream; `None`
/// below two differences or with a non-finite one.
pub fn mean_difference_interval(differences: &[f64], level: f64) -> Option<[f64; 2]> {
    let n = differences.len();
    if n < 2 || !differences.iter().all(|d| d.is_finite()) || !(level > 0.0 && level < 1.0) {
        return None;
    }
    let mut rng = crate::core::rng::Rng::new(0x0b00_7572_a901);
    let means: Vec<f64> = (0..BOOTSTRAP_RESAMPLES)
        .map(|_| (0..n).map(|_| differences[rng.below(n)]).sum::<f64>() / n as f64)
        .collect();
    let tail = (1.0 - level) / 2.0;
    Some([percentile(&means, tail), percentile(&means, 1.0 - tail)])
}

/// Below this many values a mean's interval is Student's t, not the percentile
/// bootstrap, which is too narrow on few values (it takes the sample's spread
/// for the population's and has no n − 1).
pub const BOOTSTRAP_FROM: usize = 30;

/// How an interval of a mean was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntervalMethod {
    /// `mean ± t(n − 1) · sd / √n`.
    StudentT,
    /// Percentile bootstrap of the mean, [`BOOTSTRAP_RESAMPLES`] resamples.
    PercentileBootstrap,
}

impl IntervalMethod {
    /// In words, for a page.
    pub fn words(self) -> &'static str {
        match self {
            IntervalMethod::StudentT => "Student's t on the per-seed values (n − 1 degrees of freedom)",
            IntervalMethod::PercentileBootstrap => "a percentile bootstrap over the seeds",
        }
    }
}

/// The central `level` interval of the mean of independent `values` (one per
/// seed) and how it was made: Student's t below [`BOOTSTRAP_FROM`] values, the
/// percentile bootstrap from there. `None` below two values, with a non-finite
/// one, or a level outside (0, 1).
pub fn mean_interval(values: &[f64], level: f64) -> Option<(IntervalMethod, [f64; 2])> {
    if values.len() >= BOOTSTRAP_FROM {
        return mean_difference_interval(values, level).map(|i| (IntervalMethod::PercentileBootstrap, i));
    }
    student_t_interval(values, level).map(|i| (IntervalMethod::StudentT, i))
}

/// `mean ± t · sd / √n` at `level` (two-sided), `t` the Student quantile with
/// n − 1 degrees of freedom; `None` as [`mean_interval`].
pub fn student_t_interval(values: &[f64], level: f64) -> Option<[f64; 2]> {
    let n = values.len();
    if n < 2 || !values.iter().all(|v| v.is_finite()) || !(level > 0.0 && level < 1.0) {
        return None;
    }
    let s = mean_sd(values);
    let t = student_t_quantile(0.5 + level / 2.0, (n - 1) as f64)?;
    let half = t * s.std / (n as f64).sqrt();
    Some([s.mean - half, s.mean + half])
}

/// The `p` quantile of Student's t with `dof` degrees of freedom (bisection on
/// its distribution function); `None` for `p` outside (0, 1) or `dof` ≤ 0.
pub fn student_t_quantile(p: f64, dof: f64) -> Option<f64> {
    if !(p > 0.0 && p < 1.0 && dof > 0.0 && dof.is_finite()) {
        return None;
    }
    let (mut lo, mut hi) = (-1e4, 1e4);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if student_t_cdf(mid, dof) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// Student's t distribution function: `1 − I_x(dof/2, 1/2) / 2` for t ≥ 0,
/// `x = dof / (dof + t²)`.
fn student_t_cdf(t: f64, dof: f64) -> f64 {
    let tail = 0.5 * regularized_beta(dof / (dof + t * t), dof / 2.0, 0.5);
    if t >= 0.0 {
        1.0 - tail
    } else {
        tail
    }
}

/// The regularised incomplete beta function `I_x(a, b)` (continued fraction,
/// modified Lentz; Numerical Recipes §6.4).
fn regularized_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(x, a, b) / a
    } else {
        1.0 - front * beta_fraction(1.0 - x, b, a) / b
    }
}

fn beta_fraction(x: f64, a: f64, b: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    d = 1.0 / if d.abs() < TINY { TINY } else { d };
    let mut h = d;
    for m in 1..300 {
        let m = m as f64;
        let m2 = 2.0 * m;
        for aa in [
            m * (b - m) * x / ((qam + m2) * (a + m2)),
            -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
        ] {
            d = 1.0 + aa * d;
            d = 1.0 / if d.abs() < TINY { TINY } else { d };
            c = 1.0 + aa / c;
            c = if c.abs() < TINY { TINY } else { c };
            h *= d * c;
        }
        if (d * c - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// `ln Γ(x)` for x > 0 (Lanczos, g = 7, nine terms).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut sum = G[0];
    for (k, g) in G.iter().enumerate().skip(1) {
        sum += g / (x + k as f64);
    }
    let t = x + 7.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// A moving-block bootstrap interval at `level` of the mean of a series whose
/// neighbours are correlated (e.g. one difference per frame of a sweep): blocks
/// of `block` consecutive values are drawn with replacement and joined to the
/// series' length, [`BOOTSTRAP_RESAMPLES`] times, from a fixed stream. `None`
/// below two blocks' worth of values, with a non-finite value, or a level
/// outside (0, 1).
pub fn block_mean_interval(values: &[f64], block: usize, level: f64) -> Option<[f64; 2]> {
    let (n, block) = (values.len(), block.max(1));
    if n < 2 * block || !values.iter().all(|d| d.is_finite()) || !(level > 0.0 && level < 1.0) {
        return None;
    }
    let mut rng = crate::core::rng::Rng::new(0x0b00_7572_a902);
    let starts = n - block + 1;
    let means: Vec<f64> = (0..BOOTSTRAP_RESAMPLES)
        .map(|_| {
            let (mut sum, mut taken) = (0.0, 0);
            while taken < n {
                let start = rng.below(starts);
                for v in &values[start..start + block.min(n - taken)] {
                    sum += v;
                }
                taken += block.min(n - taken);
            }
            sum / n as f64
        })
        .collect();
    let tail = (1.0 - level) / 2.0;
    Some([percentile(&means, tail), percentile(&means, 1.0 - tail)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_difference_interval_holds_zero_only_for_differences_in_the_noise() {
        // Differences around +0.05 with spread 0.01: the interval is clear of zero.
        let clear: Vec<f64> = (0..12).map(|k| 0.05 + 0.01 * ((k as f64) * 1.7).sin()).collect();
        let [lo, hi] = mean_difference_interval(&clear, 0.9).unwrap();
        assert!(lo > 0.03 && hi < 0.07 && lo < hi, "{lo} {hi}");
        // Symmetric differences about zero: the interval holds it.
        let noise: Vec<f64> = (0..12).map(|k| if k % 2 == 0 { 0.05 } else { -0.05 }).collect();
        let [lo, hi] = mean_difference_interval(&noise, 0.9).unwrap();
        assert!(lo < 0.0 && hi > 0.0, "{lo} {hi}");
        assert!(mean_difference_interval(&[1.0], 0.9).is_none());
        assert!(mean_difference_interval(&[1.0, f64::NAN], 0.9).is_none());
    }

    #[test]
    fn student_t_quantiles_match_the_tables() {
        // Two-sided 90 % points (one-sided 0.95) from any t table.
        for (dof, t) in [
            (1.0, 6.313_752),
            (4.0, 2.131_847),
            (9.0, 1.833_113),
            (29.0, 1.699_127),
            (1e6, 1.644_855),
        ] {
            let q = student_t_quantile(0.95, dof).unwrap();
            assert!((q - t).abs() < 2e-6, "dof {dof}: {q} against {t}");
            assert!((student_t_quantile(0.05, dof).unwrap() + t).abs() < 2e-6);
        }
        assert!((student_t_quantile(0.975, 9.0).unwrap() - 2.262_157).abs() < 2e-6);
        assert!(student_t_quantile(1.0, 9.0).is_none() && student_t_quantile(0.9, 0.0).is_none());
    }

    #[test]
    fn few_values_get_the_t_interval_many_the_bootstrap_and_t_is_the_wider() {
        let ten: Vec<f64> = (0..10).map(|k| 0.05 + 0.02 * ((k as f64) * 1.3).sin()).collect();
        let (method, [lo, hi]) = mean_interval(&ten, 0.9).unwrap();
        assert_eq!(method, IntervalMethod::StudentT);
        let s = mean_sd(&ten);
        let half = 1.833_113 * s.std / 10f64.sqrt();
        assert!((lo - (s.mean - half)).abs() < 1e-6 && (hi - (s.mean + half)).abs() < 1e-6);
        let [b0, b1] = mean_difference_interval(&ten, 0.9).unwrap();
        assert!(hi - lo > b1 - b0, "t {lo}..{hi} against bootstrap {b0}..{b1}");
        let forty: Vec<f64> = (0..40).map(|k| ((k as f64) * 0.7).sin()).collect();
        assert_eq!(
            mean_interval(&forty, 0.9).unwrap().0,
            IntervalMethod::PercentileBootstrap
        );
        assert!(mean_interval(&[1.0], 0.9).is_none() && mean_interval(&[1.0, f64::INFINITY], 0.9).is_none());
    }

    #[test]
    fn the_block_interval_widens_with_correlated_neighbours() {
        // The same values, alternating or in runs of ten: blocks of ten see the
        // runs and give the wider interval; both hold the true mean of zero.
        let alternating: Vec<f64> = (0..100).map(|k| if k % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let runs: Vec<f64> = (0..100).map(|k| if (k / 10) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let [a0, a1] = block_mean_interval(&alternating, 10, 0.9).unwrap();
        let [r0, r1] = block_mean_interval(&runs, 10, 0.9).unwrap();
        assert!(a0 <= 0.0 && a1 >= 0.0 && r0 < 0.0 && r1 > 0.0);
        assert!(r1 - r0 > 3.0 * (a1 - a0), "{r0} {r1} vs {a0} {a1}");
        // A shift clear of the noise is clear of zero.
        let shifted: Vec<f64> = runs.iter().map(|v| v * 0.1 + 0.5).collect();
        let [s0, s1] = block_mean_interval(&shifted, 10, 0.9).unwrap();
        assert!(s0 > 0.4 && s1 < 0.6, "{s0} {s1}");
        assert!(block_mean_interval(&runs[..15], 10, 0.9).is_none());
        assert!(block_mean_interval(&[0.0, f64::NAN, 1.0, 2.0], 1, 0.9).is_none());
    }

    #[test]
    fn hand_computed_values() {
        let s = mean_sd(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!((s.mean, s.n), (2.5, 4));
        assert!((s.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(mean_sd(&[7.0]).std, 0.0);
        assert_eq!(mean_sd_of(&[]), None);
        assert_eq!(mean_max(&[1.0, 3.0]), Some((2.0, 3.0)));
        assert_eq!(median(&mut [3.0, 1.0, 2.0, 10.0]), 2.5);
        assert_eq!(percentile(&[0.0, 10.0, 20.0], 0.25), 5.0);
        assert_eq!(percentile_sorted_nearest(&[1.0, 2.0, 3.0], 0.74), 2.0);
        assert_eq!(mean([1.0, 2.0].into_iter()), Some(1.5));
    }

    #[test]
    fn the_rms_ratio_interval_covers_the_population_ratio_about_as_often_as_its_level() {
        // Ten seeds whose errors are their bounds times a chi (3 dof) / √3
        // draw: the population's RMS ratio is 1.
        let mut rng = crate::core::rng::Rng::new(11);
        let trials = 400;
        let mut covered = 0;
        for _ in 0..trials {
            let pairs: Vec<(f64, f64)> = (0..10)
                .map(|_| {
                    let bound = rng.uniform(0.1, 0.13);
                    let chi2: f64 = (0..3).map(|_| rng.normal(0.0, 1.0).powi(2)).sum();
                    (bound * (chi2 / 3.0).sqrt(), bound)
                })
                .collect();
            let [lo, hi] = rms_ratio_interval(&pairs, 0.9).unwrap();
            let point = rms_ratio(&pairs).unwrap();
            assert!(lo <= point && point <= hi, "{lo} {point} {hi}");
            covered += usize::from(lo <= 1.0 && 1.0 <= hi);
        }
        // The percentile bootstrap covers a little less than its level with
        // ten values; a fixed width or a wrong resampling would fall far outside.
        let rate = covered as f64 / trials as f64;
        assert!((0.78..=0.95).contains(&rate), "covered in {rate}");
    }

    #[test]
    fn the_rms_ratio_interval_is_repeatable_and_refuses_what_it_cannot_bound() {
        let pairs = [(0.2, 0.1), (0.1, 0.1), (0.15, 0.12), (0.3, 0.11)];
        let interval = rms_ratio_interval(&pairs, 0.9).unwrap();
        assert_eq!(rms_ratio_interval(&pairs, 0.9), Some(interval));
        assert!(interval[0] < interval[1]);
        let point = rms_ratio(&pairs).unwrap();
        assert!((point - (0.1625f64 / 0.0465).sqrt()).abs() < 1e-12, "{point}");
        assert_eq!(rms_ratio_interval(&pairs[..1], 0.9), None);
        assert_eq!(rms_ratio_interval(&[(0.1, 0.1), (f64::NAN, 0.1)], 0.9), None);
        assert_eq!(rms_ratio_interval(&[(0.1, 0.0), (0.2, 0.0)], 0.9), None);
        assert_eq!(rms_ratio_interval(&pairs, 1.0), None);
    }

    #[test]
    fn selection_gives_the_sorted_quantiles() {
        let mut rng = crate::core::rng::Rng::new(5);
        for n in [1usize, 2, 3, 10, 1001, 40_000, 100_000] {
            // Many ties (rounded) for the small sizes, every sign, fraction and
            // magnitude for the large, where the radix count is used.
            let values: Vec<f32> = (0..n)
                .map(|i| match (n > 50_000, i % 7) {
                    (false, _) => (rng.uniform(0.0, 50.0) as f32).round(),
                    (true, 0) => -0.0,
                    (true, 1) => rng.uniform(-1e6, 1e6) as f32,
                    (true, 2) => rng.uniform(-1e-3, 1e-3) as f32,
                    (true, _) => rng.uniform(0.0, 255.0) as f32,
                })
                .collect();
            let mut sorted = values.clone();
            sorted.sort_by(|a, b| a.total_cmp(b));
            for q in [0.0, 0.2, 0.5, 0.9, 0.997, 1.0] {
                let mut scratch = values.clone();
                assert_eq!(
                    median_and_quantile_nearest(&mut scratch, q),
                    (
                        percentile_sorted_nearest(&sorted, 0.5),
                        percentile_sorted_nearest(&sorted, q)
                    ),
                    "n {n}, q {q}"
                );
            }
        }
        for v in [
            0.0f32,
            -0.0,
            1.5,
            -1.5,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            assert_eq!(from_order_key(order_key(v)).to_bits(), v.to_bits(), "{v}");
        }
        assert!(order_key(-0.0) < order_key(0.0) && order_key(-1.0) < order_key(-0.5));
    }
}
