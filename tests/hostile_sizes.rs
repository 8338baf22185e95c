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
