//! probecal reads PNG and JPEG files with the pixels OpenCV's
//! `imread(IMREAD_GRAYSCALE)` gives and writes JPEG with the bytes OpenCV's
//! `imencode(".jpg")` writes, checked against Debian's python3-opencv
//! (`tests/peers/image_codecs.py`) on PNGs of every colour type and bit depth,
//! with and without gamma, JPEGs of several kinds, and every PNG and JPEG of the
//! shared data.

use std::path::{Path, PathBuf};

fn u32_at(bytes: &[u8], k: usize) -> usize {
    u32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap()) as usize
}

/// Runs the peer into a fresh folder; `None` (with the reason printed) where
/// python3-opencv cannot run.
fn peer() -> Option<PathBuf> {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("image-codecs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = manifest.join("../shared/data");
    if !shared.join("opencv-aruco/gboriginal.png").exists() {
        println!("skipped: {} is not there", shared.display());
        return None;
    }
    let run = std::process::Command::new("/usr/bin/python3")
        .arg(manifest.join("tests/peers/image_codecs.py"))
        .arg(&out)
        .arg(&shared)
        .output();
    match run {
        Ok(o) if o.status.success() => Some(out),
        Ok(o) => {
            println!(
                "skipped: python3-opencv is not usable ({})",
                String::from_utf8_lossy(&o.stderr)
            );
            None
        }
        Err(e) => {
            println!("skipped: /usr/bin/python3 cannot run ({e})");
            None
        }
    }
}

#[test]
#[ignore = "needs ../shared/data and python3-opencv (full tier: scripts/test.sh)"]
fn every_png_and_jpeg_reads_as_opencv_reads_it_and_jpeg_writes_its_bytes() {
    let Some(out) = peer() else {
        return;
    };
    let listing = std::fs::read_to_string(out.join("cases.txt")).unwrap();
    let mut differing = Vec::new();
    let mut cases = 0;
    for line in listing.lines() {
        let (image, reference) = line.split_once('\t').unwrap();
        let want = std::fs::read(reference).unwrap();
        let (w, h) = (u32_at(&want, 0), u32_at(&want, 1));
        let got =
            probecal::io::image::mat_to_gray8(&probecal::io::image::read_gray(Path::new(image)).unwrap()).unwrap();
        cases += 1;
        if (got.width, got.height) != (w, h) || got.data != want[8..] {
            let worst = got.data.iter().zip(&want[8..]).map(|(a, b)| a.abs_diff(*b)).max();
            differing.push(format!(
                "{image}: {}x{} against {w}x{h}, worst {worst:?}",
                got.width, got.height
            ));
        }
    }
    assert!(cases >= 30, "{cases} cases");
    assert!(differing.is_empty(), "not OpenCV's pixels:\n{}", differing.join("\n"));
    for name in ["grey", "colour"] {
        let raw = std::fs::read(out.join(format!("encode_{name}.raw"))).unwrap();
        let (w, h, channels) = (u32_at(&raw, 0), u32_at(&raw, 1), u32_at(&raw, 2));
        let ours = probecal::io::jpeg::encode(&raw[12..], w, h, channels, 80).unwrap();
        let opencv = std::fs::read(out.join(format!("encode_{name}.jpg"))).unwrap();
        assert!(
            ours == opencv,
            "{name}: {} bytes, OpenCV's {}",
            ours.len(),
            opencv.len()
        );
    }
    std::fs::remove_dir_all(&out).unwrap();
}
