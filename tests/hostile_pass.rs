//! A hostile pass over every command and every input format: files cut off,
//! sized to allocate gigabytes, nested past any stack, numbers that are not
//! numbers or not physical, keys given twice, settings that would run for
//! hours, outputs aimed at inputs. Each case must be refused with its exit code
//! and an error that names the file it is about, within a minute, under an
//! 8 GiB address-space limit, without a panic, and without writing anything
//! outside its `--out`.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::{root, scratch, shared_data};

#[path = "hostile_pass/commands.rs"]
mod commands;
#[path = "hostile_pass/files.rs"]
mod files;

use commands::*;
use files::*;

const FCAL: &str = "plus-fcal2.0-3nwires";
const FCAL_SET: &str = "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml";
const FCAL_VALIDATION: &str = "fCal_Test_Validation_3NWires_fCal2.0.igs.mha";
const VOLUME: &str = "plus-volume-reconstruction";
const VOLUME_SET: &str = "PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_NN_MEAN.xml";
const SWEEP: &str = "SpinePhantomFreehand.igs.mha";
const TANK: &str = "plus-temporal-watertank";

/// Writes a case's files into its folder and gives its command line.
type Setup = Box<dyn Fn(&Path) -> Vec<String>>;

/// One hostile input: `setup` writes its files into the case's folder and
/// gives the command line; the command must exit with `code` and say `expect`.
struct Case {
    name: String,
    setup: Setup,
    code: i32,
    expect: String,
}

fn case(name: &str, code: i32, expect: &str, setup: impl Fn(&Path) -> Vec<String> + 'static) -> Case {
    Case {
        name: name.to_string(),
        setup: Box::new(setup),
        code,
        expect: expect.to_string(),
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> String {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path.display().to_string()
}

fn s(p: impl AsRef<Path>) -> String {
    p.as_ref().display().to_string()
}

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|a| a.to_string()).collect()
}

/// Every file under `dir` but those under `skip` and `skip`'s lock, with its
/// size and time of change: what a case may not change.
fn snapshot(dir: &Path, skip: &Path) -> Vec<(PathBuf, u64, std::time::SystemTime)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(folder) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            // The output and the lock that claims it (`.<name>.lock` beside it).
            let lock = skip.with_file_name(format!(".{}.lock", skip.file_name().unwrap().to_string_lossy()));
            if path.starts_with(skip) || path == lock {
                continue;
            }
            let Ok(meta) = std::fs::symlink_metadata(&path) else {
                continue;
            };
            if meta.is_dir() {
                stack.push(path.clone());
            }
            out.push((path, meta.len(), meta.modified().unwrap()));
        }
    }
    out.sort();
    out
}

/// Runs `args` under an 8 GiB address-space limit for at most `limit`:
/// the exit code (`None`: killed by a signal, or by us when it ran over) and stderr.
fn run_bounded(args: &[String], limit: Duration) -> (Option<i32>, String, bool) {
    let mut child = std::process::Command::new("prlimit")
        .arg("--as=8589934592")
        .arg("--")
        .arg(env!("CARGO_BIN_EXE_probecal"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("prlimit (util-linux) runs the command");
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        use std::io::Read;
        let mut text = String::new();
        let _ = std::io::BufReader::new(stderr).take(1 << 20).read_to_string(&mut text);
        text
    });
    let started = Instant::now();
    let mut timed_out = false;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > limit {
            timed_out = true;
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (status.code(), reader.join().unwrap(), timed_out)
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_hostile_pass_over_every_command_finds_nothing() {
    let cases: Vec<Case> = [
        sequence_cases(),
        device_set_cases(),
        volume_cases(),
        camera_cases(),
        manifest_cases(),
        time_cases(),
        study_cases(),
        check_cases(),
        output_cases(),
    ]
    .into_iter()
    .flatten()
    .collect();
    let base = scratch("hostile_pass", "cases");
    let data_before = snapshot(&root().join("../shared/data"), Path::new("/nonexistent"));
    let mut failures = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        let dir = base.join(format!("{i:03}"));
        std::fs::create_dir_all(&dir).unwrap();
        let args = (c.setup)(&dir);
        let before = snapshot(&dir, &dir.join("out"));
        let (code, stderr, timed_out) = run_bounded(&args, Duration::from_secs(60));
        let after = snapshot(&dir, &dir.join("out"));
        let first = stderr.lines().find(|l| !l.trim().is_empty()).unwrap_or("").to_string();
        let wrong = if timed_out {
            Some("still running after 60 s".to_string())
        } else if stderr.contains("panicked") || code.is_none() || code == Some(101) || code == Some(134) {
            Some(format!("crashed (exit {code:?})"))
        } else if code != Some(c.code) {
            Some(format!("exit {code:?}, expected {}", c.code))
        } else if !stderr.contains(&c.expect) {
            Some(format!("`{}` not said", c.expect))
        } else if before != after {
            Some("wrote outside its --out".to_string())
        } else {
            None
        };
        println!(
            "{i:03} {:<60} {code:?} {}",
            c.name,
            first.chars().take(160).collect::<String>()
        );
        if let Some(why) = wrong {
            failures.push(format!(
                "{i:03} {}: {why}\n    {}",
                c.name,
                stderr.trim().replace('\n', "\n    ")
            ));
        }
    }
    if data_before != snapshot(&root().join("../shared/data"), Path::new("/nonexistent")) {
        failures.push("the shared data changed".into());
    }
    println!("{} hostile cases", cases.len());
    assert!(
        cases.len() >= 108,
        "a pass of the first one's size: {} cases",
        cases.len()
    );
    let guide = std::fs::read_to_string(root().join("docs/guide/bad-input-and-safety.md")).unwrap();
    assert!(
        guide.contains(&format!("`tests/hostile_pass.rs` runs {} inputs", cases.len())),
        "docs/guide/bad-input-and-safety.md gives another count of the hostile pass's cases"
    );
    assert!(
        failures.is_empty(),
        "{} of {} cases wrong:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
