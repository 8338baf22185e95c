//! The bright straight line of a flat reflector (a water tank's bottom) in a
//! B-scan: each column's brightest row is a candidate point; a seeded RANSAC
//! keeps the points within a few pixels of one line and a total-least-squares
//! fit of them is the line.

use crate::core::rng::Rng;

/// A line in pixels: a point of it (the inliers' centroid) and its unit
/// direction (pointing to growing columns).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub origin_px: [f64; 2],
    pub direction: [f64; 2],
    /// Columns whose brightest row lies on the line.
    pub inliers: usize,
}

/// Why a B-scan has no line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineRejection {
    #[error("the image is empty or dark (brightest grey level {0})")]
    Dark(u8),
    #[error("{inliers} of {columns} columns lie on one line, at least {needed} are needed")]
    TooFewOnLine {
        inliers: usize,
        columns: usize,
        needed: usize,
    },
}

/// Distance of a column's brightest point from the line to count as on it, px.
const ON_LINE_PX: f64 = 3.0;
/// Share of the bright columns that must lie on the line.
const MIN_SHARE: f64 = 0.3;
/// A column's brightest point counts when it is at least this share of the
/// image's brightest grey level.
const BRIGHT_SHARE: f64 = 0.5;
const SAMPLES: usize = 300;

/// Total least squares through `points`: centroid and unit direction.
fn fit(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    let n = points.len().max(1) as f64;
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - cx, p[1] - cy);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mut d = [angle.cos(), angle.sin()];
    if d[0] < 0.0 {
        d = [-d[0], -d[1]];
    }
    ([cx, cy], d)
}

fn distance(p: [f64; 2], origin: [f64; 2], d: [f64; 2]) -> f64 {
    ((p[0] - origin[0]) * d[1] - (p[1] - origin[1]) * d[0]).abs()
}

/// Finds the line in a `width` x `height` grey image.
pub fn find_line(pixels: &[u8], width: usize, height: usize) -> Result<Line, LineRejection> {
    let brightest = pixels.iter().copied().max().unwrap_or(0);
    if width == 0 || height == 0 || brightest < 10 {
        return Err(LineRejection::Dark(brightest));
    }
    let floor = BRIGHT_SHARE * brightest as f64;
    // Each column's brightest row, lightly smoothed along the column (3 rows).
    let points: Vec<[f64; 2]> = (0..width)
        .filter_map(|u| {
            let at = |v: usize| pixels[v * width + u] as f64;
            let (mut best, mut best_v) = (0.0, 0);
            for v in 1..height.saturating_sub(1) {
                let s = (at(v - 1) + at(v) + at(v + 1)) / 3.0;
                if s > best {
                    (best, best_v) = (s, v);
                }
            }
            (best >= floor).then_some([u as f64, best_v as f64])
        })
        .collect();
    let needed = ((MIN_SHARE * points.len() as f64).ceil() as usize).max(10);
    let mut rng = Rng::new(1);
    let mut best: Vec<[f64; 2]> = Vec::new();
    if points.len() >= 2 {
        for _ in 0..SAMPLES {
            let a = points[rng.below(points.len())];
            let b = points[rng.below(points.len())];
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            if len < 10.0 {
                continue;
            }
            let d = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
            let on: Vec<[f64; 2]> = points
                .iter()
                .copied()
                .filter(|p| distance(*p, a, d) <= ON_LINE_PX)
                .collect();
            if on.len() > best.len() {
                best = on;
            }
        }
    }
    if best.len() < needed {
        return Err(LineRejection::TooFewOnLine {
            inliers: best.len(),
            columns: points.len(),
            needed,
        });
    }
    // Refit, take the points near the refitted line, refit once more.
    let (origin, d) = fit(&best);
    let on: Vec<[f64; 2]> = points
        .iter()
        .copied()
        .filter(|p| distance(*p, origin, d) <= ON_LINE_PX)
        .collect();
    let (origin, direction) = fit(&on);
    Ok(Line {
        origin_px: origin,
        direction,
        inliers: on.len(),
    })
}

/// Signed distance of `point` from the line along its normal `(−dy, dx)`, px.
pub fn signed_distance(line: &Line, point: [f64; 2]) -> f64 {
    let [dx, dy] = line.direction;
    (point[0] - line.origin_px[0]) * -dy + (point[1] - line.origin_px[1]) * dx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_tilted_bright_line_among_speckle_and_refuses_a_dark_image() {
        let (w, h) = (200usize, 120usize);
        let mut img = vec![0u8; w * h];
        let mut rng = Rng::new(3);
        for p in img.iter_mut() {
            *p = (rng.uniform(0.0, 40.0)) as u8;
        }
        // v = 40 + 0.25 u, two pixels thick.
        for u in 0..w {
            let v = (40.0 + 0.25 * u as f64).round() as usize;
            img[v * w + u] = 220;
            img[(v + 1) * w + u] = 200;
        }
        // A bright blob off the line.
        for v in 100..105 {
            for u in 10..20 {
                img[v * w + u] = 255;
            }
        }
        let line = find_line(&img, w, h).unwrap();
        let slope = line.direction[1] / line.direction[0];
        assert!((slope - 0.25).abs() < 0.01, "{line:?}");
        assert!(signed_distance(&line, [100.0, 65.0]).abs() < 1.5, "{line:?}");
        assert!(line.inliers > 150, "{line:?}");
        assert!(matches!(find_line(&vec![0; w * h], w, h), Err(LineRejection::Dark(0))));
    }
}
