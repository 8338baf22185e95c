//! Manifest errors: each bad input is a small edit of a good manifest, and the
//! test pins the error text, the field path and the line.

use std::path::Path;

use super::*;

const GOOD: &str = "\
experiment: demo
phantom:
  hemisphere:
    centre_in_phantom_mm: [285.7, 76.2, -26.5]
    radius_mm: 15.0
rig:
  checkerboard:
    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}
    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}
camera:
  calibrate:
    inner_corners: [9, 6]
    square_mm: 30.0
bscan:
  spacing_mm_per_px: [0.2, 0.2]
thresholds:
  bre_cutoffs_mm: [.inf, 2.0, 1.5, 1.0]
  calibration_cutoff_mm: 2.0
datasets:
  - name: first
    render:
      seed: 3
      frames: 20
";

fn parse(text: &str) -> Result<Manifest, ManifestErrors> {
    Manifest::from_text(Path::new("experiments/demo.yaml"), text)
}

#[test]
fn good_manifest_parses_with_defaults() {
    let m = parse(GOOD).expect("good manifest");
    assert_eq!(m.experiment, "demo");
    assert_eq!(m.thresholds.calibration_cutoff_mm, 2.0);
    assert_eq!(m.thresholds.cutoff_rule, CutoffRule::MaxAxis);
    assert_eq!(m.arc_detection.fit_radius, FitRadius::Known);
    match &m.datasets[0].source {
        DatasetSource::Render(spec) => {
            assert_eq!(spec.frames, 20);
            assert_eq!(spec.camera.image_size_px, [1920, 1080]);
        }
        other => panic!("expected a render spec, got {other:?}"),
    }
}

/// (what is changed, replace this, with this, expected field, expected line, expected message part)
type BadCase = (
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    Option<usize>,
    &'static str,
);

const BAD: &[BadCase] = &[
    (
        "unknown top-level key",
        "experiment: demo\n",
        "experiment: demo\ncolour: red\n",
        "colour",
        Some(2),
        "unknown field `colour`",
    ),
    (
        "typo in a nested key",
        "    radius_mm: 15.0",
        "    radius: 15.0",
        "phantom.hemisphere.radius",
        Some(5),
        "unknown field `radius`",
    ),
    (
        "negative radius",
        "radius_mm: 15.0",
        "radius_mm: -4.0",
        "phantom.hemisphere.radius_mm",
        Some(5),
        "must be a positive number",
    ),
    (
        "zero square size",
        "probe_board: {inner_corners: [10, 10], square_mm: 13.0",
        "probe_board: {inner_corners: [10, 10], square_mm: 0.0",
        "rig.checkerboard.probe_board.square_mm",
        Some(8),
        "got 0",
    ),
    (
        "wrong type",
        "seed: 3",
        "seed: three",
        "datasets[0].render.seed",
        Some(22),
        "invalid type",
    ),
    (
        "missing required field",
        "    radius_mm: 15.0\n",
        "",
        "phantom.hemisphere",
        Some(4),
        "missing field `radius_mm`",
    ),
    (
        "unknown phantom",
        "  hemisphere:\n",
        "  sphere:\n",
        "phantom.sphere",
        Some(3),
        "unknown variant `sphere`",
    ),
    (
        "thresholds out of order",
        "[.inf, 2.0, 1.5, 1.0]",
        "[.inf, 1.0, 1.5]",
        "thresholds.bre_cutoffs_mm[2]",
        Some(17),
        "strictly descending",
    ),
    (
        "calibration cut-off not listed",
        "calibration_cutoff_mm: 2.0",
        "calibration_cutoff_mm: 3.0",
        "thresholds.calibration_cutoff_mm",
        Some(18),
        "must be one of bre_cutoffs_mm",
    ),
    (
        "too few frames",
        "frames: 20",
        "frames: 2",
        "datasets[0].render.frames",
        Some(23),
        "at least 3 frames",
    ),
    (
        "same identification dots",
        "square_mm: 13.0, id_dots: 2",
        "square_mm: 13.0, id_dots: 1",
        "rig.checkerboard.phantom_board.id_dots",
        Some(9),
        "different number",
    ),
    (
        "intrinsics file missing",
        "  calibrate:\n    inner_corners: [9, 6]\n    square_mm: 30.0\n",
        "  intrinsics_file: nowhere/intrinsics.yml\n",
        "camera.intrinsics_file",
        Some(11),
        "does not exist",
    ),
    (
        "both camera sources",
        "  calibrate:\n",
        "  intrinsics_file: x.yml\n  calibrate:\n",
        "camera",
        Some(10),
        "exactly one of",
    ),
    (
        "dataset without source",
        "    render:\n      seed: 3\n      frames: 20\n",
        "    seed: 3\n",
        "datasets[0].seed",
        Some(21),
        "unknown field `seed`",
    ),
    (
        "recorded folder missing",
        "    render:\n      seed: 3\n      frames: 20\n",
        "    folder: no/such/folder\n",
        "datasets[0].folder",
        Some(21),
        "does not exist",
    ),
    (
        "duplicate dataset names",
        "      frames: 20\n",
        "      frames: 20\n  - name: first\n    render: {seed: 4}\n",
        "datasets[1].name",
        Some(24),
        "used twice",
    ),
    (
        "no datasets",
        "datasets:\n  - name: first\n    render:\n      seed: 3\n      frames: 20\n",
        "datasets: []\n",
        "datasets",
        Some(19),
        "lists no dataset",
    ),
    (
        "min_frames below three",
        "  calibration_cutoff_mm: 2.0\n",
        "  calibration_cutoff_mm: 2.0\n  min_frames: 2\n",
        "thresholds.min_frames",
        Some(19),
        "at least 3 frames",
    ),
    (
        "negative spacing",
        "[0.2, 0.2]",
        "[0.2, -0.2]",
        "bscan.spacing_mm_per_px[1]",
        Some(15),
        "must be a positive number",
    ),
    (
        "board too small",
        "inner_corners: [10, 10], square_mm: 13.0, id_dots: 1",
        "inner_corners: [1, 10], square_mm: 13.0, id_dots: 1",
        "rig.checkerboard.probe_board.inner_corners",
        Some(8),
        "at least 2x2",
    ),
    (
        "pin head of no size",
        "  hemisphere:\n    centre_in_phantom_mm: [285.7, 76.2, -26.5]\n    radius_mm: 15.0\n",
        "  point:\n    position_in_phantom_mm: [1, 2, 3]\n    head_radius_mm: 0\n",
        "phantom.point.head_radius_mm",
        Some(5),
        "must be a positive number",
    ),
    (
        "a fitted pixel size on the hemisphere",
        "bscan:\n  spacing_mm_per_px: [0.2, 0.2]\n",
        "bscan:\n  spacing_mm_per_px: [0.2, 0.2]\nsolve:\n  sphere_fit:\n    fit_pixel_size: true\n",
        "solve.sphere_fit.fit_pixel_size",
        Some(18),
        "`phantom: spheres:` only",
    ),
    (
        "4-wire phantom without a start",
        "  hemisphere:\n    centre_in_phantom_mm: [285.7, 76.2, -26.5]\n    radius_mm: 15.0\n",
        "  four_wire:\n    wire_diameter_mm: 1.5\n    wires:\n      - {name: a, start_in_phantom_mm: [0, 0, 0], end_in_phantom_mm: [0, 50, 0]}\n      - {name: b, start_in_phantom_mm: [30, 0, 0], end_in_phantom_mm: [30, 50, 0]}\n      - {name: c, start_in_phantom_mm: [0, 0, 0], end_in_phantom_mm: [30, 50, 0]}\n",
        "solve.initial_marker_T_image",
        None,
        "rough marker_T_image",
    ),
    (
        "4-wire phantom of parallel wires",
        "  hemisphere:\n    centre_in_phantom_mm: [285.7, 76.2, -26.5]\n    radius_mm: 15.0\n",
        "  four_wire:\n    wire_diameter_mm: 1.5\n    wires:\n      - {name: a, start_in_phantom_mm: [0, 0, 0], end_in_phantom_mm: [0, 50, 0]}\n      - {name: b, start_in_phantom_mm: [30, 0, 0], end_in_phantom_mm: [30, 50, 0]}\n      - {name: c, start_in_phantom_mm: [9, 0, 0], end_in_phantom_mm: [9, 50, 0]}\n",
        "phantom.four_wire.wires",
        Some(5),
        "all wires are parallel",
    ),
    (
        "YAML syntax error",
        "    radius_mm: 15.0\n",
        "    radius_mm: 15.0\n   oops: 1\n",
        "phantom",
        Some(6),
        "did not find expected key",
    ),
    (
        "fan angle impossible",
        "      frames: 20\n",
        "      frames: 20\n      bscan: {fan_deg: 200}\n",
        "datasets[0].render.bscan.fan_deg",
        Some(24),
        "between 0 and 170",
    ),
    (
        "outlier rate above one",
        "      frames: 20\n",
        "      frames: 20\n      bscan: {outlier_rate: 1.5}\n",
        "datasets[0].render.bscan.outlier_rate",
        Some(24),
        "fraction between 0 and 1",
    ),
    (
        "JPEG quality of 0",
        "      frames: 20\n",
        "      frames: 20\n      realism:\n        jpeg: {quality: 0}\n",
        "datasets[0].render.realism.jpeg.quality",
        Some(25),
        "between 1 and 100",
    ),
    (
        "a speed of sound no medium has",
        "      frames: 20\n",
        "      frames: 20\n      realism:\n        speed_of_sound: {scanner_m_per_s: 1540, medium_m_per_s: 15}\n",
        "datasets[0].render.realism.speed_of_sound.medium_m_per_s",
        Some(25),
        "between 300 and 5000 m/s",
    ),
    (
        "an error source that does not exist",
        "      frames: 20\n",
        "      frames: 20\n      realism:\n        fog: {density: 1}\n",
        "datasets[0].render.realism.fog",
        Some(25),
        "unknown field `fog`",
    ),
    (
        "a shutter's asynchrony without the hand's speed",
        "      frames: 20\n",
        "      frames: 20\n      realism:\n        shutter: {asynchrony_sd_s: 0.1}\n",
        "datasets[0].render.realism.hand",
        Some(24),
        "need the hand's speed",
    ),
    (
        "a negative bow",
        "      frames: 20\n",
        "      frames: 20\n      realism:\n        board_warp: {bow_sd_mm: -1}\n",
        "datasets[0].render.realism.board_warp.bow_sd_mm",
        Some(25),
        "",
    ),
];

#[test]
fn bad_manifests_name_file_field_and_line() {
    let mut failures = Vec::new();
    for (what, from, to, field, line, message) in BAD {
        assert!(
            GOOD.contains(from),
            "test case `{what}`: `{from}` is not in the good manifest"
        );
        let text = GOOD.replacen(from, to, 1);
        let result = std::panic::catch_unwind(|| parse(&text));
        let errors = match result {
            Err(_) => {
                failures.push(format!("{what}: panicked"));
                continue;
            }
            Ok(Ok(_)) => {
                failures.push(format!("{what}: accepted"));
                continue;
            }
            Ok(Err(e)) => e,
        };
        let first = &errors.0[0];
        let shown = errors.to_string();
        if first.field != *field || first.line != *line || !first.message.contains(message) {
            failures.push(format!(
                "{what}: got `{shown}` (field `{}`, line {:?})",
                first.field, first.line
            ));
        }
        if !shown.starts_with("experiments/demo.yaml") {
            failures.push(format!("{what}: the file is not named first: `{shown}`"));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases wrong:\n{}",
        failures.len(),
        BAD.len(),
        failures.join("\n")
    );
}

const ARUCO_RIG: &str = "rig:
  aruco:
    dictionary: DICT_4X4_50
    probe_board: {markers: [4, 4], marker_mm: 30.0, separation_mm: 8.0, first_id: 0}
    phantom_board: {markers: [4, 4], marker_mm: 30.0, separation_mm: 8.0, first_id: 16}
camera:";

#[test]
fn aruco_rig_parses_and_its_mistakes_are_located() {
    let good = GOOD.replacen(
        "rig:\n  checkerboard:\n    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}\n    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}\ncamera:",
        ARUCO_RIG,
        1,
    );
    let m = parse(&good).expect("ArUco manifest");
    assert!(matches!(
        m.rig,
        Rig::Aruco {
            subpixel_half_window_px: 3,
            min_markers: 4,
            ..
        }
    ));
    let cases = [
        (
            "first_id: 16}",
            "first_id: 10}",
            "rig.aruco.phantom_board.first_id",
            "overlap the probe board's 0..15",
        ),
        (
            "DICT_4X4_50",
            "DICT_4X4_5O",
            "rig.aruco.dictionary",
            "unknown ArUco dictionary `DICT_4X4_5O`",
        ),
        (
            "first_id: 16}",
            "first_id: 40}",
            "rig.aruco.phantom_board.first_id",
            "ids 40..55 do not fit in DICT_4X4_50 (50 markers)",
        ),
        (
            "marker_mm: 30.0, separation_mm: 8.0, first_id: 0",
            "marker_mm: 0.0, separation_mm: 8.0, first_id: 0",
            "rig.aruco.probe_board.marker_mm",
            "positive",
        ),
    ];
    for (from, to, field, message) in cases {
        let errors = parse(&good.replacen(from, to, 1)).unwrap_err();
        let e = &errors.0[0];
        assert_eq!(e.field, field, "{errors}");
        assert!(e.message.contains(message) && e.line.is_some(), "{errors}");
    }
}

#[test]
fn several_problems_are_reported_together() {
    let text = GOOD
        .replace("radius_mm: 15.0", "radius_mm: -1.0")
        .replace("frames: 20", "frames: 1");
    let errors = parse(&text).unwrap_err();
    assert_eq!(errors.0.len(), 2, "{errors}");
}

#[test]
fn shipped_experiments_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).expect("experiments folder") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "yaml") {
            if let Err(e) = super::Experiment::load(&path) {
                panic!("{e}");
            }
            count += 1;
        }
    }
    assert!(count >= 1, "no experiments found in {}", dir.display());
}

#[test]
fn nesting_past_the_limit_is_refused_with_its_line() {
    let deep = format!("{}{}", "[".repeat(40), "]".repeat(40));
    let text = GOOD.replacen(
        "experiment: demo\n",
        &format!("experiment: demo\ndescription: {deep}\n"),
        1,
    );
    let e = parse(&text).unwrap_err().to_string();
    assert!(e.contains(":2: nested 33 levels deep"), "{e}");
    let shallow = format!("{}{}", "[".repeat(20), "]".repeat(20));
    assert!(crate::io::yaml_limits::too_deep(&format!("a: {shallow}\nb:\n  c: 1\n")).is_none());
}

const CHARUCO_RIG: &str = "rig:
  charuco:
    probe_board: {squares: [11, 11], square_mm: 13.0, marker_mm: 10.0, dictionary: DICT_4X4_250}
    phantom_board: {squares: [11, 11], square_mm: 13.0, marker_mm: 10.0, dictionary: DICT_4X4_250, first_id: 60}
camera:";

#[test]
fn charuco_rig_parses_and_its_mistakes_are_located() {
    let good = GOOD.replacen(
        "rig:\n  checkerboard:\n    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}\n    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}\ncamera:",
        CHARUCO_RIG,
        1,
    );
    let m = parse(&good).expect("ChArUco manifest");
    assert!(matches!(
        m.rig,
        Rig::Charuco {
            min_corners: 6,
            detector_params: None,
            ..
        }
    ));
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/opencv-aruco/tutorial_dict.yml");
    let cases = [
        (
            "DICT_4X4_250, first_id: 60}",
            "DICT_4X4_250, first_id: 30}",
            "rig.charuco.phantom_board.first_id",
            "overlap the probe board's 0..59",
        ),
        (
            "DICT_4X4_250, first_id: 60}",
            "DICT_4X4_250, first_id: 200}",
            "rig.charuco.phantom_board.first_id",
            "needs ids up to 259, the dictionary `DICT_4X4_250` has 250",
        ),
        (
            "marker_mm: 10.0, dictionary: DICT_4X4_250}",
            "marker_mm: 13.0, dictionary: DICT_4X4_250}",
            "rig.charuco.probe_board.marker_mm",
            "a marker is smaller than its square (13 mm), got 13",
        ),
        (
            "squares: [11, 11], square_mm: 13.0, marker_mm: 10.0, dictionary: DICT_4X4_250}",
            "squares: [1, 11], square_mm: 13.0, marker_mm: 10.0, dictionary: DICT_4X4_250}",
            "rig.charuco.probe_board.squares",
            "2x2 to 101x101 squares, got 1x11",
        ),
        (
            "dictionary: DICT_4X4_250}",
            "dictionary: DICT_4X4_25O}",
            "rig.charuco.probe_board.dictionary",
            "unknown ArUco dictionary `DICT_4X4_25O`",
        ),
        (
            "dictionary: DICT_4X4_250}",
            "dictionary: no_such_dict.yml}",
            "rig.charuco.probe_board.dictionary",
            "no_such_dict.yml` does not exist",
        ),
        (
            "first_id: 60}\n",
            "first_id: 60}\n    min_corners: 3\n",
            "rig.charuco.min_corners",
            "a pose needs at least 4 corners, got 3",
        ),
        (
            "first_id: 60}\n",
            "first_id: 60}\n    detector_params: no_params.yml\n",
            "rig.charuco.detector_params",
            "no_params.yml` does not exist",
        ),
    ];
    for (from, to, field, message) in cases {
        let errors = parse(&good.replacen(from, to, 1)).unwrap_err();
        let e = &errors.0[0];
        assert_eq!(e.field, field, "{errors}");
        assert!(e.message.contains(message) && e.line.is_some(), "{errors}");
    }
    // A custom dictionary file (tutorial_dict.yml: 35 markers of 6x6 bits) is read and held to its size.
    if shared.is_file() {
        let custom = good
            .replace("squares: [11, 11]", "squares: [5, 5]")
            .replace("first_id: 60", "first_id: 12")
            .replace("dictionary: DICT_4X4_250", &format!("dictionary: {}", shared.display()));
        assert!(matches!(
            parse(&custom).expect("custom dictionary").rig,
            Rig::Charuco { .. }
        ));
        let errors = parse(&custom.replace("first_id: 12", "first_id: 30")).unwrap_err();
        assert!(errors.0[0].message.contains("needs ids up to 41"), "{errors}");
    }
}
