//! N-wire (Z-fiducial) phantoms: the B-scan dot segmentation (the geometry is
//! [`crate::spec::nwire`]).
//!
//! An N is three wires in one plane of the phantom: wire 1 and wire 3 parallel,
//! wire 2 diagonal between them. A B-scan plane crossing the N shows three dots
//! p1, p2, p3 on a line. With `alpha = |p2 - p1| / |p3 - p1|` (a ratio along a line,
//! the same in pixels as in millimetres), the middle dot sits at
//! `W12 + alpha (W32 - W12)` in the phantom frame, where W12 (W32) is the crossing
//! of the infinite lines of wires 1 and 2 (3 and 2): similar triangles.

use serde::{Deserialize, Serialize};

use crate::spec::nwire::NWire;

/// Settings of the dot segmentation.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Segmentation {
    /// Pixels brighter than this grey level belong to a dot; absent: each
    /// frame's own, `threshold_percent` % of its brightest pixel after the opening
    /// (inside the clip rectangle).
    pub threshold_grey: Option<u8>,
    /// The frame's threshold as a share of its brightest opened pixel, % (PLUS's
    /// `ThresholdImagePercent`).
    pub threshold_percent: f64,
    /// Fewest pixels of a dot.
    pub min_dot_px: usize,
    /// A dot's centre is weighted by the grey levels above this fraction of its peak
    /// (0: every pixel above the threshold), so a comet tail does not pull it.
    pub core_fraction: f64,
    /// Radius of the disk of the morphological opening applied first (0: none);
    /// absent: `opening_radius_mm` over the approximate pixel size.
    pub opening_radius_px: Option<u32>,
    /// The opening's radius in the image, mm (PLUS's
    /// `MorphologicalOpeningCircleRadiusMm`): thinner than a wire's echo, thicker
    /// than speckle.
    pub opening_radius_mm: f64,
    /// How many of the brightest spots are considered.
    pub max_candidates: usize,
    /// Largest distance of the middle dot from the line through the outer two.
    pub collinear_tolerance_mm: f64,
    /// Largest tilt of a row of dots from the image's horizontal.
    pub max_row_angle_deg: f64,
    /// Largest angle between the rows of one frame.
    pub max_row_angle_difference_deg: f64,
    /// Largest difference between two neighbouring rows' distance and the
    /// phantom's distance between their patterns, % (PLUS's
    /// `MaxLinePairDistanceErrorPercent`).
    pub row_gap_tolerance_percent: f64,
    /// Largest shift of neighbouring rows' centres along the rows, mm (PLUS's
    /// `MaxLineShiftMm`): the patterns lie one behind the other.
    pub max_row_shift_mm: f64,
    /// Region searched `[u, v, width, height]` px; absent: the configuration's clip
    /// rectangle, or the whole image.
    pub clip_rectangle_px: Option<[usize; 4]>,
    /// Which image row holds the first pattern of the phantom definition.
    pub first_pattern_row: RowOrder,
    /// On which side of a row the pattern's wire 1 appears.
    pub first_wire_side: Side,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RowOrder {
    Top,
    Bottom,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    Left,
    Right,
}

impl Default for Segmentation {
    fn default() -> Self {
        // The threshold and the opening follow each image and its pixel size, with
        // PLUS's defaults (10 % of the brightest opened pixel; a 0.27 mm disk);
        // comet tails below a dot are dimmer and off the row's line.
        Segmentation {
            threshold_grey: None,
            threshold_percent: 10.0,
            min_dot_px: 4,
            core_fraction: 0.5,
            opening_radius_px: None,
            opening_radius_mm: 0.27,
            max_candidates: 20,
            collinear_tolerance_mm: 0.6,
            max_row_angle_deg: 40.0,
            max_row_angle_difference_deg: 10.0,
            row_gap_tolerance_percent: 10.0,
            max_row_shift_mm: 10.0,
            clip_rectangle_px: None,
            first_pattern_row: RowOrder::Top,
            first_wire_side: Side::Right,
        }
    }
}

impl Segmentation {
    /// The opening's radius for images of about `spacing_mm_per_px`.
    pub fn opening_radius_for(&self, spacing_mm_per_px: f64) -> u32 {
        self.opening_radius_px
            .unwrap_or_else(|| (self.opening_radius_mm / spacing_mm_per_px).round().clamp(0.0, 50.0) as u32)
    }

    /// One frame's grey threshold: the manifest's, or `threshold_percent` % of the
    /// brightest pixel of `centre_pixels` (the opened image) in `clip`, at least 1.
    pub fn threshold_for(&self, centre_pixels: &[u8], width: usize, height: usize, clip: [usize; 4]) -> u8 {
        if let Some(t) = self.threshold_grey {
            return t;
        }
        let [u0, v0, w, h] = clip;
        let (u1, v1) = ((u0 + w).min(width), (v0 + h).min(height));
        let brightest = (v0..v1)
            .flat_map(|v| centre_pixels[v * width + u0.min(u1)..v * width + u1].iter().copied())
            .max()
            .unwrap_or(0);
        (self.threshold_percent / 100.0 * brightest as f64)
            .round()
            .clamp(1.0, 254.0) as u8
    }
}

/// A bright region that may be a wire dot: its intensity-weighted centre and strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DotCandidate {
    pub centre_px: [f64; 2],
    pub pixels: usize,
    /// Sum of grey levels above the threshold.
    pub weight: f64,
}

/// The dots of one frame, per pattern: `[wire 1, wire 2, wire 3]` pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct NWireDots {
    pub patterns: Vec<[[f64; 2]; 3]>,
}

/// Grey-level morphological opening with a disk (erosion, then dilation): removes
/// bright structures thinner than the disk (speckle, the streaks of comet tails)
/// and keeps the dots' shape.
pub fn open_image(pixels: &[u8], width: usize, height: usize, radius_px: u32) -> Result<Vec<u8>, opencv::Error> {
    use opencv::core::{Mat, Point, Size, BORDER_CONSTANT};
    use opencv::imgproc;
    use opencv::prelude::*;
    let src = Mat::new_rows_cols_with_data(height as i32, width as i32, pixels)?;
    let d = 2 * radius_px as i32 + 1;
    let kernel = imgproc::get_structuring_element(imgproc::MORPH_ELLIPSE, Size::new(d, d), Point::new(-1, -1))?;
    let mut out = Mat::default();
    imgproc::morphology_ex(
        &src,
        &mut out,
        imgproc::MORPH_OPEN,
        &kernel,
        Point::new(-1, -1),
        1,
        BORDER_CONSTANT,
        imgproc::morphology_default_border_value()?,
    )?;
    Ok(out.data_bytes()?.to_vec())
}

/// Bright spots in the clip rectangle, strongest first. Spots are the connected
/// regions above the threshold in `pixels`; their centres are weighted by
/// `centre_pixels` (e.g. the opened image), falling back to `pixels` where that
/// leaves nothing.
pub fn find_spots(
    pixels: &[u8],
    centre_pixels: &[u8],
    width: usize,
    height: usize,
    clip: [usize; 4],
    settings: &Segmentation,
) -> Vec<DotCandidate> {
    let [u0, v0, w, h] = clip;
    let (u1, v1) = ((u0 + w).min(width), (v0 + h).min(height));
    let t = settings.threshold_for(centre_pixels, width, height, clip);
    let mut seen = vec![false; width * height];
    let mut spots = Vec::new();
    let mut stack = Vec::new();
    for v in v0..v1 {
        for u in u0..u1 {
            let i = v * width + u;
            if seen[i] || pixels[i] <= t {
                continue;
            }
            seen[i] = true;
            stack.push(i);
            let mut members = Vec::new();
            while let Some(j) = stack.pop() {
                members.push(j);
                let (ju, jv) = (j % width, j / width);
                for dv in -1i64..=1 {
                    for du in -1i64..=1 {
                        let (nu, nv) = (ju as i64 + du, jv as i64 + dv);
                        if nu < u0 as i64 || nv < v0 as i64 || nu >= u1 as i64 || nv >= v1 as i64 {
                            continue;
                        }
                        let k = nv as usize * width + nu as usize;
                        if !seen[k] && pixels[k] > t {
                            seen[k] = true;
                            stack.push(k);
                        }
                    }
                }
            }
            if members.len() < settings.min_dot_px {
                continue;
            }
            let weight: f64 = members.iter().map(|&j| f64::from(pixels[j] - t)).sum();
            // The centre from the dot's core: grey levels above a fraction of its peak.
            let centre = |grey: &[u8]| {
                let peak = members.iter().map(|&j| grey[j]).max().unwrap_or(t);
                let level = (f64::from(peak) * settings.core_fraction).max(f64::from(t));
                let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
                for &j in &members {
                    let w = f64::from(grey[j]) - level;
                    if w > 0.0 {
                        sw += w;
                        su += w * (j % width) as f64;
                        sv += w * (j / width) as f64;
                    }
                }
                (sw, su, sv)
            };
            let (mut sw, mut su, mut sv) = centre(centre_pixels);
            if sw <= 0.0 {
                (sw, su, sv) = centre(pixels);
            }
            if sw > 0.0 {
                spots.push(DotCandidate {
                    centre_px: [su / sw, sv / sw],
                    pixels: members.len(),
                    weight,
                });
            }
        }
    }
    spots.sort_by(|a, b| {
        b.weight
            .total_cmp(&a.weight)
            .then(a.centre_px[0].total_cmp(&b.centre_px[0]))
    });
    spots.truncate(settings.max_candidates);
    spots
}

/// A candidate row: three spots (indices, sorted by u) on a line.
#[derive(Debug, Clone, Copy)]
struct Row {
    spots: [usize; 3],
    angle_rad: f64,
    /// Outer dots' distance over the pattern width's scale (px).
    length_px: f64,
    weight: f64,
    mean_u: f64,
    mean_v: f64,
}

/// Why a B-scan's dots do not make the phantom's N-wire patterns.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NWireRejection {
    #[error("{spots} bright spots above the grey threshold, {needed} needed for {patterns} N-wires")]
    TooFewSpots {
        spots: usize,
        needed: usize,
        patterns: usize,
    },
    #[error("{rows} rows of 3 collinear dots among {spots} spots, {patterns} needed")]
    TooFewRows { rows: usize, spots: usize, patterns: usize },
    #[error(
        "no {patterns} disjoint, parallel rows of 3 collinear dots spaced as the phantom's patterns (of {rows} candidate rows)"
    )]
    NoParallelRows { patterns: usize, rows: usize },
}

/// What the image of the phantom's patterns should look like.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternGeometry {
    pub patterns: usize,
    /// Shortest and longest distance between a pattern's outer dots (side-wire
    /// distance over the approximate pixel size), px.
    pub widths_px: (f64, f64),
    /// Distance between each pattern's plane and the next one's, over the
    /// approximate pixel size (px), in the phantom definition's order.
    pub row_gaps_px: Vec<f64>,
    pub spacing_mm_per_px: f64,
    /// The patterns themselves (empty: their middle dots are not checked).
    pub nwires: Vec<NWire>,
}

/// Finds one row of three collinear dots per pattern and assigns them to the wires.
///
/// A row may be up to 1.6x longer than its pattern's width (a plane crossing the
/// wires obliquely) and 0.85x shorter; neighbouring rows must lie as far apart
/// as their patterns, within `row_gap_tolerance_percent`, taken along the rows'
/// normal (a plane tilted about the rows only lengthens that distance by a few
/// percent at the tilts a sweep uses).
pub fn segment(
    spots: &[DotCandidate],
    geometry: &PatternGeometry,
    settings: &Segmentation,
) -> Result<NWireDots, NWireRejection> {
    let patterns = geometry.patterns;
    let widths_px = geometry.widths_px;
    let spacing_mm_per_px = geometry.spacing_mm_per_px;
    if spots.len() < 3 * patterns {
        return Err(NWireRejection::TooFewSpots {
            spots: spots.len(),
            needed: 3 * patterns,
            patterns,
        });
    }
    let tolerance_px = settings.collinear_tolerance_mm / spacing_mm_per_px;
    let max_angle = settings.max_row_angle_deg.to_radians();
    let mut rows = Vec::new();
    let n = spots.len();
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                let mut idx = [a, b, c];
                idx.sort_by(|&i, &j| spots[i].centre_px[0].total_cmp(&spots[j].centre_px[0]));
                let [p, q, r] = idx.map(|i| spots[i].centre_px);
                let (dx, dy) = (r[0] - p[0], r[1] - p[1]);
                let length = (dx * dx + dy * dy).sqrt();
                if length < 0.85 * widths_px.0 || length > 1.6 * widths_px.1 {
                    continue;
                }
                let angle = dy.atan2(dx);
                if angle.abs() > max_angle {
                    continue;
                }
                let off = ((q[0] - p[0]) * dy - (q[1] - p[1]) * dx).abs() / length;
                if off > tolerance_px {
                    continue;
                }
                rows.push(Row {
                    spots: idx,
                    angle_rad: angle,
                    length_px: length,
                    weight: idx.iter().map(|&i| spots[i].weight).sum(),
                    mean_u: (p[0] + q[0] + r[0]) / 3.0,
                    mean_v: (p[1] + q[1] + r[1]) / 3.0,
                });
            }
        }
    }
    if rows.len() < patterns {
        return Err(NWireRejection::TooFewRows {
            rows: rows.len(),
            spots: spots.len(),
            patterns,
        });
    }
    rows.sort_by(|a, b| b.weight.total_cmp(&a.weight));
    rows.truncate(60);
    // The strongest set of disjoint, parallel rows.
    let max_diff = settings.max_row_angle_difference_deg.to_radians();
    let mut best: Option<(f64, Vec<usize>)> = None;
    let mut chosen = Vec::new();
    let mut gaps = geometry.row_gaps_px.clone();
    // Rows of patterns whose side wires all run alike are stretched alike.
    let parallel = geometry.nwires.windows(2).all(|p| {
        let (a, b) = (
            p[0].wires[0].direction().normalize(),
            p[1].wires[0].direction().normalize(),
        );
        a.cross(&b).norm() < 1e-6
    });
    let mut widths: Vec<f64> = if parallel {
        geometry.nwires.iter().map(|n| n.width_mm()).collect()
    } else {
        Vec::new()
    };
    if settings.first_pattern_row == RowOrder::Bottom {
        gaps.reverse();
        widths.reverse();
    }
    let limits = SearchLimits {
        wanted: patterns,
        max_diff,
        gaps_px: &gaps,
        gap_tolerance: settings.row_gap_tolerance_percent / 100.0,
        widths_mm: &widths,
        max_shift_px: settings.max_row_shift_mm / spacing_mm_per_px,
        phantom: (!geometry.nwires.is_empty()).then_some((spots, &geometry.nwires[..], spacing_mm_per_px, settings)),
    };
    search(&rows, &limits, 0, &mut chosen, &mut best);
    let (_, picked) = best.ok_or(NWireRejection::NoParallelRows {
        patterns,
        rows: rows.len(),
    })?;
    Ok(NWireDots {
        patterns: assign(&rows, &picked, spots, settings),
    })
}

/// The chosen rows' dots as the phantom's patterns: `[wire 1, wire 2, wire 3]`
/// each, in the phantom definition's order.
fn assign(rows: &[Row], chosen: &[usize], spots: &[DotCandidate], settings: &Segmentation) -> Vec<[[f64; 2]; 3]> {
    let mut picked: Vec<&Row> = chosen.iter().map(|&i| &rows[i]).collect();
    picked.sort_by(|a, b| a.mean_v.total_cmp(&b.mean_v));
    if settings.first_pattern_row == RowOrder::Bottom {
        picked.reverse();
    }
    picked
        .iter()
        .map(|row| {
            let mut dots = row.spots.map(|i| spots[i].centre_px);
            if settings.first_wire_side == Side::Right {
                dots.reverse();
            }
            dots
        })
        .collect()
}

/// Whether the middle dots lie as far apart in the image as the points of the
/// phantom their ratios put them at (both in mm, the image's at the approximate
/// pixel size): a wrong dot moves its pattern's point along the diagonal wire.
fn middles_consistent(patterns: &[[[f64; 2]; 3]], nwires: &[NWire], spacing_mm_per_px: f64, tolerance: f64) -> bool {
    let points: Vec<_> = patterns
        .iter()
        .zip(nwires)
        .map(|(dots, n)| (dots[1], n.middle_in_phantom_mm(dots)))
        .collect();
    points.windows(2).all(|pair| {
        let ((a, pa), (b, pb)) = (pair[0], pair[1]);
        let in_image = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() * spacing_mm_per_px;
        let in_phantom = (pa - pb).norm();
        (in_image - in_phantom).abs() <= tolerance * in_phantom
    })
}

/// What a set of rows must satisfy.
struct SearchLimits<'a> {
    wanted: usize,
    max_diff: f64,
    /// Expected distances between neighbouring rows, top to bottom, px.
    gaps_px: &'a [f64],
    gap_tolerance: f64,
    /// The patterns' widths, top to bottom (empty: not checked), mm.
    widths_mm: &'a [f64],
    max_shift_px: f64,
    /// The phantom, when known: the middle dots must agree with it.
    phantom: Option<(&'a [DotCandidate], &'a [NWire], f64, &'a Segmentation)>,
}

/// Whether the rows, top to bottom, are spaced as the patterns.
fn spaced_as_patterns(rows: &[Row], chosen: &[usize], limits: &SearchLimits<'_>) -> bool {
    let mut sorted: Vec<&Row> = chosen.iter().map(|&i| &rows[i]).collect();
    sorted.sort_by(|a, b| a.mean_v.total_cmp(&b.mean_v));
    let stretch: Vec<Option<f64>> = (0..sorted.len())
        .map(|k| limits.widths_mm.get(k).map(|w| sorted[k].length_px / w))
        .collect();
    sorted
        .windows(2)
        .zip(limits.gaps_px)
        .enumerate()
        .all(|(k, (pair, want))| {
            // The second row's centre from the first row's line, along its normal.
            let angle = (pair[0].angle_rad + pair[1].angle_rad) / 2.0;
            let (du, dv) = (pair[1].mean_u - pair[0].mean_u, pair[1].mean_v - pair[0].mean_v);
            let gap = dv * angle.cos() - du * angle.sin();
            let shift = du * angle.cos() + dv * angle.sin();
            // One plane cutting parallel side wires stretches every pattern's width alike.
            let alike = match (stretch[k], stretch[k + 1]) {
                (Some(a), Some(b)) => (a - b).abs() <= limits.gap_tolerance * a.max(b),
                _ => true,
            };
            (gap - want).abs() <= limits.gap_tolerance * want && shift.abs() <= limits.max_shift_px && alike
        })
}

fn search(
    rows: &[Row],
    limits: &SearchLimits<'_>,
    start: usize,
    chosen: &mut Vec<usize>,
    best: &mut Option<(f64, Vec<usize>)>,
) {
    let (wanted, max_diff) = (limits.wanted, limits.max_diff);
    if chosen.len() == wanted {
        if !spaced_as_patterns(rows, chosen, limits) {
            return;
        }
        if let Some((spots, nwires, spacing, settings)) = limits.phantom {
            let patterns = assign(rows, chosen, spots, settings);
            if !middles_consistent(&patterns, nwires, spacing, limits.gap_tolerance) {
                return;
            }
        }
        let weight: f64 = chosen.iter().map(|&i| rows[i].weight).sum();
        if best.as_ref().is_none_or(|(w, _)| weight > *w) {
            *best = Some((weight, chosen.clone()));
        }
        return;
    }
    for i in start..rows.len() {
        let row = &rows[i];
        let fits = chosen.iter().all(|&j| {
            let other = &rows[j];
            (row.angle_rad - other.angle_rad).abs() <= max_diff && row.spots.iter().all(|s| !other.spots.contains(s))
        });
        if fits {
            chosen.push(i);
            search(rows, limits, i + 1, chosen, best);
            chosen.pop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_three_rows_and_skips_a_tail() {
        let (w, h) = (200usize, 120usize);
        let mut img = vec![0u8; w * h];
        let mut dot = |u: usize, v: usize, level: u8| {
            for dv in 0..3 {
                for du in 0..3 {
                    img[(v + dv) * w + u + du] = level;
                }
            }
        };
        for (row, v) in [20usize, 55, 90].iter().enumerate() {
            dot(30, *v, 200);
            dot(80 + 10 * row, *v + 1, 180);
            dot(150, *v + 2, 160);
        }
        dot(80, 30, 60); // a comet tail under the first row's middle dot
        let settings = Segmentation {
            min_dot_px: 4,
            ..Segmentation::default()
        };
        let spots = find_spots(&img, &img, w, h, [0, 0, w, h], &settings);
        assert_eq!(spots.len(), 10);
        let geometry = PatternGeometry {
            patterns: 3,
            widths_px: (110.0, 130.0),
            row_gaps_px: vec![35.0, 35.0],
            spacing_mm_per_px: 0.1,
            nwires: Vec::new(),
        };
        let dots = segment(&spots, &geometry, &settings).unwrap();
        assert_eq!(dots.patterns.len(), 3);
        // First pattern on the top row, wire 1 on the right.
        assert!((dots.patterns[0][0][0] - 151.0).abs() < 1e-9 && (dots.patterns[0][0][1] - 23.0).abs() < 1e-9);
        assert!((dots.patterns[2][1][0] - 101.0).abs() < 1e-9);
        // Rows spaced unlike the phantom's patterns are not a pattern set.
        let far_apart = PatternGeometry {
            row_gaps_px: vec![60.0, 60.0],
            ..geometry.clone()
        };
        assert!(matches!(
            segment(&spots, &far_apart, &settings),
            Err(NWireRejection::NoParallelRows { .. })
        ));
        // Two patterns 70 px apart: the top and bottom rows, not neighbours.
        let two = PatternGeometry {
            patterns: 2,
            row_gaps_px: vec![70.0],
            ..geometry
        };
        let dots = segment(&spots, &two, &settings).unwrap();
        assert!((dots.patterns[0][0][1] - 23.0).abs() < 1e-9 && (dots.patterns[1][0][1] - 93.0).abs() < 1e-9);
    }

    /// The threshold follows each image's own brightness unless the manifest
    /// fixes it; the opening follows the pixel size.
    #[test]
    fn threshold_and_opening_follow_the_image_and_its_pixel_size() {
        let (width, height) = (40, 30);
        let mut image = vec![3u8; width * height];
        image[15 * width + 20] = 200;
        // Bright text outside the clip rectangle does not count.
        image[2 * width + 2] = 255;
        let auto = Segmentation::default();
        let clip = [5, 5, 30, 20];
        assert_eq!(auto.threshold_for(&image, width, height, clip), 20);
        let dim: Vec<u8> = image.iter().map(|p| p / 2).collect();
        assert_eq!(auto.threshold_for(&dim, width, height, clip), 10);
        let fixed = Segmentation {
            threshold_grey: Some(25),
            ..Segmentation::default()
        };
        assert_eq!(fixed.threshold_for(&dim, width, height, clip), 25);
        // An empty image still thresholds above black.
        assert_eq!(auto.threshold_for(&vec![0; width * height], width, height, clip), 1);
        assert_eq!(auto.opening_radius_for(0.078), 3);
        assert_eq!(auto.opening_radius_for(0.2), 1);
    }
}
