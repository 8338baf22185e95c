//! How sharp and where a phantom's wires come out in a reconstructed volume: a
//! calibration-quality figure downstream of the calibration. A wrong
//! `ImageToProbe` places each frame's echo of a wire somewhere else, so the wire
//! is smeared (thick), bent (not straight) and moved (off its true line).
//!
//! Along each wire, every `STEP_MM`, the volume is sampled (trilinearly) on a
//! square cross-section `2·HALF_WIDTH_MM` wide, perpendicular to the wire's
//! nominal line. A section counts when all its samples lie in the volume and
//! its brightest sample stands out from the section's median by more than
//! `PEAK_OVER_MAD` times the section's median absolute deviation, taken as at
//! least one grey level (the wire is seen there; a section the sweep did not
//! reach is all zeros and never counts). In a counted section,
//! the samples above the median within `SPOT_RADIUS_MM` of the brightest one
//! give the wire's centre (intensity-weighted) and its width (the weighted
//! second moment, as a Gaussian's FWHM). Per wire: the mean distance of the
//! centres from the nominal line (its position error, which includes the
//! phantom's registration), the RMS distance of the centres from their own
//! fitted line (straightness) and the median FWHM (thickness). The ends of a
//! wire, where an N-wire's diagonal meets its neighbours, are left out
//! (`END_FRACTION` of its length each).

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::reconstruct::Grid;

/// Distance between cross-sections along a wire, mm.
pub const STEP_MM: f64 = 0.5;
/// Half the width of a cross-section, mm.
pub const HALF_WIDTH_MM: f64 = 3.0;
/// Sample spacing within a cross-section, mm.
pub const SAMPLE_MM: f64 = 0.1;
/// The spot around the brightest sample that measures the wire, mm.
pub const SPOT_RADIUS_MM: f64 = 1.5;
/// The brightest sample must exceed the median by this many MADs.
pub const PEAK_OVER_MAD: f64 = 8.0;
/// Share of a wire's length left out at each end.
pub const END_FRACTION: f64 = 0.1;
/// Fewest counted sections for a wire's figures.
pub const MIN_SECTIONS: usize = 5;
/// Gaussian FWHM over its standard deviation.
const FWHM_PER_SD: f64 = 2.354_820_045;

/// A wire: its name and its nominal end points in the volume's frame, mm.
#[derive(Debug, Clone)]
pub struct Wire {
    pub name: String,
    pub front_mm: Point3<f64>,
    pub back_mm: Point3<f64>,
}

/// One wire's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WireFigure {
    pub name: String,
    /// Cross-sections sampled, and those counted (the wire seen there).
    pub sections: usize,
    pub sections_counted: usize,
    /// Mean distance of the centres from the nominal line, mm.
    pub position_error_mm: Option<f64>,
    /// RMS distance of the centres from their own fitted line, mm.
    pub straightness_rms_mm: Option<f64>,
    /// Median FWHM of the cross-sections, mm.
    pub thickness_fwhm_mm: Option<f64>,
}

/// Every wire's figures and their summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WireFigures {
    pub wires: Vec<WireFigure>,
    /// Over the wires with figures: mean position error, RMS straightness and
    /// median thickness, mm; how many wires had figures.
    pub wires_measured: usize,
    pub position_error_mm: Option<f64>,
    pub straightness_rms_mm: Option<f64>,
    pub thickness_fwhm_mm: Option<f64>,
}

/// The volume as the measurement reads it.
pub struct VolumeView<'a, T> {
    pub grid: &'a Grid,
    /// The voxels as they are (8-bit, float): read one by one, never copied.
    pub values: &'a [T],
}

impl<T: Copy + Into<f64>> VolumeView<'_, T> {
    /// Trilinear value at `p` (mm); `None` outside the volume.
    fn sample(&self, p: &Point3<f64>) -> Option<f64> {
        let g = self.grid;
        let c = [0, 1, 2].map(|k| (p[k] - g.origin_mm[k]) / g.spacing_mm[k]);
        if (0..3).any(|k| !(c[k] >= 0.0 && c[k] <= (g.dims[k] - 1) as f64)) {
            return None;
        }
        let base = [0, 1, 2].map(|k| (c[k].floor() as usize).min(g.dims[k].saturating_sub(2)));
        let f = [0, 1, 2].map(|k| c[k] - base[k] as f64);
        let mut total = 0.0;
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let idx = [0, 1, 2].map(|k| (base[k] + o[k]).min(g.dims[k] - 1));
            let v: f64 = self.values[(idx[2] * g.dims[1] + idx[1]) * g.dims[0] + idx[0]].into();
            let w: f64 = (0..3).map(|k| if o[k] == 1 { f[k] } else { 1.0 - f[k] }).product();
            total += w * v;
        }
        Some(total)
    }
}

/// Two unit vectors perpendicular to `u` and to each other.
fn section_axes(u: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if u.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let e1 = u.cross(&helper).normalize();
    (e1, u.cross(&e1))
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// The wire's centre offset (along e1, e2) and FWHM in one section, if it is seen.
fn measure_section(samples: &[(f64, f64, f64)]) -> Option<([f64; 2], f64)> {
    let mut values: Vec<f64> = samples.iter().map(|s| s.2).collect();
    let background = median(&mut values);
    let mut deviations: Vec<f64> = samples.iter().map(|s| (s.2 - background).abs()).collect();
    let mad = median(&mut deviations).max(1.0);
    let peak = samples.iter().max_by(|a, b| a.2.total_cmp(&b.2))?;
    if peak.2 - background < PEAK_OVER_MAD * mad {
        return None;
    }
    let spot: Vec<(f64, f64, f64)> = samples
        .iter()
        .filter(|s| (s.0 - peak.0).hypot(s.1 - peak.1) <= SPOT_RADIUS_MM && s.2 > background)
        .map(|s| (s.0, s.1, s.2 - background))
        .collect();
    let total: f64 = spot.iter().map(|s| s.2).sum();
    if total <= 0.0 {
        return None;
    }
    let cx = spot.iter().map(|s| s.0 * s.2).sum::<f64>() / total;
    let cy = spot.iter().map(|s| s.1 * s.2).sum::<f64>() / total;
    let var = spot
        .iter()
        .map(|s| ((s.0 - cx).powi(2) + (s.1 - cy).powi(2)) * s.2)
        .sum::<f64>()
        / total
        / 2.0;
    Some(([cx, cy], FWHM_PER_SD * var.sqrt()))
}

/// RMS distance of `points` from their least-squares line (`None` under 2 points).
fn rms_from_fitted_line(points: &[Point3<f64>]) -> Option<f64> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let centre = points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let mut scatter = nalgebra::Matrix3::zeros();
    for p in points {
        let d = p.coords - centre;
        scatter += d * d.transpose();
    }
    let eigen = scatter.symmetric_eigen();
    let (axis, _) = eigen.eigenvalues.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    let dir = eigen.eigenvectors.column(axis).into_owned();
    let sum: f64 = points
        .iter()
        .map(|p| {
            let d = p.coords - centre;
            (d - dir * d.dot(&dir)).norm_squared()
        })
        .sum();
    Some((sum / n).sqrt())
}

/// One wire's figures in the volume.
pub fn measure_wire<T: Copy + Into<f64>>(volume: &VolumeView<T>, wire: &Wire) -> WireFigure {
    let axis = wire.back_mm - wire.front_mm;
    let length = axis.norm();
    let u = axis / length.max(1e-12);
    let (e1, e2) = section_axes(&u);
    let half = (HALF_WIDTH_MM / SAMPLE_MM).round() as i64;
    let (first, last) = (END_FRACTION * length, (1.0 - END_FRACTION) * length);
    let count = if last > first {
        ((last - first) / STEP_MM).floor() as usize + 1
    } else {
        0
    };
    let mut centres = Vec::new();
    let mut offsets = Vec::new();
    let mut widths = Vec::new();
    for s in 0..count {
        let on_line = wire.front_mm + u * (first + s as f64 * STEP_MM);
        let samples: Option<Vec<(f64, f64, f64)>> = (-half..=half)
            .flat_map(|i| (-half..=half).map(move |j| (i as f64 * SAMPLE_MM, j as f64 * SAMPLE_MM)))
            .map(|(a, b)| volume.sample(&(on_line + e1 * a + e2 * b)).map(|v| (a, b, v)))
            .collect();
        let Some(([a, b], fwhm)) = samples.as_deref().and_then(measure_section) else {
            continue;
        };
        centres.push(on_line + e1 * a + e2 * b);
        offsets.push(a.hypot(b));
        widths.push(fwhm);
    }
    let counted = centres.len();
    let enough = counted >= MIN_SECTIONS;
    WireFigure {
        name: wire.name.clone(),
        sections: count,
        sections_counted: counted,
        position_error_mm: enough.then(|| offsets.iter().sum::<f64>() / counted as f64),
        straightness_rms_mm: if enough { rms_from_fitted_line(&centres) } else { None },
        thickness_fwhm_mm: enough.then(|| median(&mut widths)),
    }
}

/// Every wire's figures and their summary.
pub fn measure<T: Copy + Into<f64>>(volume: &VolumeView<T>, wires: &[Wire]) -> WireFigures {
    let figures: Vec<WireFigure> = wires.iter().map(|w| measure_wire(volume, w)).collect();
    let measured: Vec<&WireFigure> = figures.iter().filter(|f| f.position_error_mm.is_some()).collect();
    let n = measured.len();
    let pick = |f: fn(&WireFigure) -> Option<f64>| -> Vec<f64> { measured.iter().filter_map(|w| f(w)).collect() };
    let position = pick(|w| w.position_error_mm);
    let straight = pick(|w| w.straightness_rms_mm);
    let mut thick = pick(|w| w.thickness_fwhm_mm);
    WireFigures {
        wires_measured: n,
        position_error_mm: (n > 0).then(|| position.iter().sum::<f64>() / position.len() as f64),
        straightness_rms_mm: (!straight.is_empty())
            .then(|| (straight.iter().map(|v| v * v).sum::<f64>() / straight.len() as f64).sqrt()),
        thickness_fwhm_mm: (!thick.is_empty()).then(|| median(&mut thick)),
        wires: figures,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume with a Gaussian wire of SD `sd` mm along x at (y, z) = `at`,
    /// over a background of 20.
    fn volume_with_wire(at: [f64; 2], sd: f64, bend_mm_per_mm2: f64) -> (Grid, Vec<f64>) {
        let grid = Grid {
            origin_mm: [0.0; 3],
            spacing_mm: [0.2; 3],
            dims: [101, 61, 61],
        };
        let mut values = vec![0.0; grid.voxels()];
        for k in 0..grid.dims[2] {
            for j in 0..grid.dims[1] {
                for i in 0..grid.dims[0] {
                    let [x, y, z] = [i, j, k].map(|v| v as f64 * 0.2);
                    let yc = at[0] + bend_mm_per_mm2 * (x - 10.0).powi(2);
                    let r2 = (y - yc).powi(2) + (z - at[1]).powi(2);
                    values[(k * grid.dims[1] + j) * grid.dims[0] + i] = 20.0 + 200.0 * (-r2 / (2.0 * sd * sd)).exp();
                }
            }
        }
        (grid, values)
    }

    /// The nominal wire: along x at (y, z) = (6, 6) mm.
    fn along_x() -> Wire {
        Wire {
            name: "w".into(),
            front_mm: Point3::new(0.0, 6.0, 6.0),
            back_mm: Point3::new(20.0, 6.0, 6.0),
        }
    }

    #[test]
    fn a_straight_wire_off_its_line_gives_its_offset_and_width() {
        // The wire lies 0.3 mm off the nominal line in y, SD 0.4 mm (FWHM 0.94 mm).
        let (grid, values) = volume_with_wire([6.3, 6.0], 0.4, 0.0);
        let view = VolumeView {
            grid: &grid,
            values: &values,
        };
        let nominal = along_x();
        let f = measure_wire(&view, &nominal);
        assert!(f.sections_counted >= 30, "{f:?}");
        assert!((f.position_error_mm.unwrap() - 0.3).abs() < 0.02, "{f:?}");
        assert!(f.straightness_rms_mm.unwrap() < 0.02, "{f:?}");
        assert!((f.thickness_fwhm_mm.unwrap() - 0.94).abs() < 0.1, "{f:?}");
    }

    #[test]
    fn a_bent_wire_is_not_straight_and_an_empty_volume_measures_nothing() {
        let (grid, values) = volume_with_wire([6.0, 6.0], 0.4, 0.01);
        let view = VolumeView {
            grid: &grid,
            values: &values,
        };
        let nominal = along_x();
        let bent = measure_wire(&view, &nominal);
        // The bend is up to 0.64 mm at the measured ends (x = 2 and 18 mm).
        assert!(bent.straightness_rms_mm.unwrap() > 0.1, "{bent:?}");
        let empty = vec![0.0; grid.voxels()];
        let none = measure(
            &VolumeView {
                grid: &grid,
                values: &empty,
            },
            &[nominal],
        );
        assert_eq!(none.wires_measured, 0);
        assert_eq!(none.wires[0].sections_counted, 0);
        assert!(none.position_error_mm.is_none());
    }
}
