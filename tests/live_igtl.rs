//! `probecal live --igtl`: PLUS's fCal 2.0 calibration sweep broadcast over
//! OpenIGTLink by pyigtl (an implementation independent of probecal's) at 4x
//! real time; the calibration sent back equals `probecal run`'s on the same
//! file, every frame sent is accounted for, and the received sequence re-runs
//! offline to the same matrix. Malformed messages (bad CRC, bodies that contradict
//! their sizes, unknown types) are counted skips; a cut or a silence ends the
//! acquisition and says so. Streams that fail under a session are in
//! `hostile_streams.rs`.

mod common;

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

#[path = "igtl/serve.rs"]
mod serve;

use common::{probecal, root, scratch, shared_data};
use probecal::io::igtl::message::{self, Body, HEADER_BYTES};
use probecal::io::plus::sequence::Sequence;
use serve::{json, manifest, serve, serve_with, stream, CALIBRATION, SET};

fn matrix(v: &serde_json::Value) -> nalgebra::Matrix4<f64> {
    nalgebra::Matrix4::from_fn(|r, c| v[r][c].as_f64().unwrap())
}

/// The largest distance between where two ImageToProbe matrices put the
/// corners of an 820x616 image, mm.
fn corner_distance_mm(a: &nalgebra::Matrix4<f64>, b: &nalgebra::Matrix4<f64>) -> f64 {
    [[0.0, 0.0], [819.0, 0.0], [0.0, 615.0], [819.0, 615.0]]
        .iter()
        .map(|[u, v]| {
            let p = nalgebra::Vector4::new(*u, *v, 0.0, 1.0);
            (a * p - b * p).norm()
        })
        .fold(0.0, f64::max)
}

fn pyigtl_python() -> PathBuf {
    let venv = std::env::var("PROBECAL_PYIGTL_VENV").unwrap_or_else(|_| "/var/tmp/probecal-pyigtl".into());
    let python = Path::new(&venv).join("bin/python3");
    assert!(
        python.exists(),
        "{}: no pyigtl environment; scripts/setup.sh makes it",
        python.display()
    );
    python
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

fn run_matrix(manifest: &Path, out: &Path) -> nalgebra::Matrix4<f64> {
    let o = probecal()
        .arg("run")
        .arg(manifest)
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = json(&out.join("plus_fcal2_nwire/fcal2_3nwires/summary.json"));
    matrix(&summary["image_to_probe"]["matrix"])
}

#[test]
#[ignore = "needs ../shared/data and pyigtl (full tier: scripts/test.sh)"]
fn a_pyigtl_stream_at_4x_calibrates_as_run_does_and_gets_the_matrix_back() {
    let dir = scratch("live_igtl", "pyigtl");
    let port = free_port();
    let report = dir.join("server.json");
    let mut server = Command::new(pyigtl_python())
        .arg(root().join("tests/igtl/replay_server.py"))
        .arg(shared_data(SET, CALIBRATION))
        .args(["--port", &port.to_string(), "--speed", "4", "--report"])
        .arg(&report)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(server.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert_eq!(line.trim(), "listening");
    let live = probecal()
        .arg("live")
        .arg(root().join("experiments/plus_fcal2_nwire.yaml"))
        .args(["--igtl", &format!("127.0.0.1:{port}"), "--out"])
        .arg(dir.join("live"))
        .output()
        .unwrap();
    let status = finish(server, &live);
    assert!(live.status.success(), "{}", String::from_utf8_lossy(&live.stderr));
    assert!(status.success());
    let sent = json(&report);
    let s = json(&dir.join("live/summary.json"));
    // The typed results model holds every field written.
    let typed: probecal::results::live::IgtlSummary = serde_json::from_value(s.clone()).unwrap();
    assert_eq!(serde_json::to_value(&typed).unwrap(), s);
    // Every frame sent is received, paired and accounted for.
    assert_eq!(sent["images_sent"], 190);
    assert_eq!(s["images_received"], sent["images_sent"]);
    assert_eq!(s["frames"], 190);
    assert_eq!(s["frames_without_pose"], 0);
    assert_eq!(s["messages"]["skipped"], 0);
    let by = &s["messages"]["by_device"];
    let transforms: u64 = ["ProbeToTracker", "ReferenceToTracker", "StylusToTracker"]
        .iter()
        .map(|n| by[format!("TRANSFORM {n}")].as_u64().unwrap())
        .sum();
    assert_eq!(transforms, sent["transforms_sent"].as_u64().unwrap());
    assert_eq!(s["messages"]["ignored"]["TRANSFORM StylusToTracker"], 190);
    assert!(s["ended_by"].as_str().unwrap().contains("SequenceEnd"));
    // The matrix sent back (float32 on the wire) is the session's calibration...
    let ours = matrix(&s["image_to_probe_matrix"]);
    let received = matrix(&sent["image_to_probe"]);
    assert!(corner_distance_mm(&ours, &received) < 1e-3);
    // ...which places the image corners within 0.05 mm of `probecal run`'s.
    let batch = run_matrix(&root().join("experiments/plus_fcal2_nwire.yaml"), &dir.join("run"));
    let d = corner_distance_mm(&ours, &batch);
    assert!(d < 0.05, "corners {d} mm from probecal run's");
    // The received frames re-run offline to the same matrix.
    let received_file = dir.join("live/received.igs.mha");
    let again = run_matrix(
        &manifest(&dir, "offline", Some(&received_file), ""),
        &dir.join("offline"),
    );
    assert!(corner_distance_mm(&ours, &again) < 1e-9);
    assert!(dir.join("live/calibration/report.html").exists());
    let rows = std::fs::read_to_string(dir.join("live/live.csv")).unwrap();
    assert_eq!(rows.lines().count(), 191);
}

/// A server process's exit once probecal has ended: given 60 s to finish its
/// stream, then killed and the test failed with probecal's stderr, so a client
/// that never connected fails the test instead of hanging it.
fn finish(mut server: std::process::Child, client: &Output) -> std::process::ExitStatus {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        if let Some(status) = server.try_wait().unwrap() {
            return status;
        }
        if std::time::Instant::now() > deadline {
            let _ = server.kill();
            let _ = server.wait();
            panic!(
                "the server was still waiting 60 s after probecal ended ({}): {}",
                client.status,
                String::from_utf8_lossy(&client.stderr)
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn malformed_messages_are_skipped_with_their_reasons_and_counted() {
    let dir = scratch("live_igtl", "hostile");
    let m = nalgebra::Matrix4::identity();
    let mut bad_crc = message::encode("TRANSFORM", "ProbeToTracker", 1.0, &message::transform_body(&m));
    *bad_crc.last_mut().unwrap() ^= 0x55;
    // An IMAGE whose pixels are one short of its size (the CRC is right).
    let mut short = message::image_body([820, 616, 1], [1.0; 3], [0.0; 3], &vec![0; 820 * 616]);
    short.pop();
    let short = message::encode("IMAGE", "Image", 2573.0, &short);
    let small = message::encode(
        "IMAGE",
        "Image",
        2573.01,
        &message::image_body([10, 10, 1], [1.0; 3], [0.0; 3], &[0; 100]),
    );
    let unknown = message::encode("FOO", "Image", 1.0, b"bar");
    let status = message::encode("STATUS", "Tracker", 1.0, &[0; 31]);
    let end = message::encode("STRING", "SequenceEnd", 0.0, &message::string_body("end"));
    let hostile = vec![bad_crc, short, small, unknown, status];
    let path = manifest(&dir, "hostile", None, "");
    let (out, replies) = serve(
        &dir,
        &path,
        [stream(40, &hostile), vec![end]].concat(),
        Vec::new(),
        true,
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("3 message(s) skipped"), "{stderr}");
    let s = json(&dir.join("live/summary.json"));
    assert_eq!(s["frames"], 40);
    assert_eq!(s["images_received"], 41);
    let reasons = s["messages"]["skip_reasons"].to_string();
    assert!(reasons.contains("CRC-64"), "{reasons}");
    assert!(
        reasons.contains("needs 505120 bytes of pixels, the body holds 505119"),
        "{reasons}"
    );
    assert!(
        reasons.contains("a 10x10 image in a stream of 820x616 images"),
        "{reasons}"
    );
    assert_eq!(s["messages"]["ignored"]["FOO Image"], 1);
    assert_eq!(s["messages"]["statuses"].as_array().unwrap().len(), 1);
    // The calibration came back as a TRANSFORM `ImageToProbe`.
    assert_eq!(replies.len(), 1);
    let (header, body) = replies.into_iter().next().unwrap();
    assert_eq!(
        (header.kind.as_str(), header.device.as_str()),
        ("TRANSFORM", "ImageToProbe")
    );
    let Body::Transform(sent) = body else {
        panic!("not a transform")
    };
    assert!(corner_distance_mm(&sent, &matrix(&s["image_to_probe_matrix"])) < 1e-3);
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_cut_or_silent_stream_ends_the_acquisition_and_says_so() {
    let dir = scratch("live_igtl", "cut");
    let path = manifest(&dir, "cut", None, "");
    let mut half = message::encode("IMAGE", "Image", 3000.0, &[0; 1000]);
    half.truncate(HEADER_BYTES + 400);
    let (out, _) = serve(&dir, &path, stream(30, &[]), half, false);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = json(&dir.join("live/summary.json"));
    let ended = s["ended_by"].as_str().unwrap();
    assert!(
        ended.contains("400 bytes into the 1000-byte body of a IMAGE message"),
        "{ended}"
    );
    assert!(s["sent_error"].as_str().unwrap().contains("not sent"));
    assert_eq!(s["frames"], 30);
    // A server that goes quiet: the manifest's silence ends it, and the
    // calibration is still sent back on the open connection.
    let quiet = manifest(&dir, "quiet", None, "live:\n  silence_s: 1.5\n");
    let (out, replies) = serve(&dir, &quiet, stream(30, &[]), Vec::new(), true);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = json(&dir.join("live/summary.json"));
    assert!(s["ended_by"].as_str().unwrap().contains("1.5 s without a message"));
    assert_eq!(replies.len(), 1);
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn bad_settings_and_no_server_are_said_before_anything_is_written() {
    let dir = scratch("live_igtl", "settings");
    let bad = manifest(
        &dir,
        "bad",
        None,
        "live:\n  silence_s: -1\n  send_device: ImageToProbeWithAVeryLongName\n",
    );
    let out = probecal()
        .arg("live")
        .arg(&bad)
        .args(["--igtl", "127.0.0.1:1", "--out"])
        .arg(dir.join("live"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines = std::fs::read_to_string(&bad).unwrap().lines().count();
    assert!(
        stderr.contains("live.silence_s") && stderr.contains("at most 3600"),
        "{stderr}"
    );
    assert!(stderr.contains(&format!(":{}", lines - 1)), "names the line: {stderr}");
    assert!(
        stderr.contains("live.send_device") && stderr.contains("1 to 20"),
        "{stderr}"
    );
    let camera = probecal()
        .arg("live")
        .arg(root().join("experiments/hemisphere_checkerboard.yaml"))
        .args(["--igtl", "127.0.0.1:1", "--out"])
        .arg(dir.join("live"))
        .output()
        .unwrap();
    assert_eq!(camera.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&camera.stderr).contains("--igtl takes a tracked manifest"));
    // Nothing listens on the port: a clear error, nothing written.
    let port = free_port();
    let good = manifest(&dir, "good", None, "");
    let none = probecal()
        .arg("live")
        .arg(&good)
        .args(["--igtl", &format!("127.0.0.1:{port}"), "--out"])
        .arg(dir.join("live"))
        .output()
        .unwrap();
    assert_eq!(none.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&none.stderr);
    assert!(
        stderr.contains(&format!("127.0.0.1:{port}: cannot connect")),
        "{stderr}"
    );
    assert!(!dir.join("live").exists());
}

/// Builds the server of tests/igtl/reference_server.cxx against Debian's
/// libopenigtlink-dev (OpenIGTLink's reference implementation).
fn reference_server(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let binary = dir.join("reference_server");
    let built = Command::new("g++")
        .args(["-O1", "-I/usr/include/openigtlink"])
        .arg(root().join("tests/igtl/reference_server.cxx"))
        .args(["-lOpenIGTLink", "-o"])
        .arg(&binary)
        .output()
        .expect("g++ (scripts/setup.sh installs it)");
    assert!(
        built.status.success(),
        "building the reference server (libopenigtlink-dev, scripts/setup.sh): {}",
        String::from_utf8_lossy(&built.stderr)
    );
    binary
}

#[test]
#[ignore = "needs ../shared/data and libopenigtlink-dev (full tier: scripts/test.sh)"]
fn messages_of_the_reference_implementation_are_read_as_it_sent_them() {
    let dir = scratch("live_igtl", "reference");
    let port = free_port();
    let mut server = Command::new(reference_server(&dir))
        .arg(port.to_string())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(server.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert_eq!(line.trim(), "listening");
    let path = manifest(&dir, "reference", None, "");
    let out = probecal()
        .arg("live")
        .arg(&path)
        .args(["--igtl", &format!("127.0.0.1:{port}"), "--out"])
        .arg(dir.join("live"))
        .output()
        .unwrap();
    assert!(finish(server, &out).success());
    // Five synthetic frames are too few to calibrate: a clear failure, and the
    // session's files kept beside the output.
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("no calibration") && stderr.contains(".live.failed"),
        "{stderr}"
    );
    let kept = dir.join(".live.failed");
    let s = json(&kept.join("summary.json"));
    assert_eq!(s["images_received"], 5);
    assert_eq!(s["frames"], 5);
    assert_eq!(s["messages"]["skipped"], 0);
    assert!(s["ended_by"].as_str().unwrap().contains("SequenceEnd"));
    assert_eq!(s["messages"]["statuses"][0], "1 none: tracking");
    let received = Sequence::read(&kept.join("received.igs.mha")).unwrap();
    assert_eq!((received.width, received.height), (64, 48));
    for f in 0..5 {
        let expected: Vec<u8> = (0..64 * 48).map(|i| ((i * 7 + f) % 256) as u8).collect();
        assert_eq!(received.pixels(f), expected.as_slice(), "frame {f}");
        let t: f64 = received.frame_field(f, "Timestamp").unwrap().parse().unwrap();
        assert!((t - (1000.0 + 0.125 * f as f64)).abs() < 1e-6, "frame {f}: {t}");
        for (n, name) in ["ProbeToTracker", "ReferenceToTracker"].iter().enumerate() {
            let m = received.matrix(f, name).unwrap();
            let a = 0.1 * f as f64 + n as f64;
            let expected = nalgebra::Matrix4::new(
                a.cos(),
                -a.sin(),
                0.0,
                10.0 + f as f64,
                a.sin(),
                a.cos(),
                0.0,
                20.0 * n as f64,
                0.0,
                0.0,
                1.0,
                -30.5,
                0.0,
                0.0,
                0.0,
                1.0,
            );
            assert!((m - expected).abs().max() < 1e-6, "frame {f} {name}: {m}");
        }
    }
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_live_volume_is_sent_every_n_frames_on_the_device_sets_grid() {
    let dir = scratch("live_igtl", "volume");
    std::fs::create_dir_all(&dir).unwrap();
    // 1 mm voxels over the fCal phantom's region in the Reference frame.
    let config = dir.join("volume.xml");
    std::fs::write(
        &config,
        r#"<PlusConfiguration version="2.1">
  <VolumeReconstruction OutputSpacing="1 1 1" OutputOrigin="-60 -140 -70"
    OutputExtent="0 119 0 139 0 89" ClipRectangleOrigin="0 0" ClipRectangleSize="820 616"
    Interpolation="NEAREST_NEIGHBOR" Optimization="FULL" CompoundingMode="MEAN" FillHoles="OFF" />
</PlusConfiguration>
"#,
    )
    .unwrap();
    let path = manifest(&dir, "volume", None, "");
    let end = message::encode("STRING", "SequenceEnd", 0.0, &message::string_body("end"));
    let config_arg = config.display().to_string();
    let options = ["--reconstruct", config_arg.as_str(), "--volume-every", "10"];
    let (out, replies) = serve_with(
        &dir,
        &path,
        [stream(40, &[]), vec![end]].concat(),
        Vec::new(),
        true,
        &options,
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = json(&dir.join("live/summary.json"));
    let v = &s["live_volume"];
    assert_eq!(v["dims"], serde_json::json!([120, 140, 90]));
    let (inserted, waiting) = (
        v["frames_inserted"].as_u64().unwrap(),
        v["frames_not_inserted"].as_u64().unwrap(),
    );
    assert_eq!(inserted + waiting, 40);
    // Frames before the first calibration (10 frames) wait outside.
    assert_eq!((inserted, waiting), (31, 9), "{v}");
    let volumes: Vec<&message::Image> = replies
        .iter()
        .filter_map(|(h, b)| match b {
            Body::Image(i) if h.device == "Volume" => Some(i),
            _ => None,
        })
        .collect();
    assert_eq!(volumes.len() as u64, v["volumes_sent"].as_u64().unwrap());
    assert_eq!(volumes.len() as u64, inserted.div_ceil(10));
    let filled: Vec<usize> = volumes
        .iter()
        .map(|i| i.pixels.iter().filter(|&&p| p > 0).count())
        .collect();
    assert!(volumes
        .iter()
        .all(|i| i.size == [120, 140, 90] && (i.spacing_mm[0] - 1.0).abs() < 1e-6));
    // Each 820x616 frame (about 65x50 mm) reaches a few thousand 1 mm voxels;
    // the wires' dots are the bright ones.
    let reached = v["voxels_reached"].as_u64().unwrap();
    assert!(reached > 20_000 && reached < 120 * 140 * 90 / 2, "{v}");
    assert!(filled.iter().all(|&n| n > 0), "{filled:?}");
    assert_eq!(replies.last().unwrap().0.device, "ImageToProbe");
    // A device set without a grid is refused before connecting.
    let plain = root().join("experiments/plus/fcal2_volume.xml");
    let out = probecal()
        .arg("live")
        .arg(&path)
        .args([
            "--igtl",
            "127.0.0.1:1",
            "--reconstruct",
            plain.to_str().unwrap(),
            "--out",
        ])
        .arg(dir.join("refused"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("needs OutputOrigin and OutputExtent"));
}
