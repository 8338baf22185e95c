//! Hostile inputs, class "limits cap each declared size, not what the sizes
//! cost": a file's declared size is believed only as far as its bytes bear it
//! out. A 200-byte `--compare` volume whose header claims 2048³ voxels, and
//! /dev/zero (which has no size and no end), are refused at once, in bounded
//! memory (the command runs under a 2 GiB address-space limit here).

mod common;

use std::io::Write;
use std::path::Path;

use common::{scratch, shared_data};

const SET: &str = "plus-volume-reconstruction";

/// `reconstruct --compare <reference>` under a 2 GiB address space (the
/// binary under test, started through sh for its limit): exit code and stderr.
fn compare_with(dir: &Path, reference: &Path) -> (Option<i32>, String) {
    let command = format!(
        "ulimit -v 2097152; exec '{}' reconstruct '{}' --config '{}' --compare '{}' --out '{}'",
        env!("CARGO_BIN_EXE_probecal"),
        shared_data(SET, "SpinePhantomFreehand.igs.mha").display(),
        shared_data(SET, "PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_NN_MEAN.xml").display(),
        reference.display(),
        dir.join("out").display()
    );
    let o = std::process::Command::new("sh")
        .args(["-c", &command])
        .output()
        .unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_volume_header_is_believed_only_as_far_as_its_bytes_go() {
    if !shared_data(SET, "SpinePhantomFreehand.igs.mha").exists() {
        eprintln!("skipped: the shared data is absent");
        return;
    }
    let dir = scratch("hostile_sizes", "compare");
    std::fs::create_dir_all(&dir).unwrap();
    let bomb = dir.join("bomb.mha");
    let mut f = std::fs::File::create(&bomb).unwrap();
    f.write_all(
        b"ObjectType = Image\nNDims = 3\nDimSize = 2048 2048 2048\nElementType = MET_UCHAR\n\
          ElementSpacing = 1 1 1\nOffset = 0 0 0\nCompressedData = True\nElementDataFile = LOCAL\n",
    )
    .unwrap();
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(&[0u8; 1000]).unwrap();
    f.write_all(&z.finish().unwrap()).unwrap();
    drop(f);
    for (reference, words) in [
        (bomb.as_path(), "1000 bytes of voxels, 8589934592 expected"),
        (
            Path::new("/dev/zero"),
            "no `ElementDataFile = LOCAL` line in its first 1024 KiB",
        ),
    ] {
        let started = std::time::Instant::now();
        let (code, stderr) = compare_with(&dir, reference);
        assert_eq!(code, Some(2), "{}: {stderr}", reference.display());
        assert!(stderr.contains(words), "{}: {stderr}", reference.display());
        assert!(started.elapsed().as_secs() < 60, "{}", reference.display());
        assert!(!dir.join("out").exists());
    }
}

/// An `OutputSpacing` of 1e-300 mm made the grid's voxel count overflow (a
/// panic): refused at its line, with the accepted range.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_spacing_that_would_overflow_the_grid_is_refused_at_its_line() {
    let config = shared_data(SET, "PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_NN_MEAN.xml");
    if !config.exists() {
        eprintln!("skipped: the shared data is absent");
        return;
    }
    let dir = scratch("hostile_sizes", "spacing");
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(&config).unwrap();
    let at = text.find("OutputSpacing=\"").unwrap() + "OutputSpacing=\"".len();
    let end = at + text[at..].find('"').unwrap();
    let edited = format!("{}1e-300 1e-300 1e-300{}", &text[..at], &text[end..]);
    let line = text[..at].lines().count();
    let path = dir.join("DeviceSet.xml");
    std::fs::write(&path, edited).unwrap();
    let o = common::probecal()
        .arg("reconstruct")
        .arg(shared_data(SET, "SpinePhantomFreehand.igs.mha"))
        .arg("--config")
        .arg(&path)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "DeviceSet.xml:{line}: `OutputSpacing` must be 3 numbers in [0.001, 100] mm"
        )),
        "{stderr}"
    );
}

/// `probecal <args>` under a 768 MiB address space and a 30 s limit: exit code,
/// stderr, and how long it took.
fn bounded(args: &[String]) -> (Option<i32>, String, std::time::Duration) {
    let start = std::time::Instant::now();
    let o = common::probecal_bounded(args, 786_432, 30);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        start.elapsed(),
    )
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn every_reader_believes_no_size_it_has_not_read() {
    let dir = scratch("hostile_sizes", "readers");
    std::fs::create_dir_all(&dir).unwrap();
    let s = |p: &Path| p.display().to_string();
    let nwire = |name: &str| s(&shared_data("plus-fcal2.0-3nwires", name));
    let device_set = nwire("PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml");
    let sweep = nwire("fCal_Test_Calibration_3NWires_fCal2.0.igs.mha");
    let volume_config = s(&shared_data(
        SET,
        "PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_NN_MEAN.xml",
    ));
    // A 60-byte dictionary whose markers would be 40000 bits a side (OpenCV
    // allocates for them before it reads one).
    let dictionary = dir.join("dictionary.yml");
    std::fs::write(
        &dictionary,
        "%YAML:1.0\n---\nnmarkers: 1\nmarkersize: 40000\nmarker_0: \"1\"\n",
    )
    .unwrap();
    let photo = s(&shared_data("opencv-aruco", "choriginal.jpg"));
    let out = |name: &str| s(&dir.join(name));
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["validate".into(), "/dev/zero".into()],
            "larger than any such file probecal reads",
        ),
        (
            vec![
                "segment".into(),
                sweep.clone(),
                "--config".into(),
                "/dev/zero".into(),
                "--out".into(),
                out("a"),
            ],
            "larger than any such file probecal reads",
        ),
        (
            vec![
                "segment".into(),
                "/dev/zero".into(),
                "--config".into(),
                device_set,
                "--out".into(),
                out("b"),
            ],
            "/dev/zero:1",
        ),
        (
            vec![
                "reconstruct".into(),
                "/dev/zero".into(),
                "--config".into(),
                volume_config,
                "--out".into(),
                out("c"),
            ],
            "/dev/zero:1",
        ),
        (
            vec!["study".into(), "compare".into(), "/dev/zero".into(), "/dev/zero".into()],
            "larger than any such file probecal reads",
        ),
        (
            vec![
                "calibrate-camera".into(),
                "--charuco".into(),
                "5x7".into(),
                "--square-mm".into(),
                "30".into(),
                "--marker-mm".into(),
                "15".into(),
                "--dictionary".into(),
                s(&dictionary),
                "--out".into(),
                out("camera.yml"),
                photo,
            ],
            "`markersize: 40000`",
        ),
    ];
    for (args, expect) in cases {
        let (code, stderr, took) = bounded(&args);
        assert!(matches!(code, Some(1 | 2)), "{args:?}: exit {code:?}: {stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(took < std::time::Duration::from_secs(20), "{args:?}: {took:?}");
    }
}
