//! The check: is a given calibration consistent with the sweeps? The search
//! from it ([`super::refine::search`]) gives the sweeps' own calibration along
//! the directions they hold; the statistic is how far that one puts the
//! image's corners from where the given one puts them, and the verdict is that
//! distance against a tolerance. The false-alarm rate is the chance that the
//! sweeps' noise alone (each held direction's standard error from resampled
//! sweeps, drawn as independent normals) puts the corners past the tolerance
//! when the given calibration is right. It does not count a bias of the
//! sweeps' optimum (a texture that favours one pose): that is measured on
//! resampled recordings, not assumed.

use nalgebra::Vector6;

use super::refine::Search;
use super::Frame0;

/// What the check compares against.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CheckSettings {
    /// A calibration is consistent when the sweeps' own puts the image's
    /// corners at most this far from it, mm.
    pub tolerance_mm: f64,
    /// Draws of the sweeps' noise for the false-alarm rate.
    pub draws: usize,
}

impl Default for CheckSettings {
    fn default() -> Self {
        CheckSettings {
            // Half of the 2 mm a bumped marker or remounted probe is to be caught at.
            tolerance_mm: 1.0,
            draws: 4000,
        }
    }
}

/// What the check says of the given calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The sweeps' own calibration is within the tolerance of it.
    Consistent,
    /// Farther than the tolerance.
    Inconsistent,
    /// The sweeps hold no direction: nothing could be checked.
    Unchecked,
}

impl Verdict {
    /// The verdict in words.
    pub fn words(self) -> &'static str {
        match self {
            Verdict::Consistent => "consistent with the sweeps",
            Verdict::Inconsistent => "NOT consistent with the sweeps",
            Verdict::Unchecked => "not checked: the sweeps hold no direction",
        }
    }
}

/// The check's outcome.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Consistency {
    /// The largest distance between where the given calibration and the
    /// sweeps' own (along the held directions) put the image's corners, mm.
    pub offset_mm: f64,
    pub tolerance_mm: f64,
    pub verdict: Verdict,
    /// The chance that the sweeps' noise alone puts the corners past the
    /// tolerance from a right calibration (over `draws` draws).
    pub false_alarm_rate: f64,
    /// The 95th percentile of the noise-alone distance, mm: the smallest
    /// offset the check tells from noise.
    pub noise_95_mm: f64,
    pub draws: usize,
    /// The directions checked (held), and those the sweeps cannot check.
    pub checked: Vec<String>,
    pub not_checked: Vec<String>,
}

/// The check of `frame0`'s calibration from the search that started there.
pub fn consistency(search: &Search, frame0: &Frame0, settings: &CheckSettings) -> Consistency {
    let start = frame0.probe_T_pixel;
    let offset_of = |q: &Vector6<f64>| frame0.corner_error_mm(&frame0.calibration(q), &start);
    let offset_mm = offset_of(&search.correction);
    let held: Vec<(Vector6<f64>, f64)> = search
        .directions
        .iter()
        .filter(|d| d.held)
        .filter_map(|d| {
            d.standard_error_mm
                .map(|se| (Vector6::from_column_slice(&d.vector), se))
        })
        .collect();
    let mut rng = crate::core::rng::Rng::new(0x0c0e_c4ec);
    let draws = settings.draws.max(1);
    let mut noise: Vec<f64> = (0..draws)
        .map(|_| {
            let q = held
                .iter()
                .fold(Vector6::zeros(), |q, (v, se)| q + v * rng.normal(0.0, *se));
            offset_of(&q)
        })
        .collect();
    noise.sort_by(f64::total_cmp);
    let past = noise.iter().filter(|&&d| d > settings.tolerance_mm).count();
    let names = |held: bool| -> Vec<String> {
        search
            .directions
            .iter()
            .filter(|d| d.held == held)
            .map(|d| d.mostly.clone())
            .collect()
    };
    Consistency {
        offset_mm,
        tolerance_mm: settings.tolerance_mm,
        verdict: if held.is_empty() {
            Verdict::Unchecked
        } else if offset_mm <= settings.tolerance_mm {
            Verdict::Consistent
        } else {
            Verdict::Inconsistent
        },
        false_alarm_rate: past as f64 / draws as f64,
        noise_95_mm: noise[((0.95 * draws as f64).ceil() as usize).clamp(1, draws) - 1],
        draws,
        checked: names(true),
        not_checked: names(false),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::selfcal::refine::{Direction, Quadratic};
    use nalgebra::{Matrix4, Matrix6};

    fn search_with(correction: Vector6<f64>, held_se: &[(usize, f64)]) -> Search {
        let directions = (0..6)
            .map(|k| {
                let se = held_se.iter().find(|(i, _)| *i == k).map(|(_, se)| *se);
                let mut vector = [0.0; 6];
                vector[k] = 1.0;
                Direction {
                    vector,
                    curvature_per_mm2: 1.0,
                    held: se.is_some(),
                    mostly: crate::estimate::selfcal::UNKNOWNS[k].into(),
                    standard_error_mm: se.or(Some(5.0)),
                }
            })
            .collect();
        Search {
            correction,
            unprojected: correction,
            directions,
            start_correlation: 0.5,
            end: Quadratic {
                disagreement: 0.4,
                gradient: Vector6::zeros(),
                hessian: Matrix6::identity(),
                voxels: 1000,
            },
            iterations: 1,
            resamples_used: 16,
            path: Vec::new(),
        }
    }

    fn frame() -> Frame0 {
        Frame0::new(
            Matrix4::new_nonuniform_scaling(&nalgebra::Vector3::new(0.1, 0.1, 0.1)),
            400,
            300,
        )
    }

    #[test]
    fn the_verdict_follows_the_offset_and_names_what_is_not_checked() {
        let settings = CheckSettings::default();
        let moved = consistency(
            &search_with(Vector6::new(0.0, 2.0, 0.0, 0.0, 0.0, 0.0), &[(1, 0.1)]),
            &frame(),
            &settings,
        );
        assert_eq!(moved.verdict, Verdict::Inconsistent);
        assert!((moved.offset_mm - 2.0).abs() < 1e-9);
        assert_eq!(moved.checked, vec!["move along y".to_string()]);
        assert_eq!(moved.not_checked.len(), 5);
        let near = consistency(
            &search_with(Vector6::new(0.0, 0.5, 0.0, 0.0, 0.0, 0.0), &[(1, 0.1)]),
            &frame(),
            &settings,
        );
        assert_eq!(near.verdict, Verdict::Consistent);
        let none = consistency(&search_with(Vector6::zeros(), &[]), &frame(), &settings);
        assert_eq!(none.verdict, Verdict::Unchecked);
        assert_eq!(none.false_alarm_rate, 0.0);
    }

    #[test]
    fn the_false_alarm_rate_is_the_noise_past_the_tolerance() {
        // One move held with a standard error of half the tolerance: noise
        // alone goes past the tolerance with P(|z| > 2) = 4.55 %.
        let settings = CheckSettings::default();
        let c = consistency(&search_with(Vector6::zeros(), &[(0, 0.5)]), &frame(), &settings);
        assert!((c.false_alarm_rate - 0.0455).abs() < 0.01, "{}", c.false_alarm_rate);
        // Its 95th percentile is 1.96 standard errors.
        assert!((c.noise_95_mm - 0.98).abs() < 0.06, "{}", c.noise_95_mm);
    }
}
