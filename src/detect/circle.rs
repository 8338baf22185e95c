//! Circles among points: the Hough vote for an arc's centre, the radius
//! histogram around it, the geometric fit, and how well a line or the arc's
//! span explains the points (mm throughout).

use crate::io::image::{gaussian_blur_f32, ImageError};

/// The Hough accumulator's cell, mm.
pub const CELL_MM: f64 = 0.25;
/// Angular bins for the arc's coverage check.
const FILL_BIN_DEG: f64 = 5.0;

/// Step 2: each point votes along its normal, towards the centre below it (the
/// dome faces the probe), at every radius of `radius_mm`, over an image of
/// `size_mm`; the strongest centre and how much it stands out from the next
/// one away from it, or `None` with no vote.
pub fn hough_centre(
    points_mm: &[[f64; 2]],
    normals: &[[f64; 2]],
    size_mm: [f64; 2],
    radius_mm: [f64; 2],
) -> Result<Option<([f64; 2], f64)>, ImageError> {
    let [r_min, r_max] = radius_mm;
    let (gw, gh) = (
        (size_mm[0] / CELL_MM).ceil() as usize + 1,
        (size_mm[1] / CELL_MM).ceil() as usize + 1,
    );
    let mut accumulator = vec![0f32; gw * gh];
    let radii: Vec<f64> = (0..)
        .map(|i| r_min + i as f64 * CELL_MM)
        .take_while(|r| *r <= r_max)
        .collect();
    for (p, n) in points_mm.iter().zip(normals) {
        if n[1] < (70f64).to_radians().cos() {
            continue; // the centre lies within 70° of straight below an arc point
        }
        for spread in [-6.0f64, -3.0, 0.0, 3.0, 6.0] {
            let (sin, cos) = spread.to_radians().sin_cos();
            let d = [n[0] * cos - n[1] * sin, n[0] * sin + n[1] * cos];
            for &r in &radii {
                let (gx, gy) = (
                    ((p[0] + r * d[0]) / CELL_MM).round(),
                    ((p[1] + r * d[1]) / CELL_MM).round(),
                );
                if gx < 0.0 || gy < 0.0 || gx >= gw as f64 || gy >= gh as f64 {
                    continue;
                }
                accumulator[gy as usize * gw + gx as usize] += 1.0;
            }
        }
    }
    gaussian_blur_f32(gw, gh, &mut accumulator, 2.0, 2.0)?;
    let Some((bx, by, best_votes)) = accumulator_peak(&accumulator, gw) else {
        return Ok(None);
    };
    let competing = strongest_outside(&accumulator, gw, [bx, by], (3.0 / CELL_MM) as usize);
    let peak_ratio = if competing > 0.0 {
        (best_votes / competing) as f64
    } else {
        f64::INFINITY
    };
    Ok(Some(([bx as f64 * CELL_MM, by as f64 * CELL_MM], peak_ratio)))
}

/// Step 3: the most common distance of the points above `centre` from it
/// (0.1 mm bins, smoothed), mm.
pub fn radius_peak(points_mm: &[[f64; 2]], centre: [f64; 2], radius_mm: [f64; 2]) -> f64 {
    let [r_min, r_max] = radius_mm;
    let bin = 0.1;
    let bins = ((r_max - r_min) / bin).ceil() as usize + 1;
    let mut histogram = vec![0f64; bins];
    for p in points_mm {
        if p[1] >= centre[1] {
            continue;
        }
        let d = ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt();
        if d >= r_min && d <= r_max {
            histogram[((d - r_min) / bin) as usize] += 1.0;
        }
    }
    let smoothed: Vec<f64> = (0..bins)
        .map(|i| {
            [(-2i64, 1.0), (-1, 2.0), (0, 3.0), (1, 2.0), (2, 1.0)]
                .iter()
                .filter_map(|(o, wgt)| histogram.get((i as i64 + o) as usize).map(|v| v * wgt))
                .sum()
        })
        .collect();
    let (peak_bin, _) = smoothed
        .iter()
        .enumerate()
        .fold((0, 0.0), |acc, (i, v)| if *v > acc.1 { (i, *v) } else { acc });
    r_min + (peak_bin as f64 + 0.5) * bin
}

/// How continuously the angles (degrees, from `first` over `span`) cover the
/// span: a dome's echo is one unbroken arc; pieces of other structures that
/// happen to lie on a circle are not.
pub fn angular_fill(angles: &[f64], first: f64, span: f64) -> f64 {
    let bins = ((span / FILL_BIN_DEG).ceil() as usize).max(1);
    let mut occupied = vec![false; bins];
    for a in angles {
        occupied[(((a - first) / FILL_BIN_DEG) as usize).min(bins - 1)] = true;
    }
    occupied.iter().filter(|o| **o).count() as f64 / bins as f64
}

/// The accumulator's first strongest cell `(column, row, votes)`, or `None`
/// when no cell has a vote. The maximum is found over all cells first and then
/// its first cell, so the loops vectorise.
pub(crate) fn accumulator_peak(accumulator: &[f32], width: usize) -> Option<(usize, usize, f32)> {
    let votes = accumulator.iter().copied().fold(0f32, f32::max);
    if votes <= 0.0 {
        return None;
    }
    let best = accumulator.iter().position(|v| *v == votes)?;
    Some((best % width, best / width, votes))
}

/// The strongest accumulator cell more than `exclusion` cells from `peak` in
/// column or in row (0 when there is none): whole rows away from the peak's
/// rows, and the parts left and right of the peak's columns in its rows.
pub(crate) fn strongest_outside(accumulator: &[f32], width: usize, peak: [usize; 2], exclusion: usize) -> f32 {
    let [bx, by] = peak;
    let row_max = |row: &[f32]| row.iter().copied().fold(0f32, f32::max);
    accumulator
        .chunks(width.max(1))
        .enumerate()
        .map(|(y, row)| {
            if y.abs_diff(by) > exclusion {
                row_max(row)
            } else {
                let left = row_max(&row[..bx.saturating_sub(exclusion)]);
                let right = row_max(row.get(bx + exclusion + 1..).unwrap_or(&[]));
                left.max(right)
            }
        })
        .fold(0f32, f32::max)
}

/// Geometric circle fit (Gauss–Newton) from a start; returns centre, radius, RMS (mm).
/// With `fixed_radius` the radius stays at the start's value.
pub fn fit_circle(points: &[[f64; 2]], start: ([f64; 2], f64), fixed_radius: bool) -> Option<([f64; 2], f64, f64)> {
    let ([mut a, mut b], mut r) = start;
    for _ in 0..30 {
        let mut jtj = nalgebra::Matrix3::<f64>::zeros();
        let mut jtr = nalgebra::Vector3::<f64>::zeros();
        for p in points {
            let (dx, dy) = (p[0] - a, p[1] - b);
            let d = (dx * dx + dy * dy).sqrt().max(1e-9);
            let j = nalgebra::Vector3::new(-dx / d, -dy / d, if fixed_radius { 0.0 } else { -1.0 });
            let res = d - r;
            jtj += j * j.transpose();
            jtr += j * res;
        }
        if fixed_radius {
            jtj[(2, 2)] = 1.0;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        a += step[0];
        b += step[1];
        r += step[2];
        if step.norm() < 1e-7 {
            break;
        }
    }
    let sum: f64 = points
        .iter()
        .map(|p| (((p[0] - a).powi(2) + (p[1] - b).powi(2)).sqrt() - r).powi(2))
        .sum();
    let rms = (sum / points.len().max(1) as f64).sqrt();
    (a.is_finite() && b.is_finite() && r.is_finite()).then_some(([a, b], r, rms))
}

/// RMS distance of points to their total-least-squares line (mm).
pub fn line_rms(points: &[[f64; 2]]) -> f64 {
    let n = points.len().max(1) as f64;
    let (mx, my) = (
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    );
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
    }
    // Smallest eigenvalue of the scatter matrix = sum of squared line distances.
    let half_trace = (sxx + syy) / 2.0;
    let smallest = half_trace - (((sxx - syy) / 2.0).powi(2) + sxy * sxy).sqrt();
    (smallest.max(0.0) / n).sqrt()
}
