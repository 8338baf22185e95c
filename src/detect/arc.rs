//! Stage 3: the hemisphere's arc in a B-scan and its circle centre.
//!
//! As in the thesis: a two-parameter Hough transform for the centre, then a
//! radius histogram around it; then a sub-pixel geometric circle fit on the arc's
//! echo points. Work is done in millimetres (pixel spacing applied), so that
//! anisotropic pixels still give circles.
//!
//! 1. Echo points: along each image column, local maxima of the smoothed image
//!    above an adaptive threshold, below the transducer's near field, inside the
//!    fan (eroded, so the fan's edge is no echo), refined to sub-pixel: along
//!    the column, or along the ridge's normal (`ArcSettings::peak`, [`super::ridge`]).
//! 2. Every point votes for the centres below it (the dome faces the probe) at all
//!    radii in the searched range; the smoothed accumulator's peak is the centre.
//! 3. The radius is the peak of the histogram of point distances to that centre.
//! 4. Points within a band of that circle are refitted by Gauss–Newton; the band
//!    is narrowed twice. The frame is rejected, with the reason, when the arc is
//!    too short, has too few points, is not circular, or has an implausible radius.

use super::circle::{angular_fill, fit_circle, hough_centre, line_rms, radius_peak};
use super::fan::{FAN_EDGE_MM, NEAR_FIELD_MM};
use super::ridge::{locate, ridge_sample, RidgePeak};
use crate::core::stats::median_and_quantile_nearest;
use opencv::core::Mat;

use crate::io::image::{gaussian_blur_f32, mat_to_gray8, ImageError};

/// What the detector needs to know.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcSettings {
    pub spacing_mm_per_px: [f64; 2],
    /// Arc radii searched, mm.
    pub radius_mm: [f64; 2],
    pub min_span_deg: f64,
    pub max_rms_px: f64,
    pub min_points: usize,
    /// Fit the circle with this radius (mm): the sphere's, when the plane passes
    /// near its centre. A free radius makes the centre of a short arc unstable
    /// along the arc's axis; `None` fits the radius too.
    pub fixed_radius_mm: Option<f64>,
    /// How an echo point is placed on its ridge ([`super::ridge`]).
    pub peak: RidgePeak,
}

/// A detected arc.
#[derive(Debug, Clone, PartialEq)]
pub struct ArcFeature {
    /// Circle centre, pixels (u = column, v = row).
    pub centre_px: [f64; 2],
    pub radius_mm: f64,
    /// Echo points on the arc.
    pub points: usize,
    pub span_deg: f64,
    /// RMS distance of the arc points to the circle, px.
    pub rms_px: f64,
    /// Accumulator peak over the strongest competing peak (1 = ambiguous).
    pub peak_ratio: f64,
    /// Fraction of 5° bins over the arc's span that hold echo points.
    pub fill: f64,
    /// 0..1: geometric mean of the arc's span (full at 120°), its support (full at
    /// four times the minimum number of points) and its fit (1 − RMS / limit).
    pub confidence: f64,
    /// Arc points, pixels (for figures).
    pub arc_points_px: Vec<[f64; 2]>,
}

/// Smallest fraction of the arc's span that must hold echo points.
const MIN_FILL: f64 = 0.75;

/// Why a B-scan shows no usable arc.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArcRejection {
    #[error("no ultrasound image content (empty fan)")]
    EmptyFan,
    #[error("no echo arc: only {found} bright echo points (need {needed})")]
    TooFewEchoPoints { found: usize, needed: usize },
    #[error("no circular arc in the Hough accumulator")]
    NoHoughPeak,
    #[error("arc has only {found} echo points on a circle (need {needed})")]
    TooFewOnCircle { found: usize, needed: usize },
    #[error("circle fit did not converge")]
    FitDiverged,
    #[error("arc radius {radius_mm:.2} mm is outside the searched {min_mm:.2}–{max_mm:.2} mm")]
    RadiusOutside { radius_mm: f64, min_mm: f64, max_mm: f64 },
    #[error("arc spans only {span_deg:.0}° (need {needed_deg:.0}°)")]
    ShortSpan { span_deg: f64, needed_deg: f64 },
    /// A wall or the floor: a line fits the echo nearly as well as the circle.
    #[error("the echo is nearly straight (a line fits it {line_to_circle:.1}x as well as the circle; need {needed}x): a wall or the floor, not the dome")]
    Straight { line_to_circle: f64, needed: f64 },
    /// Pieces of other echoes, not one arc.
    #[error("echo points cover only {covered_percent:.0}% of the {span_deg:.0}° arc (need {needed_percent:.0}%): pieces of other echoes, not one arc")]
    Patchy {
        covered_percent: f64,
        span_deg: f64,
        needed_percent: f64,
    },
    #[error("arc is not circular: RMS {rms_px:.2} px from the fitted circle (limit {limit_px:.2} px)")]
    NotCircular { rms_px: f64, limit_px: f64 },
}

/// A circle must fit the arc points at least this many times better than a line.
const MIN_LINE_TO_CIRCLE_RMS: f64 = 2.0;

/// Detects the arc. The inner `Err` is the frame's rejection reason.
pub fn detect(image: &Mat, settings: &ArcSettings) -> Result<Result<ArcFeature, ArcRejection>, ImageError> {
    Ok(match echo_points(image, settings)? {
        Ok(points) => arc_from_points(&points, settings)?,
        Err(reason) => Err(reason),
    })
}

/// Detects up to `max_arcs` arcs (domes of several spheres), strongest first:
/// each found arc's echo points (and those within a band of its circle) are
/// removed before the next search. The search stops at the first rejection,
/// which is returned beside the arcs found (`None` when `max_arcs` were found).
pub fn detect_many(
    image: &Mat,
    settings: &ArcSettings,
    max_arcs: usize,
) -> Result<(Vec<ArcFeature>, Option<ArcRejection>), ImageError> {
    let mut points = match echo_points(image, settings)? {
        Ok(points) => points,
        Err(reason) => return Ok((Vec::new(), Some(reason))),
    };
    let [sx, sy] = settings.spacing_mm_per_px;
    let mut arcs = Vec::new();
    while arcs.len() < max_arcs {
        let arc = match arc_from_points(&points, settings)? {
            Ok(arc) => arc,
            Err(reason) => return Ok((arcs, Some(reason))),
        };
        let centre = [arc.centre_px[0] * sx, arc.centre_px[1] * sy];
        let band = (3.0 * arc.rms_px * (sx + sy) / 2.0).max(1.0);
        (points.points_mm, points.normals) = points
            .points_mm
            .iter()
            .zip(&points.normals)
            .filter(|(p, _)| {
                (((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt() - arc.radius_mm).abs() > band
            })
            .map(|(p, n)| (*p, *n))
            .unzip();
        arcs.push(arc);
    }
    Ok((arcs, None))
}

/// A B-scan's echo points (mm) and their ridge normals.
#[derive(Debug, Clone)]
pub struct EchoPoints {
    pub points_mm: Vec<[f64; 2]>,
    pub normals: Vec<[f64; 2]>,
    /// The image size, px.
    pub size_px: [usize; 2],
}

/// Step 1: the echo points of a B-scan, or why there are too few.
pub fn echo_points(image: &Mat, settings: &ArcSettings) -> Result<Result<EchoPoints, ArcRejection>, ImageError> {
    let gray = mat_to_gray8(image)?;
    let (w, h) = (gray.width, gray.height);
    let [sx, sy] = settings.spacing_mm_per_px;
    // Fan mask, its first row per column, and an eroded interior.
    let inside: Vec<bool> = gray.data.iter().map(|v| *v > 0).collect();
    let top = super::fan::first_rows(w, h, |i| inside[i]);
    let edge_x = (FAN_EDGE_MM / sx).ceil() as usize;
    let edge_y = (FAN_EDGE_MM / sy).ceil() as usize;
    let interior = super::fan::eroded(w, h, &inside, [edge_x, edge_y]);
    let mut smooth: Vec<f32> = gray.data.iter().map(|v| *v as f32).collect();
    // Ridge orientation needs isotropic smoothing (in mm): an anisotropic blur
    // would tilt every ridge normal towards the blur's short axis.
    let mut iso = smooth.clone();
    gaussian_blur_f32(w, h, &mut smooth, 0.4 / sx, 0.2 / sy)?;
    gaussian_blur_f32(w, h, &mut iso, 0.4 / sx, 0.4 / sy)?;

    let near_rows = (NEAR_FIELD_MM / sy).ceil() as usize;
    // Rows in memory order (the quantiles do not depend on the order).
    let first_searched: Vec<usize> = top
        .iter()
        .map(|t| t.map_or(usize::MAX, |t| (t + near_rows).min(h)))
        .collect();
    let mut values: Vec<f32> = Vec::new();
    for y in 0..h {
        let row = y * w..(y + 1) * w;
        for ((v, inner), first) in smooth[row.clone()].iter().zip(&interior[row]).zip(&first_searched) {
            if y >= *first && *inner {
                values.push(*v);
            }
        }
    }
    if values.is_empty() {
        return Ok(Err(ArcRejection::EmptyFan));
    }
    let (median, high) = median_and_quantile_nearest(&mut values, 0.997);
    let threshold = median + 0.45 * (high - median).max(10.0);

    // 1. Echo points: column-wise ridge maxima, placed on the ridge as
    //    `settings.peak` says, with the ridge's normal
    //    (Hessian eigenvector of the most negative curvature), kept only where the
    //    structure is line-like rather than a speckle blob.
    //    The image is read row by row, in memory order; the points are then put
    //    in column order (top to bottom within a column).
    let mut found: Vec<(usize, [f64; 2], [f64; 2])> = Vec::new();
    for y in 2..h.saturating_sub(2) {
        for x in 2..w.saturating_sub(2) {
            if top[x].is_none_or(|t| y < (t + near_rows).max(2)) {
                continue;
            }
            let v = smooth[y * w + x];
            if v < threshold || !interior[y * w + x] {
                continue;
            }
            let Some(sample) = ridge_sample(&smooth, &iso, w, [x, y], [sx, sy]) else {
                continue;
            };
            if let Some(point) = locate(settings.peak, x, y, &sample, [sx, sy]) {
                found.push((x, point, sample.normal));
            }
        }
    }
    found.sort_by_key(|(x, _, _)| *x);
    let (points_mm, normals): (Vec<[f64; 2]>, Vec<[f64; 2]>) = found.into_iter().map(|(_, p, n)| (p, n)).unzip();
    if points_mm.len() < settings.min_points {
        return Ok(Err(ArcRejection::TooFewEchoPoints {
            found: points_mm.len(),
            needed: settings.min_points,
        }));
    }
    Ok(Ok(EchoPoints {
        points_mm,
        normals,
        size_px: [w, h],
    }))
}

/// Step 5: the arc's checks (radius in range, span, a circle and not a line,
/// coverage, roundness); the first failed one is the rejection.
fn checked(
    feature: ArcFeature,
    inliers: &[[f64; 2]],
    rms_mm: f64,
    settings: &ArcSettings,
) -> Result<ArcFeature, ArcRejection> {
    let [r_min, r_max] = settings.radius_mm;
    if !(r_min..=r_max).contains(&feature.radius_mm) {
        return Err(ArcRejection::RadiusOutside {
            radius_mm: feature.radius_mm,
            min_mm: r_min,
            max_mm: r_max,
        });
    }
    if feature.span_deg < settings.min_span_deg {
        return Err(ArcRejection::ShortSpan {
            span_deg: feature.span_deg,
            needed_deg: settings.min_span_deg,
        });
    }
    let straightness = line_rms(inliers) / rms_mm.max(1e-9);
    if straightness < MIN_LINE_TO_CIRCLE_RMS {
        return Err(ArcRejection::Straight {
            line_to_circle: straightness,
            needed: MIN_LINE_TO_CIRCLE_RMS,
        });
    }
    if feature.fill < MIN_FILL {
        return Err(ArcRejection::Patchy {
            covered_percent: 100.0 * feature.fill,
            span_deg: feature.span_deg,
            needed_percent: 100.0 * MIN_FILL,
        });
    }
    if feature.rms_px > settings.max_rms_px {
        return Err(ArcRejection::NotCircular {
            rms_px: feature.rms_px,
            limit_px: settings.max_rms_px,
        });
    }
    Ok(feature)
}

/// Steps 2 to 4: the strongest arc among echo points.
fn arc_from_points(echo: &EchoPoints, settings: &ArcSettings) -> Result<Result<ArcFeature, ArcRejection>, ImageError> {
    let [sx, sy] = settings.spacing_mm_per_px;
    let [w, h] = echo.size_px;
    let (points_mm, normals) = (&echo.points_mm, &echo.normals);
    if points_mm.len() < settings.min_points {
        return Ok(Err(ArcRejection::TooFewEchoPoints {
            found: points_mm.len(),
            needed: settings.min_points,
        }));
    }

    let [r_min, r_max] = settings.radius_mm;
    let size_mm = [w as f64 * sx, h as f64 * sy];
    let Some((centre, peak_ratio)) = hough_centre(points_mm, normals, size_mm, [r_min, r_max])? else {
        return Ok(Err(ArcRejection::NoHoughPeak));
    };

    let mut radius = radius_peak(points_mm, centre, [r_min, r_max]);

    // 4. Inlier band, geometric fit, narrowed twice.
    let pixel_mm = (sx + sy) / 2.0;
    let mut band = (3.0 * pixel_mm).max(0.6);
    let mut centre_fit = centre;
    let mut rms_mm = f64::INFINITY;
    let mut inliers: Vec<[f64; 2]> = Vec::new();
    for _ in 0..3 {
        inliers = points_mm
            .iter()
            .filter(|p| p[1] < centre_fit[1])
            .filter(|p| {
                ((((p[0] - centre_fit[0]).powi(2) + (p[1] - centre_fit[1]).powi(2)).sqrt()) - radius).abs() < band
            })
            .copied()
            .collect();
        if inliers.len() < settings.min_points {
            return Ok(Err(ArcRejection::TooFewOnCircle {
                found: inliers.len(),
                needed: settings.min_points,
            }));
        }
        let start = (centre_fit, settings.fixed_radius_mm.unwrap_or(radius));
        let Some((c, r, rms)) = fit_circle(&inliers, start, settings.fixed_radius_mm.is_some()) else {
            return Ok(Err(ArcRejection::FitDiverged));
        };
        centre_fit = c;
        radius = r;
        rms_mm = rms;
        band = (2.5 * rms).max(1.5 * pixel_mm);
    }
    let angles: Vec<f64> = inliers
        .iter()
        .map(|p| (p[0] - centre_fit[0]).atan2(centre_fit[1] - p[1]).to_degrees())
        .collect();
    let first = angles.iter().cloned().fold(f64::MAX, f64::min);
    let span = angles.iter().cloned().fold(f64::MIN, f64::max) - first;
    let fill = angular_fill(&angles, first, span);
    let rms_px = rms_mm / pixel_mm;
    let feature = ArcFeature {
        centre_px: [centre_fit[0] / sx, centre_fit[1] / sy],
        radius_mm: radius,
        points: inliers.len(),
        span_deg: span,
        rms_px,
        peak_ratio,
        fill,
        confidence: ((span / 120.0).clamp(0.0, 1.0)
            * (inliers.len() as f64 / (4.0 * settings.min_points as f64)).clamp(0.0, 1.0)
            * (1.0 - rms_px / settings.max_rms_px).clamp(0.0, 1.0))
        .cbrt(),
        arc_points_px: inliers.iter().map(|p| [p[0] / sx, p[1] / sy]).collect(),
    };
    Ok(checked(feature, &inliers, rms_mm, settings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::circle::{accumulator_peak, strongest_outside};

    #[test]
    fn peak_and_strongest_competitor_are_the_cell_by_cell_search() {
        // Cell by cell, as the accumulator was once searched.
        let brute = |acc: &[f32], gw: usize, e: i64| {
            let (best, votes) = acc
                .iter()
                .enumerate()
                .fold((0, 0f32), |a, (i, v)| if *v > a.1 { (i, *v) } else { a });
            let (bx, by) = ((best % gw) as i64, (best / gw) as i64);
            let competing = acc
                .iter()
                .enumerate()
                .filter(|(i, _)| ((i % gw) as i64 - bx).abs() > e || ((i / gw) as i64 - by).abs() > e)
                .map(|(_, v)| *v)
                .fold(0f32, f32::max);
            (votes > 0.0).then_some((best % gw, best / gw, votes, competing))
        };
        let mut state = 12345u64;
        for (gw, gh) in [(1, 1), (7, 3), (40, 31), (3, 50)] {
            for e in [0usize, 2, 12] {
                let acc: Vec<f32> = (0..gw * gh)
                    .map(|_| {
                        state = state
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        ((state >> 40) % 7) as f32 // ties on purpose
                    })
                    .collect();
                let fast =
                    accumulator_peak(&acc, gw).map(|(x, y, v)| (x, y, v, strongest_outside(&acc, gw, [x, y], e)));
                assert_eq!(fast, brute(&acc, gw, e as i64), "{gw}x{gh}, exclusion {e}");
            }
        }
        assert_eq!(accumulator_peak(&[0.0; 6], 3), None);
    }

    #[test]
    fn circle_fit_recovers_an_arc() {
        let pts: Vec<[f64; 2]> = (0..40)
            .map(|i| {
                let a = (-50.0 + 100.0 * i as f64 / 39.0f64).to_radians();
                [30.0 + 12.0 * a.sin() + 0.01 * (i % 3) as f64, 60.0 - 12.0 * a.cos()]
            })
            .collect();
        let (c, r, rms) = fit_circle(&pts, ([31.0, 58.0], 10.0), false).unwrap();
        assert!((c[0] - 30.0).abs() < 0.02 && (c[1] - 60.0).abs() < 0.05, "{c:?}");
        assert!((r - 12.0).abs() < 0.05 && rms < 0.02);
    }
}
