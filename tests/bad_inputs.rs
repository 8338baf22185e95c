//! A table of bad inputs — manifests, datasets, images, intrinsics, command-line
//! arguments — each with the exit code and the error text it must give. A bad
//! frame is rejected with its reason and the run goes on; a bad run stops with a
//! clear error; nothing panics.

mod common;

use common::{probecal, root};

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn work() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("bad_inputs")
}

/// A recorded-style lab folder, made once: the small fixture's rendered frames,
/// intrinsics from its calibration views, and a manifest that reads them.
fn lab() -> &'static PathBuf {
    static LAB: OnceLock<PathBuf> = OnceLock::new();
    LAB.get_or_init(|| {
        let lab = work().join("lab");
        let _ = std::fs::remove_dir_all(&lab);
        std::fs::create_dir_all(&lab).unwrap();
        let datasets = work().join("datasets");
        let r = probecal()
            .arg("synth")
            .arg(root().join("tests/fixtures/hemisphere_small.yaml"))
            .arg("--datasets")
            .arg(&datasets)
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let rendered = datasets.join("hemisphere_small__small");
        let r = probecal()
            .args(["calibrate-camera", "--board", "9x6", "--square-mm", "30", "--out"])
            .arg(lab.join("camera.yml"))
            .arg(rendered.join("camera_calibration"))
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        std::fs::create_dir_all(lab.join("shared")).unwrap();
        copy_dir(&rendered.join("frames"), &lab.join("shared/frames"));
        std::fs::copy(rendered.join("tracker_poses.csv"), lab.join("shared/tracker_poses.csv")).unwrap();
        lab
    })
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
    }
}

const MANIFEST: &str = "\
experiment: lab_run
phantom:
  hemisphere: {centre_in_phantom_mm: [285.7, 76.2, -26.5], radius_mm: 15.0}
rig:
  checkerboard:
    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}
    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}
camera:
  intrinsics_file: ../camera.yml
bscan:
  spacing_mm_per_px: [0.2, 0.2]
thresholds:
  min_frames: 5
datasets:
  - name: session
    folder: session
";

/// One case: a name, a setup that edits a fresh case folder, the command, the
/// expected exit code, and text that must appear (in stderr, or in the frame table).
struct Case {
    name: &'static str,
    setup: fn(&Path),
    args: fn(&Path) -> Vec<String>,
    code: i32,
    expect: &'static str,
    /// Where `expect` must appear: "stderr" or "frames" (the run's per-frame table).
    in_output: &'static str,
}

fn frame_list(n: usize) -> String {
    let mut s = String::from("frame,camera_image,bscan_image\n");
    for k in 0..n {
        s.push_str(&format!(
            "{k},../../shared/frames/camera_{k:03}.png,../../shared/frames/bscan_{k:03}.png\n"
        ));
    }
    s
}

/// A case folder holding `experiment.yaml` and a `session/` dataset of 14 frames.
fn standard(dir: &Path) {
    std::fs::create_dir_all(dir.join("session")).unwrap();
    std::fs::write(dir.join("experiment.yaml"), MANIFEST).unwrap();
    std::fs::write(dir.join("session/frames.csv"), frame_list(14)).unwrap();
}

fn with_manifest(dir: &Path, from: &str, to: &str) {
    standard(dir);
    let text = MANIFEST.replacen(from, to, 1);
    assert_ne!(text, MANIFEST, "case edit `{from}` did not apply");
    std::fs::write(dir.join("experiment.yaml"), text).unwrap();
}

/// Frame 2's camera photo replaced by `bytes` (or removed with None).
fn replace_photo(dir: &Path, bytes: Option<Vec<u8>>, bscan: bool) {
    standard(dir);
    let name = if bscan { "bscan_002.png" } else { "camera_002.png" };
    let list = frame_list(14).replace(&format!("../../shared/frames/{name}"), &format!("local/{name}"));
    std::fs::write(dir.join("session/frames.csv"), list).unwrap();
    std::fs::create_dir_all(dir.join("session/local")).unwrap();
    if let Some(b) = bytes {
        std::fs::write(dir.join("session/local").join(name), b).unwrap();
    }
}

/// The standard case with poses from `session/poses.csv` (the rendered tracker's
/// poses, edited by `edit`) instead of the camera.
fn tracker_csv(dir: &Path, edit: fn(String) -> String) {
    with_manifest(
        dir,
        "camera:\n  intrinsics_file: ../camera.yml\n",
        "poses:\n  tracker_csv: {file: poses.csv}\n",
    );
    let text = std::fs::read_to_string(lab().join("shared/tracker_poses.csv")).unwrap();
    std::fs::write(dir.join("session/poses.csv"), edit(text)).unwrap();
}

/// Line `n` (1-based) of a text, edited.
fn edit_line(text: &str, n: usize, edit: impl Fn(&str) -> String) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == n { edit(l) } else { l.to_string() } + "\n")
        .collect()
}

fn shared(name: &str) -> Vec<u8> {
    std::fs::read(lab().join("shared/frames").join(name)).unwrap()
}

fn png(width: i32, height: i32, value: u8) -> Vec<u8> {
    let mat = opencv::core::Mat::new_rows_cols_with_default(
        height,
        width,
        opencv::core::CV_8UC1,
        opencv::core::Scalar::all(value as f64),
    )
    .unwrap();
    let grey = probecal::io::image::mat_to_gray8(&mat).unwrap();
    probecal::io::png_codec::encode(&grey.data, grey.width, grey.height, 1).unwrap()
}

fn validate(dir: &Path) -> Vec<String> {
    vec!["validate".into(), dir.join("experiment.yaml").display().to_string()]
}

fn run(dir: &Path) -> Vec<String> {
    vec![
        "run".into(),
        dir.join("experiment.yaml").display().to_string(),
        "--out".into(),
        dir.join("out").display().to_string(),
        "--quiet".into(),
    ]
}

fn plus_data(name: &str) -> PathBuf {
    root().join("../shared/data/plus-fcal2.0-3nwires").join(name)
}

/// A tracker-sequence experiment (named like the camera ones, so its frame table
/// is found at the same place) over a copy of PLUS's calibration sequence whose
/// header is edited by `edit` and whose data is cut by `cut` bytes.
fn tracked(dir: &Path, edit: fn(String) -> String, cut: usize, manifest_edit: (&str, &str)) {
    std::fs::create_dir_all(dir).unwrap();
    let bytes = std::fs::read(plus_data("fCal_Test_Calibration_3NWires_fCal2.0.igs.mha")).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let at = bytes.windows(marker.len()).position(|w| w == marker).unwrap() + marker.len();
    let mut out = edit(String::from_utf8(bytes[..at].to_vec()).unwrap()).into_bytes();
    out.extend_from_slice(&bytes[at..bytes.len() - cut]);
    std::fs::write(dir.join("calibration.igs.mha"), out).unwrap();
    let config = plus_data("PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml");
    let text = format!(
        "experiment: lab_run\ntracking:\n  plus_sequence:\n    dataset: session\n    calibration: calibration.igs.mha\n    time_offset_s: 0.0\nphantom:\n  nwire:\n    plus_config: {}\n",
        config.display()
    );
    let edited = text.replacen(manifest_edit.0, manifest_edit.1, 1);
    assert!(
        manifest_edit.0 == manifest_edit.1 || edited != text,
        "case edit `{}` did not apply",
        manifest_edit.0
    );
    std::fs::write(dir.join("experiment.yaml"), edited).unwrap();
}

fn no_edit(h: String) -> String {
    h
}

const CASES: &[Case] = &[
    // Tracker sequences (PLUS files).
    Case {
        name: "tracked: sequence file missing",
        setup: |d| tracked(d, no_edit, 0, ("calibration.igs.mha", "gone.igs.mha")),
        args: validate,
        code: 2,
        expect: "experiment.yaml:5: field `tracking.plus_sequence.calibration`: file",
        in_output: "stderr",
    },
    Case {
        name: "tracked: time offset neither seconds nor estimate",
        setup: |d| tracked(d, no_edit, 0, ("time_offset_s: 0.0", "time_offset_s: soon")),
        args: validate,
        code: 2,
        expect: "experiment.yaml:6: field `tracking.plus_sequence.time_offset_s`: must be `estimate`, seconds",
        in_output: "stderr",
    },
    Case {
        name: "tracked: sequence data cut off",
        setup: |d| tracked(d, no_edit, 300_000, ("dataset: session", "dataset: session")),
        args: run,
        code: 1,
        expect: "calibration.igs.mha:8: data truncated: `CompressedDataSize` says 1205020 bytes, the file has 905020",
        in_output: "stderr",
    },
    Case {
        name: "tracked: frame count differs from DimSize",
        setup: |d| {
            tracked(
                d,
                |h| h.replace("DimSize = 820 616 190", "DimSize = 820 616 180"),
                0,
                ("dataset: session", "dataset: session"),
            )
        },
        args: run,
        code: 1,
        expect: "frame count mismatch: `DimSize` has 180 frames, the header describes 190",
        in_output: "stderr",
    },
    Case {
        name: "tracked: a transform marked INVALID rejects its frame only",
        setup: |d| {
            tracked(
                d,
                |h| {
                    h.replacen(
                        "Seq_Frame0005_ProbeToTrackerTransformStatus = OK",
                        "Seq_Frame0005_ProbeToTrackerTransformStatus = INVALID",
                        1,
                    )
                },
                0,
                ("dataset: session", "dataset: session"),
            )
        },
        args: run,
        code: 0,
        expect: "frame 5: `ProbeToTrackerTransformStatus` is INVALID, not OK",
        in_output: "frames",
    },
    Case {
        name: "tracked: a NaN in a pose matrix rejects its frame only",
        setup: |d| {
            tracked(
                d,
                |h| {
                    h.replacen(
                        "Seq_Frame0009_ProbeToTrackerTransform = 0.216028",
                        "Seq_Frame0009_ProbeToTrackerTransform = nan",
                        1,
                    )
                },
                0,
                ("dataset: session", "dataset: session"),
            )
        },
        args: run,
        code: 0,
        expect: "is not a rigid transform: matrix has a non-finite entry",
        in_output: "frames",
    },
    // Poses from a tracker CSV.
    Case {
        name: "tracker CSV: camera and poses both given",
        setup: |d| with_manifest(d, "bscan:\n", "poses:\n  tracker_csv: {file: poses.csv}\nbscan:\n"),
        args: validate,
        code: 2,
        expect:
            "experiment.yaml:10: field `poses`: give `camera` (poses from photos) or `poses` (from a tracker), not both",
        in_output: "stderr",
    },
    Case {
        name: "tracker CSV: file missing from the dataset",
        setup: |d| {
            tracker_csv(d, |t| t);
            std::fs::remove_file(d.join("session/poses.csv")).unwrap();
        },
        args: validate,
        code: 2,
        expect: "field `poses.tracker_csv.file`: dataset `session`",
        in_output: "stderr",
    },
    Case {
        name: "tracker CSV: a scaled matrix names its line",
        setup: |d| {
            // Line 4 is frame 1's ProbeToTracker; its m00 doubled.
            tracker_csv(d, |t| {
                edit_line(&t, 4, |l| {
                    let mut f: Vec<String> = l.split(',').map(String::from).collect();
                    f[2] = format!("{}", 2.0 * f[2].parse::<f64>().unwrap());
                    f.join(",")
                })
            })
        },
        args: run,
        code: 1,
        expect: "poses.csv:4: ProbeToTracker of frame 1: the rotation part is not orthonormal",
        in_output: "stderr",
    },
    Case {
        name: "tracker CSV: a frame without poses is rejected with its reason",
        setup: |d| {
            tracker_csv(d, |t| {
                t.lines()
                    .filter(|l| !l.starts_with("2,"))
                    .map(|l| format!("{l}\n"))
                    .collect()
            })
        },
        args: run,
        code: 0,
        expect: "tracker pose,poses.csv has no ProbeToTracker for frame 2",
        in_output: "frames",
    },
    Case {
        name: "tracker CSV: a rigid but absurd pose rejects its frame at the plausibility check",
        setup: |d| {
            // Frame 2's marker 1 km from the tracker: a rigid matrix, not a measurement.
            tracker_csv(d, |t| {
                t.lines()
                    .map(|l| {
                        let mut f: Vec<String> = l.split(',').map(String::from).collect();
                        if l.starts_with("2,ProbeToTracker,") {
                            f[5] = "1000000".into();
                        }
                        format!("{}\n", f.join(","))
                    })
                    .collect()
            })
        },
        args: run,
        code: 0,
        expect: "plausibility,tracker_T_marker puts its board 1000",
        in_output: "frames",
    },
    Case {
        name: "a B-scan whose PNG header claims 50000x50000 px is refused before decoding",
        setup: |d| {
            let mut bytes = png(8, 8, 40);
            bytes[16..20].copy_from_slice(&50_000u32.to_be_bytes());
            bytes[20..24].copy_from_slice(&50_000u32.to_be_bytes());
            replace_photo(d, Some(bytes), true)
        },
        args: run,
        code: 0,
        expect: "image is 50000x50000 px, more than the 100000000 pixels probecal decodes",
        in_output: "frames",
    },
    Case {
        name: "a frame number wider than 32 bits reaches the table whole",
        setup: |d| {
            standard(d);
            let list = edit_line(&frame_list(14), 2, |l| l.replacen("0,", "18446744073709551615,", 1));
            std::fs::write(d.join("session/frames.csv"), list).unwrap();
        },
        args: run,
        code: 0,
        expect: "\n18446744073709551615,",
        in_output: "frames",
    },
    Case {
        name: "a manifest nested past the limit is refused before parsing",
        setup: |d| {
            let deep = format!("{}{}", "[".repeat(40), "]".repeat(40));
            with_manifest(
                d,
                "experiment: lab_run\n",
                &format!("experiment: lab_run\ndescription: {deep}\n"),
            )
        },
        args: validate,
        code: 2,
        expect: "experiment.yaml:2: nested 33 levels deep; a manifest nests at most 32",
        in_output: "stderr",
    },
    Case {
        name: "more worker threads than the limit",
        setup: standard,
        args: |d| {
            let mut a = run(d);
            a.extend(["--threads".into(), "1000".into()]);
            a
        },
        code: 2,
        expect: "1000 is not in 0..=256",
        in_output: "stderr",
    },
    Case {
        name: "a B-scan of another size than the dataset's is rejected with both sizes",
        setup: |d| {
            use opencv::prelude::*;
            // The real B-scan with 24 more columns: its arc is still found.
            let bscan = lab().join("shared/frames/bscan_002.png");
            let image = probecal::io::image::read_gray(&bscan).unwrap();
            let mut wider = opencv::core::Mat::default();
            opencv::core::copy_make_border(
                &image,
                &mut wider,
                0,
                0,
                0,
                24,
                opencv::core::BORDER_CONSTANT,
                opencv::core::Scalar::all(0.0),
            )
            .unwrap();
            let grey = probecal::io::image::mat_to_gray8(&wider).unwrap();
            let png = probecal::io::png_codec::encode(&grey.data, grey.width, grey.height, 1).unwrap();
            assert_eq!(wider.cols(), image.cols() + 24);
            replace_photo(d, Some(png), true)
        },
        args: run,
        code: 0,
        expect: "session/local/bscan_002.png: image is 825x601 px, expected 801x601",
        in_output: "frames",
    },
    // Manifests: each names the file, the field and the line; nothing runs.
    Case {
        name: "unknown key",
        setup: |d| with_manifest(d, "thresholds:\n", "thresholds:\n  colour: red\n"),
        args: validate,
        code: 2,
        expect: "experiment.yaml:13: field `thresholds.colour`: unknown field `colour`",
        in_output: "stderr",
    },
    Case {
        name: "wrong type",
        setup: |d| with_manifest(d, "radius_mm: 15.0", "radius_mm: fifteen"),
        args: validate,
        code: 2,
        expect: "field `phantom.hemisphere.radius_mm`: invalid type: string \"fifteen\", expected f64",
        in_output: "stderr",
    },
    Case {
        name: "missing field",
        setup: |d| with_manifest(d, ", radius_mm: 15.0}", "}"),
        args: validate,
        code: 2,
        expect: "missing field `radius_mm`",
        in_output: "stderr",
    },
    Case {
        name: "negative radius",
        setup: |d| with_manifest(d, "radius_mm: 15.0", "radius_mm: -15.0"),
        args: validate,
        code: 2,
        expect: "experiment.yaml:3: field `phantom.hemisphere.radius_mm`: must be a positive number",
        in_output: "stderr",
    },
    Case {
        name: "zero square size",
        setup: |d| with_manifest(d, "square_mm: 13.0, id_dots: 1", "square_mm: 0, id_dots: 1"),
        args: validate,
        code: 2,
        expect: "experiment.yaml:6: field `rig.checkerboard.probe_board.square_mm`",
        in_output: "stderr",
    },
    Case {
        name: "min_frames below 3",
        setup: |d| with_manifest(d, "min_frames: 5", "min_frames: 2"),
        args: validate,
        code: 2,
        expect: "field `thresholds.min_frames`: Horn's solution needs at least 3 frames, got 2",
        in_output: "stderr",
    },
    Case {
        name: "thresholds out of order",
        setup: |d| with_manifest(d, "thresholds:\n", "thresholds:\n  bre_cutoffs_mm: [.inf, 1.0, 2.0]\n"),
        args: validate,
        code: 2,
        expect: "field `thresholds.bre_cutoffs_mm[2]`: cut-offs must be strictly descending",
        in_output: "stderr",
    },
    Case {
        name: "intrinsics file missing",
        setup: |d| with_manifest(d, "../camera.yml", "../nowhere.yml"),
        args: validate,
        code: 2,
        expect: "field `camera.intrinsics_file`: file",
        in_output: "stderr",
    },
    Case {
        name: "dataset folder missing",
        setup: |d| with_manifest(d, "folder: session", "folder: elsewhere"),
        args: validate,
        code: 2,
        expect: "experiment.yaml:16: field `datasets[0].folder`: folder",
        in_output: "stderr",
    },
    Case {
        name: "empty manifest",
        setup: |d| {
            standard(d);
            std::fs::write(d.join("experiment.yaml"), "").unwrap()
        },
        args: validate,
        code: 2,
        expect: "experiment.yaml",
        in_output: "stderr",
    },
    Case {
        name: "manifest file missing",
        setup: |_| {},
        args: validate,
        code: 2,
        expect: "cannot read the manifest",
        in_output: "stderr",
    },
    Case {
        name: "YAML syntax error",
        setup: |d| with_manifest(d, "bscan:\n", "bscan: [\n"),
        args: validate,
        code: 2,
        expect: "experiment.yaml:",
        in_output: "stderr",
    },
    Case {
        name: "manifest is binary",
        setup: |d| {
            standard(d);
            std::fs::write(d.join("experiment.yaml"), [0xff, 0xfe, 0x00, 0x81]).unwrap()
        },
        args: validate,
        code: 2,
        expect: "cannot read the manifest",
        in_output: "stderr",
    },
    Case {
        name: "unknown ArUco dictionary",
        setup: |d| {
            with_manifest(d, "  checkerboard:\n    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}\n    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}\n", "  aruco:\n    dictionary: DICT_9X9_9\n    probe_board: {markers: [4, 4], marker_mm: 30, separation_mm: 8, first_id: 0}\n    phantom_board: {markers: [4, 4], marker_mm: 30, separation_mm: 8, first_id: 16}\n")
        },
        args: validate,
        code: 2,
        expect: "field `rig.aruco.dictionary`: unknown ArUco dictionary `DICT_9X9_9`",
        in_output: "stderr",
    },
    Case {
        name: "frames' boards refine the camera on an ArUco rig",
        setup: |d| {
            standard(d);
            let text = MANIFEST
                .replacen("  checkerboard:\n    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}\n    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}\n", "  aruco:\n    dictionary: DICT_4X4_50\n    probe_board: {markers: [4, 4], marker_mm: 30, separation_mm: 8, first_id: 0}\n    phantom_board: {markers: [4, 4], marker_mm: 30, separation_mm: 8, first_id: 16}\n", 1)
                .replacen("  intrinsics_file: ../camera.yml\n", "  calibrate: {inner_corners: [9, 6], square_mm: 30.0, refine_with_frames: true}\n", 1);
            std::fs::write(d.join("experiment.yaml"), text).unwrap();
        },
        args: validate,
        code: 2,
        expect: "field `camera.calibrate.refine_with_frames`: the frames' boards refine the intrinsics on a checkerboard rig only",
        in_output: "stderr",
    },
    Case {
        name: "gates name an estimator that does not exist",
        setup: |d| with_manifest(d, "thresholds:\n", "thresholds:\n  gates: {method: sphere_fit_magic, truth_corner_error_mm: 1.0}\n"),
        args: validate,
        code: 2,
        expect: "field `thresholds.gates.method`: `sphere_fit_magic` is not an estimator",
        in_output: "stderr",
    },
    Case {
        name: "pose prior on a hemisphere",
        setup: |d| {
            with_manifest(
                d,
                "bscan:\n",
                "solve:\n  sphere_fit:\n    pose_prior: {hand: {speed_mm_per_s: 3.0, rotation_deg_per_s: 1.0}, asynchrony_sd_s: 0.05}\nbscan:\n",
            )
        },
        args: validate,
        code: 2,
        expect: "field `solve.sphere_fit.pose_prior`: the pose prior belongs to the multi-sphere fit",
        in_output: "stderr",
    },
    Case {
        name: "edge offset model unknown",
        setup: |d| {
            with_manifest(
                d,
                "bscan:\n",
                "solve:\n  sphere_fit:\n    pose_prior:\n      hand: {speed_mm_per_s: 3.0, rotation_deg_per_s: 1.0}\n      asynchrony_sd_s: 0.05\n      edge_offset: sideways\nbscan:\n",
            )
        },
        args: validate,
        code: 2,
        expect: "experiment.yaml:15: field `solve.sphere_fit.pose_prior.edge_offset`: unknown variant `sideways`, expected one of `none`, `constant`, `obliquity`, `constant_and_obliquity`",
        in_output: "stderr",
    },
    Case {
        name: "arc peak unknown",
        setup: |d| with_manifest(d, "bscan:\n", "bscan:\n  arc_detection: {peak: ridge}\n"),
        args: validate,
        code: 2,
        expect: "field `bscan.arc_detection.peak`: unknown variant `ridge`, expected `column` or `normal`",
        in_output: "stderr",
    },
    Case {
        name: "slice blur of no pulse",
        setup: |d| {
            with_manifest(
                d,
                "bscan:\n",
                "solve:\n  sphere_fit:\n    pose_prior:\n      hand: {speed_mm_per_s: 3.0, rotation_deg_per_s: 1.0}\n      asynchrony_sd_s: 0.05\n      slice_blur: {axial_sd_mm: 0, elevation_sd_mm: 0.41}\nbscan:\n",
            )
        },
        args: validate,
        code: 2,
        expect: "field `solve.sphere_fit.pose_prior.slice_blur.axial_sd_mm`: must be a positive number",
        in_output: "stderr",
    },
    Case {
        name: "slice blur field unknown",
        setup: |d| {
            with_manifest(
                d,
                "bscan:\n",
                "solve:\n  sphere_fit:\n    pose_prior:\n      hand: {speed_mm_per_s: 3.0, rotation_deg_per_s: 1.0}\n      asynchrony_sd_s: 0.05\n      slice_blur: {axial_sd_mm: 0.36, width_mm: 1.5}\nbscan:\n",
            )
        },
        args: validate,
        code: 2,
        expect: "experiment.yaml:15: field `solve.sphere_fit.pose_prior.slice_blur.width_mm`: unknown field `width_mm`, expected `axial_sd_mm` or `elevation_sd_mm`",
        in_output: "stderr",
    },
    Case {
        name: "ArUco ids overlap",
        setup: |d| {
            with_manifest(d, "  checkerboard:\n    probe_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}\n    phantom_board: {inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}\n", "  aruco:\n    dictionary: DICT_4X4_50\n    probe_board: {markers: [4, 4], marker_mm: 30, separation_mm: 8, first_id: 0}\n    phantom_board: {markers: [4, 4], marker_mm: 30, separation_mm: 8, first_id: 8}\n")
        },
        args: validate,
        code: 2,
        expect: "overlap the probe board's 0..15",
        in_output: "stderr",
    },
    // Frame lists: the run stops, naming the file and the line.
    Case {
        name: "frame list line malformed",
        setup: |d| {
            standard(d);
            std::fs::write(
                d.join("session/frames.csv"),
                frame_list(14).replacen("\n3,", "\nthree,", 1),
            )
            .unwrap()
        },
        args: run,
        code: 1,
        expect: "frames.csv:5: frame `three` is not a whole number",
        in_output: "stderr",
    },
    Case {
        name: "frame list missing",
        setup: |d| {
            standard(d);
            std::fs::remove_file(d.join("session/frames.csv")).unwrap()
        },
        args: run,
        code: 1,
        expect: "cannot read the frame list",
        in_output: "stderr",
    },
    Case {
        name: "frame list header wrong",
        setup: |d| {
            standard(d);
            std::fs::write(d.join("session/frames.csv"), "id,photo,scan\n").unwrap()
        },
        args: run,
        code: 1,
        expect: "the header must be `frame,camera_image,bscan_image`",
        in_output: "stderr",
    },
    Case {
        name: "frame listed twice",
        setup: |d| {
            standard(d);
            std::fs::write(d.join("session/frames.csv"), frame_list(14) + "3,a.png,b.png\n").unwrap()
        },
        args: run,
        code: 1,
        expect: "frames.csv:16: frame 3 is listed twice",
        in_output: "stderr",
    },
    Case {
        name: "frame list with two fields",
        setup: |d| {
            standard(d);
            std::fs::write(d.join("session/frames.csv"), frame_list(14) + "20,only.png\n").unwrap()
        },
        args: run,
        code: 1,
        expect: "frames.csv:16: expected 3 comma-separated fields, found 2",
        in_output: "stderr",
    },
    // Bad frames: rejected with the reason, the run goes on.
    Case {
        name: "camera image missing",
        setup: |d| replace_photo(d, None, false),
        args: run,
        code: 0,
        expect: "camera_002.png: image file does not exist",
        in_output: "frames",
    },
    Case {
        name: "camera image empty",
        setup: |d| replace_photo(d, Some(Vec::new()), false),
        args: run,
        code: 0,
        expect: "camera_002.png: image file is empty (0 bytes)",
        in_output: "frames",
    },
    Case {
        name: "camera image truncated",
        setup: |d| replace_photo(d, Some(shared("camera_002.png")[..5000].to_vec()), false),
        args: run,
        code: 0,
        expect: "camera_002.png: a damaged or truncated PNG (unexpected end of file)",
        in_output: "frames",
    },
    Case {
        name: "camera image a GIF",
        setup: |d| replace_photo(d, Some(b"GIF89a not really".to_vec()), false),
        args: run,
        code: 0,
        expect: "camera_002.png: a GIF file; probecal reads PNG and JPEG images",
        in_output: "frames",
    },
    Case {
        name: "camera image not an image",
        setup: |d| replace_photo(d, Some(b"no image format at all".to_vec()), false),
        args: run,
        code: 0,
        expect: "camera_002.png: not a decodable image",
        in_output: "frames",
    },
    Case {
        name: "camera image wrong size",
        setup: |d| replace_photo(d, Some(png(640, 480, 128)), false),
        args: run,
        code: 0,
        expect: "camera_002.png: image is 640x480 px, expected 1920x1080",
        in_output: "frames",
    },
    Case {
        name: "photo without boards",
        setup: |d| replace_photo(d, Some(png(1920, 1080, 90)), false),
        args: run,
        code: 0,
        expect: "neither board found",
        in_output: "frames",
    },
    Case {
        name: "B-scan missing",
        setup: |d| replace_photo(d, None, true),
        args: run,
        code: 0,
        expect: "bscan_002.png: image file does not exist",
        in_output: "frames",
    },
    Case {
        name: "B-scan truncated",
        setup: |d| replace_photo(d, Some(shared("bscan_002.png")[..3000].to_vec()), true),
        args: run,
        code: 0,
        expect: "bscan_002.png: a damaged or truncated PNG (unexpected end of file)",
        in_output: "frames",
    },
    Case {
        name: "B-scan blank",
        setup: |d| replace_photo(d, Some(png(801, 601, 0)), true),
        args: run,
        code: 0,
        expect: "no ultrasound image content (empty fan)",
        in_output: "frames",
    },
    // Runs that cannot give a calibration stop with a clear error.
    Case {
        name: "too few usable frames",
        setup: |d| {
            standard(d);
            std::fs::write(
                d.join("session/frames.csv"),
                frame_list(14).replace("../../shared/frames/camera_00", "missing/camera_00"),
            )
            .unwrap()
        },
        args: run,
        code: 1,
        expect: "only 3 of 14 frames are usable, at least 5 are needed",
        in_output: "stderr",
    },
    Case {
        name: "intrinsics not FileStorage",
        setup: |d| {
            with_manifest(d, "../camera.yml", "bad_camera.yml");
            std::fs::write(d.join("bad_camera.yml"), "fx = 1400\n").unwrap()
        },
        args: run,
        code: 1,
        expect: "cannot open as OpenCV FileStorage",
        in_output: "stderr",
    },
    Case {
        name: "intrinsics without camera_matrix",
        setup: |d| {
            with_manifest(d, "../camera.yml", "partial.yml");
            std::fs::write(d.join("partial.yml"), "%YAML:1.0\n---\nimage_width: 1920\n").unwrap()
        },
        args: run,
        code: 1,
        expect: "field `camera_matrix` is missing",
        in_output: "stderr",
    },
    Case {
        name: "intrinsics without the image size",
        setup: |d| {
            with_manifest(d, "../camera.yml", "sizeless.yml");
            std::fs::write(
                d.join("sizeless.yml"),
                "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   \
                 data: [ 1400., 0., 966., 0., 1400., 535.5, 0., 0., 1. ]\n\
                 distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   \
                 data: [ -0.12, 0.05, 0., 0., 0. ]\n",
            )
            .unwrap()
        },
        args: run,
        code: 1,
        expect: "field `image_width` is missing",
        in_output: "stderr",
    },
    Case {
        name: "existing output without --force",
        setup: |d| {
            standard(d);
            std::fs::create_dir_all(d.join("out/lab_run")).unwrap()
        },
        args: run,
        code: 2,
        expect: "exists already; pass --force",
        in_output: "stderr",
    },
    // Command-line arguments.
    Case {
        name: "calibrate-camera: board not COLSxROWS",
        setup: |_| {},
        args: |d| {
            vec![
                "calibrate-camera".into(),
                "--board".into(),
                "9by6".into(),
                "--square-mm".into(),
                "25".into(),
                "--out".into(),
                d.join("x.yml").display().to_string(),
                d.display().to_string(),
            ]
        },
        code: 2,
        expect: "`9by6` is not COLSxROWS",
        in_output: "stderr",
    },
    Case {
        name: "calibrate-camera: negative square",
        setup: |d| std::fs::create_dir_all(d).unwrap(),
        args: |d| {
            vec![
                "calibrate-camera".into(),
                "--board".into(),
                "9x6".into(),
                "--square-mm=-25".into(),
                "--out".into(),
                d.join("x.yml").display().to_string(),
                d.display().to_string(),
            ]
        },
        code: 2,
        expect: "--square-mm must be a positive number",
        in_output: "stderr",
    },
    Case {
        name: "calibrate-camera: folder without images",
        setup: |d| std::fs::create_dir_all(d).unwrap(),
        args: |d| {
            vec![
                "calibrate-camera".into(),
                "--board".into(),
                "9x6".into(),
                "--square-mm".into(),
                "25".into(),
                "--out".into(),
                d.join("x.yml").display().to_string(),
                d.display().to_string(),
            ]
        },
        code: 1,
        expect: "no images (.png, .jpg, .jpeg, .bmp, .tif) found",
        in_output: "stderr",
    },
    Case {
        name: "check: nothing to check",
        setup: |d| std::fs::create_dir_all(d).unwrap(),
        args: |d| vec!["check".into(), d.display().to_string()],
        code: 2,
        expect: "no run summaries (*/*/summary.json) found",
        in_output: "stderr",
    },
];

#[test]
#[ignore = "needs ../shared/data and renders a lab (full tier: scripts/test.sh)"]
fn every_bad_input_gives_its_error_and_no_panic() {
    lab();
    let mut failures = Vec::new();
    for (i, case) in CASES.iter().enumerate() {
        let dir = lab().join(format!("case{i:02}"));
        let _ = std::fs::remove_dir_all(&dir);
        (case.setup)(&dir);
        let out = probecal().args((case.args)(&dir)).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        let shown = match case.in_output {
            "frames" => std::fs::read_to_string(dir.join("out/lab_run/session/frames.csv")).unwrap_or_default(),
            _ => stderr.clone(),
        };
        if stderr.contains("panicked") {
            failures.push(format!("{}: panicked: {stderr}", case.name));
        } else if out.status.code() != Some(case.code) {
            failures.push(format!(
                "{}: exit {:?}, expected {}: {stderr}",
                case.name,
                out.status.code(),
                case.code
            ));
        } else if !shown.contains(case.expect) {
            failures.push(format!(
                "{}: `{}` not in {}:\n{}",
                case.name,
                case.expect,
                case.in_output,
                shown.lines().take(6).collect::<Vec<_>>().join("\n")
            ));
        }
    }
    println!("{} bad inputs checked", CASES.len());
    assert!(CASES.len() >= 30);
    assert!(
        failures.is_empty(),
        "{} of {} cases wrong:\n{}",
        failures.len(),
        CASES.len(),
        failures.join("\n\n")
    );
}
