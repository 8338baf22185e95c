//! `probecal live <camera manifest> --watch DIR`: frames taken from a folder
//! while another process writes them, photos written in two pieces (as a
//! camera's software may), and the session's final all-frames calibration equal
//! to the batch run's on the same folder.

mod common;

use std::io::Write;
use std::path::Path;
use std::time::Duration;

use common::{probecal, root, scratch};

fn copy_in_two_pieces(from: &Path, to: &Path) {
    let bytes = std::fs::read(from).unwrap();
    let mut file = std::fs::File::create(to).unwrap();
    file.write_all(&bytes[..bytes.len() / 2]).unwrap();
    file.flush().unwrap();
    std::thread::sleep(Duration::from_millis(40));
    file.write_all(&bytes[bytes.len() / 2..]).unwrap();
}

#[test]
#[ignore = "renders the default dataset and replays it into a folder (full tier: scripts/test.sh)"]
fn frames_written_into_a_folder_give_the_batch_calibration() {
    let base = scratch("live_folder", "session");
    let datasets = base.join("datasets");
    let manifest = root().join("experiments/hemisphere_checkerboard.yaml");
    let r = probecal()
        .arg("synth")
        .arg(&manifest)
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let source = datasets.join("hemisphere_checkerboard__dataset3");
    let watched = base.join("incoming");
    std::fs::create_dir_all(watched.join("frames")).unwrap();
    std::fs::create_dir_all(watched.join("camera_calibration")).unwrap();
    for entry in std::fs::read_dir(source.join("camera_calibration")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(
            &path,
            watched.join("camera_calibration").join(path.file_name().unwrap()),
        )
        .unwrap();
    }
    let out = base.join("live");
    let session = probecal()
        .arg("live")
        .arg(&manifest)
        .arg("--watch")
        .arg(&watched)
        .arg("--idle-s")
        .arg("30")
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let list = std::fs::read_to_string(source.join("frames.csv")).unwrap();
    let mut frames = 0;
    for line in list.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        std::fs::copy(source.join(fields[2]), watched.join(fields[2])).unwrap();
        copy_in_two_pieces(&source.join(fields[1]), &watched.join(fields[1]));
        frames += 1;
    }
    std::fs::write(watched.join("frames.csv"), &list).unwrap();
    let done = session.wait_with_output().unwrap();
    assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    // The typed results model holds every field written.
    let typed: probecal::results::live::FolderSummary = serde_json::from_value(summary.clone()).unwrap();
    assert_eq!(serde_json::to_value(&typed).unwrap(), summary);
    assert_eq!(summary["ended_by"], "frame_list");
    assert_eq!(summary["frames"].as_u64().unwrap(), frames);
    let difference = summary["live_minus_batch_max_abs"].as_f64().unwrap();
    assert!(
        difference < 1e-9,
        "live and batch all-frames fits differ by {difference}"
    );
    // Every frame was read whole: a frame rejected for an unreadable image would
    // mean a photo was taken before its second piece was written.
    let csv = std::fs::read_to_string(out.join("live.csv")).unwrap();
    assert_eq!(csv.lines().count() as u64, frames + 1);
    assert!(!csv.contains("decodable"), "{csv}");
    // The occluded photo's frame keeps its reason; the others are used.
    let used = summary["frames_used"].as_u64().unwrap();
    let rejected: Vec<&str> = csv
        .lines()
        .skip(1)
        .filter(|l| l.split(',').nth(4) != Some(""))
        .collect();
    assert_eq!(used + rejected.len() as u64, frames, "{csv}");
    assert!(rejected.iter().all(|l| l.contains("board")), "{rejected:?}");
}

#[test]
fn a_watch_needs_an_existing_folder_and_a_sensible_idle_time() {
    let out = scratch("live_folder", "refused");
    let camera = root().join("experiments/hemisphere_checkerboard.yaml");
    let cases: [(&str, &str, i32, &str); 3] = [
        (
            "/nonexistent-folder-for-live",
            "10",
            1,
            "the watched folder does not exist",
        ),
        ("/tmp", "0", 2, "invalid value '0' for '--idle-s <IDLE_S>'"),
        ("/tmp", "nan", 2, "invalid value 'nan' for '--idle-s <IDLE_S>'"),
    ];
    for (folder, idle, code, message) in cases {
        let r = probecal()
            .arg("live")
            .arg(&camera)
            .args(["--watch", folder, "--idle-s", idle, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(code), "{stderr}");
        assert!(stderr.contains(message), "{stderr}");
        assert!(!out.exists(), "nothing is written on a refusal");
    }
}

#[test]
fn a_camera_solved_again_from_the_frames_is_refused_live() {
    // Live calibration updates after each frame; the frames' boards refine the
    // camera only once every frame is in, so `live` refuses it rather than
    // calibrate with other intrinsics than the batch run.
    let base = scratch("live_folder", "refine_with_frames");
    std::fs::create_dir_all(&base).unwrap();
    let text = std::fs::read_to_string(root().join("experiments/hemisphere_checkerboard.yaml"))
        .unwrap()
        .replacen(
            "    square_mm: 30.0\n",
            "    square_mm: 30.0\n    refine_with_frames: true\n",
            1,
        );
    assert!(text.contains("refine_with_frames"), "the edit did not apply");
    let manifest = base.join("experiment.yaml");
    std::fs::write(&manifest, &text).unwrap();
    let out = base.join("out");
    let r = probecal()
        .arg("live")
        .arg(&manifest)
        .args(["--watch", "/tmp", "--idle-s", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("refine_with_frames"), "{stderr}");
    assert!(!out.exists(), "nothing is written on a refusal");
}
