//! PLUS's fCal 2.0 triple N-wire recordings (`../shared/data/plus-fcal2.0-3nwires`):
//! the sequence reader against the file's known header, the N-wire geometry
//! against the configuration, the whole tracked experiment against PLUS's own
//! result, and broken sequence files.
#![allow(non_snake_case)]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::Point3;
use probecal::io::plus::config::PlusConfig;
use probecal::io::plus::sequence::{FrameFault, Sequence};
use probecal::pipeline::tracked::TrackedInputs;

fn data(name: &str) -> PathBuf {
    common::shared_data("plus-fcal2.0-3nwires", name)
}

const CALIBRATION: &str = "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha";
const VALIDATION: &str = "fCal_Test_Validation_3NWires_fCal2.0.igs.mha";
const CONFIG: &str = "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml";

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn sequence_reader_matches_the_header() {
    let s = Sequence::read(&data(CALIBRATION)).unwrap();
    assert_eq!((s.width, s.height, s.frames.len()), (820, 616, 190));
    assert_eq!(s.header["UltrasoundImageOrientation"].value, "MFA");
    // Frame 0, written in the header as 0.214041 -0.922145 0.322235 284.342 ...
    let t = s.transform(0, "ProbeToTracker").unwrap();
    let m = t.to_homogeneous();
    assert!((m[(0, 3)] - 284.342).abs() < 1e-9 && (m[(2, 3)] + 13.1385).abs() < 1e-9);
    assert!((m[(0, 0)] - 0.214041).abs() < 1e-4);
    assert_eq!(s.frame_field(0, "Timestamp"), Some("2572.905343"));
    // The pixels decompress to the declared size and are not blank.
    let frame = s.pixels(189);
    assert_eq!(frame.len(), 820 * 616);
    assert!(frame.iter().filter(|&&p| p > 100).count() > 200);
    let v = Sequence::read(&data(VALIDATION)).unwrap();
    assert_eq!(v.frames.len(), 103);
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn nwire_crossings_of_the_shared_configuration() {
    let config = PlusConfig::read(&data(CONFIG)).unwrap();
    assert_eq!(config.nwires.len(), 3);
    // Pattern 1 (z = 20): wire 1 is x = 30, the diagonal runs (55, 0) -> (35, 40), wire 3 is x = 60.
    let expected = [
        ((30.0, 50.0, 20.0), (60.0, -10.0, 20.0)),
        ((30.0, -10.0, 10.0), (60.0, 50.0, 10.0)),
        ((35.0, 53.333333333, 0.0), (60.0, -13.333333333, 0.0)),
    ];
    for (n, (w12, w32)) in config.nwires.iter().zip(expected) {
        assert!(
            (n.w12_in_phantom_mm - Point3::new(w12.0, w12.1, w12.2)).norm() < 1e-6,
            "{:?}",
            n.w12_in_phantom_mm
        );
        assert!(
            (n.w32_in_phantom_mm - Point3::new(w32.0, w32.1, w32.2)).norm() < 1e-6,
            "{:?}",
            n.w32_in_phantom_mm
        );
    }
    let reference_T_phantom = config.transform("Phantom", "Reference").unwrap();
    assert!((reference_T_phantom[(0, 3)] - 15.6642).abs() < 1e-9);
    assert!((config.approximate_spacing_mm_per_px.unwrap() - 0.078).abs() < 1e-12);
}

/// The same phantom written out in a manifest's YAML gives the same inputs as the
/// PLUS device set; a YAML N that is not an N is refused with its field.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn nwire_phantom_from_yaml_matches_the_plus_configuration() {
    use probecal::manifest::tracked::TrackedManifest;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let load = |p: &Path| {
        let text = std::fs::read_to_string(p).unwrap();
        TrackedManifest::from_text(p, &text)
    };
    let from_plus = TrackedInputs::from_manifest(&load(&root.join("experiments/plus_fcal2_nwire.yaml")).unwrap());
    let yaml_path = root.join("tests/fixtures/fcal2_nwire_yaml.yaml");
    let from_yaml = TrackedInputs::from_manifest(&load(&yaml_path).unwrap());
    assert_eq!(from_yaml.nwires.len(), 3);
    for (a, b) in from_yaml.nwires.iter().zip(&from_plus.nwires) {
        assert!((a.w12_in_phantom_mm - b.w12_in_phantom_mm).norm() < 1e-9);
        assert!((a.w32_in_phantom_mm - b.w32_in_phantom_mm).norm() < 1e-9);
        for (u, v) in a.wires.iter().zip(&b.wires) {
            assert_eq!(u, v);
        }
    }
    assert_eq!(from_yaml.reference_T_phantom, from_plus.reference_T_phantom);
    assert_eq!(from_yaml.spacing_guess_mm_per_px, from_plus.spacing_guess_mm_per_px);
    assert_eq!(from_yaml.clip_rectangle_px, from_plus.clip_rectangle_px);
    // The clip rectangle is written in the YAML's segmentation; the device set
    // gives it and PLUS's defaults for the rest.
    assert_eq!(from_yaml.segmentation, from_plus.segmentation);

    let text = std::fs::read_to_string(&yaml_path).unwrap();
    let cases = [
        // Pattern 2's right side made diagonal: not an N.
        (
            "back_in_phantom_mm: [60.0, 40.0, 10.0]",
            "back_in_phantom_mm: [70.0, 40.0, 10.0]",
            "field `phantom.nwire.patterns[1].wires`: wires `4:G3_g3` and `6:M3_m3` (the N's sides) are not parallel",
        ),
        // A scaled registration.
        (
            "[-0.0167397, -0.0153548, -0.999742, 15.6642]",
            "[-0.0334794, -0.0307096, -1.999484, 15.6642]",
            "field `phantom.nwire.reference_T_phantom`: the rotation part is not orthonormal",
        ),
        // Both a device set and patterns.
        (
            "    approximate_spacing_mm_per_px: 0.078\n",
            "    plus_config: x.xml\n",
            "field `phantom.nwire`: give exactly one of `plus_config`",
        ),
    ];
    for (from, to, want) in cases {
        let edited = text.replacen(from, to, 1);
        assert_ne!(edited, text, "edit `{from}` did not apply");
        let err = TrackedManifest::from_text(&yaml_path, &edited).unwrap_err().to_string();
        assert!(err.contains(want), "expected `{want}` in:\n{err}");
        assert!(
            err.contains("fcal2_nwire_yaml.yaml:"),
            "the error names the file and line: {err}"
        );
    }
}

/// The default tracked experiment, run by the command line: the model chosen on
/// the calibration frames, PLUS's matrix scored on the same dots and poses.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn experiment_on_plus_data_chooses_on_calibration_frames_and_compares_like_for_like() {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("plus_run");
    let r = Command::new(env!("CARGO_BIN_EXE_probecal"))
        .args(["run", "--quiet", "--force", "--out"])
        .arg(&out)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/plus_fcal2_nwire.yaml"))
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let folder = out.join("plus_fcal2_nwire/fcal2_3nwires");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(folder.join("summary.json")).unwrap()).unwrap();
    // Under the tracker's lag (less than a frame period after the image) only the
    // last frame of each sequence has no pose: its time plus the lag lies past
    // the tracker's last sample. PLUS's segmented frames less those are scored.
    let lag = summary["time_offset_s"].as_f64().unwrap();
    assert!(lag > 0.0 && lag < 0.078, "{lag}");
    let csv = std::fs::read_to_string(folder.join("frames.csv")).unwrap();
    let no_pose = |sequence: &str| -> Vec<u64> {
        csv.lines()
            .skip(1)
            .map(|l| l.splitn(6, ',').collect::<Vec<&str>>())
            .filter(|f| f[0] == sequence && f[4] == "pose")
            .map(|f| f[1].parse().unwrap())
            .collect()
    };
    assert_eq!((no_pose("calibration"), no_pose("validation")), (vec![189], vec![102]));
    let (calibration_frames, validation_frames) = (184 - 1, 103 - 1);
    let best_95 = |frames: u64| (0.95 * (3 * frames) as f64).round() as u64;
    let pre3d = summary["validation"]["pre3d_mm"]["mean"].as_f64().unwrap();
    let all = summary["validation"]["pre3d_all_mm"]["mean"].as_f64().unwrap();
    println!("validation PRE3D {pre3d:.4} mm (best 95 %), {all:.4} mm (all)");
    // PLUS's published 0.5399 mm is on PLUS's own dots without the lag: no
    // like-for-like figure, so nothing is asserted against it (the guide says so).
    assert!(all >= pre3d);
    // PLUS's matrix on the same dots, poses and convention, beside ours.
    let plus = summary["validation"]["plus_matrix_pre3d_mm"]["mean"].as_f64().unwrap();
    assert_eq!(
        summary["validation"]["plus_matrix_pre3d_mm"]["n"].as_u64().unwrap(),
        best_95(validation_frames)
    );
    assert!((pre3d - plus).abs() < 0.05, "ours {pre3d} mm, PLUS's matrix {plus} mm");
    // The two paired frame by frame: the mean difference inside its interval,
    // which is what the page's sentence reads.
    let paired = &summary["validation"]["ours_minus_plus_matrix_mm"];
    assert_eq!(paired["frames"].as_u64().unwrap(), validation_frames, "{paired}");
    let d = paired["mean"].as_f64().unwrap();
    let (lo, hi) = (
        paired["interval_90"][0].as_f64().unwrap(),
        paired["interval_90"][1].as_f64().unwrap(),
    );
    assert!(lo < d && d < hi && hi - lo < 0.1, "{paired}");
    let verdict = if hi < 0.0 {
        "probecal lower"
    } else if lo > 0.0 {
        "PLUS's matrix lower"
    } else {
        "not told apart"
    };
    let page = std::fs::read_to_string(folder.join("report.html"))
        .unwrap()
        .replace("&#x27;", "'");
    assert!(
        page.contains(&format!("{d:+.3} mm")) && page.contains(verdict),
        "{paired}"
    );
    // The lag's uncertainty carried to the validation figure: the model
    // refitted at lags across the lag's interval (the wider of the curvature's
    // and the resamples'), and at the lag applied, where it is the figure above.
    let e = &summary["time_offset_estimate"];
    let at = |v: &serde_json::Value| v.as_f64().unwrap();
    let (lo, hi) = (
        at(&e["interval_90_s"][0]).min(at(&e["coarse"]["bootstrap_lag_s"]["p5"])),
        at(&e["interval_90_s"][1]).max(at(&e["coarse"]["bootstrap_lag_s"]["p95"])),
    );
    let span = summary["validation"]["across_lag_interval"].as_array().unwrap();
    let lags: Vec<f64> = span.iter().map(|p| at(&p["lag_s"])).collect();
    assert_eq!(lags.len(), 6, "{lags:?}");
    assert!(lags.windows(2).all(|w| w[0] < w[1]), "{lags:?}");
    assert!(
        (lags[0] - lo).abs() < 1e-12 && (lags[5] - hi).abs() < 1e-12,
        "{lags:?} against {lo}..{hi}"
    );
    let applied: Vec<&serde_json::Value> = span.iter().filter(|p| p["applied"] == true).collect();
    assert_eq!(applied.len(), 1);
    assert_eq!(at(&applied[0]["lag_s"]), lag);
    assert!((at(&applied[0]["pre3d_mm"]["mean"]) - pre3d).abs() < 1e-12, "{span:?}");
    assert!(
        (at(&applied[0]["plus_matrix_pre3d_mm"]["mean"]) - plus).abs() < 1e-12,
        "{span:?}"
    );
    assert!(span
        .iter()
        .all(|p| p["pre3d_mm"]["n"] == summary["validation"]["pre3d_mm"]["n"]));
    // Across the interval the figure moves by more than the paired difference's
    // resolution: the lag's uncertainty is part of the reported accuracy.
    let means: Vec<f64> = span.iter().map(|p| at(&p["pre3d_mm"]["mean"])).collect();
    let spread =
        means.iter().copied().fold(f64::NEG_INFINITY, f64::max) - means.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(spread > 0.01 && spread < 0.2, "{means:?}");
    assert!(
        page.contains("id=\"lag-span\"")
            && page.contains(&format!(
                "{:.3} to",
                means.iter().copied().fold(f64::INFINITY, f64::min)
            ))
    );
    // The model: every candidate of the family scored on the calibration frames
    // alone, and the chosen one within one standard error of the best.
    let selection = &summary["model_selection"];
    // The frames segmented are PLUS's 184 of 190, frame for frame (less the
    // one with no pose under the lag).
    assert_eq!(selection["frames"].as_u64().unwrap(), calibration_frames);
    let compared = &summary["calibration"]["frames_compared"];
    assert_eq!(
        (
            compared["ours"].as_u64(),
            compared["both"].as_u64(),
            compared["plus"].as_u64()
        ),
        (Some(calibration_frames), Some(calibration_frames), Some(184)),
        "{compared}"
    );
    let candidates = selection["candidates"].as_array().unwrap();
    assert_eq!(candidates.len(), 6);
    let score = |c: &serde_json::Value| c["cv_pre3d_mm"]["mean"].as_f64().unwrap();
    let best = candidates.iter().min_by(|a, b| score(a).total_cmp(&score(b))).unwrap();
    let chosen = candidates
        .iter()
        .find(|c| {
            c["constraints"] == selection["chosen_constraints"] && c["pixel_model"] == selection["chosen_pixel_model"]
        })
        .unwrap();
    let se = best["cv_pre3d_mm"]["std"].as_f64().unwrap() / (best["cv_pre3d_mm"]["n"].as_f64().unwrap()).sqrt();
    assert!(score(chosen) <= score(best) + se, "{selection}");
    assert_eq!(
        summary["validation"]["pre3d_mm"]["n"].as_u64().unwrap(),
        best_95(validation_frames)
    );
    // The pixel size comes out near PLUS's 0.0803 x 0.0745 mm.
    let s = &summary["image_to_probe"]["spacing_mm_per_px"];
    assert!((s[0].as_f64().unwrap() - 0.0803).abs() < 0.002 && (s[1].as_f64().unwrap() - 0.0745).abs() < 0.002);
    for f in ["ImageToProbe.xml", "ImageToProbe.tfm", "frames.csv", "report.html"] {
        assert!(folder.join(f).is_file(), "{f}");
    }
    // What the validation score can tell: the spread of refits on resampled
    // calibration blocks, the model's floor on the validation frames, the tilts.
    let r = &summary["resolution"];
    let b = &r["bootstrap_pre3d_mm"];
    let (p5, p50, p95) = (
        b["p5"].as_f64().unwrap(),
        b["p50"].as_f64().unwrap(),
        b["p95"].as_f64().unwrap(),
    );
    assert!(p5 < p50 && p50 < p95, "{b}");
    assert_eq!(b["resamples"].as_u64().unwrap() + b["failed"].as_u64().unwrap(), 200);
    // Refits on resampled frames scatter about the fit on all of them.
    assert!(p5 < pre3d && pre3d < p95, "ours {pre3d} outside {p5}..{p95}");
    // docs/guide/plus-recording.md: PLUS's matrix scores inside that spread: on
    // these validation frames it is ahead (the paired interval below), but
    // another calibration sweep of the same hand could put either ahead.
    assert!(p5 < plus && plus < p95, "PLUS's {plus} outside {p5}..{p95}");
    let floor = r["own_fit_pre3d_mm"]["mean"].as_f64().unwrap();
    assert!(
        floor < pre3d && floor < plus,
        "floor {floor}, ours {pre3d}, PLUS's {plus}"
    );
    let c = &r["pose_coverage"];
    assert_eq!(
        c["calibration"]["frames"].as_u64(),
        summary["frames"]["calibration"]["segmented"].as_u64()
    );
    assert_eq!(c["validation"]["frames"].as_u64().unwrap(), validation_frames);
    assert!(c["validation_outside_calibration"].as_u64().unwrap() <= validation_frames);
    for sweep in ["calibration", "validation"] {
        for axis in ["lateral_deg", "axial_deg"] {
            let a = &c[sweep][axis];
            let (lo, mid, hi) = (
                a["min"].as_f64().unwrap(),
                a["median"].as_f64().unwrap(),
                a["max"].as_f64().unwrap(),
            );
            assert!(lo <= mid && mid <= hi && lo > -45.0 && hi < 45.0, "{sweep} {axis}: {a}");
        }
    }
    let page = std::fs::read_to_string(folder.join("report.html")).unwrap();
    assert!(page.contains("id=\"resolution\""), "the page has no resolution table");
    // The manifest's `reconstruct:` sweep, placed with this calibration: the
    // volume in the run folder, the wires measured, both on the page.
    let volume = &summary["reconstruction"];
    assert_eq!(volume["frames_used"], validation_frames, "{volume}");
    assert!(folder.join("reconstruction/volume.mha").is_file());
    assert_eq!(volume["wires"]["wires_measured"], 9, "{volume}");
    let position = volume["wires"]["position_error_mm"].as_f64().unwrap();
    assert!(position > 0.0 && position < 1.5, "{volume}");
    assert!(page.contains("id=\"wires\"") && page.contains("reconstruction/mean_z.png"));
    // What the recording measured, in pictures: the lag's objective, PRE3D per
    // validation frame (both matrices), the residuals in the phantom's frame,
    // the sweeps' tilts and the reconstruction; each figure's PNG beside the
    // LaTeX page that includes it.
    let tex = std::fs::read_to_string(folder.join("report.tex")).unwrap();
    for id in ["lag", "pre3d_per_frame", "residuals_in_phantom", "tilts"] {
        assert!(page.contains(&format!("<figure id=\"{id}\"><svg")), "no figure {id}");
    }
    for png in ["pre3d_per_frame", "residuals_in_phantom", "tilts", "lag_objective"] {
        assert!(
            tex.contains(&format!("{{{png}.png}}")) && folder.join(format!("{png}.png")).is_file(),
            "{png}"
        );
    }
    assert!(
        page.matches("<figure").count() >= 5,
        "{} figures",
        page.matches("<figure").count()
    );
    // The frames as segmented: used ones of both sweeps, and rejected ones
    // with the reason frames.csv gives them; each picture beside report.tex too.
    let gallery = &page[page.find("id=\"gallery\"").expect("a gallery")..];
    for words in [
        "calibration frame",
        "validation frame",
        ": used, PRE3D",
        ": rejected: segmentation: spot count",
    ] {
        assert!(gallery.contains(words), "the gallery does not say {words}");
    }
    assert!(gallery.matches("<img src=\"data:image/jpeg;base64,").count() >= 7);
    assert!(tex.contains("{gallery/frame_00.jpg}") && folder.join("gallery/frame_00.jpg").is_file());
    assert!(page.contains("PLUS&#x27;s matrix") || page.contains("PLUS's matrix"));
}

/// The first `frames` frames of the calibration sequence as a new file, with the
/// header edited by `edit` and the compressed data cut by `cut` bytes.
fn broken_copy(name: &str, edit: impl Fn(String) -> String, cut: usize) -> PathBuf {
    let bytes = std::fs::read(data(CALIBRATION)).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let at = bytes.windows(marker.len()).position(|w| w == marker).unwrap() + marker.len();
    let header = edit(String::from_utf8(bytes[..at].to_vec()).unwrap());
    let mut out = header.into_bytes();
    out.extend_from_slice(&bytes[at..bytes.len() - cut]);
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, out).unwrap();
    path
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn broken_sequences_give_clear_errors() {
    let truncated = broken_copy("truncated.igs.mha", |h| h, 200_000);
    let e = Sequence::read(&truncated).unwrap_err().to_string();
    assert!(e.contains("truncated.igs.mha") && e.contains("truncated"), "{e}");

    let mismatch = broken_copy(
        "mismatch.igs.mha",
        |h| h.replace("DimSize = 820 616 190", "DimSize = 820 616 191"),
        0,
    );
    let e = Sequence::read(&mismatch).unwrap_err().to_string();
    assert!(e.contains("mismatch.igs.mha:") && e.contains("DimSize"), "{e}");

    let status = broken_copy(
        "status.igs.mha",
        |h| {
            h.replacen(
                "Seq_Frame0005_ProbeToTrackerTransformStatus = OK",
                "Seq_Frame0005_ProbeToTrackerTransformStatus = INVALID",
                1,
            )
        },
        0,
    );
    let s = Sequence::read(&status).unwrap();
    let e = s.transform(5, "ProbeToTracker").unwrap_err();
    assert!(matches!(e, FrameFault::Status { frame: 5, .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "frame 5: `ProbeToTrackerTransformStatus` is INVALID, not OK"
    );

    let nan = broken_copy(
        "nan.igs.mha",
        |h| {
            let key = "Seq_Frame0007_ProbeToTrackerTransform = ";
            let start = h.find(key).unwrap() + key.len();
            let end = start + h[start..].find(' ').unwrap();
            format!("{}nan{}", &h[..start], &h[end..])
        },
        0,
    );
    let e = Sequence::read(&nan)
        .unwrap()
        .transform(7, "ProbeToTracker")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("frame 7") && e.contains("non-finite") && e.contains("line "),
        "{e}"
    );
}

/// The shared tracked experiment on another calibration sequence, with a fixed
/// tracker lag and no validation sequence.
fn run_shared_experiment_on(calibration: PathBuf, lag_s: f64) -> probecal::pipeline::tracked::TrackedRun {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/plus_fcal2_nwire.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let manifest = probecal::manifest::tracked::TrackedManifest::from_text(&path, &text).unwrap();
    let mut inputs = TrackedInputs::from_manifest(&manifest);
    inputs.calibration_sequence = calibration;
    inputs.validation_sequence = None;
    inputs.time_offset = probecal::manifest::tracked::TimeOffset::Fixed(lag_s);
    probecal::pipeline::tracked::run(&inputs, 20).unwrap()
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_timestamp_that_is_not_a_number_rejects_only_its_frame() {
    let broken = broken_copy(
        "nan_time.igs.mha",
        |h| {
            let key = "Seq_Frame0007_Timestamp = ";
            let start = h.find(key).unwrap() + key.len();
            let end = start + h[start..].find('\n').unwrap();
            format!("{}nan{}", &h[..start], &h[end..])
        },
        0,
    );
    let run = run_shared_experiment_on(broken, 0.05);
    let frame = run.frames.iter().find(|f| f.index == 7).unwrap();
    assert_eq!(frame.timestamp_s, None);
    let reason = frame.rejected.as_ref().map(|r| r.to_string()).unwrap_or_default();
    assert!(reason.contains("frame 7: a timestamp is missing"), "{reason}");
    assert!(run.frames.iter().filter(|f| f.rejected.is_none()).count() >= 150);
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_rigid_but_absurd_tracker_pose_rejects_only_its_frame() {
    // Frame 9's probe marker 1 km from the tracker: rigid, finite, and no measurement.
    let broken = broken_copy(
        "far.igs.mha",
        |h| {
            let key = "Seq_Frame0009_ProbeToTrackerTransform = ";
            let start = h.find(key).unwrap() + key.len();
            let end = start + h[start..].find('\n').unwrap();
            let mut m: Vec<String> = h[start..end].split_whitespace().map(String::from).collect();
            m[3] = "1000000".into();
            format!("{}{}{}", &h[..start], m.join(" "), &h[end..])
        },
        0,
    );
    let run = run_shared_experiment_on(broken, 0.0);
    let frame = run.frames.iter().find(|f| f.index == 9).unwrap();
    let reason = frame.rejected.as_ref().map(|r| r.to_string()).unwrap_or_default();
    assert!(reason.contains("tracker_T_probe puts its board 1000"), "{reason}");
    assert!(run.frames.iter().filter(|f| f.rejected.is_none()).count() >= 150);
}

/// A tracked experiment may take its lag from a reflector recording instead of
/// the grid search: the manifest names the recording, the run uses the lag
/// `probecal temporal` finds in it; a missing file is a manifest error.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_tracked_experiment_takes_its_lag_from_a_reflector_recording() {
    let dir = common::scratch("plus_nwire", "temporal_lag");
    std::fs::create_dir_all(&dir).unwrap();
    let data = |set: &str, name: &str| common::shared_data(set, name).canonicalize().unwrap();
    let text = common::fcal_manifest_text()
        .replace(
            "../../shared/data",
            &common::root()
                .join("../shared/data")
                .canonicalize()
                .unwrap()
                .display()
                .to_string(),
        )
        .replace(
            "time_offset_s: estimate",
            &format!(
                "time_offset_s: {{temporal: {{tracker: {}, video: {}}}}}",
                data(
                    "plus-temporal-watertank",
                    "WaterTankBottomTranslationTrackerBuffer.igs.mha"
                )
                .display(),
                data(
                    "plus-temporal-watertank",
                    "WaterTankBottomTranslationVideoBuffer.igs.mha"
                )
                .display()
            ),
        );
    assert!(text.contains("temporal:"));
    let manifest = dir.join("temporal.yaml");
    std::fs::write(&manifest, &text).unwrap();
    let out = dir.join("out");
    let r = common::probecal()
        .args(["run", "--quiet", "--force", "--out"])
        .arg(&out)
        .arg(&manifest)
        .output()
        .unwrap();
    // The gate may fail with another lag (exit 3); the run itself must succeed.
    assert!(
        matches!(r.status.code(), Some(0 | 3)),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("plus_fcal2_nwire/fcal2_3nwires/summary.json")).unwrap(),
    )
    .unwrap();
    let lag = summary["time_offset_s"].as_f64().unwrap();
    assert!((lag - -0.0648).abs() < 0.005, "{lag}");

    let missing = dir.join("missing.yaml");
    std::fs::write(
        &missing,
        text.replace("WaterTankBottomTranslationVideoBuffer", "NoSuchVideo"),
    )
    .unwrap();
    let r = common::probecal().arg("validate").arg(&missing).output().unwrap();
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("missing.yaml") && err.contains("time_offset_s.temporal.video"),
        "{err}"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn without_a_clip_rectangle_the_same_dots_are_found() {
    // fCal 2.0's images carry no screen overlay: with the device set's clip
    // rectangle or without one (the whole image, the overlay searched for), the
    // same frames give the same dots.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/plus_fcal2_nwire.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let manifest = probecal::manifest::tracked::TrackedManifest::from_text(&path, &text).unwrap();
    let mut inputs = TrackedInputs::from_manifest(&manifest);
    assert!(
        inputs.clip_rectangle_px.is_some(),
        "the device set gives a clip rectangle"
    );
    inputs.validation_sequence = None;
    inputs.time_offset = probecal::manifest::tracked::TimeOffset::Fixed(0.0);
    let clipped = probecal::pipeline::tracked::run(&inputs, 20).unwrap();
    inputs.clip_rectangle_px = None;
    let whole = probecal::pipeline::tracked::run(&inputs, 20).unwrap();
    assert_eq!(clipped.overlay_px, None);
    assert_eq!(whole.overlay_px, Some(0), "nothing is bright in every frame");
    assert_eq!(clipped.frames.len(), whole.frames.len());
    for (a, b) in clipped.frames.iter().zip(&whole.frames) {
        assert_eq!(a.dots_px, b.dots_px, "frame {}", a.index);
    }
}

/// `reconstruct.sweep: validation` without a validation sequence, and a
/// device set that does not exist: each named at its key, nothing run.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_reconstruct_sweep_the_manifest_cannot_give_is_refused_at_its_key() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = root.join("../shared").canonicalize().unwrap();
    let text = common::fcal_manifest_text().replace("../../shared", &shared.to_string_lossy());
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("reconstruct_key");
    std::fs::create_dir_all(&dir).unwrap();
    for (edit, key) in [
        (
            text.lines()
                .filter(|l| !l.trim_start().starts_with("validation:"))
                .collect::<Vec<_>>()
                .join("\n"),
            "reconstruct.sweep",
        ),
        (text.replace("fcal2_volume.xml", "missing.xml"), "reconstruct.config"),
    ] {
        let manifest = dir.join("m.yaml");
        std::fs::write(&manifest, edit).unwrap();
        let r = Command::new(env!("CARGO_BIN_EXE_probecal"))
            .arg("validate")
            .arg(&manifest)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(key), "want {key} in: {stderr}");
    }
}
