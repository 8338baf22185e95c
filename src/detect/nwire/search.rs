//! The pattern search: rows of three collinear spots, and the strongest set of
//! rows that passes PLUS's checks and probecal's scale-free ones.

use super::settings::{RowOrder, Segmentation, Side};
use super::spots::DotCandidate;
use crate::spec::nwire::NWire;

/// The dots of one frame, per pattern: `[wire 1, wire 2, wire 3]` pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct NWireDots {
    pub patterns: Vec<[[f64; 2]; 3]>,
}

/// A candidate row: three spots (indices, sorted by u) on a line.
#[derive(Debug, Clone, Copy)]
struct Row {
    spots: [usize; 3],
    angle_rad: f64,
    /// Outer dots' distance (px).
    length_px: f64,
    weight: f64,
    /// The outer dots (px): PLUS's line start and end.
    ends: [[f64; 2]; 2],
    mean_v: f64,
}

impl Row {
    fn midpoint(&self) -> [f64; 2] {
        let [a, b] = self.ends;
        [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]
    }

    fn unit(&self) -> [f64; 2] {
        let [a, b] = self.ends;
        [(b[0] - a[0]) / self.length_px, (b[1] - a[1]) / self.length_px]
    }

    /// Distance of `point` from this row's line, px.
    fn distance_of(&self, point: [f64; 2]) -> f64 {
        let [a, _] = self.ends;
        let d = self.unit();
        ((point[0] - a[0]) * d[1] - (point[1] - a[1]) * d[0]).abs()
    }
}

/// One check of the pattern search that a set of rows failed: what was
/// measured, and the limit it broke.
#[derive(Debug, Clone, PartialEq)]
pub struct FailedCheck {
    /// The check's name (one of [`CHECKS`]).
    pub check: &'static str,
    pub value: f64,
    pub limit: f64,
    pub unit: &'static str,
    /// The setting the limit comes from.
    pub setting: &'static str,
}

/// The checks of a set of rows, in the order they are made.
pub const CHECKS: [&str; 6] = [
    "rows parallel",
    "line pair distance",
    "line shift",
    "row lengths alike",
    "row gaps in the phantom's proportion",
    "middle dots as the phantom's",
];

impl std::fmt::Display for FailedCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {:.2} {}, limit {:.2} {} ({})",
            self.check, self.value, self.unit, self.limit, self.unit, self.setting
        )
    }
}

/// Why a B-scan's dots do not make the phantom's N-wire patterns.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NWireRejection {
    #[error("spot count: {spots} bright spots above the grey threshold, {needed} needed for {patterns} N-wires")]
    TooFewSpots {
        spots: usize,
        needed: usize,
        patterns: usize,
    },
    #[error(
        "row count: {rows} rows of 3 collinear dots (CollinearPointsMaxDistanceFromLineMm, MinThetaDegrees..MaxThetaDegrees) among {spots} spots, {patterns} needed"
    )]
    TooFewRows { rows: usize, spots: usize, patterns: usize },
    #[error(
        "{failed} (of {rows} candidate rows, the strongest set of {patterns} that got furthest through the checks)"
    )]
    NoPattern {
        patterns: usize,
        rows: usize,
        failed: FailedCheck,
    },
}

impl NWireRejection {
    /// The check that failed, for summaries.
    pub fn check(&self) -> &'static str {
        match self {
            NWireRejection::TooFewSpots { .. } => "spot count",
            NWireRejection::TooFewRows { .. } => "row count",
            NWireRejection::NoPattern { failed, .. } => failed.check,
        }
    }
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
    /// Smallest and largest distance between any two patterns' planes, over the
    /// approximate pixel size (px): PLUS's line pair distance range before its
    /// tolerance.
    pub plane_distances_px: (f64, f64),
    pub spacing_mm_per_px: f64,
    /// The patterns themselves (empty: their middle dots are not checked).
    pub nwires: Vec<NWire>,
}

/// Finds one row of three collinear dots per pattern and assigns them to the wires.
///
/// A row may be up to 1.6x longer than its pattern's width (a plane crossing the
/// wires obliquely) and 0.85x shorter. A set of rows is then checked as PLUS
/// checks it and by probecal's scale-free checks (the module's doc); among the
/// sets that pass, the strongest is taken. When none passes, the rejection names
/// the check that the set that got furthest failed, with its value and limit.
pub fn segment(
    spots: &[DotCandidate],
    geometry: &PatternGeometry,
    settings: &Segmentation,
) -> Result<NWireDots, NWireRejection> {
    let patterns = geometry.patterns;
    let spacing_mm_per_px = geometry.spacing_mm_per_px;
    if spots.len() < 3 * patterns {
        return Err(NWireRejection::TooFewSpots {
            spots: spots.len(),
            needed: 3 * patterns,
            patterns,
        });
    }
    let mut rows = candidate_rows(spots, geometry, settings);
    if rows.len() < patterns {
        return Err(NWireRejection::TooFewRows {
            rows: rows.len(),
            spots: spots.len(),
            patterns,
        });
    }
    rows.sort_by(|a, b| b.weight.total_cmp(&a.weight));
    rows.truncate(60);
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
    let tolerance = settings.row_gap_tolerance_percent / 100.0;
    let limits = SearchLimits {
        wanted: patterns,
        max_angle_rad: settings.max_row_angle_difference_deg.to_radians(),
        pair_distance_px: (
            geometry.plane_distances_px.0 * (1.0 - tolerance),
            geometry.plane_distances_px.1 * (1.0 + tolerance),
        ),
        gaps_px: &gaps,
        tolerance,
        widths_mm: &widths,
        max_shift_px: settings.max_row_shift_mm / spacing_mm_per_px,
        spacing_mm_per_px,
        phantom: (!geometry.nwires.is_empty()).then_some((spots, &geometry.nwires[..], settings)),
    };
    let mut search = Search::default();
    search.run(&rows, &limits, 0, &mut Vec::new());
    let Some((_, picked)) = search.best else {
        let failed = search.furthest.map(|(_, _, f)| f).unwrap_or(FailedCheck {
            check: "rows parallel",
            value: f64::NAN,
            limit: settings.max_row_angle_difference_deg,
            unit: "°",
            setting: "no disjoint rows",
        });
        return Err(NWireRejection::NoPattern {
            patterns,
            rows: rows.len(),
            failed,
        });
    };
    Ok(NWireDots {
        patterns: assign(&rows, &picked, spots, settings),
    })
}

/// Every three spots on a line as long as a pattern's row may be (0.85 to 1.6
/// times its width), at an allowed angle, with the middle spot within
/// `CollinearPointsMaxDistanceFromLineMm` of the outer two's line.
fn candidate_rows(spots: &[DotCandidate], geometry: &PatternGeometry, settings: &Segmentation) -> Vec<Row> {
    let (widths_px, spacing_mm_per_px) = (geometry.widths_px, geometry.spacing_mm_per_px);
    let tolerance_px = settings.collinear_tolerance_mm / spacing_mm_per_px;
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
                if !settings.row_angle_allowed(angle.to_degrees()) {
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
                    ends: [p, r],
                    mean_v: (p[1] + q[1] + r[1]) / 3.0,
                });
            }
        }
    }
    rows
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

/// What a set of rows must satisfy.
struct SearchLimits<'a> {
    wanted: usize,
    /// `AngleToleranceDegrees`.
    max_angle_rad: f64,
    /// PLUS's allowed distance between any two rows, px.
    pair_distance_px: (f64, f64),
    /// The phantom's distances between neighbouring patterns, top to bottom, px.
    gaps_px: &'a [f64],
    /// `MaxLinePairDistanceErrorPercent` as a fraction.
    tolerance: f64,
    /// The patterns' widths, top to bottom (empty: not checked), mm.
    widths_mm: &'a [f64],
    max_shift_px: f64,
    spacing_mm_per_px: f64,
    /// The phantom, when known: the middle dots must agree with it.
    phantom: Option<(&'a [DotCandidate], &'a [NWire], &'a Segmentation)>,
}

/// The pattern search's state: the strongest set that passed, and the failure of
/// the set that got furthest through the checks (strongest first among equals).
#[derive(Default)]
struct Search {
    best: Option<(f64, Vec<usize>)>,
    furthest: Option<(usize, f64, FailedCheck)>,
}

impl Search {
    fn run(&mut self, rows: &[Row], limits: &SearchLimits<'_>, start: usize, chosen: &mut Vec<usize>) {
        if chosen.len() == limits.wanted {
            let weight: f64 = chosen.iter().map(|&i| rows[i].weight).sum();
            match check_set(rows, chosen, limits) {
                Ok(()) => {
                    if self.best.as_ref().is_none_or(|(w, _)| weight > *w) {
                        self.best = Some((weight, chosen.clone()));
                    }
                }
                Err(failed) => {
                    let stage = CHECKS.iter().position(|c| *c == failed.check).unwrap_or(0);
                    let further = self
                        .furthest
                        .as_ref()
                        .is_none_or(|(s, w, _)| stage > *s || (stage == *s && weight > *w));
                    if further {
                        self.furthest = Some((stage, weight, failed));
                    }
                }
            }
            return;
        }
        for i in start..rows.len() {
            let disjoint = chosen
                .iter()
                .all(|&j| rows[i].spots.iter().all(|s| !rows[j].spots.contains(s)));
            if disjoint {
                chosen.push(i);
                self.run(rows, limits, i + 1, chosen);
                chosen.pop();
            }
        }
    }
}

/// The checks of one set of rows, in [`CHECKS`]' order: the first that fails.
fn check_set(rows: &[Row], chosen: &[usize], limits: &SearchLimits<'_>) -> Result<(), FailedCheck> {
    let mut sorted: Vec<&Row> = chosen.iter().map(|&i| &rows[i]).collect();
    sorted.sort_by(|a, b| a.mean_v.total_cmp(&b.mean_v));
    let mm = limits.spacing_mm_per_px;
    // PLUS's checks, on every pair of rows.
    let pairs: Vec<(&Row, &Row)> = (0..sorted.len())
        .flat_map(|i| (i + 1..sorted.len()).map(move |j| (i, j)))
        .map(|(i, j)| (sorted[i], sorted[j]))
        .collect();
    let worst = |values: Vec<f64>| values.into_iter().fold(0.0, f64::max);
    let angle = worst(
        pairs
            .iter()
            .map(|(a, b)| {
                let d = (a.angle_rad - b.angle_rad).abs();
                d.min(std::f64::consts::PI - d)
            })
            .collect(),
    );
    if angle >= limits.max_angle_rad {
        return Err(FailedCheck {
            check: CHECKS[0],
            value: angle.to_degrees(),
            limit: limits.max_angle_rad.to_degrees(),
            unit: "°",
            setting: "AngleToleranceDegrees",
        });
    }
    let (lo, hi) = limits.pair_distance_px;
    for (a, b) in &pairs {
        let distance = b.distance_of(a.ends[0]);
        if distance > hi || distance < lo {
            let limit = if distance > hi { hi } else { lo };
            return Err(FailedCheck {
                check: CHECKS[1],
                value: distance * mm,
                limit: limit * mm,
                unit: "mm",
                setting: "MaxLinePairDistanceErrorPercent",
            });
        }
    }
    for (a, b) in &pairs {
        let (ma, mb, d) = (a.midpoint(), b.midpoint(), a.unit());
        let shift = ((mb[0] - ma[0]) * d[0] + (mb[1] - ma[1]) * d[1]).abs();
        if shift > limits.max_shift_px {
            return Err(FailedCheck {
                check: CHECKS[2],
                value: shift * mm,
                limit: limits.max_shift_px * mm,
                unit: "mm",
                setting: "MaxLineShiftMm",
            });
        }
    }
    scale_free_checks(&sorted, limits)?;
    if let Some((spots, nwires, settings)) = limits.phantom {
        let patterns = assign(rows, chosen, spots, settings);
        if let Some(off) = middles_off(&patterns, nwires, mm) {
            if off > limits.tolerance {
                return Err(FailedCheck {
                    check: CHECKS[5],
                    value: off * 100.0,
                    limit: limits.tolerance * 100.0,
                    unit: "%",
                    setting: "MaxLinePairDistanceErrorPercent",
                });
            }
        }
    }
    Ok(())
}

/// The image's scale against the approximate pixel size: the rows' gaps over
/// the phantom's, top to bottom (1 with a single row).
fn image_scale(sorted: &[&Row], gaps_px: &[f64]) -> f64 {
    let observed: f64 = sorted
        .windows(2)
        .map(|pair| pair[1].distance_of(pair[0].midpoint()))
        .sum();
    let expected: f64 = gaps_px.iter().take(sorted.len().saturating_sub(1)).sum();
    if expected > 0.0 && observed > 0.0 {
        observed / expected
    } else {
        1.0
    }
}

/// probecal's checks that hold whatever the true pixel size: the rows' lengths
/// stretched alike (patterns whose side wires run alike) and the neighbouring
/// rows apart in the proportion of their patterns' planes.
fn scale_free_checks(sorted: &[&Row], limits: &SearchLimits<'_>) -> Result<(), FailedCheck> {
    let stretch: Vec<f64> = sorted
        .iter()
        .zip(limits.widths_mm)
        .map(|(row, w)| row.length_px / w)
        .collect();
    if stretch.len() >= 2 {
        let (lo, hi) = stretch
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), s| (lo.min(*s), hi.max(*s)));
        if hi - lo > limits.tolerance * hi {
            return Err(FailedCheck {
                check: CHECKS[3],
                value: (hi - lo) / hi * 100.0,
                limit: limits.tolerance * 100.0,
                unit: "%",
                setting: "MaxLinePairDistanceErrorPercent",
            });
        }
    }
    let scale = image_scale(sorted, limits.gaps_px);
    for (pair, want) in sorted.windows(2).zip(limits.gaps_px) {
        let gap = pair[1].distance_of(pair[0].midpoint());
        let off = (gap / scale - want).abs() / want;
        if off > limits.tolerance {
            return Err(FailedCheck {
                check: CHECKS[4],
                value: off * 100.0,
                limit: limits.tolerance * 100.0,
                unit: "%",
                setting: "MaxLinePairDistanceErrorPercent",
            });
        }
    }
    Ok(())
}

/// How far (a fraction) the middle dots lie from as far apart in the image as
/// the points of the phantom their ratios put them at (a wrong dot moves its
/// pattern's point along the diagonal wire). With three patterns or more, each
/// neighbouring pair against their common scale, whatever the true pixel size;
/// with two, against the approximate pixel size (as PLUS's line pair distance).
/// `None` with a single pattern.
fn middles_off(patterns: &[[[f64; 2]; 3]], nwires: &[NWire], spacing_mm_per_px: f64) -> Option<f64> {
    let points: Vec<_> = patterns
        .iter()
        .zip(nwires)
        .map(|(dots, n)| (dots[1], n.middle_in_phantom_mm(dots)))
        .collect();
    let pairs: Vec<(f64, f64)> = points
        .windows(2)
        .map(|pair| {
            let ((a, pa), (b, pb)) = (pair[0], pair[1]);
            let in_image = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() * spacing_mm_per_px;
            (in_image, (pa - pb).norm())
        })
        .collect();
    let scale = if pairs.len() >= 2 {
        pairs.iter().map(|p| p.0).sum::<f64>() / pairs.iter().map(|p| p.1).sum::<f64>()
    } else {
        1.0
    };
    pairs
        .iter()
        .map(|(in_image, in_phantom)| (in_image / scale - in_phantom).abs() / in_phantom)
        .reduce(f64::max)
}
