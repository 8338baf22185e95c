//! Stream sessions end on what the stream does, not only on success, and keep
//! what they received whatever ends them: a stream that cannot be framed after
//! good frames, a stray first image of another size, a server that trickles a
//! body a byte at a time (every wait bounded), and SIGTERM (the frames so far
//! calibrated and written, as for Ctrl-C).

mod common;
#[path = "igtl/serve.rs"]
mod serve;

use std::io::Write;
use std::net::TcpListener;
use std::path::Path;
use std::process::Output;
use std::time::{Duration, Instant};

use common::{probecal, scratch};
use probecal::io::igtl::message;
use probecal::io::plus::sequence::Sequence;
use serve::{accept_while, json, manifest, serve, stream};

/// A header announcing a body of 2^40 bytes: nothing after it can be framed.
fn unframeable() -> Vec<u8> {
    let mut huge = message::encode("IMAGE", "Image", 1.0, &[]);
    huge[42..50].copy_from_slice(&(1u64 << 40).to_be_bytes());
    huge
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_stream_that_cannot_be_framed_keeps_the_frames_before_it() {
    let dir = scratch("hostile_streams", "unframed");
    let path = manifest(&dir, "unframed", None, "");
    // After 40 good frames: they are calibrated and written, and the ending says why.
    let (out, _) = serve(&dir, &path, stream(40, &[]), unframeable(), false);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: the acquisition ended on a stream that could not be read on"),
        "{stderr}"
    );
    let s = json(&dir.join("live/summary.json"));
    assert_eq!(s["frames"], 40);
    let ended = s["ended_by"].as_str().unwrap();
    assert!(
        ended.contains("announces a body of 1099511627776 bytes, above the limit"),
        "{ended}"
    );
    assert!(s["sent_error"].as_str().unwrap().contains("not sent"));
    assert_eq!(
        Sequence::read(&dir.join("live/received.igs.mha")).unwrap().frames.len(),
        40
    );
    // After 3 frames, too few to calibrate: a failure, the frames kept beside.
    std::fs::remove_dir_all(dir.join("live")).unwrap();
    let (out, _) = serve(&dir, &path, stream(3, &[]), unframeable(), false);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("above the limit"), "{stderr}");
    assert!(!dir.join("live").exists());
    let kept = Sequence::read(&dir.join(".live.failed/received.igs.mha")).unwrap();
    assert_eq!(kept.frames.len(), 3);
    // A header of an unknown version, likewise.
    let mut version = message::encode("STRING", "x", 1.0, &message::string_body("x"));
    version[0..2].copy_from_slice(&9u16.to_be_bytes());
    let (out, _) = serve(&dir, &path, stream(40, &[]), version, false);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(json(&dir.join("live/summary.json"))["ended_by"]
        .as_str()
        .unwrap()
        .contains("header version 9"));
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_stray_first_image_does_not_set_the_streams_size() {
    let dir = scratch("hostile_streams", "stray");
    let path = manifest(&dir, "stray", None, "");
    // A 4096x4096 image (16 MiB, within the body limit) before the sweep.
    let big = message::encode(
        "IMAGE",
        "Image",
        1.0,
        &message::image_body([4096, 4096, 1], [0.08, 0.08, 1.0], [0.0; 3], &vec![7; 4096 * 4096]),
    );
    let end = message::encode("STRING", "SequenceEnd", 0.0, &message::string_body("end"));
    let (out, _) = serve(
        &dir,
        &path,
        [vec![big], stream(40, &[]), vec![end]].concat(),
        Vec::new(),
        false,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let s = json(&dir.join("live/summary.json"));
    assert_eq!(s["images_received"], 41);
    assert_eq!(s["frames"], 40);
    let reasons = s["messages"]["skip_reasons"].to_string();
    assert!(
        reasons.contains("a 4096x4096 first image, not followed by another of its size (the next is 820x616)"),
        "{reasons}"
    );
    // The batch step reads what the session wrote.
    let received = Sequence::read(&dir.join("live/received.igs.mha")).unwrap();
    assert_eq!((received.width, received.height, received.frames.len()), (820, 616, 40));
}

/// Serves `frames` of the sweep, then a message whose bytes follow one every
/// 5 ms (faster than any one read's wait, slower than any message) until the
/// client goes; probecal's
/// output, how long it ran, and `signal` sent to it `after` the start.
fn trickle(dir: &Path, manifest: &Path, frames: usize, signal: Option<(&str, Duration)>) -> (Output, Duration) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let client_done = done.clone();
    let messages = stream(frames, &[]);
    let server = std::thread::spawn(move || {
        let Some(mut socket) = accept_while(&listener, &client_done) else {
            return;
        };
        for m in &messages {
            socket.write_all(m).unwrap();
        }
        let body = message::encode("IMAGE", "Image", 9999.0, &vec![0; 100_000]);
        for byte in &body {
            if client_done.load(std::sync::atomic::Ordering::SeqCst) || socket.write_all(&[*byte]).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    });
    let start = Instant::now();
    let child = probecal()
        .arg("live")
        .arg(manifest)
        .args(["--igtl", &format!("127.0.0.1:{port}"), "--out"])
        .arg(dir.join("live"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    if let Some((name, after)) = signal {
        std::thread::sleep(after);
        let sent = std::process::Command::new("kill")
            .args(["-s", name, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
    }
    let pid = child.id();
    let waiter = std::thread::spawn(move || child.wait_with_output().unwrap());
    while !waiter.is_finished() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(50));
    }
    if !waiter.is_finished() {
        let _ = std::process::Command::new("kill")
            .args(["-9", &pid.to_string()])
            .status();
        done.store(true, std::sync::atomic::Ordering::SeqCst);
        panic!("probecal live was still running 120 s after it started, on a trickling server");
    }
    let out = waiter.join().unwrap();
    let took = start.elapsed();
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    server.join().unwrap();
    (out, took)
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_trickling_server_is_waited_on_within_bounds_and_sigterm_is_honoured() {
    let dir = scratch("hostile_streams", "trickle");
    // The silence is counted in whole messages: a body a byte at a time is silence.
    let quiet = manifest(&dir, "quiet", None, "live:\n  silence_s: 2\n");
    let (out, took) = trickle(&dir, &quiet, 30, None);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(took < Duration::from_secs(60), "{took:?}");
    let s = json(&dir.join("live/summary.json"));
    assert_eq!(s["frames"], 30);
    assert!(s["ended_by"].as_str().unwrap().contains("2 s without a message"));
    // With a long silence, SIGTERM ends the acquisition: the frames are calibrated and written.
    let long = manifest(&dir, "long", None, "live:\n  silence_s: 600\n");
    let (out, took) = trickle(&dir, &long, 30, Some(("TERM", Duration::from_secs(8))));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(took < Duration::from_secs(60), "{took:?}");
    let s = json(&dir.join("live/summary.json"));
    assert_eq!(s["frames"], 30);
    assert!(
        s["ended_by"].as_str().unwrap().contains("an interrupt"),
        "{}",
        s["ended_by"]
    );
}
