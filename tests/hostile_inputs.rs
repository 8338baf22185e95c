//! Inputs made to mislead, each refused where it enters with an error naming
//! the file (and the line where there is one), no panic or abort, and nothing
//! written: header fields given twice, sizes that would allocate gigabytes,
//! device sets nested past any parser's stack, transforms that scale, rectangles
//! outside the image, wires kilometres away, baselines of another experiment.

mod common;

use std::path::{Path, PathBuf};

use common::{probecal, scratch, shared_data};

const SET: &str = "plus-fcal2.0-3nwires";
const CONFIG: &str = "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml";
const VALIDATION: &str = "fCal_Test_Validation_3NWires_fCal2.0.igs.mha";

/// A small uncompressed sequence of `frames` grey frames, 40x30 px, with
/// `extra` header lines before the data.
fn tiny_sequence(frames: usize, dims: &str, extra: &str) -> Vec<u8> {
    let mut text = format!(
        "ObjectType = Image\nNDims = 3\nCompressedData = False\nDimSize = {dims}\nElementType = MET_UCHAR\n{extra}"
    );
    for i in 0..frames {
        text += &format!("Seq_Frame{i:04}_Timestamp = {}\n", i as f64 * 0.1);
        text += &format!("Seq_Frame{i:04}_ImageStatus = OK\n");
    }
    text += "ElementDataFile = LOCAL\n";
    let mut bytes = text.into_bytes();
    bytes.extend(std::iter::repeat_n(7u8, 40 * 30 * frames));
    bytes
}

/// `probecal segment` on `sequence` with `config`: stderr, after checking that
/// it failed with exit code 1 (not a panic's 101 or an abort's signal) and
/// wrote nothing.
fn segment_refused(dir: &Path, sequence: &Path, config: &Path) -> String {
    let out = dir.join("out");
    let r = probecal()
        .arg("segment")
        .arg(sequence)
        .arg("--config")
        .arg(config)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr).to_string();
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out.exists(), "nothing is written on an error: {stderr}");
    stderr
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn sequence_headers_that_say_two_things_or_too_much_are_refused() {
    let dir = scratch("hostile_inputs", "sequences");
    let config = shared_data(SET, CONFIG);
    // One frame's field under two spellings of its index: the same field twice.
    let twice = tiny_sequence(2, "40 30 2", "Seq_Frame00000_Timestamp = 99\n");
    let path = write(&dir, "twice.mha", &twice);
    let e = segment_refused(&dir, &path, &config);
    assert!(
        e.contains("twice.mha:7: frame 0's `Timestamp` is given twice (lines 6 and 7)"),
        "{e}"
    );
    // A second DimSize.
    let dims = tiny_sequence(2, "40 30 2", "DimSize = 40 30 1\n");
    let path = write(&dir, "dims.mha", &dims);
    let e = segment_refused(&dir, &path, &config);
    assert!(
        e.contains("dims.mha:6: `DimSize` is given twice (lines 4 and 6)"),
        "{e}"
    );
    // A header that asks for 4 Gpx of one frame in a file of a few hundred
    // bytes: refused before anything is allocated.
    let huge = tiny_sequence(0, "65536 65536 1", "Seq_Frame0000_Timestamp = 0\n");
    let path = write(&dir, "huge.mha", &huge[..huge.len().min(400)]);
    let e = segment_refused(&dir, &path, &config);
    assert!(
        e.contains("huge.mha:4: `DimSize = 65536 65536 1` is implausibly large: at most 67108864 pixels a frame"),
        "{e}"
    );
}

/// The shared device set with `from` replaced by `to` (which must occur).
fn device_set(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    device_set_edits(dir, name, &[(from, to)])
}

/// The shared device set with each `(from, to)` replaced in turn.
fn device_set_edits(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(shared_data(SET, CONFIG)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "`{from}` is not in the device set");
        text = text.replacen(from, to, 1);
    }
    write(dir, name, text.as_bytes())
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn device_sets_are_held_to_physical_values() {
    let dir = scratch("hostile_inputs", "device_sets");
    let sequence = shared_data(SET, VALIDATION);
    // Nested 100 000 deep: refused before parsing, not a stack overflow.
    let deep = format!(
        "<PlusConfiguration>{}{}</PlusConfiguration>",
        "<a>".repeat(100_000),
        "</a>".repeat(100_000)
    );
    let path = write(&dir, "deep.xml", deep.as_bytes());
    let e = segment_refused(&dir, &path, &path);
    assert!(e.contains("deep.xml: elements nested more than 256 deep"), "{e}");
    // A transform defined twice (here as its own inverse).
    let again = "<Transform From=\"Reference\" To=\"Phantom\" Matrix=\"1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\"/>\n    <Transform From=\"Phantom\" To=\"Reference\"";
    let path = device_set(&dir, "again.xml", "<Transform From=\"Phantom\" To=\"Reference\"", again);
    let e = segment_refused(&dir, &path, &path);
    assert!(
        e.contains("transform PhantomToReference is defined again (first as ReferenceToPhantom on line"),
        "{e}"
    );
    // The clip rectangle past the 820x616 B-scans.
    let path = device_set(
        &dir,
        "clip.xml",
        "ClipRectangleSize=\"766 562\"",
        "ClipRectangleSize=\"900 562\"",
    );
    let e = segment_refused(&dir, &sequence, &path);
    assert!(
        e.contains("the clip rectangle (origin 27 27, size 900 562 px) reaches beyond the 820x616 px B-scans"),
        "{e}"
    );
    // A wire 10 km away.
    let path = device_set(
        &dir,
        "wire.xml",
        "EndPointFront=\"30.0 0.0 20.0\"",
        "EndPointFront=\"1e7 0.0 20.0\"",
    );
    let e = segment_refused(&dir, &sequence, &path);
    assert!(
        e.contains("wire.xml:") && e.contains("is beyond ±2000 mm of the phantom's origin"),
        "{e}"
    );
    // A pixel size of a kilometre.
    let path = device_set(
        &dir,
        "spacing.xml",
        "ApproximateSpacingMmPerPixel=\"0.078\"",
        "ApproximateSpacingMmPerPixel=\"1e6\"",
    );
    let e = segment_refused(&dir, &sequence, &path);
    assert!(
        e.contains("`ApproximateSpacingMmPerPixel` must be 0.001 to 10 mm per pixel, got 1000000"),
        "{e}"
    );
    // More dot candidates than the search can take.
    let path = device_set(
        &dir,
        "candidates.xml",
        "NumberOfMaximumFiducialPointCandidates=\"20\"",
        "NumberOfMaximumFiducialPointCandidates=\"500\"",
    );
    let e = segment_refused(&dir, &sequence, &path);
    assert!(
        e.contains("candidates.xml:")
            && e.contains("`NumberOfMaximumFiducialPointCandidates` must be a positive number up to 200, got 500"),
        "{e}"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_phantom_registration_that_scales_is_refused_not_absorbed() {
    // PhantomToReference scaled x2: before, the pixel size absorbed the scale,
    // PRE3D doubled, and the run ended with exit 0.
    let dir = scratch("hostile_inputs", "scaled_registration");
    let config = device_set_edits(
        &dir,
        "scaled.xml",
        &[
            (
                "-0.0167397  -0.0153548  -0.999742  15.6642",
                "-0.0334794  -0.0307096  -1.999484  15.6642",
            ),
            (
                "-0.999834  0.0075107  0.0166258  -25.3628",
                "-1.999668  0.0150214  0.0332516  -25.3628",
            ),
            (
                "0.00725347  0.999854  -0.015478  -40.7799",
                "0.01450694  1.999708  -0.030956  -40.7799",
            ),
        ],
    );
    let manifest = format!(
        "experiment: scaled_registration\ntracking:\n  plus_sequence:\n    dataset: fcal2\n    calibration: {}\n    validation: {}\nphantom:\n  nwire:\n    plus_config: {}\n",
        shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha").display(),
        shared_data(SET, VALIDATION).display(),
        config.display()
    );
    let path = write(&dir, "scaled.yaml", manifest.as_bytes());
    let r = probecal().arg("validate").arg(&path).output().unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_ne!(r.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("transform PhantomToReference is not rigid: its axes are 2.0000, 2.0000, 2.0000 long"),
        "{stderr}"
    );
    assert!(stderr.contains("scaled.xml:43"), "the transform's line: {stderr}");
}

const TANK: &str = "plus-temporal-watertank";

/// A copy of sequence `source` as `out` whose header lines are passed through
/// `edit` (the pixel data after `ElementDataFile` kept as it is).
fn edited_sequence(source: &Path, out: &Path, edit: impl Fn(&str) -> String) {
    let bytes = std::fs::read(source).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header = String::from_utf8(bytes[..end].to_vec()).unwrap();
    let mut text: String = header.lines().map(|l| edit(l) + "\n").collect();
    text += "ElementDataFile = LOCAL\n";
    let mut data = text.into_bytes();
    data.extend_from_slice(&bytes[end + marker.len()..]);
    std::fs::write(out, data).unwrap();
}

/// `line`'s frame index and value when it is `Seq_FrameNNNN_<field> = value`.
fn frame_field(line: &str, field: &str) -> Option<(usize, String)> {
    let rest = line.strip_prefix("Seq_Frame")?;
    let (index, rest) = rest.split_once('_')?;
    let value = rest.strip_prefix(field)?.strip_prefix(" = ")?;
    Some((index.parse().ok()?, value.to_string()))
}

fn temporal(dir: &Path, tracker: &Path) -> (Option<i32>, String) {
    let r = probecal()
        .arg("temporal")
        .arg("--tracker")
        .arg(tracker)
        .arg("--video")
        .arg(shared_data(TANK, "WaterTankBottomTranslationVideoBuffer.igs.mha"))
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    (r.status.code(), String::from_utf8_lossy(&r.stderr).to_string())
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn temporal_refuses_a_clock_or_a_sample_it_cannot_trust() {
    let dir = scratch("hostile_inputs", "temporal");
    std::fs::create_dir_all(&dir).unwrap();
    let source = shared_data(TANK, "WaterTankBottomTranslationTrackerBuffer.igs.mha");
    // Frame 100's timestamp equal to frame 99's: the clock stands still.
    let still = dir.join("still.igs.mha");
    let text = std::fs::read(&source).unwrap();
    let header = String::from_utf8_lossy(&text[..text.len().min(2_000_000)]).to_string();
    let t99 = header
        .lines()
        .find_map(|l| frame_field(l, "Timestamp").filter(|(i, _)| *i == 99).map(|(_, v)| v))
        .unwrap();
    edited_sequence(&source, &still, |l| match frame_field(l, "Timestamp") {
        Some((100, _)) => format!("Seq_Frame0100_Timestamp = {t99}"),
        _ => l.to_string(),
    });
    let (code, e) = temporal(&dir, &still);
    assert_eq!(code, Some(1), "{e}");
    assert!(
        e.contains("still.igs.mha: frame 100's `Timestamp`") && e.contains("the clock stands still"),
        "{e}"
    );
    // One probe sample a thousand kilometres away.
    let far = dir.join("far.igs.mha");
    edited_sequence(&source, &far, |l| match frame_field(l, "ProbeToTrackerTransform") {
        Some((300, v)) => {
            let mut n: Vec<String> = v.split_whitespace().map(str::to_string).collect();
            n[3] = "1e9".into();
            format!("Seq_Frame0300_ProbeToTrackerTransform = {}", n.join(" "))
        }
        _ => l.to_string(),
    });
    let (code, e) = temporal(&dir, &far);
    assert_eq!(code, Some(1), "{e}");
    assert!(
        e.contains("far.igs.mha: frame 300's probe is") && e.contains("beyond any tracker's workspace"),
        "{e}"
    );
    assert!(!dir.join("out").exists());
}

/// A tracked manifest over the fCal sequences `calibration` and `validation`.
fn fcal_manifest(dir: &Path, name: &str, calibration: &Path, validation: &Path, offset: &str) -> PathBuf {
    let text = format!(
        "experiment: {name}\ntracking:\n  plus_sequence:\n    dataset: fcal2\n    calibration: {}\n    validation: {}\n    time_offset_s: {offset}\nphantom:\n  nwire:\n    plus_config: {}\n",
        calibration.display(),
        validation.display(),
        shared_data(SET, CONFIG).display()
    );
    write(dir, &format!("{name}.yaml"), text.as_bytes())
}

fn run_into(manifest: &Path, out: &Path) -> (Option<i32>, String) {
    let r = probecal()
        .args(["run", "--quiet", "--out"])
        .arg(out)
        .arg(manifest)
        .output()
        .unwrap();
    (r.status.code(), String::from_utf8_lossy(&r.stderr).to_string())
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn tracked_runs_check_their_clock_and_their_validation_recording() {
    let dir = scratch("hostile_inputs", "tracked_clock");
    std::fs::create_dir_all(&dir).unwrap();
    let calibration = shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha");
    let validation = shared_data(SET, VALIDATION);
    // The validation sequence is the calibration sequence (a copy): refused,
    // it would score the calibration on its own frames.
    let copy = dir.join("copy.igs.mha");
    std::fs::copy(&calibration, &copy).unwrap();
    let m = fcal_manifest(&dir, "same", &calibration, &copy, "0.0");
    let (code, e) = run_into(&m, &dir.join("out_same"));
    assert_ne!(code, Some(0), "{e}");
    assert!(
        e.contains(
            "`tracking.plus_sequence.validation`: is the calibration sequence (the same file or the same bytes)"
        ),
        "{e}"
    );
    // A clock that runs backwards at frame 60.
    let backwards = dir.join("backwards.igs.mha");
    edited_sequence(&calibration, &backwards, |l| match frame_field(l, "Timestamp") {
        Some((60, v)) => format!("Seq_Frame0060_Timestamp = {}", v.parse::<f64>().unwrap() - 30.0),
        _ => l.to_string(),
    });
    // A fixed lag cannot be applied on it ...
    let m = fcal_manifest(&dir, "fixed_lag", &backwards, &validation, "0.05");
    let (code, e) = run_into(&m, &dir.join("out_fixed"));
    assert_ne!(code, Some(0), "{e}");
    assert!(
        e.contains("frame 60's `Timestamp`") && e.contains("the clock runs backwards"),
        "{e}"
    );
    // ... and an estimate is unresolved, none applied, said in summary.json.
    let m = fcal_manifest(&dir, "estimated", &backwards, &validation, "estimate");
    let out = dir.join("out_estimate");
    let (code, e) = run_into(&m, &out);
    assert_eq!(code, Some(0), "{e}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("estimated/fcal2/summary.json")).unwrap()).unwrap();
    let why = summary["time_offset_estimate"]["unresolved"]
        .as_str()
        .unwrap_or_default();
    assert!(
        why.contains("the clock runs backwards"),
        "{}",
        summary["time_offset_estimate"]
    );
    assert_eq!(summary["time_offset_s"], 0.0);
    assert!(summary["time_offset_estimate"]["lag_s"].is_null());
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_replay_never_waits_on_an_untrusted_clock_or_speed() {
    let dir = scratch("hostile_inputs", "live_clock");
    std::fs::create_dir_all(&dir).unwrap();
    let calibration = shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha");
    // Frames from 50 on a year later: a paced replay would sleep for a year.
    let jump = dir.join("jump.igs.mha");
    edited_sequence(&calibration, &jump, |l| match frame_field(l, "Timestamp") {
        Some((i, v)) if i >= 50 => format!("Seq_Frame{i:04}_Timestamp = {}", v.parse::<f64>().unwrap() + 3.15e7),
        _ => l.to_string(),
    });
    let m = fcal_manifest(&dir, "jump", &jump, &shared_data(SET, VALIDATION), "0.0");
    let live = |speed: &str| {
        let r = probecal()
            .arg("live")
            .arg(&m)
            .arg(format!("--speed={speed}"))
            .arg("--out")
            .arg(dir.join("out"))
            .output()
            .unwrap();
        (r.status.code(), String::from_utf8_lossy(&r.stderr).to_string())
    };
    let started = std::time::Instant::now();
    let (code, e) = live("1");
    assert_ne!(code, Some(0), "{e}");
    assert!(
        e.contains("frame 50 comes 3.150e7 s after frame 49, more than 10 s"),
        "{e}"
    );
    assert!(started.elapsed().as_secs() < 60, "refused before any wait");
    // A speed that turns the recording's seconds into centuries, or NaN.
    for speed in ["1e-300", "NaN", "-1"] {
        let (code, e) = live(speed);
        assert_eq!(code, Some(2), "{speed}: {e}");
        assert!(e.contains("a replay speed is 0"), "{e}");
    }
    assert!(!dir.join("out").exists());
}

#[test]
fn a_camera_board_larger_than_any_printed_one_is_refused() {
    for (arg, value) in [("--board", "50000x50000"), ("--charuco", "500x7")] {
        let mut c = probecal();
        c.args([
            "calibrate-camera",
            "x.png",
            arg,
            value,
            "--square-mm",
            "10",
            "--out",
            "never.yml",
        ]);
        if arg == "--charuco" {
            c.args(["--marker-mm", "7", "--dictionary", "DICT_4X4_50"]);
        }
        let r = c.output().unwrap();
        let e = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{e}");
        assert!(e.contains("a board has at most"), "{e}");
        assert!(!Path::new("never.yml").exists());
    }
}

fn segment_into(sequence: &Path, config: &Path, out: &Path, force: bool) -> (Option<i32>, String) {
    let mut c = probecal();
    c.arg("segment")
        .arg(sequence)
        .arg("--config")
        .arg(config)
        .arg("--out")
        .arg(out);
    if force {
        c.arg("--force");
    }
    let r = c.output().unwrap();
    (r.status.code(), String::from_utf8_lossy(&r.stderr).to_string())
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn every_command_writes_its_own_folder_whole_and_nothing_else() {
    let dir = scratch("hostile_inputs", "outputs");
    std::fs::create_dir_all(&dir).unwrap();
    // A copy of the inputs in a folder of their own.
    let inputs = dir.join("inputs");
    std::fs::create_dir_all(&inputs).unwrap();
    let sequence = inputs.join("validation.igs.mha");
    let config = inputs.join("device_set.xml");
    std::fs::copy(shared_data(SET, VALIDATION), &sequence).unwrap();
    std::fs::copy(shared_data(SET, CONFIG), &config).unwrap();
    let before = std::fs::read(&config).unwrap();
    // --out the inputs' folder, or an input file: refused even with --force.
    for out in [&inputs, &config] {
        let (code, e) = segment_into(&sequence, &config, out, true);
        assert_eq!(code, Some(2), "{e}");
        assert!(
            e.contains("which `probecal segment` reads; choose another --out"),
            "{e}"
        );
    }
    assert_eq!(std::fs::read(&config).unwrap(), before, "the input is untouched");
    // A folder someone else wrote (here: a run's) is replaced only with --force.
    let theirs = dir.join("theirs");
    std::fs::create_dir_all(&theirs).unwrap();
    std::fs::write(theirs.join("summary.json"), "{\"kind\": \"tracked\"}").unwrap();
    let (code, e) = segment_into(&sequence, &config, &theirs, false);
    assert_eq!(code, Some(2), "{e}");
    assert!(
        e.contains("was not written by this command") && e.contains("pass --force"),
        "{e}"
    );
    assert_eq!(
        std::fs::read_to_string(theirs.join("summary.json")).unwrap(),
        "{\"kind\": \"tracked\"}"
    );
    // Two segmentations into one folder: the second replaces the first whole
    // (no gallery of the first left among the second's).
    let out = dir.join("segmented");
    let vlc = shared_data(
        "plus-segmentation-vlcus",
        "SegmentationTest_VLCUS_RandomStepperMotionData2.igs.mha",
    );
    let vlc_config = shared_data(
        "plus-segmentation-vlcus",
        "PlusDeviceSet_iCal_CalibrationOnly_VLCUS_FrameGrabber.xml",
    );
    assert_eq!(segment_into(&vlc, &vlc_config, &out, false).0, Some(0));
    assert_eq!(std::fs::read_dir(out.join("gallery")).unwrap().count(), 201);
    let (code, e) = segment_into(&sequence, &config, &out, false);
    assert_eq!(code, Some(0), "{e}");
    assert_eq!(std::fs::read_dir(out.join("gallery")).unwrap().count(), 103);
    // temporal into segment's folder: another command's, refused.
    let r = probecal()
        .arg("temporal")
        .arg("--tracker")
        .arg(shared_data(TANK, "WaterTankBottomTranslationTrackerBuffer.igs.mha"))
        .arg("--video")
        .arg(shared_data(TANK, "WaterTankBottomTranslationVideoBuffer.igs.mha"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(e.contains("holds the output of `probecal segment`"), "{e}");
    // calibrate-camera writing over one of its photos.
    let photo = dir.join("left01.jpg");
    std::fs::copy(shared_data("opencv-chessboard", "left01.jpg"), &photo).unwrap();
    let jpeg = std::fs::read(&photo).unwrap();
    let r = probecal()
        .arg("calibrate-camera")
        .arg(&photo)
        .args(["--board", "9x6", "--square-mm", "25", "--out"])
        .arg(&photo)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(e.contains("which `probecal calibrate-camera` reads"), "{e}");
    assert_eq!(std::fs::read(&photo).unwrap(), jpeg);
    // A run whose --out is its dataset cache.
    let r = probecal()
        .arg("run")
        .arg(common::root().join("tests/fixtures/hemisphere_small.yaml"))
        .arg("--out")
        .arg(dir.join("shared"))
        .arg("--datasets")
        .arg(dir.join("shared"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(
        e.contains("overlap: a run's folder and a cached dataset could replace each other"),
        "{e}"
    );
}
