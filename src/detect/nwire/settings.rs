//! The N-wire segmentation's settings: PLUS's device-set attributes with PLUS's
//! meaning and defaults, and a manifest's overrides of them.

use serde::{Deserialize, Serialize};

use crate::io::plus::config::PlusConfig;

/// Settings of the dot segmentation (each with the PLUS attribute it stands for).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Segmentation {
    /// Cleaned pixels at or above this grey level belong to a dot; absent: each
    /// frame's own, `threshold_percent` % of its brightest pixel after the clean-up
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
    /// Half the length of the bars whose openings are subtracted first, mm
    /// (`MorphologicalOpeningBarSizeMm`; 0: none): bright lines longer than
    /// twice this (the phantom's walls, reverberations) leave the image.
    pub opening_bar_size_mm: f64,
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
    pub opening_bar_size_mm: Option<f64>,
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
            opening_bar_size_mm,
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
            opening_bar_size_mm: 2.0,
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
            opening_bar_size_mm: s.opening_bar_size_mm.unwrap_or(defaults.opening_bar_size_mm),
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
            max_candidates: s.max_candidates.unwrap_or(defaults.max_candidates),
            clip_rectangle_px: config.clip_rectangle_px.map(|(o, s)| [o[0], o[1], s[0], s[1]]),
            ..defaults
        }
    }

    /// The opening's radius for images of about `spacing_mm_per_px`.
    pub fn opening_radius_for(&self, spacing_mm_per_px: f64) -> u32 {
        self.opening_radius_px
            .unwrap_or_else(|| (self.opening_radius_mm / spacing_mm_per_px).round().clamp(0.0, 50.0) as u32)
    }

    /// The bars' half length in pixels for images of about `spacing_mm_per_px`
    /// (PLUS rounds it the same way).
    pub fn bar_px_for(&self, spacing_mm_per_px: f64) -> usize {
        (self.opening_bar_size_mm / spacing_mm_per_px).round().clamp(0.0, 200.0) as usize
    }

    /// One frame's grey threshold: the manifest's, or `threshold_percent` % of the
    /// brightest pixel of `centre_pixels` (the cleaned image) in `clip`, at least 1.
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
    pub(super) fn row_angle_allowed(&self, angle_deg: f64) -> bool {
        let (lo, hi) = (self.min_row_angle_deg, self.max_row_angle_deg);
        [angle_deg, angle_deg - 180.0, angle_deg + 180.0]
            .iter()
            .any(|a| *a > lo && *a < hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device set's candidate count is used as PLUS uses it, below the
    /// default as well as above it.
    #[test]
    fn device_set_candidates_are_taken_as_given() {
        for n in [10usize, 20, 150] {
            let text = format!(
                "<PlusConfiguration>\n<Segmentation ApproximateSpacingMmPerPixel=\"0.078\" NumberOfMaximumFiducialPointCandidates=\"{n}\" />\n</PlusConfiguration>"
            );
            let config = PlusConfig::parse(std::path::Path::new("c.xml"), &text).unwrap();
            assert_eq!(Segmentation::from_device_set(&config).max_candidates, n);
        }
    }
}
