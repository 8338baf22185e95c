//! What the integration tests share: the binary, the checkout, scratch folders,
//! the real third-party data beside the checkout.
//!
//! Tiers: a plain `cargo test` runs the fast tests. Tests that need
//! `../shared/data`, pdflatex or Chromium, or that run a whole experiment or a
//! statistical check, are `#[ignore]`d with the reason; the README's test command
//! (`scripts/test.sh`, which CI runs) includes them with `--include-ignored`, except
//! the test files of the long reproductions (`scripts/long-tests`), which
//! `scripts/reproduce.sh` runs after it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The `probecal` binary under test.
pub fn probecal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_probecal"))
}

/// The checkout's root.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// An empty scratch folder for a test (`<group>/<name>` under cargo's test tmp dir).
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(group).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The text of the fCal experiment (`experiments/plus_fcal2_nwire.yaml`) with
/// the files it names inside `experiments/` given by absolute path, for a test
/// that writes an edited copy elsewhere (the `../../shared` paths are the
/// caller's to replace).
#[allow(dead_code)]
pub fn fcal_manifest_text() -> String {
    let text = std::fs::read_to_string(root().join("experiments/plus_fcal2_nwire.yaml")).unwrap();
    let local = "config: plus/fcal2_volume.xml";
    assert!(text.contains(local), "the fCal experiment no longer names `{local}`");
    text.replace(
        local,
        &format!("config: {}", root().join("experiments/plus/fcal2_volume.xml").display()),
    )
}

/// A file of the real third-party data beside the checkout (`../shared/data/<set>/<name>`).
pub fn shared_data(set: &str, name: &str) -> PathBuf {
    root().join("../shared/data").join(set).join(name)
}

/// `probecal <args>` under an address-space limit of `kib` KiB and a time
/// limit of `seconds` (started through sh for its `ulimit`): the output.
pub fn probecal_bounded(args: &[String], kib: u64, seconds: u64) -> std::process::Output {
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    let command = format!(
        "ulimit -v {kib}; exec timeout {seconds} '{}' {}",
        env!("CARGO_BIN_EXE_probecal"),
        quoted.join(" ")
    );
    Command::new("sh").args(["-c", &command]).output().unwrap()
}

/// A tracked run's `summary.json` text with `rows` as its `ImageToProbe` and no
/// lag: the committed fCal 2.0 run's summary, its matrix and `time_offset_s`
/// replaced (a real probecal summary, so that only the matrix is what a test
/// varies).
#[allow(dead_code)]
pub fn tracked_summary_with_matrix(rows: serde_json::Value) -> String {
    let path = root().join("reports/plus_fcal2_nwire/fcal2_3nwires/summary.json");
    let mut summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    summary["image_to_probe"]["matrix"] = rows;
    summary["time_offset_s"] = serde_json::json!(0.0);
    serde_json::to_string_pretty(&summary).unwrap()
}
