//! Whether a validation sweep holds the probe as the calibration sweep did.
//!
//! A calibration is only checked where its frames were: a validation sweep held
//! at other tilts against the phantom extrapolates the fit's rotation errors
//! over a longer lever. Each frame's tilt is the phantom's wire direction in the
//! image frame (`image_T_phantom` applied to the wire's unit vector, its sign
//! taken so that it points along +z, the image normal), as two angles:
//! `lateral_deg` toward the image's x axis, `axial_deg` toward its y axis
//! (both 0 when the wires cross the image plane square). A validation frame is
//! outside the calibration's range when either angle is beyond the calibration
//! frames' extremes.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::core::stats::percentile;

/// Smallest, median and largest of a sweep's angles, degrees.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct AngleRange {
    pub min: f64,
    pub median: f64,
    pub max: f64,
}

impl AngleRange {
    fn of(angles: &[f64]) -> AngleRange {
        AngleRange {
            min: angles.iter().copied().fold(f64::INFINITY, f64::min),
            median: percentile(angles, 0.5),
            max: angles.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }

    fn contains(&self, angle: f64) -> bool {
        (self.min..=self.max).contains(&angle)
    }
}

/// One sweep's tilts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SweepTilts {
    pub frames: usize,
    pub lateral_deg: AngleRange,
    pub axial_deg: AngleRange,
}

/// Both sweeps' tilts and how many validation frames lie outside the calibration's.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseCoverage {
    pub calibration: SweepTilts,
    pub validation: SweepTilts,
    pub validation_outside_calibration: usize,
}

/// A frame's `(lateral, axial)` tilt, degrees, from the wires' direction in the
/// image frame; `None` for a direction in the image plane (or not finite).
pub fn tilt_deg(wire_in_image: &Vector3<f64>) -> Option<(f64, f64)> {
    let d = if wire_in_image.z < 0.0 {
        -wire_in_image
    } else {
        *wire_in_image
    };
    if !(d.z > 1e-9 && d.iter().all(|v| v.is_finite())) {
        return None;
    }
    Some((d.x.atan2(d.z).to_degrees(), d.y.atan2(d.z).to_degrees()))
}

fn sweep(tilts: &[(f64, f64)]) -> Option<SweepTilts> {
    if tilts.is_empty() {
        return None;
    }
    let (lateral, axial): (Vec<f64>, Vec<f64>) = tilts.iter().copied().unzip();
    Some(SweepTilts {
        frames: tilts.len(),
        lateral_deg: AngleRange::of(&lateral),
        axial_deg: AngleRange::of(&axial),
    })
}

/// The coverage of two sweeps, each given as its frames' wire directions in
/// the image frame; `None` when either has no usable frame.
pub fn coverage(calibration: &[Vector3<f64>], validation: &[Vector3<f64>]) -> Option<PoseCoverage> {
    let tilts = |d: &[Vector3<f64>]| d.iter().filter_map(tilt_deg).collect::<Vec<_>>();
    let (cal, val) = (tilts(calibration), tilts(validation));
    let (calibration, validation) = (sweep(&cal)?, sweep(&val)?);
    let outside = val
        .iter()
        .filter(|(l, a)| !(calibration.lateral_deg.contains(*l) && calibration.axial_deg.contains(*a)))
        .count();
    Some(PoseCoverage {
        calibration,
        validation,
        validation_outside_calibration: outside,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wires' direction tilted by `lateral` and `axial` degrees.
    fn wire(lateral: f64, axial: f64) -> Vector3<f64> {
        Vector3::new(lateral.to_radians().tan(), axial.to_radians().tan(), 1.0).normalize()
    }

    #[test]
    fn tilts_are_the_wires_angles_whichever_way_they_point() {
        let (l, a) = tilt_deg(&wire(4.0, -2.5)).unwrap();
        assert!((l - 4.0).abs() < 1e-9 && (a + 2.5).abs() < 1e-9, "{l} {a}");
        let (l, a) = tilt_deg(&-wire(4.0, -2.5)).unwrap();
        assert!((l - 4.0).abs() < 1e-9 && (a + 2.5).abs() < 1e-9, "{l} {a}");
        assert_eq!(tilt_deg(&Vector3::new(1.0, 0.0, 0.0)), None);
        assert_eq!(tilt_deg(&Vector3::new(f64::NAN, 0.0, 1.0)), None);
    }

    #[test]
    fn validation_frames_beyond_the_calibrations_tilts_are_counted() {
        let calibration: Vec<_> = (0..=10).map(|k| wire(k as f64 * 0.5, -1.0 + k as f64 * 0.2)).collect();
        let validation = [wire(2.0, 0.0), wire(-3.0, 0.0), wire(2.0, 1.5), wire(5.0, 1.0)];
        let c = coverage(&calibration, &validation).unwrap();
        assert_eq!(c.calibration.frames, 11);
        assert!((c.calibration.lateral_deg.min - 0.0).abs() < 1e-9);
        assert!((c.calibration.lateral_deg.median - 2.5).abs() < 1e-9);
        assert!((c.calibration.lateral_deg.max - 5.0).abs() < 1e-9);
        assert!((c.calibration.axial_deg.max - 1.0).abs() < 1e-9);
        // Outside: lateral -3 and axial 1.5; inside: (2, 0) and the corner (5, 1).
        assert_eq!(c.validation_outside_calibration, 2);
        assert_eq!(coverage(&calibration, &[]), None);
    }
}
