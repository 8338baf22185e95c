//! Hostile inputs, class "output protection sees every path a command reads":
//! the files named inside a manifest or a device set (the phantom's device set,
//! a reconstruction's importance mask) are guarded as the paths on the command
//! line are: `--force` never replaces a folder holding one, for `run`, `live`
//! (replay and stream) and `reconstruct` alike.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{probecal, root, scratch, shared_data};

const NWIRE: &str = "plus-fcal2.0-3nwires";
const DEVICE_SET: &str = "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml";

fn write(path: &Path, bytes: &[u8]) -> PathBuf {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
    path.to_path_buf()
}

/// The fCal experiment with absolute paths, its phantom's device set at
/// `device_set` and its reconstruction's at `volume` (which names `mask`).
fn manifest(dir: &Path, device_set: &Path, volume: &Path, mask: &Path) -> PathBuf {
    let shared = root().join("../shared").canonicalize().unwrap();
    let mut text = common::fcal_manifest_text().replace("../../shared", &shared.display().to_string());
    let original = format!("{}/data/{NWIRE}/{DEVICE_SET}", shared.display());
    assert!(text.contains(&original));
    text = text.replace(&original, &device_set.display().to_string());
    let local = root().join("experiments/plus/fcal2_volume.xml").display().to_string();
    assert!(text.contains(&local));
    text = text.replace(&local, &volume.display().to_string());
    write(device_set, &std::fs::read(shared_data(NWIRE, DEVICE_SET)).unwrap());
    let config = std::fs::read_to_string(root().join("experiments/plus/fcal2_volume.xml")).unwrap();
    let named = config.replacen(
        "<VolumeReconstruction ",
        &format!("<VolumeReconstruction ImportanceMaskFilename=\"{}\" ", mask.display()),
        1,
    );
    assert_ne!(named, config);
    write(volume, named.as_bytes());
    write(mask, b"a mask");
    write(&dir.join("fcal.yaml"), text.as_bytes())
}

fn refused(o: &Output, named: &Path) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    let name = named.file_name().unwrap().to_string_lossy();
    assert!(stderr.contains(name.as_ref()), "{stderr}");
    assert!(named.exists(), "{} was deleted", named.display());
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_file_named_inside_a_manifest_or_a_device_set_is_never_replaced() {
    let dir = scratch("hostile_outputs", "named");
    let held = dir.join("held");
    // The phantom's device set inside the folder `live` would replace.
    let device_set = held.join("device_set.xml");
    let m = manifest(&dir, &device_set, &dir.join("volume.xml"), &dir.join("mask.png"));
    for extra in [&[][..], &["--igtl", "127.0.0.1:9"][..]] {
        let o = probecal()
            .arg("live")
            .arg(&m)
            .args(extra)
            .arg("--out")
            .arg(&held)
            .arg("--force")
            .output()
            .unwrap();
        refused(&o, &device_set);
    }
    // The reconstruction's importance mask inside the experiment's folder `run` would replace.
    let runs = dir.join("runs");
    let mask = runs.join("plus_fcal2_nwire/mask.png");
    let m = manifest(&dir, &dir.join("device_set.xml"), &dir.join("volume.xml"), &mask);
    let o = probecal()
        .arg("run")
        .arg(&m)
        .arg("--out")
        .arg(&runs)
        .arg("--force")
        .output()
        .unwrap();
    refused(&o, &mask);
    // A device set for `reconstruct` naming a mask inside its --out.
    let out = dir.join("recon");
    let mask = out.join("mask.png");
    let _ = manifest(&dir, &dir.join("device_set.xml"), &dir.join("volume.xml"), &mask);
    let o = probecal()
        .arg("reconstruct")
        .arg(shared_data(NWIRE, "fCal_Test_Validation_3NWires_fCal2.0.igs.mha"))
        .arg("--config")
        .arg(dir.join("volume.xml"))
        .arg("--out")
        .arg(&out)
        .arg("--force")
        .output()
        .unwrap();
    refused(&o, &mask);
}

/// Single-file writers replace an existing file only with `--force`:
/// `calibrate-camera` wrote over any file named by `--out`.
#[test]
fn a_single_file_writer_replaces_an_existing_file_only_with_force() {
    let dir = scratch("hostile_outputs", "single_file");
    let notes = write(&dir.join("notes.yml"), b"my notes");
    let o = probecal()
        .args(["calibrate-camera", "--board", "9x6", "--square-mm", "25", "--out"])
        .arg(&notes)
        .arg(dir.join("no_such_photo.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("exists; pass --force to replace it"), "{stderr}");
    assert_eq!(std::fs::read(&notes).unwrap(), b"my notes");
}
