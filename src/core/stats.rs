//! Summary statistics, written once: mean and sample SD, mean and maximum,
//! median, and percentiles (interpolated, or nearest rank on sorted values).

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

/// The `q` quantile of already sorted grey levels, nearest rank; 0 for none.
/// The median and the `q` quantile of `values` by nearest rank, as
/// [`percentile_sorted_nearest`] gives them on the sorted values, found by
/// selection (linear time; `values` is reordered). 0 for no values.
pub fn median_and_quantile_nearest(values: &mut [f32], q: f64) -> (f32, f32) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let rank = |q: f64| ((values.len() - 1) as f64 * q).round() as usize;
    let (m, k) = (rank(0.5), rank(q));
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

pub fn percentile_sorted_nearest(sorted: &[f32], q: f64) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn selection_gives_the_sorted_quantiles() {
        let mut rng = crate::core::rng::Rng::new(5);
        for n in [1usize, 2, 3, 10, 1001, 40_000] {
            let values: Vec<f32> = (0..n).map(|_| (rng.uniform(0.0, 50.0) as f32).round()).collect();
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
    }
}
