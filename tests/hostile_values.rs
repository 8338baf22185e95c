//! Hostile inputs, class "a check belongs to a reader, not to the kind of
//! value": a transform the tracked run refuses (scaled, mirrored, projective,
//! singular) is refused the same by `reconstruct`, whichever file it comes
//! from, and a calibration given in place of the device set's is the one used.

mod common;

use std::path::{Path, PathBuf};

use common::{probecal, scratch, shared_data};
use serde_json::Value;

const SET: &str = "plus-volume-reconstruction";
const SWEEP: &str = "SpinePhantomFreehand.igs.mha";
const CONFIG: &str = "PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_NN_MEAN.xml";

/// The sweep with its header edited by `edit` (the pixels untouched).
fn edited_sweep(dir: &Path, name: &str, edit: impl Fn(&str) -> String) -> PathBuf {
    let bytes = std::fs::read(shared_data(SET, SWEEP)).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header = edit(&String::from_utf8_lossy(&bytes[..end]));
    let path = dir.join(name);
    std::fs::write(&path, [header.as_bytes(), &bytes[end..]].concat()).unwrap();
    path
}

/// `reconstruct` of `sequence` into `dir/<out>` with `extra` arguments: its
/// exit code, stderr and summary.json (when written).
fn reconstruct(dir: &Path, sequence: &Path, out: &str, extra: &[&str]) -> (Option<i32>, String, Option<Value>) {
    let r = probecal()
        .arg("reconstruct")
        .arg(sequence)
        .arg("--config")
        .arg(shared_data(SET, CONFIG))
        .args(extra)
        .arg("--out")
        .arg(dir.join(out))
        .output()
        .unwrap();
    let summary = std::fs::read_to_string(dir.join(out).join("summary.json"))
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap());
    (
        r.status.code(),
        String::from_utf8_lossy(&r.stderr).into_owned(),
        summary,
    )
}

fn available() -> bool {
    let there = shared_data(SET, SWEEP).exists();
    if !there {
        eprintln!("skipped: {} is absent", shared_data(SET, SWEEP).display());
    }
    there
}

/// A tracker pose scaled, or mirrored, in one frame: that frame is left out
/// with the reason, as the tracked run leaves it out; the volume is made of
/// the others.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_tracker_pose_that_is_not_rigid_leaves_its_frame_out() {
    if !available() {
        return;
    }
    let dir = scratch("hostile_values", "not_rigid");
    std::fs::create_dir_all(&dir).unwrap();
    let line = |frame: usize| format!("Seq_Frame{frame:04}_ProbeToTrackerTransform = ");
    let scaled = edited_sweep(&dir, "scaled.igs.mha", |h| {
        // Frame 3's rotation part times 2, frame 7's first axis mirrored.
        h.lines()
            .map(|l| match l.strip_prefix(&line(3)).or(l.strip_prefix(&line(7))) {
                Some(values) => {
                    let mut v: Vec<f64> = values.split_whitespace().map(|x| x.parse().unwrap()).collect();
                    if l.starts_with(&line(3)) {
                        for r in 0..3 {
                            for c in 0..3 {
                                v[r * 4 + c] *= 2.0;
                            }
                        }
                    } else {
                        for r in 0..3 {
                            v[r * 4] = -v[r * 4];
                        }
                    }
                    let text: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                    format!("{}{}", &l[..line(3).len()], text.join(" "))
                }
                None => l.to_string(),
            })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    });
    let (code, stderr, summary) = reconstruct(&dir, &scaled, "out", &[]);
    assert_eq!(code, Some(0), "{stderr}");
    let summary = summary.unwrap();
    let skipped = summary["frames"]["skipped"].as_array().unwrap();
    let reasons: Vec<(u64, &str)> = skipped
        .iter()
        .map(|s| (s["index"].as_u64().unwrap(), s["reason"].as_str().unwrap()))
        .collect();
    assert_eq!(
        reasons.iter().map(|r| r.0).collect::<Vec<_>>(),
        vec![3, 7],
        "{reasons:?}"
    );
    assert!(
        reasons
            .iter()
            .all(|r| r.1.contains("ProbeToTracker") && r.1.contains("rigid")),
        "{reasons:?}"
    );
    assert_eq!(summary["frames"]["used"], 19);
}

/// A calibration that is no affine transform (projective, all zero, not a
/// number) is refused where it is read, naming the file and the field, and
/// nothing is written; from a run folder and from a PLUS result alike.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_calibration_that_is_not_affine_is_refused_where_it_is_read() {
    if !available() {
        return;
    }
    let dir = scratch("hostile_values", "calibration");
    std::fs::create_dir_all(&dir).unwrap();
    let sweep = shared_data(SET, SWEEP);
    let good = [
        [0.0, 0.08, 0.0, 10.0],
        [-0.08, 0.0, 0.0, 50.0],
        [0.0, 0.0, 0.08, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut projective = good;
    projective[3][0] = 0.01;
    // All zero but the last row: no axes at all.
    let mut zero = [[0.0; 4]; 4];
    zero[3][3] = 1.0;
    for (name, rows, words) in [
        ("projective", projective, "the last row is"),
        ("zero", zero, "singular"),
    ] {
        let run = dir.join(name);
        std::fs::create_dir_all(&run).unwrap();
        let summary = common::tracked_summary_with_matrix(serde_json::json!(rows));
        std::fs::write(run.join("summary.json"), summary).unwrap();
        let out = format!("out_{name}");
        let (code, stderr, _) = reconstruct(&dir, &sweep, &out, &["--calibration", run.to_str().unwrap()]);
        assert_eq!(code, Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains(&run.join("summary.json").display().to_string())
                && stderr.contains("image_to_probe.matrix")
                && stderr.contains(words),
            "{name}: {stderr}"
        );
        assert!(!dir.join(&out).exists(), "{name}: something was written");
    }
    // A PLUS result whose ImageToProbe is projective, refused at its line.
    let text: String = projective.iter().flatten().map(|v| format!("{v} ")).collect();
    let xml = dir.join("Result.xml");
    std::fs::write(
        &xml,
        format!("<PlusConfiguration>\n<CoordinateDefinitions>\n<Transform From=\"Image\" To=\"Probe\"\n Matrix=\"{text}\" />\n</CoordinateDefinitions>\n</PlusConfiguration>\n"),
    )
    .unwrap();
    let (code, stderr, _) = reconstruct(&dir, &sweep, "out_xml", &["--calibration", xml.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("Result.xml:3") && stderr.contains("the last row is"),
        "{stderr}"
    );
}

/// Frames that carry their own image transform: a calibration given with
/// `--calibration` is the one that places the image (the summary names it as
/// the source, and the volume follows it), not the frames' own.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_given_calibration_places_the_image_even_where_the_frames_carry_one() {
    if !available() {
        return;
    }
    let dir = scratch("hostile_values", "own_image");
    std::fs::create_dir_all(&dir).unwrap();
    // Every frame's own ImageToReference, the same in all: a recording whose
    // images were placed by its own software.
    let own = "0.1 0 0 250 0 0.1 0 90 0 0 0.1 0 0 0 0 1";
    let sweep = edited_sweep(&dir, "own.igs.mha", |h| {
        h.lines()
            .flat_map(|l| {
                let mut out = vec![l.to_string()];
                if let Some(frame) = l.strip_suffix("_ImageStatus = OK") {
                    out.push(format!("{frame}_ImageToReferenceTransform = {own}"));
                    out.push(format!("{frame}_ImageToReferenceTransformStatus = OK"));
                }
                out
            })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    });
    let run = dir.join("run");
    std::fs::create_dir_all(&run).unwrap();
    let given = [
        [0.0, 0.05, 0.0, 0.0],
        [0.05, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.05, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let summary = common::tracked_summary_with_matrix(serde_json::json!(given));
    std::fs::write(run.join("summary.json"), summary).unwrap();
    let (code, stderr, plain) = reconstruct(&dir, &sweep, "plain", &[]);
    assert_eq!(code, Some(0), "{stderr}");
    let (code, stderr, calibrated) = reconstruct(&dir, &sweep, "given", &["--calibration", run.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{stderr}");
    let (plain, calibrated) = (plain.unwrap(), calibrated.unwrap());
    assert_ne!(
        plain["volume"]["dims"], calibrated["volume"]["dims"],
        "the given calibration changed nothing"
    );
    // The frames' own placement puts every image in one plane: one voxel
    // thick; placed by the given calibration and the tracker, the sweep fills
    // a volume.
    let thinnest = |s: &Value| {
        s["volume"]["dims"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| d.as_u64().unwrap())
            .min()
            .unwrap()
    };
    assert!(
        thinnest(&plain) <= 2 && thinnest(&calibrated) > 10,
        "{plain} {calibrated}"
    );
}

/// The sweep as 32-bit float samples, in the byte order `big_endian` says,
/// with `poison` written over one sample of one frame (frame, sample index).
fn float_sweep(dir: &Path, name: &str, big_endian: bool, poison: Option<(usize, usize, f32)>) -> PathBuf {
    let bytes = std::fs::read(shared_data(SET, SWEEP)).unwrap();
    let sequence = probecal::io::plus::sequence::Sequence::parse(Path::new(SWEEP), &bytes).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let msb = if big_endian { "True" } else { "False" };
    let header = String::from_utf8_lossy(&bytes[..end])
        .replace("ElementType = MET_UCHAR", "ElementType = MET_FLOAT")
        .replace("CompressedData = True", "CompressedData = False")
        .replace(
            "BinaryDataByteOrderMSB = False",
            &format!("BinaryDataByteOrderMSB = {msb}"),
        )
        // The samples are written as read (flipped to MF): say so.
        .replace("UltrasoundImageOrientation = MFA", "UltrasoundImageOrientation = MF")
        .lines()
        .filter(|l| !l.starts_with("CompressedDataSize"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = format!("{header}\nElementDataFile = LOCAL\n").into_bytes();
    for i in 0..sequence.frames.len() {
        for (k, p) in sequence.pixels(i).iter().enumerate() {
            let v = match poison {
                Some((frame, at, v)) if frame == i && at == k => v,
                _ => f32::from(*p),
            };
            out.extend_from_slice(&if big_endian { v.to_be_bytes() } else { v.to_le_bytes() });
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, out).unwrap();
    path
}

/// Float samples: a big-endian file (`BinaryDataByteOrderMSB = True`) gives the
/// volume its little-endian twin gives (the order was ignored: garbage voxels,
/// exit 0), and a sample that is not a finite number is refused with its frame
/// and pixel (it gave non-finite voxels, exit 0).
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn float_samples_are_read_in_their_byte_order_and_must_be_finite() {
    if !available() {
        return;
    }
    let dir = scratch("hostile_values", "float");
    std::fs::create_dir_all(&dir).unwrap();
    let little = float_sweep(&dir, "little.igs.mha", false, None);
    let big = float_sweep(&dir, "big.igs.mha", true, None);
    for (sequence, out) in [(&little, "little"), (&big, "big")] {
        let (code, stderr, _) = reconstruct(&dir, sequence, out, &[]);
        assert_eq!(code, Some(0), "{out}: {stderr}");
    }
    let volume = |out: &str| std::fs::read(dir.join(out).join("volume.mha")).unwrap();
    assert!(
        volume("little") == volume("big"),
        "the big-endian file gives another volume"
    );
    for v in [f32::NAN, f32::INFINITY] {
        let poisoned = float_sweep(&dir, "poisoned.igs.mha", false, Some((5, 820 * 3 + 7, v)));
        let (code, stderr, _) = reconstruct(&dir, &poisoned, "poisoned", &[]);
        assert_eq!(code, Some(2), "{v}: {stderr}");
        assert!(
            stderr.contains("frame 5: the sample at column 7, row 3") && stderr.contains("not a finite number"),
            "{v}: {stderr}"
        );
        assert!(!dir.join("poisoned").exists());
    }
}

/// A volume no pixel reached (a given extent far from the sweep) is no
/// reconstruction: refused, nothing written (an empty volume was written with
/// exit 0 and no word).
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_volume_no_pixel_reached_is_refused() {
    if !available() {
        return;
    }
    let dir = scratch("hostile_values", "empty");
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(shared_data(SET, CONFIG)).unwrap();
    let far = text.replacen(
        "OutputSpacing=",
        "OutputOrigin=\"5000 5000 5000\" OutputExtent=\"0 10 0 10 0 10\" OutputSpacing=",
        1,
    );
    assert_ne!(far, text);
    let config = dir.join("far.xml");
    std::fs::write(&config, far).unwrap();
    let o = probecal()
        .arg("reconstruct")
        .arg(shared_data(SET, SWEEP))
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("21 frames placed, but no pixel was inserted"),
        "{stderr}"
    );
    assert!(!dir.join("out").exists());
}

/// The memory a volume's work takes, not only its voxel count, is held to one
/// budget before anything is allocated: float frames at 0.07 mm give about
/// 0.6 billion voxels (under the voxel limit) whose float voxels, weights,
/// hole filling and written copy need 8 GiB.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_volume_beyond_the_work_budget_is_refused_before_it_is_allocated() {
    if !available() {
        return;
    }
    let dir = scratch("hostile_values", "budget");
    std::fs::create_dir_all(&dir).unwrap();
    let sweep = float_sweep(&dir, "float.igs.mha", false, None);
    let text = std::fs::read_to_string(shared_data(SET, CONFIG)).unwrap();
    let fine = text.replace("OutputSpacing=\"0.5 0.5 0.5\"", "OutputSpacing=\"0.07 0.07 0.07\"");
    assert_ne!(fine, text);
    let config = dir.join("fine.xml");
    std::fs::write(&config, fine).unwrap();
    let args: Vec<String> = ["reconstruct".into(), sweep.display().to_string(), "--config".into()]
        .into_iter()
        .chain([
            config.display().to_string(),
            "--out".into(),
            dir.join("out").display().to_string(),
        ])
        .collect();
    let o = common::probecal_bounded(&args, 8_388_608, 60);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("fine.xml"), "{stderr}");
    assert!(
        stderr.contains("more than the 6 GiB a reconstruction may hold"),
        "{stderr}"
    );
    assert!(!dir.join("out").exists());
}
