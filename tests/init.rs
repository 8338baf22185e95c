//! `probecal init`: a manifest for a recording the project has not seen runs
//! with no edit. The PLUS recording is fCal 2.0's with every transform and frame
//! renamed (another lab's names: `TransducerHolderToOpticalCamera`, …), so the
//! names must come from the files; the folders are rendered ones, read as
//! recorded folders.

mod common;

use std::path::Path;

use common::{probecal, root, scratch, shared_data};

const SET: &str = "plus-fcal2.0-3nwires";

/// `source` copied to `out` with each `(from, to)` replaced in its text part
/// (a sequence's header, or the whole of a configuration).
fn renamed_copy(source: &Path, out: &Path, names: &[(&str, &str)]) {
    let bytes = std::fs::read(source).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .unwrap_or(bytes.len());
    let mut text = String::from_utf8(bytes[..end].to_vec()).unwrap();
    for (from, to) in names {
        text = text.replace(from, to);
    }
    let mut data = text.into_bytes();
    data.extend_from_slice(&bytes[end..]);
    std::fs::write(out, data).unwrap();
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
#[ignore = "needs ../shared/data (full tier scripts/test.sh)"]
fn a_plus_recording_with_other_names_runs_from_its_init_manifest_unedited() {
    let dir = scratch("init", "plus");
    std::fs::create_dir_all(&dir).unwrap();
    let sequence_names = [
        ("ProbeToTracker", "TransducerHolderToOpticalCamera"),
        ("ReferenceToTracker", "PhantomMarkerToOpticalCamera"),
        ("StylusToTracker", "PointerToOpticalCamera"),
    ];
    let config_names = [
        ("\"Probe\"", "\"TransducerHolder\""),
        ("\"Reference\"", "\"PhantomMarker\""),
    ];
    let calibration = dir.join("session_cal.igs.mha");
    let validation = dir.join("session_val.igs.mha");
    let config = dir.join("DeviceSet.xml");
    let shared_calibration = shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha");
    if !shared_calibration.exists() {
        eprintln!("skipped: {} is absent", shared_calibration.display());
        return;
    }
    renamed_copy(&shared_calibration, &calibration, &sequence_names);
    renamed_copy(
        &shared_data(SET, "fCal_Test_Validation_3NWires_fCal2.0.igs.mha"),
        &validation,
        &sequence_names,
    );
    renamed_copy(
        &shared_data(SET, "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml"),
        &config,
        &config_names,
    );
    let plus_result = dir.join("PlusResult.xml");
    std::fs::copy(
        shared_data(SET, "FreehandCalibration3NWires_fCal2.0.results.xml"),
        &plus_result,
    )
    .unwrap();
    let manifest = dir.join("mine.yaml");
    let init = |result: &Path| {
        probecal()
            .args(["init", "--plus-config"])
            .arg(&config)
            .arg("--calibration")
            .arg(&calibration)
            .arg("--validation")
            .arg(&validation)
            .arg("--plus-result")
            .arg(result)
            .arg("--out")
            .arg(&manifest)
            .output()
            .unwrap()
    };
    // A PLUS result that is not one is refused, naming it, and nothing is written.
    let r = init(&config);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("DeviceSet.xml"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    assert!(!manifest.exists());
    let r = init(&plus_result);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = std::fs::read_to_string(&manifest).unwrap();
    assert!(text.contains("\ncompare_with_plus_result: PlusResult.xml"), "{text}");
    assert!(
        text.contains("probe_transform: TransducerHolderToOpticalCamera"),
        "{text}"
    );
    assert!(text.contains("reference_frame: PhantomMarker"), "{text}");
    assert!(
        text.contains("calibration: session_cal.igs.mha"),
        "paths relative to the manifest:\n{text}"
    );
    // A second init does not overwrite it.
    let again = probecal()
        .args(["init", "--plus-config"])
        .arg(&config)
        .arg("--calibration")
        .arg(&calibration)
        .arg("--out")
        .arg(&manifest)
        .output()
        .unwrap();
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));

    let out = dir.join("runs");
    let r = probecal()
        .arg("run")
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // The same recording under its own names gives the committed experiment's result.
    let ours = json(&out.join("mine/session_cal/summary.json"));
    let committed = json(&root().join("reports/plus_fcal2_nwire/fcal2_3nwires/summary.json"));
    for key in ["mean", "std", "n"] {
        assert_eq!(
            ours["validation"]["pre3d_mm"][key], committed["validation"]["pre3d_mm"][key],
            "validation PRE3D {key}"
        );
        // --plus-result: PLUS's matrix compared on the same dots, as the committed run does.
        assert_eq!(
            ours["validation"]["plus_matrix_pre3d_mm"][key], committed["validation"]["plus_matrix_pre3d_mm"][key],
            "PLUS's matrix's validation PRE3D {key}"
        );
    }
    assert!(out.join("mine/session_cal/ImageToProbe.tfm").is_file());

    // A second experiment run into the same folder: the index links both runs.
    let second = dir.join("second.yaml");
    std::fs::write(&second, text.replace("experiment: mine", "experiment: second")).unwrap();
    let r = probecal()
        .arg("run")
        .arg(&second)
        .arg("--out")
        .arg(&out)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let index = std::fs::read_to_string(out.join("index.html"))
        .unwrap()
        .replace("&#x2F;", "/");
    for link in ["mine/session_cal/report.html", "second/session_cal/report.html"] {
        assert!(index.contains(link), "index.html does not link {link}:\n{index}");
    }
    // The index fits the kind of run: PRE3D named as such, both sequences'
    // counts, "no gate" where none was set, and no thesis chapter (none of its
    // experiments ran here).
    let pre3d = format!(
        "validation PRE3D {:.3}",
        ours["validation"]["pre3d_mm"]["mean"].as_f64().unwrap()
    );
    for words in [
        "tracked recording",
        pre3d.as_str(),
        "calibration 183 / 190, validation 102 / 103",
        ">no gate<",
    ] {
        assert!(index.contains(words), "index.html does not say {words}:\n{index}");
    }
    assert!(!index.contains("BRE 0") && !index.contains(">pass<"), "{index}");
    assert!(
        !index.contains("thesis.html") && !out.join("thesis.html").exists(),
        "{index}"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier scripts/test.sh)"]
fn a_recording_without_a_reference_pose_is_refused_with_the_names_it_has() {
    // PLUS's VLCUS segmentation data: a stepper's ToolToTracker, no phantom marker.
    let set = "plus-segmentation-vlcus";
    let sequence = shared_data(set, "SegmentationTest_VLCUS_RandomStepperMotionData2.igs.mha");
    if !sequence.exists() {
        eprintln!("skipped: {} is absent", sequence.display());
        return;
    }
    let dir = scratch("init", "vlcus");
    let manifest = dir.join("vlcus.yaml");
    let r = probecal()
        .args(["init", "--plus-config"])
        .arg(shared_data(
            set,
            "PlusDeviceSet_iCal_CalibrationOnly_VLCUS_FrameGrabber.xml",
        ))
        .arg("--calibration")
        .arg(&sequence)
        .arg("--out")
        .arg(&manifest)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("SegmentationTest_VLCUS_RandomStepperMotionData2.igs.mha")
            && stderr.contains("ToolToTracker")
            && stderr.contains("--probe-transform"),
        "{stderr}"
    );
    assert!(!manifest.exists(), "nothing is written on an error");
}

/// Renders `experiment`'s dataset into `datasets`, moves it to `my_session/`,
/// then runs the README's three commands as written, from the folder that
/// holds it, relative paths and all (`init --folder my_session --out mine.yaml`,
/// `validate mine.yaml`, `run mine.yaml --out runs/mine`); the run's summary.
fn init_and_run_folder(name: &str, experiment: &str, dataset: &str, prepare: fn(&Path)) -> serde_json::Value {
    let dir = scratch("init", name);
    let datasets = dir.join("datasets");
    let r = probecal()
        .arg("synth")
        .arg(root().join("experiments").join(format!("{experiment}.yaml")))
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let folder = dir.join("my_session");
    std::fs::rename(datasets.join(format!("{experiment}__{dataset}")), &folder).unwrap();
    prepare(&folder);
    let command = |args: &[&str]| {
        let r = probecal().current_dir(&dir).args(args).output().unwrap();
        assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
    };
    command(&["init", "--folder", "my_session", "--out", "mine.yaml"]);
    let text = std::fs::read_to_string(dir.join("mine.yaml")).unwrap();
    assert!(text.contains("GUESS"), "the guesses are marked:\n{text}");
    command(&["validate", "mine.yaml"]);
    command(&["run", "mine.yaml", "--out", "runs/mine", "--quiet"]);
    json(&dir.join("runs/mine/mine/my_session/summary.json"))
}

#[test]
#[ignore = "renders a dataset and runs it (full tier scripts/test.sh)"]
fn a_folder_of_photos_and_bscans_runs_from_its_init_manifest() {
    let summary = init_and_run_folder("camera", "hemisphere_checkerboard", "dataset3", |_| {});
    // The rendered rig is the source study's, which is what init guesses: the run
    // finds the camera board's corner count itself and calibrates as the experiment does.
    assert!(
        summary["frames"]["used"].as_u64().unwrap() >= 40,
        "{}",
        summary["frames"]
    );
    assert!(summary["truth"]["corner_error_mm"]["mean"].as_f64().unwrap() < 1.0);
    assert!(
        summary["camera"]["views_used"].as_u64().unwrap() >= 10,
        "{}",
        summary["camera"]
    );
}

#[test]
#[ignore = "renders a dataset and runs it (full tier scripts/test.sh)"]
fn a_folder_of_tracker_poses_and_bscans_runs_from_its_init_manifest() {
    // A tracker's recording: no photos, no camera calibration, the poses in a CSV.
    let summary = init_and_run_folder("tracker", "hemisphere_tracker_csv", "dataset3", |folder| {
        std::fs::remove_dir_all(folder.join("camera_calibration")).unwrap();
        let list = std::fs::read_to_string(folder.join("frames.csv")).unwrap();
        let without_photos: Vec<String> = list
            .lines()
            .enumerate()
            .map(|(i, line)| {
                let cells: Vec<&str> = line.split(',').collect();
                if i == 0 {
                    line.to_string()
                } else {
                    format!("{},,{}", cells[0], cells[2])
                }
            })
            .collect();
        std::fs::write(folder.join("frames.csv"), without_photos.join("\n") + "\n").unwrap();
    });
    assert!(
        summary["frames"]["used"].as_u64().unwrap() >= 40,
        "{}",
        summary["frames"]
    );
    assert!(
        summary["camera"].is_null() || summary["camera"]["views_used"].is_null(),
        "{}",
        summary["camera"]
    );
}
