//! What both live pages print per frame: a number's column and the per-frame
//! times' summary.

use serde::Serialize;

use crate::core::stats::{mean_sd, percentile};

/// A number as the live tables write it (4 decimals; empty when absent).
pub(crate) fn number(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.4}")).unwrap_or_default()
}

/// Mean, 95th percentile and largest of per-frame times, ms.
#[derive(Serialize)]
pub struct Timing {
    pub mean: f64,
    pub p95: f64,
    pub max: f64,
}

pub(crate) fn timing(values: &[f64]) -> Timing {
    Timing {
        mean: mean_sd(values).mean,
        p95: if values.is_empty() {
            0.0
        } else {
            percentile(values, 0.95)
        },
        max: values.iter().copied().fold(0.0, f64::max),
    }
}
