//! `probecal live --igtl`: PLUS's fCal 2.0 calibration sweep broadcast over
//! OpenIGTLink by pyigtl (an implementation independent of probecal's) at 4x
//! real time; the calibration sent back equals `probecal run`'s on the same
//! file, every frame sent is accounted for, and the received sequence re-runs
//! offline to the same matrix. Hostile streams (bad CRC, bodies that contradict
//! their sizes, unknown types, a body above the limit, a cut, a silence) end
//! with a clear error or a counted skip.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::{probecal, root, scratch, shared_data};
use probecal::io::igtl::message::{self, Body, Header, HEADER_BYTES};
use probecal::io::plus::sequence::Sequence;

const SET: &str = "plus-fcal2.0-3nwires";
const CALIBRATION: &str = "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha";

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

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

/// The fCal experiment with absolute paths, its calibration sequence replaced
/// where `calibration` is given, and `extra` YAML appended.
fn manifest(dir: &Path, name: &str, calibration: Option<&Path>, extra: &str) -> PathBuf {
    let text = common::fcal_manifest_text();
    let shared = root().join("../shared").canonicalize().unwrap();
    let mut text = text.replace("../../shared", &shared.display().to_string());
    if let Some(c) = calibration {
        let original = format!("{}/data/{SET}/{CALIBRATION}", shared.display());
        assert!(text.contains(&original));
        text = text.replace(&original, &c.display().to_string());
    }
    text.push_str(extra);
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, text).unwrap();
    path
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

/// The fCal sweep's first `n` frames as PlusServer's messages, with hostile
/// messages put in after frame 5 (each a whole message).
fn stream(n: usize, hostile: &[Vec<u8>]) -> Vec<Vec<u8>> {
    let s = Sequence::read(&shared_data(SET, CALIBRATION)).unwrap();
    let mut out = Vec::new();
    for i in 0..n {
        let t: f64 = s.frame_field(i, "Timestamp").unwrap().parse().unwrap();
        let body = message::image_body([s.width, s.height, 1], [0.08, 0.08, 1.0], [0.0; 3], s.pixels(i));
        out.push(message::encode("IMAGE", "Image", t, &body));
        for name in ["ProbeToTracker", "ReferenceToTracker"] {
            let m = s.matrix(i, name).unwrap();
            out.push(message::encode("TRANSFORM", name, t, &message::transform_body(&m)));
        }
        if i == 5 {
            out.extend(hostile.iter().cloned());
        }
    }
    out
}

/// Serves `messages` (then `tail` bytes and a close, or, with `wait_reply`,
/// reads the client's messages up to its `ImageToProbe`) to one client;
/// probecal's output and those messages.
fn serve(
    dir: &Path,
    manifest_path: &Path,
    messages: Vec<Vec<u8>>,
    tail: Vec<u8>,
    wait_reply: bool,
) -> (Output, Vec<(Header, Body)>) {
    serve_with(dir, manifest_path, messages, tail, wait_reply, &[])
}

/// [`serve`] with more options for `probecal live`.
fn serve_with(
    dir: &Path,
    manifest_path: &Path,
    messages: Vec<Vec<u8>>,
    tail: Vec<u8>,
    wait_reply: bool,
    options: &[&str],
) -> (Output, Vec<(Header, Body)>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let client_done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let done = client_done.clone();
    let server = std::thread::spawn(move || {
        let Some(mut socket) = accept_while(&listener, &done) else {
            return Vec::new();
        };
        for m in &messages {
            socket.write_all(m).unwrap();
        }
        socket.write_all(&tail).unwrap();
        if !wait_reply {
            return Vec::new();
        }
        replies(&mut socket)
    });
    let out = probecal()
        .arg("live")
        .arg(manifest_path)
        .args(["--igtl", &format!("127.0.0.1:{port}"), "--out"])
        .arg(dir.join("live"))
        .args(options)
        .output()
        .unwrap();
    client_done.store(true, std::sync::atomic::Ordering::SeqCst);
    (out, server.join().unwrap())
}

/// The client's connection, or `None` once `client_done` says the client has
/// exited without connecting (the test then fails on its output, not hangs).
fn accept_while(listener: &TcpListener, client_done: &std::sync::atomic::AtomicBool) -> Option<TcpStream> {
    listener.set_nonblocking(true).unwrap();
    loop {
        match listener.accept() {
            Ok((socket, _)) => {
                socket.set_nonblocking(false).unwrap();
                return Some(socket);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if client_done.load(std::sync::atomic::Ordering::SeqCst) {
                    return None;
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            Err(e) => panic!("accept: {e}"),
        }
    }
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

/// The client's messages, up to its `ImageToProbe` (or the connection's end).
fn replies(socket: &mut TcpStream) -> Vec<(Header, Body)> {
    socket
        .set_read_timeout(Some(std::time::Duration::from_secs(120)))
        .unwrap();
    let mut out = Vec::new();
    loop {
        let mut header = [0u8; HEADER_BYTES];
        if socket.read_exact(&mut header).is_err() {
            return out;
        }
        let header = Header::parse(&header).unwrap();
        let mut body = vec![0u8; header.body_bytes as usize];
        socket.read_exact(&mut body).unwrap();
        assert_eq!(message::crc64(&body), header.crc);
        let decoded = message::decode(&header, &body).unwrap();
        let last = header.device == "ImageToProbe";
        out.push((header, decoded));
        if last {
            return out;
        }
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
fn a_stream_that_cannot_be_framed_ends_the_session_with_a_clear_error() {
    let dir = scratch("live_igtl", "unframed");
    let path = manifest(&dir, "unframed", None, "");
    let mut huge = message::encode("IMAGE", "Image", 1.0, &[]);
    huge[42..50].copy_from_slice(&(1u64 << 40).to_be_bytes());
    let (out, _) = serve(&dir, &path, stream(3, &[]), huge, false);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("announces a body of 1099511627776 bytes, above the limit"),
        "{stderr}"
    );
    assert!(!dir.join("live").exists());
    let mut version = message::encode("STRING", "x", 1.0, &message::string_body("x"));
    version[0..2].copy_from_slice(&9u16.to_be_bytes());
    let (out, _) = serve(&dir, &path, stream(3, &[]), version, false);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("header version 9"));
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
