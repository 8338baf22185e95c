//! A scripted OpenIGTLink server for the stream tests: PLUS's fCal 2.0 sweep
//! as PlusServer's messages, hostile messages put in, served to one
//! `probecal live --igtl` client. Shared by `live_igtl.rs` and
//! `hostile_streams.rs`.
#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Output;

use super::common::{self, probecal, root, shared_data};
use probecal::io::igtl::message::{self, Body, Header, HEADER_BYTES};
use probecal::io::plus::sequence::Sequence;

pub const SET: &str = "plus-fcal2.0-3nwires";
pub const CALIBRATION: &str = "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha";

pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The fCal experiment with absolute paths, its calibration sequence replaced
/// where `calibration` is given, and `extra` YAML appended.
pub fn manifest(dir: &Path, name: &str, calibration: Option<&Path>, extra: &str) -> PathBuf {
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

/// The fCal sweep's first `n` frames as PlusServer's messages, with hostile
/// messages put in after frame 5 (each a whole message).
pub fn stream(n: usize, hostile: &[Vec<u8>]) -> Vec<Vec<u8>> {
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
pub fn serve(
    dir: &Path,
    manifest_path: &Path,
    messages: Vec<Vec<u8>>,
    tail: Vec<u8>,
    wait_reply: bool,
) -> (Output, Vec<(Header, Body)>) {
    serve_with(dir, manifest_path, messages, tail, wait_reply, &[])
}

/// [`serve`] with more options for `probecal live`.
pub fn serve_with(
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
pub fn accept_while(listener: &TcpListener, client_done: &std::sync::atomic::AtomicBool) -> Option<TcpStream> {
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

/// The client's messages, up to its `ImageToProbe` (or the connection's end).
pub fn replies(socket: &mut TcpStream) -> Vec<(Header, Body)> {
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
