//! Hostile inputs, class "commands share one definition of a valid input": for
//! every recording `init` is given, `init`, `validate` and `run` agree. A
//! recording `run` refuses (a validation sequence that is the calibration's, a
//! probe transform that is the reference's, a tracker-only sequence, transforms
//! the frames do not carry) is refused by `init` (nothing written) and by
//! `validate`, with the same reason `run` gives.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{probecal, scratch, shared_data};

const SET: &str = "plus-fcal2.0-3nwires";
const CONFIG: &str = "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml";
const CALIBRATION: &str = "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha";
const VALIDATION: &str = "fCal_Test_Validation_3NWires_fCal2.0.igs.mha";

/// The calibration sequence with its images taken out (`DimSize = 0 0 n`, no
/// pixels): a tracker-only recording, which the sequence reader accepts.
fn tracker_only(dir: &Path) -> PathBuf {
    let bytes = std::fs::read(shared_data(SET, CALIBRATION)).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header: String = String::from_utf8_lossy(&bytes[..end])
        .lines()
        .filter(|l| !l.starts_with("CompressedDataSize"))
        .map(|l| match l {
            l if l.starts_with("DimSize") => format!("DimSize = 0 0 {}", l.split_whitespace().last().unwrap()),
            l if l.starts_with("CompressedData") => "CompressedData = False".into(),
            l => l.to_string(),
        })
        .map(|l| l + "\n")
        .collect();
    let path = dir.join("tracker_only.igs.mha");
    std::fs::write(&path, [header.as_bytes(), marker].concat()).unwrap();
    path
}

fn probecal_in(dir: &Path, args: &[&str]) -> Output {
    probecal().current_dir(dir).args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `init` with `extra` refuses with `reason` and writes nothing; the manifest
/// `init` writes from the good recording, edited by `edit`, is refused by
/// `validate` and by `run` with the same reason.
fn agree(dir: &Path, name: &str, extra: &[&str], edit: &dyn Fn(String) -> String, reason: &str) {
    let config = shared_data(SET, CONFIG).display().to_string();
    let calibration = shared_data(SET, CALIBRATION).display().to_string();
    let manifest = format!("{name}.yaml");
    let mut args = vec!["init", "--plus-config", &config, "--out", &manifest];
    if !extra.contains(&"--calibration") {
        args.extend(["--calibration", &calibration]);
    }
    args.extend(extra);
    let o = probecal_in(dir, &args);
    assert_eq!(o.status.code(), Some(2), "init {name}: {}", stderr(&o));
    assert!(stderr(&o).contains(reason), "init {name}: {}", stderr(&o));
    assert!(!dir.join(&manifest).exists(), "init {name} wrote its manifest");
    let good = probecal_in(
        dir,
        &[
            "init",
            "--plus-config",
            &config,
            "--calibration",
            &calibration,
            "--out",
            &manifest,
        ],
    );
    assert!(good.status.success(), "{}", stderr(&good));
    let text = std::fs::read_to_string(dir.join(&manifest)).unwrap();
    let edited = edit(text.clone());
    assert_ne!(edited, text, "{name}: the edit changed nothing");
    std::fs::write(dir.join(&manifest), edited).unwrap();
    let o = probecal_in(dir, &["validate", &manifest]);
    assert_eq!(o.status.code(), Some(2), "validate {name}: {}", stderr(&o));
    assert!(stderr(&o).contains(reason), "validate {name}: {}", stderr(&o));
    let o = probecal_in(dir, &["run", &manifest, "--out", &format!("runs_{name}"), "--quiet"]);
    assert!(!o.status.success(), "run {name} succeeded");
    assert!(stderr(&o).contains(reason), "run {name}: {}", stderr(&o));
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn init_validate_and_run_refuse_the_same_recordings() {
    let dir = scratch("hostile_manifests", "agree");
    std::fs::create_dir_all(&dir).unwrap();
    let calibration = shared_data(SET, CALIBRATION).display().to_string();
    let validation = shared_data(SET, VALIDATION).display().to_string();
    let with_validation = |path: String| {
        move |t: String| {
            t.lines()
                .map(|l| match l.trim_start().starts_with("# validation:") {
                    true => format!("    validation: {path}"),
                    false => l.to_string(),
                })
                .collect::<Vec<_>>()
                .join("\n")
                + "\n"
        }
    };
    agree(
        &dir,
        "same",
        &["--validation", &calibration],
        &with_validation(calibration.clone()),
        "is the calibration sequence (the same file or the same bytes)",
    );
    agree(
        &dir,
        "equal",
        &[
            "--probe-transform",
            "ReferenceToTracker",
            "--reference-transform",
            "ReferenceToTracker",
        ],
        &|t: String| t.replace("probe_transform: ProbeToTracker", "probe_transform: ReferenceToTracker"),
        "the probe's transform too",
    );
    let only = tracker_only(&dir).display().to_string();
    agree(
        &dir,
        "tracker_only",
        &["--calibration", &only],
        &|t: String| t.replace(&calibration, &only),
        "hold no image (0x0 px: a tracker-only recording?)",
    );
    agree(
        &dir,
        "tracker_only_validation",
        &["--validation", &only],
        &with_validation(only.clone()),
        "hold no image (0x0 px: a tracker-only recording?)",
    );
    // Transforms the frames do not carry: init names what they carry; validate and run alike.
    agree(
        &dir,
        "absent",
        &[
            "--probe-transform",
            "NeedleToTracker",
            "--reference-transform",
            "ReferenceToTracker",
        ],
        &|t: String| t.replace("probe_transform: ProbeToTracker", "probe_transform: NeedleToTracker"),
        "NeedleToTracker",
    );
    // The good recording with a held-out validation passes all three.
    let o = probecal_in(
        &dir,
        &[
            "init",
            "--plus-config",
            &shared_data(SET, CONFIG).display().to_string(),
            "--calibration",
            &calibration,
            "--validation",
            &validation,
            "--out",
            "good.yaml",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = probecal_in(&dir, &["validate", "good.yaml"]);
    assert!(o.status.success(), "{}", stderr(&o));
}
