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
//! Each image is first cleaned as PLUS cleans it ([`clean`]: long bright lines
//! removed, then an opening with a disk), and its dots are the regions of the
//! cleaned image at or above the frame's threshold ([`find_spots`]).
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

mod morphology;
mod search;
mod settings;
mod spots;

pub use morphology::{clean, region_of_interest, Cleaned};
pub use search::{segment, FailedCheck, NWireDots, NWireRejection, PatternGeometry, CHECKS};
pub use settings::{RowOrder, Segmentation, SegmentationOverrides, Side};
pub use spots::{find_spots, DotCandidate};

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
