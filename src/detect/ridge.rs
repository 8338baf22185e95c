//! Where a bright echo ridge lies, from a pixel on it: along the image column
//! or along the ridge's own normal.
//!
//! The arc detector takes a column's local maximum as a point of the ridge.
//! Where the ridge is steep (the ends of a dome's arc) the column runs almost
//! along it, so the column's maximum slides towards where the echo is stronger:
//! a dome's echo weakens away from its top (the surface turns from the beam),
//! so the ends of every arc come out shallower than the surface, its radius
//! larger and its centre deeper. The ridge's centre along its normal (Steger's
//! line detector: the zero of the first derivative along the normal, from the
//! second-order Taylor expansion of the smoothed image) does not move with the
//! echo's strength along the ridge.

/// How a ridge point is placed from the pixel where its column peaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RidgePeak {
    /// The column's parabolic peak (sub-pixel in the row only).
    #[default]
    Column,
    /// The ridge's centre along its normal.
    Normal,
}

/// The image around a column's peak: the column's three values, and the
/// smoothed image's gradient (per mm), Hessian `[xx, xy, yy]` (per mm²) and
/// unit ridge normal there.
#[derive(Debug, Clone, Copy)]
pub struct RidgeSample {
    pub column: [f32; 3],
    pub gradient: [f64; 2],
    pub hessian: [f64; 3],
    pub normal: [f64; 2],
}

/// A ridge centre along the normal farther than this many pixels from the
/// column's peak is not taken: the expansion no longer holds there.
const MAX_NORMAL_STEP_PX: f64 = 2.0;

/// The ridge point (mm) from the column's peak at pixel `(x, y)`, or `None`
/// when its centre along the normal is not within reach.
pub fn locate(
    peak: RidgePeak,
    x: usize,
    y: usize,
    sample: &RidgeSample,
    spacing_mm_per_px: [f64; 2],
) -> Option<[f64; 2]> {
    let [sx, sy] = spacing_mm_per_px;
    match peak {
        RidgePeak::Column => {
            let [up, v, down] = sample.column;
            let denom = up - 2.0 * v + down;
            let offset = if denom.abs() > 1e-6 {
                (0.5 * (up - down) / denom).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            Some([x as f64 * sx, (y as f64 + offset as f64) * sy])
        }
        RidgePeak::Normal => {
            let [nx, ny] = sample.normal;
            let [xx, xy, yy] = sample.hessian;
            let curvature = nx * nx * xx + 2.0 * nx * ny * xy + ny * ny * yy;
            let slope = sample.gradient[0] * nx + sample.gradient[1] * ny;
            let step_mm = -slope / curvature;
            (step_mm.is_finite() && curvature < 0.0 && step_mm.abs() <= MAX_NORMAL_STEP_PX * sx.max(sy))
                .then_some([x as f64 * sx + step_mm * nx, y as f64 * sy + step_mm * ny])
        }
    }
}

/// The ridge sample of pixel `[x, y]` (at least 2 px from the image's edges):
/// `None` unless the smoothed column peaks there and the structure is
/// line-like rather than a speckle blob. The Hessian is taken in mm on the
/// isotropically smoothed image over a 2-pixel baseline, to average out speckle;
/// the normal is the eigenvector of the most negative curvature, pointing down.
pub fn ridge_sample(
    smooth: &[f32],
    iso: &[f32],
    w: usize,
    [x, y]: [usize; 2],
    [sx, sy]: [f64; 2],
) -> Option<RidgeSample> {
    let at = |x: usize, y: usize| iso[y * w + x] as f64;
    let v = smooth[y * w + x];
    let up = smooth[(y - 1) * w + x];
    let down = smooth[(y + 1) * w + x];
    if !(v >= up && v > down && v >= smooth[(y - 2) * w + x] && v >= smooth[(y + 2) * w + x]) {
        return None;
    }
    // Hessian in mm units, over a 2-pixel baseline to average out speckle.
    let ixx = (at(x + 2, y) - 2.0 * at(x, y) + at(x - 2, y)) / (4.0 * sx * sx);
    let iyy = (at(x, y + 2) - 2.0 * at(x, y) + at(x, y - 2)) / (4.0 * sy * sy);
    let ixy = (at(x + 2, y + 2) - at(x + 2, y - 2) - at(x - 2, y + 2) + at(x - 2, y - 2)) / (16.0 * sx * sy);
    let half_trace = (ixx + iyy) / 2.0;
    let root = (((ixx - iyy) / 2.0).powi(2) + ixy * ixy).sqrt();
    let (l_min, l_other) = (half_trace - root, half_trace + root);
    if l_min >= 0.0 || l_min.abs() < 2.0 * l_other.abs() {
        return None;
    }
    // Eigenvector of l_min.
    let (mut nx, mut ny) = if ixy.abs() > 1e-12 {
        (ixy, l_min - ixx)
    } else if ixx < iyy {
        (1.0, 0.0)
    } else {
        (0.0, 1.0)
    };
    let norm = (nx * nx + ny * ny).sqrt();
    nx /= norm;
    ny /= norm;
    if ny < 0.0 {
        nx = -nx;
        ny = -ny;
    }
    Some(RidgeSample {
        column: [up, v, down],
        gradient: [
            (at(x + 2, y) - at(x - 2, y)) / (4.0 * sx),
            (at(x, y + 2) - at(x, y - 2)) / (4.0 * sy),
        ],
        hessian: [ixx, ixy, iyy],
        normal: [nx, ny],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::arc::{echo_points, ArcSettings};
    use crate::io::image::gaussian_blur_f32;
    use opencv::core::{Mat, CV_8UC1};
    use opencv::prelude::*;

    /// A dome's arc as the scanner shows it: a thin bright ridge on a circle of
    /// radius 8 mm, its echo weakening from the top towards the ends (by half
    /// of `sin²` of the surface's turn from the beam), blurred more across the
    /// beam than along it. Returns the image, the centre and the radius (mm).
    fn arc_image(spacing: [f64; 2]) -> (Mat, [f64; 2], f64) {
        let (w, h) = (300usize, 300usize);
        let [sx, sy] = spacing;
        let (centre, radius) = ([30.0, 40.0], 8.0);
        let mut ridge = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f64 * sx - centre[0], y as f64 * sy - centre[1]);
                let distance = (dx * dx + dy * dy).sqrt();
                let turn = (-dy / distance).clamp(0.0, 1.0); // cos of the angle from the top
                if dy < 0.0 {
                    let profile = (-((distance - radius) / 0.15).powi(2) / 2.0).exp();
                    ridge[y * w + x] = (200.0 * (0.5 + 0.5 * turn.powi(2)) * profile) as f32;
                }
            }
        }
        gaussian_blur_f32(w, h, &mut ridge, 0.45 / sx, 0.2 / sy).unwrap();
        let mut image = Mat::new_rows_cols_with_default(h as i32, w as i32, CV_8UC1, 1.into()).unwrap();
        for y in 0..h {
            for x in 0..w {
                *image.at_2d_mut::<u8>(y as i32, x as i32).unwrap() = (10.0 + ridge[y * w + x]).clamp(1.0, 255.0) as u8;
            }
        }
        (image, centre, radius)
    }

    /// Mean distance outside the circle of the ridge points more than 50° from
    /// the arc's top, and how many there are.
    fn steep_offset(peak: RidgePeak) -> (f64, usize) {
        let spacing = [0.2, 0.2];
        let (image, centre, radius) = arc_image(spacing);
        let settings = ArcSettings {
            spacing_mm_per_px: spacing,
            radius_mm: [6.0, 10.0],
            min_span_deg: 40.0,
            max_rms_px: 2.5,
            min_points: 10,
            fixed_radius_mm: None,
            peak,
        };
        let points = echo_points(&image, &settings).unwrap().unwrap();
        let steep: Vec<f64> = points
            .points_mm
            .iter()
            .filter_map(|p| {
                let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
                let distance = (dx * dx + dy * dy).sqrt();
                ((-dy / distance) < 50f64.to_radians().cos() && (distance - radius).abs() < 1.5)
                    .then_some(distance - radius)
            })
            .collect();
        (steep.iter().sum::<f64>() / steep.len().max(1) as f64, steep.len())
    }

    #[test]
    fn the_column_peak_puts_a_steep_arc_end_outside_its_circle_and_the_normal_peak_does_not() {
        let (column_mm, column_points) = steep_offset(RidgePeak::Column);
        let (normal_mm, normal_points) = steep_offset(RidgePeak::Normal);
        assert!(
            column_points >= 10 && normal_points >= 10,
            "{column_points} {normal_points}"
        );
        assert!(column_mm > 0.05, "column peak: {column_mm} mm");
        assert!(normal_mm.abs() < 0.03, "normal peak: {normal_mm} mm");
    }

    #[test]
    fn a_ridge_point_too_far_along_the_normal_or_in_a_valley_is_not_taken() {
        let sample = RidgeSample {
            column: [1.0, 2.0, 1.0],
            gradient: [0.0, 10.0],
            hessian: [0.0, 0.0, -1.0],
            normal: [0.0, 1.0],
        };
        assert_eq!(locate(RidgePeak::Normal, 5, 5, &sample, [0.2, 0.2]), None);
        let valley = RidgeSample {
            gradient: [0.0, 0.01],
            hessian: [0.0, 0.0, 1.0],
            ..sample
        };
        assert_eq!(locate(RidgePeak::Normal, 5, 5, &valley, [0.2, 0.2]), None);
        let near = RidgeSample {
            gradient: [0.0, 0.1],
            ..sample
        };
        let p = locate(RidgePeak::Normal, 5, 5, &near, [0.2, 0.2]).unwrap();
        assert!((p[0] - 1.0).abs() < 1e-12 && (p[1] - 1.1).abs() < 1e-12, "{p:?}");
        assert_eq!(locate(RidgePeak::Column, 5, 5, &sample, [0.2, 0.2]), Some([1.0, 1.0]));
    }
}
