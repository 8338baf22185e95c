//! N-wire (Z-fiducial) phantoms: the B-scan dot segmentation (the geometry is
//! [`crate::spec::nwire`]).
//!
//! An N is three wires in one plane of the phantom: wire 1 and wire 3 parallel,
//! wire 2 diagonal between them. A B-scan plane crossing the N shows three dots
//! p1, p2, p3 on a line. With `alpha = |p2 - p1| / |p3 - p1|` (a ratio along a line,
//! the same in pixels as in millimetres), the middle dot sits at
//! `W12 + alpha (W32 - W12)` in the phantom frame, where W12 (W32) is the crossing
//! of the infinite lines of wires 1 and 2 (3 and 2): similar triangles.
//!
//! The pattern search takes PLUS's device-set settings with PLUS's meaning
//! (`PlusFidLabeling`, `PlusFidLineFinder`): rows (PLUS's lines) of three
//! collinear dots at an angle within `MinThetaDegrees`..`MaxThetaDegrees`; every
//! two rows of a set parallel within `AngleToleranceDegrees`, apart by between
//! the phantom's smallest plane distance less `MaxLinePairDistanceErrorPercent`
//! and its largest plus it, and shifted along each other by at most
//! `MaxLineShiftMm`. probecal's own checks on top are scale-free (they hold
//! whatever the true pixel size): neighbouring rows apart in the proportion of
//! their patterns' planes, the rows' lengths stretched alike, and the middle dots
//! as far apart as the phantom puts them, each within the same percentage.

use serde::{Deserialize, Serialize};

use crate::io::plus::config::PlusConfig;
use crate::spec::nwire::NWire;

/// Settings of the dot segmentation (each with the PLUS attribute it stands for).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Segmentation {
    /// Pixels brighter than this grey level belong to a dot; absent: each
    /// frame's own, `threshold_percent` % of its brightest pixel after the opening
    /// (inside the clip rectangle).
    pub threshold_grey: Option<u8>,
    /// The frame's threshold as a share of its brightest opened pixel, %
    /// (`ThresholdImagePercent`).
    pub threshold_percent: f64,
    /// Fewest pixels of a dot.
    pub min_dot_px: usize,
    /// A dot's centre is weighted by the grey levels above this fraction of its peak
    /// (0: every pixel above the threshold), so a comet tail does not pull it.
    pub core_fraction: f64,
    /// Radius of the disk of the morphological opening applied first (0: none);
    /// absent: `opening_radius_mm` over the approximate pixel size.
    pub opening_radius_px: Option<u32>,
    /// The opening's radius in the image, mm (`MorphologicalOpeningCircleRadiusMm`):
    /// thinner than a wire's echo, thicker than speckle.
    pub opening_radius_mm: f64,
    /// How many of the brightest spots are considered
    /// (`NumberOfMaximumFiducialPointCandidates`).
    pub max_candidates: usize,
    /// Largest distance of the middle dot from the line through the outer two, mm
    /// (`CollinearPointsMaxDistanceFromLineMm`).
    pub collinear_tolerance_mm: f64,
    /// Smallest and largest angle of a row of dots from the image's horizontal,
    /// degrees (`MinThetaDegrees`, `MaxThetaDegrees`).
    pub min_row_angle_deg: f64,
    pub max_row_angle_deg: f64,
    /// Largest angle between two rows of one frame, degrees
    /// (`AngleToleranceDegrees`: rows closer than it are parallel; the
    /// patterns' planes are parallel, so no other pair is a pattern set).
    pub max_row_angle_difference_deg: f64,
    /// Every two rows of a set lie between the phantom's smallest plane distance
    /// less this and its largest plus this, % (`MaxLinePairDistanceErrorPercent`);
    /// probecal's scale-free checks use the same percentage.
    pub row_gap_tolerance_percent: f64,
    /// Largest shift of two rows' midpoints along the rows, mm (`MaxLineShiftMm`):
    /// the patterns lie one behind the other.
    pub max_row_shift_mm: f64,
    /// A spot's strength is the sum of the original image's grey levels over it
    /// (`UseOriginalImageIntensityForDotIntensityScore`); otherwise the opened
    /// image's, as PLUS's default.
    pub original_intensity_score: bool,
    /// Region searched `[u, v, width, height]` px; absent: the configuration's clip
    /// rectangle, or the whole image.
    pub clip_rectangle_px: Option<[usize; 4]>,
    /// Which image row holds the first pattern of the phantom definition.
    pub first_pattern_row: RowOrder,
    /// On which side of a row the pattern's wire 1 appears.
    pub first_wire_side: Side,
}

/// A manifest's `bscan.segmentation`: each key replaces the device set's value
/// (or PLUS's default where the device set gives none).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SegmentationOverrides {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold_grey: Option<u8>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold_percent: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_dot_px: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub core_fraction: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opening_radius_px: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opening_radius_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_candidates: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub collinear_tolerance_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_row_angle_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_row_angle_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_row_angle_difference_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub row_gap_tolerance_percent: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_row_shift_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub original_intensity_score: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clip_rectangle_px: Option<[usize; 4]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_pattern_row: Option<RowOrder>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_wire_side: Option<Side>,
}

impl SegmentationOverrides {
    /// `base` with every key this gives replaced.
    pub fn apply(&self, base: &Segmentation) -> Segmentation {
        let mut s = base.clone();
        macro_rules! set {
            ($($field:ident),*) => {$(if let Some(v) = self.$field { s.$field = v; })*};
        }
        set!(
            threshold_percent,
            min_dot_px,
            core_fraction,
            opening_radius_mm,
            max_candidates,
            collinear_tolerance_mm,
            min_row_angle_deg,
            max_row_angle_deg,
            max_row_angle_difference_deg,
            row_gap_tolerance_percent,
            max_row_shift_mm,
            original_intensity_score,
            first_pattern_row,
            first_wire_side
        );
        if self.threshold_grey.is_some() {
            s.threshold_grey = self.threshold_grey;
        }
        if self.opening_radius_px.is_some() {
            s.opening_radius_px = self.opening_radius_px;
        }
        if self.clip_rectangle_px.is_some() {
            s.clip_rectangle_px = self.clip_rectangle_px;
        }
        s
    }
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
        // PLUS's defaults (`PlusFidSegmentation`): the threshold and the opening
        // follow each image and its pixel size (10 % of the brightest opened
        // pixel; a 0.27 mm disk); comet tails below a dot are dimmer and off the
        // row's line.
        Segmentation {
            threshold_grey: None,
            threshold_percent: 10.0,
            min_dot_px: 4,
            core_fraction: 0.5,
            opening_radius_px: None,
            opening_radius_mm: 0.27,
            max_candidates: 20,
            collinear_tolerance_mm: 0.6,
            min_row_angle_deg: -70.0,
            max_row_angle_deg: 70.0,
            max_row_angle_difference_deg: 10.0,
            row_gap_tolerance_percent: 10.0,
            max_row_shift_mm: 10.0,
            original_intensity_score: false,
            clip_rectangle_px: None,
            first_pattern_row: RowOrder::Top,
            first_wire_side: Side::Right,
        }
    }
}

/// Most dot candidates a frame's pattern search considers.
const MAX_CANDIDATES: usize = 50;

impl Segmentation {
    /// The segmentation settings a device set gives, over PLUS's defaults, each
    /// with PLUS's meaning (the module's doc).
    pub fn from_device_set(config: &PlusConfig) -> Segmentation {
        let s = &config.segmentation;
        let defaults = Segmentation::default();
        let (min_row_angle_deg, max_row_angle_deg) = s
            .theta_range_deg
            .unwrap_or((defaults.min_row_angle_deg, defaults.max_row_angle_deg));
        Segmentation {
            opening_radius_mm: s.opening_radius_mm.unwrap_or(defaults.opening_radius_mm),
            threshold_percent: s.threshold_percent.unwrap_or(defaults.threshold_percent),
            collinear_tolerance_mm: s.collinear_tolerance_mm.unwrap_or(defaults.collinear_tolerance_mm),
            row_gap_tolerance_percent: s
                .row_gap_tolerance_percent
                .unwrap_or(defaults.row_gap_tolerance_percent),
            max_row_shift_mm: s.max_row_shift_mm.unwrap_or(defaults.max_row_shift_mm),
            max_row_angle_difference_deg: s.angle_tolerance_deg.unwrap_or(defaults.max_row_angle_difference_deg),
            min_row_angle_deg,
            max_row_angle_deg,
            original_intensity_score: s.original_intensity_score.unwrap_or(defaults.original_intensity_score),
            max_candidates: s
                .max_candidates
                .map(|n| n.clamp(defaults.max_candidates, MAX_CANDIDATES))
                .unwrap_or(defaults.max_candidates),
            clip_rectangle_px: config.clip_rectangle_px.map(|(o, s)| [o[0], o[1], s[0], s[1]]),
            ..defaults
        }
    }

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

    /// Whether a row at `angle_deg` from the horizontal (either direction) lies
    /// within `MinThetaDegrees`..`MaxThetaDegrees`.
    fn row_angle_allowed(&self, angle_deg: f64) -> bool {
        let (lo, hi) = (self.min_row_angle_deg, self.max_row_angle_deg);
        [angle_deg, angle_deg - 180.0, angle_deg + 180.0]
            .iter()
            .any(|a| *a > lo && *a < hi)
    }
}

/// A bright region that may be a wire dot: its intensity-weighted centre and strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DotCandidate {
    pub centre_px: [f64; 2],
    pub pixels: usize,
    /// Sum of the spot's grey levels (the opened image's, or the original's with
    /// `original_intensity_score`).
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
            let scored = if settings.original_intensity_score {
                pixels
            } else {
                centre_pixels
            };
            let weight: f64 = members.iter().map(|&j| f64::from(scored[j])).sum();
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
    #[error("{failed} (the strongest set of {patterns} disjoint rows of {rows} candidate rows that got furthest)")]
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
            plane_distances_px: (35.0, 70.0),
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
            plane_distances_px: (60.0, 120.0),
            ..geometry.clone()
        };
        let rejection = segment(&spots, &far_apart, &settings).unwrap_err();
        assert_eq!(rejection.check(), "line pair distance", "{rejection}");
        assert!(
            rejection
                .to_string()
                .contains("limit 5.40 mm (MaxLinePairDistanceErrorPercent)"),
            "{rejection}"
        );
        // Two patterns 70 px apart: the top and bottom rows, not neighbours.
        let two = PatternGeometry {
            patterns: 2,
            row_gaps_px: vec![70.0],
            plane_distances_px: (70.0, 70.0),
            ..geometry
        };
        let dots = segment(&spots, &two, &settings).unwrap();
        assert!((dots.patterns[0][0][1] - 23.0).abs() < 1e-9 && (dots.patterns[1][0][1] - 93.0).abs() < 1e-9);
    }

    /// Rows 11 % further apart than the approximate pixel size puts the
    /// patterns (39 px for 35): PLUS's 10 % refuses the outer pair (78 px
    /// against at most 77), 15 % takes them, as PLUS would.
    #[test]
    fn line_pair_distance_is_plus_s_range_over_every_pair() {
        let (w, h) = (200usize, 140usize);
        let mut img = vec![0u8; w * h];
        for v in [20usize, 59, 98] {
            for u in [30usize, 90, 150] {
                for dv in 0..3 {
                    for du in 0..3 {
                        img[(v + dv) * w + u + du] = 200;
                    }
                }
            }
        }
        let geometry = PatternGeometry {
            patterns: 3,
            widths_px: (110.0, 130.0),
            row_gaps_px: vec![35.0, 35.0],
            plane_distances_px: (35.0, 70.0),
            spacing_mm_per_px: 0.1,
            nwires: Vec::new(),
        };
        let strict = Segmentation::default();
        let spots = find_spots(&img, &img, w, h, [0, 0, w, h], &strict);
        let rejection = segment(&spots, &geometry, &strict).unwrap_err();
        assert_eq!(rejection.check(), "line pair distance");
        let NWireRejection::NoPattern { failed, .. } = &rejection else {
            panic!("{rejection}")
        };
        assert!(
            (failed.value - 7.8).abs() < 1e-9 && (failed.limit - 7.7).abs() < 1e-9,
            "{rejection}"
        );
        let loose = Segmentation {
            row_gap_tolerance_percent: 15.0,
            ..Segmentation::default()
        };
        assert_eq!(segment(&spots, &geometry, &loose).unwrap().patterns.len(), 3);
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
