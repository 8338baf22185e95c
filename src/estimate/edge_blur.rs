//! How much an arc's edge points are worth, by where the plane cuts its dome:
//! the noise model the multi-sphere fit (`sphere_bundle`) weighs the
//! arcs by and its Cramér–Rao bound assumes.
//!
//! A B-scan's slice has a thickness: the beam's elevation profile, SD `σ_e`.
//! A plane cut `d` from a dome's centre meets the dome in circles whose radius
//! changes across the slice by `−d·δz / r` (`r = √(R² − d²)` the arc's
//! radius), so the echo at an arc's edge is spread in range over
//! `σ_e·|d| / r` besides the pulse's own length (SD `σ_a`). An edge located in
//! noise is located as much worse as it is wider, so an edge point's variance
//! grows by the factor `1 + (σ_e·|d| / (r·σ_a))²` over that of an arc cut
//! through its dome's centre. Both SDs are the scanner's: its axial resolution
//! and its slice, stated where the model is set.

/// The scanner's pulse and slice, as the edge noise's growth with the cut needs them.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct SliceBlur {
    /// SD of the pulse's envelope along the beam (axial resolution), mm.
    pub axial_sd_mm: f64,
    /// SD of the beam's elevation profile across the slice, mm.
    pub elevation_sd_mm: f64,
}

/// The cut's arc radius is taken as at least this fraction of the dome's, so
/// that a plane grazing a dome (an arc the detector would not find) gives a
/// finite factor.
const MIN_ARC_FRACTION: f64 = 0.1;

impl SliceBlur {
    /// The factor on an edge point's variance for an arc of a dome of radius
    /// `radius_mm` cut `offset_mm` from its centre (1 through the centre).
    pub fn variance_factor(&self, radius_mm: f64, offset_mm: f64) -> f64 {
        let r_sq = (radius_mm * radius_mm - offset_mm * offset_mm).max((MIN_ARC_FRACTION * radius_mm).powi(2));
        let spread_mm = self.elevation_sd_mm * offset_mm.abs() / r_sq.sqrt();
        1.0 + (spread_mm / self.axial_sd_mm).powi(2)
    }
}

/// The factor under an optional model (none: every arc alike).
pub fn variance_factor(blur: Option<SliceBlur>, radius_mm: f64, offset_mm: f64) -> f64 {
    blur.map_or(1.0, |b| b.variance_factor(radius_mm, offset_mm))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLUR: SliceBlur = SliceBlur {
        axial_sd_mm: 0.3,
        elevation_sd_mm: 0.5,
    };

    #[test]
    fn a_cut_through_the_centre_is_worth_what_the_model_says_and_an_oblique_one_less() {
        assert_eq!(BLUR.variance_factor(10.0, 0.0), 1.0);
        // d = 6 of R = 10: r = 8, spread 0.5·6/8 = 0.375 mm; (0.375/0.3)² = 1.5625.
        assert!((BLUR.variance_factor(10.0, 6.0) - 2.5625).abs() < 1e-12);
        assert_eq!(BLUR.variance_factor(10.0, -6.0), BLUR.variance_factor(10.0, 6.0));
        let mut last = 1.0;
        for d in [1.0, 3.0, 5.0, 7.0, 9.0] {
            let f = BLUR.variance_factor(10.0, d);
            assert!(f > last, "{d}: {f} after {last}");
            last = f;
        }
    }

    #[test]
    fn a_grazing_or_missed_dome_gives_a_finite_factor_and_no_model_none() {
        for d in [9.999, 10.0, 12.0] {
            let f = BLUR.variance_factor(10.0, d);
            assert!(f.is_finite() && f > 100.0, "{d}: {f}");
        }
        assert_eq!(variance_factor(None, 10.0, 8.0), 1.0);
        assert_eq!(variance_factor(Some(BLUR), 10.0, 6.0), BLUR.variance_factor(10.0, 6.0));
    }
}
