//! The command line end to end on a small rendered experiment: files, keys of
//! summary.json, accuracy against the truth, the HTML page, and manifest errors.

mod common;

use common::probecal;

use std::path::{Path, PathBuf};

use serde_json::Value;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hemisphere_small.yaml")
}

fn tmp(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
#[ignore = "runs an experiment (full tier: scripts/test.sh)"]
fn run_writes_the_tables_summary_and_page() {
    let out = tmp("run");
    let datasets = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end_datasets");
    // A study written beside the runs earlier is linked from the index.
    std::fs::create_dir_all(out.join("study/variant_a")).unwrap();
    std::fs::write(out.join("study/variant_a/study.html"), "<html></html>").unwrap();
    // A study's results as `probecal study` writes them (a committed one).
    std::fs::copy(
        common::root().join("reports/study/spheres/study.json"),
        out.join("study/variant_a/study.json"),
    )
    .unwrap();
    std::fs::create_dir_all(out.join("study/variant_b")).unwrap();
    std::fs::write(out.join("study/variant_b/study.html"), "<html></html>").unwrap();
    // And one in a group of studies.
    std::fs::create_dir_all(out.join("study/group/variant_c")).unwrap();
    std::fs::write(out.join("study/group/variant_c/study.html"), "<html></html>").unwrap();
    let result = probecal()
        .arg("run")
        .arg(fixture())
        .arg("--out")
        .arg(&out)
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&result.stdout);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(result.status.success(), "exit {:?}\n{stdout}\n{stderr}", result.status);
    // The thesis's tables are printed.
    assert!(
        stdout.contains("Std.") && stdout.contains("Mean") && stdout.contains("<∞ (") && stdout.contains("<1 ("),
        "{stdout}"
    );

    let run = out.join("hemisphere_small/small");
    for file in [
        "frames.csv",
        "frames.parquet",
        "summary.json",
        "report.html",
        "report_context.json",
        "camera_intrinsics.yml",
    ] {
        assert!(run.join(file).is_file(), "{file} missing in {}", run.display());
    }
    assert!(out.join("hemisphere_small/manifest.yaml").is_file());
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(index.contains("study&#x2F;variant_a&#x2F;study.html"), "{index}");
    assert!(
        index.contains("Monte Carlo accuracy study of spheres_checkerboard (10 seeds, 1000–1009)"),
        "{index}"
    );
    // Without a readable study.json the folder's name stands for it.
    assert!(index.contains("study&#x2F;variant_b&#x2F;study.html"), "{index}");
    assert!(index.contains("Study: variant b"), "{index}");
    assert!(
        index.contains("study&#x2F;group&#x2F;variant_c&#x2F;study.html"),
        "{index}"
    );
    assert!(!index.contains("study&#x2F;group&#x2F;study.html"), "{index}");

    let summary: Value = serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["experiment"], "hemisphere_small");
    assert_eq!(summary["dataset"], "small");
    let frames = &summary["frames"];
    assert_eq!(frames["total"], 14);
    assert_eq!(
        frames["used"].as_u64().unwrap() + frames["rejected"].as_u64().unwrap(),
        14
    );
    let m = summary["calibration"]["marker_T_image"].as_array().unwrap();
    assert_eq!(m.len(), 4);
    assert_eq!(m[3], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
    assert_eq!(summary["calibration"]["scale_mm_per_px"], serde_json::json!([0.2, 0.2]));
    for axis in ["x", "y", "z"] {
        for stat in ["mean", "std", "min", "max"] {
            assert!(
                summary["bre_mm"][axis][stat].is_number(),
                "bre_mm.{axis}.{stat} missing"
            );
        }
    }
    let corner_mean = summary["truth"]["corner_error_mm"]["mean"].as_f64().unwrap();
    let corner_max = summary["truth"]["corner_error_mm"]["max"].as_f64().unwrap();
    let rotation = summary["truth"]["rotation_error_deg"].as_f64().unwrap();
    println!(
        "small experiment: corner error mean {corner_mean:.3} mm, max {corner_max:.3} mm, rotation {rotation:.3} deg"
    );
    // 11 or so frames with elevation offsets of ~0.5 mm: a coarse bound; the default
    // experiment's accuracy is checked in `default_experiment_meets_its_gates`.
    assert!(
        corner_mean < 2.5 && rotation < 2.5,
        "corner {corner_mean} mm, rotation {rotation} deg"
    );
    assert_eq!(summary["thresholds"].as_array().unwrap().len(), 4);
    assert_eq!(summary["thresholds"][0]["cutoff_mm"], "inf");

    // Every rejected frame keeps its stage and reason.
    let csv = std::fs::read_to_string(run.join("frames.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let status = header.iter().position(|h| *h == "status").unwrap();
    let reason = header.iter().position(|h| *h == "reason").unwrap();
    for line in csv.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        if fields[status] == "rejected" {
            assert!(!fields[reason].is_empty(), "rejected frame without a reason: {line}");
        }
    }

    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(html.contains("id=\"bre-table\"") && html.contains("id=\"threshold-table\"") && html.contains("<svg"));

    // A second run into the same folder is refused without --force.
    let again = probecal()
        .arg("run")
        .arg(fixture())
        .arg("--out")
        .arg(&out)
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("pass --force"));
}

#[test]
#[ignore = "runs an experiment twice (full tier: scripts/test.sh)"]
fn same_inputs_give_identical_outputs() {
    let datasets = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end_datasets_det");
    let a = tmp("det_a");
    let b = tmp("det_b");
    for out in [&a, &b] {
        let r = probecal()
            .arg("run")
            .arg(fixture())
            .arg("--out")
            .arg(out)
            .arg("--datasets")
            .arg(&datasets)
            .arg("--quiet")
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    for file in ["frames.csv", "summary.json", "report.html"] {
        let one = std::fs::read(a.join("hemisphere_small/small").join(file)).unwrap();
        let two = std::fs::read(b.join("hemisphere_small/small").join(file)).unwrap();
        assert!(one == two, "{file} differs between two runs");
    }
}

#[test]
fn manifest_errors_stop_before_any_work() {
    let dir = tmp("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(fixture())
        .unwrap()
        .replace("radius_mm: 15.0", "radius_mm: -15.0")
        .replace("square_mm: 30.0", "square_mm: 30.0\n    colour: red");
    let bad = dir.join("bad.yaml");
    std::fs::write(&bad, text).unwrap();
    for command in ["validate", "run", "synth"] {
        let r = probecal()
            .arg(command)
            .arg(&bad)
            .arg("--datasets")
            .arg(dir.join("datasets"))
            .output();
        let r = if command == "validate" {
            probecal().arg(command).arg(&bad).output()
        } else {
            r
        }
        .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{command}: {stderr}");
        assert!(
            stderr.contains("bad.yaml:") && stderr.contains("field `camera.calibrate.colour`"),
            "{command}: {stderr}"
        );
    }
    assert!(!dir.join("datasets").exists(), "work was done despite a bad manifest");
    let fixed = std::fs::read_to_string(&bad).unwrap().replace("\n    colour: red", "");
    std::fs::write(&bad, fixed).unwrap();
    let r = probecal().arg("validate").arg(&bad).output().unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(
        stderr.contains("bad.yaml:7: field `phantom.hemisphere.radius_mm`: must be a positive number"),
        "{stderr}"
    );
}

#[test]
#[ignore = "runs the default experiment (full tier: scripts/test.sh)"]
fn default_experiment_meets_its_gates() {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/hemisphere_checkerboard.yaml");
    let out = tmp("default");
    let datasets = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end_datasets_default");
    let r = probecal()
        .arg("run")
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "exit {:?} (3 = a gate failed)\n{stderr}", r.status);
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("hemisphere_checkerboard/dataset3/summary.json")).unwrap(),
    )
    .unwrap();
    let corner = summary["truth"]["corner_error_mm"]["mean"].as_f64().unwrap();
    let rotation = summary["truth"]["rotation_error_deg"].as_f64().unwrap();
    println!(
        "default experiment: corner error {corner:.3} mm, rotation {rotation:.3} deg, frames {}",
        summary["frames"]
    );
    assert!(
        corner <= 1.0 && rotation <= 0.5,
        "corner {corner} mm, rotation {rotation} deg"
    );
    for gate in summary["gates"].as_array().unwrap() {
        assert_eq!(gate["passed"], true, "{gate}");
    }
}

/// A recorded dataset is a folder with frames.csv and images; here the small
/// rendered dataset copied without its ground truth, with intrinsics from a file.
#[test]
#[ignore = "runs an experiment (full tier: scripts/test.sh)"]
fn recorded_folder_dataset_runs_without_truth() {
    let base = tmp("recorded");
    let datasets = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end_datasets_recorded");
    let synth = probecal()
        .arg("synth")
        .arg(fixture())
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    assert!(synth.status.success(), "{}", String::from_utf8_lossy(&synth.stderr));
    let rendered = datasets.join("hemisphere_small__small");
    let recorded = base.join("lab/session1");
    std::fs::create_dir_all(recorded.join("frames")).unwrap();
    std::fs::copy(rendered.join("frames.csv"), recorded.join("frames.csv")).unwrap();
    for entry in std::fs::read_dir(rendered.join("frames")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, recorded.join("frames").join(path.file_name().unwrap())).unwrap();
    }
    // Intrinsics from a file, as a lab would have them from an earlier calibration.
    let cal = probecal()
        .args(["calibrate-camera", "--board", "9x6", "--square-mm", "30", "--out"])
        .arg(base.join("lab/camera.yml"))
        .arg(rendered.join("camera_calibration"))
        .output()
        .unwrap();
    assert!(cal.status.success(), "{}", String::from_utf8_lossy(&cal.stderr));
    let text = std::fs::read_to_string(fixture())
        .unwrap()
        .replace("  calibrate:\n    inner_corners: [9, 6]\n    square_mm: 30.0\n", "  intrinsics_file: camera.yml\n")
        .replace("    render:\n      seed: 11\n      frames: 14\n      calibration_views: 8\n      bscan: {outlier_rate: 0.15, missing_rate: 0.1}\n", "    folder: session1\n");
    let manifest = base.join("lab/recorded.yaml");
    std::fs::write(&manifest, text).unwrap();
    let out = base.join("out");
    let r = probecal()
        .arg("run")
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .arg("--datasets")
        .arg(base.join("unused"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    // The fixture's truth gate cannot be evaluated without truth: exit 3, reported.
    assert_eq!(r.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("truth_corner_error_mm = missing"), "{stderr}");
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("hemisphere_small/small/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["rendered"], false);
    assert!(summary.get("truth").is_none());
    assert!(
        summary["frames"]["used"].as_u64().unwrap() >= 8,
        "{}",
        summary["frames"]
    );
    assert!(
        !base.join("unused").exists(),
        "nothing is rendered for a recorded dataset"
    );
}

/// The ArUco rig on the same probe motion as the checkerboard rig, side by side.
#[test]
#[ignore = "runs two experiments (full tier: scripts/test.sh)"]
fn compare_checkerboard_and_aruco_on_the_same_motion() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = tmp("compare");
    let datasets = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end_datasets_compare");
    let r = probecal()
        .arg("compare")
        .arg(root.join("experiments/hemisphere_checkerboard.yaml"))
        .arg(root.join("experiments/hemisphere_aruco.yaml"))
        .arg("--out")
        .arg(&out)
        .arg("--datasets")
        .arg(&datasets)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let table = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(
        table.contains("hemisphere_checkerboard / dataset3 (checkerboard 11x11 squares of 13 mm)"),
        "{table}"
    );
    assert!(
        table.contains("hemisphere_aruco / dataset3 (ArUco DICT_4X4_50 4x4 markers of 30 mm)"),
        "{table}"
    );
    for row in [
        "frames used / total",
        "probe board reprojection RMS (px)",
        "BRE y Mean (mm)",
        "truth: image corners mean (mm)",
        "probe rotation error × lever arm (mm)",
    ] {
        assert!(table.contains(&format!("| {row} |")), "row `{row}` missing");
    }
    assert!(out.join("compare.html").is_file());
    // The index, written again after the comparison into this new folder, links it.
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(index.contains("<a href=\"compare.html\">"), "{index}");
    let aruco: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("hemisphere_aruco/dataset3/summary.json")).unwrap())
            .unwrap();
    let corner = aruco["truth"]["corner_error_mm"]["mean"].as_f64().unwrap();
    println!("ArUco rig: corner error {corner:.3} mm, frames {}", aruco["frames"]);
    assert!(corner <= 1.5, "ArUco corner error {corner} mm");
    // Same motion: the two datasets share their B-scans' probe poses.
    let truth = |name: &str| -> Value {
        serde_json::from_str(&std::fs::read_to_string(datasets.join(name).join("ground_truth.json")).unwrap()).unwrap()
    };
    let (a, b) = (
        truth("hemisphere_checkerboard__dataset3"),
        truth("hemisphere_aruco__dataset3"),
    );
    for k in [0, 17, 49] {
        let pa = &a["frames"][k]["centre_projection_px"];
        let pb = &b["frames"][k]["centre_projection_px"];
        let d = (pa[0].as_f64().unwrap() - pb[0].as_f64().unwrap()).abs()
            + (pa[1].as_f64().unwrap() - pb[1].as_f64().unwrap()).abs();
        assert!(
            d < 1.0,
            "frame {k}: the feature is at different pixels in the two rigs' datasets"
        );
    }
}

#[test]
fn resolve_reproduces_the_committed_default_run() {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/hemisphere_checkerboard/dataset3");
    let out = probecal().arg("resolve").arg(&folder).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("(the same calibration)"), "{stdout}");
}

#[test]
fn resolve_notices_inputs_that_do_not_give_the_reported_calibration() {
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/hemisphere_checkerboard/dataset3");
    let folder = tmp("resolve_tampered");
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::copy(committed.join("summary.json"), folder.join("summary.json")).unwrap();
    let inputs = std::fs::read_to_string(committed.join("solve_inputs.yaml")).unwrap();
    // One feature pixel moved by a tenth of a pixel: a different calibration.
    let at = inputs.find("  - pixel:\n    - ").unwrap() + "  - pixel:\n    - ".len();
    let end = at + inputs[at..].find('\n').unwrap();
    let moved: f64 = inputs[at..end].parse::<f64>().unwrap() + 0.1;
    let tampered = format!("{}{moved}{}", &inputs[..at], &inputs[end..]);
    std::fs::write(folder.join("solve_inputs.yaml"), tampered).unwrap();
    let out = probecal().arg("resolve").arg(&folder).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("NOT the calibration the run reports"), "{stdout}");
    // A broken file names the file and the field.
    std::fs::write(
        folder.join("solve_inputs.yaml"),
        inputs.replace("cutoff_rule: max_axis", "cutoff_rule: 7"),
    )
    .unwrap();
    let out = probecal().arg("resolve").arg(&folder).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("solve_inputs.yaml") && stderr.contains("cutoff_rule"),
        "{stderr}"
    );
}
