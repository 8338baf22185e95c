//! What a run does to the folders around it: it never deletes what it did not
//! write, swaps an experiment's folder in only when it is complete, keeps the old
//! one when a rerun fails or is killed, refuses names and folders that would
//! collide, and lets one run at a time write into an output folder.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::{Duration, Instant};

use common::{probecal, root, scratch};

fn fixture_text() -> String {
    std::fs::read_to_string(root().join("tests/fixtures/hemisphere_small.yaml")).unwrap()
}

/// The rendered datasets' cache of the test whose output folder is `out`: one per
/// test, since a run claims its cache and the tests run at the same time.
fn datasets(out: &Path) -> PathBuf {
    out.parent().unwrap().join("datasets")
}

fn run(manifests: &[&Path], out: &Path, force: bool) -> Output {
    let mut cmd = probecal();
    cmd.arg("run")
        .args(manifests)
        .arg("--out")
        .arg(out)
        .arg("--datasets")
        .arg(datasets(out))
        .arg("--quiet");
    if force {
        cmd.arg("--force");
    }
    cmd.output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn names_that_would_escape_or_collide_are_refused() {
    let dir = scratch("output_safety", "names");
    for (name, expect) in [
        (
            "..",
            "field `experiment`: `..` must use only letters, digits, `_` and `-`",
        ),
        (".", "field `experiment`: `.` must use only letters"),
        ("a/b", "must use only letters"),
        ("study", "field `experiment`: `study` is reserved"),
    ] {
        let manifest = write(
            &dir,
            "m.yaml",
            &fixture_text().replace("experiment: hemisphere_small", &format!("experiment: \"{name}\"")),
        );
        let out = probecal().arg("validate").arg(&manifest).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{name}: {}", stderr(&out));
        assert!(stderr(&out).contains(expect), "{name}: {}", stderr(&out));
    }
    let manifest = write(
        &dir,
        "m.yaml",
        &fixture_text().replace("- name: small", "- name: ../small"),
    );
    let out = probecal().arg("validate").arg(&manifest).output().unwrap();
    assert!(stderr(&out).contains("field `datasets[0].name`"), "{}", stderr(&out));
}

#[test]
fn two_manifests_with_one_experiment_name_are_refused_before_any_work() {
    let dir = scratch("output_safety", "twice");
    let a = write(&dir, "a.yaml", &fixture_text());
    let b = write(&dir, "b.yaml", &fixture_text());
    let out = run(&[&a, &b], &dir.join("out"), false);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("both name experiment `hemisphere_small`"),
        "{}",
        stderr(&out)
    );
    assert!(!dir.join("out/hemisphere_small").exists());
}

#[test]
fn a_folder_holding_an_input_is_not_replaced() {
    let dir = scratch("output_safety", "input_inside");
    // The manifest sits inside the folder its experiment would replace.
    let manifest = write(&dir.join("out/hemisphere_small"), "m.yaml", &fixture_text());
    let out = run(&[&manifest], &dir.join("out"), true);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("would be replaced, and it holds"),
        "{}",
        stderr(&out)
    );
    assert!(manifest.is_file(), "the input is still there");
}

#[test]
#[ignore = "renders and runs an experiment, kills runs (full tier: scripts/test.sh)"]
fn a_failed_or_killed_rerun_keeps_the_previous_report_and_one_run_writes_at_a_time() {
    let dir = scratch("output_safety", "rerun");
    let out_dir = dir.join("out");
    let good = write(&dir, "good.yaml", &fixture_text());
    let first = run(&[&good], &out_dir, false);
    assert!(first.status.success(), "{}", stderr(&first));
    let summary = out_dir.join("hemisphere_small/small/summary.json");
    let before = std::fs::read(&summary).unwrap();
    let baselines = dir.join("baselines");
    let update = probecal()
        .args(["check", "--update", "--baselines"])
        .arg(&baselines)
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(update.status.success(), "{}", stderr(&update));

    // A rerun that fails at run time (too few usable frames) keeps the old folder.
    let failing = write(
        &dir,
        "failing.yaml",
        &fixture_text().replace("min_frames: 6", "min_frames: 1000"),
    );
    let failed = run(&[&failing], &out_dir, true);
    assert_eq!(failed.status.code(), Some(1), "{}", stderr(&failed));
    assert!(
        stderr(&failed).contains("previous folder is kept"),
        "{}",
        stderr(&failed)
    );
    assert_eq!(
        std::fs::read(&summary).unwrap(),
        before,
        "the previous summary is untouched"
    );
    assert!(out_dir.join(".hemisphere_small.failed/manifest.yaml").is_file());

    // Killed mid-run (SIGKILL and SIGINT): the previous report is intact, nothing
    // half-written sits where a reader would take it as complete, and the next
    // run is not kept out by the dead run's lock.
    for signal in ["-KILL", "-INT"] {
        // A run may finish between its folder's appearing and the signal's landing
        // (a loaded machine): it then wrote the same report, and is started again.
        let mut cut_off = false;
        for _ in 0..5 {
            // Caught while it writes, then killed.
            let mut child = started_run(&good, &out_dir, &["--force"]);
            let killed = std::process::Command::new("kill")
                .arg(signal)
                .arg(child.id().to_string())
                .status()
                .unwrap();
            assert!(killed.success());
            if !child.wait().unwrap().success() {
                cut_off = true;
                break;
            }
        }
        assert!(
            cut_off,
            "{signal}: five runs each finished before the signal reached them"
        );
        assert_eq!(
            std::fs::read(&summary).unwrap(),
            before,
            "{signal}: the previous summary changed"
        );
        let check = probecal()
            .arg("check")
            .arg(&out_dir)
            .arg("--baselines")
            .arg(&baselines)
            .output()
            .unwrap();
        assert!(check.status.success(), "{signal}: {}", stderr(&check));
    }
    let again = run(&[&good], &out_dir, true);
    assert!(again.status.success(), "{}", stderr(&again));
    assert_eq!(
        std::fs::read(&summary).unwrap(),
        before,
        "the same inputs give the same summary"
    );
    assert!(!out_dir.join(".hemisphere_small.partial").exists());
}

/// Gives the command's process the default action for SIGINT, as a user's
/// Ctrl-C meets it: a process started in the background by a shell without job
/// control inherits SIGINT ignored, and the test would then interrupt nothing.
fn interruptible(command: &mut std::process::Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: between fork and exec the closure only calls signal(2), which is
    // async-signal-safe, and allocates nothing.
    unsafe {
        command.pre_exec(|| {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            Ok(())
        });
    }
}

/// A run of the fixture into `out` (with `extra` arguments), started and caught
/// while it writes; Ctrl-C interrupts it.
fn started_run(manifest: &Path, out: &Path, extra: &[&str]) -> std::process::Child {
    let mut run = probecal();
    run.arg("run")
        .arg(manifest)
        .arg("--out")
        .arg(out)
        .arg("--datasets")
        .arg(datasets(out))
        .arg("--quiet")
        .args(extra);
    interruptible(&mut run);
    let child = run.spawn().unwrap();
    let started = Instant::now();
    while !out.join(".hemisphere_small.partial").exists() && started.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(10));
    }
    child
}

#[test]
#[ignore = "runs experiments (full tier: scripts/test.sh)"]
fn a_second_process_is_kept_out_of_a_busy_output_folder_and_waits_for_a_busy_dataset() {
    let dir = scratch("output_safety", "concurrent");
    let out_dir = dir.join("out");
    let good = write(&dir, "good.yaml", &fixture_text());
    let mut first = started_run(&good, &out_dir, &[]);
    let holder = format!("another probecal (process {})", first.id());
    // Until the first run holds its rendered dataset.
    let dataset_lock = datasets(&out_dir).join(".hemisphere_small__small.lock");
    let started = Instant::now();
    loop {
        if let Ok(file) = std::fs::File::open(&dataset_lock) {
            match file.try_lock_shared() {
                Err(std::fs::TryLockError::WouldBlock) => break,
                _ => drop(file),
            }
        }
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "the first run never claimed its dataset"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    // While the first writes: the same output folder is refused at once.
    let same_out = run(&[&good], &out_dir, true);
    assert_eq!(same_out.status.code(), Some(2), "{}", stderr(&same_out));
    let expected = format!("{}: {holder}", out_dir.join(".probecal.lock").display());
    assert!(
        stderr(&same_out).contains(&expected),
        "`{expected}` not in {}",
        stderr(&same_out)
    );
    // Another output folder sharing the datasets' cache waits for the dataset
    // the first run renders and reads, then runs.
    let same_cache = probecal()
        .arg("run")
        .arg(&good)
        .arg("--out")
        .arg(dir.join("other"))
        .arg("--datasets")
        .arg(datasets(&out_dir))
        .output()
        .unwrap();
    let status = first.wait().unwrap();
    assert!(status.success(), "the first run failed");
    assert!(same_cache.status.success(), "{}", stderr(&same_cache));
    let expected = format!("{}: waiting for {holder}", dataset_lock.display());
    assert!(
        String::from_utf8_lossy(&same_cache.stderr).contains(&expected),
        "`{expected}` not in {}",
        stderr(&same_cache)
    );
    assert_eq!(
        std::fs::read(dir.join("other/hemisphere_small/small/summary.json")).unwrap(),
        std::fs::read(out_dir.join("hemisphere_small/small/summary.json")).unwrap(),
        "the waiting run gives the same summary"
    );
    // The first run's report is whole, and the folder is free again.
    let check = probecal()
        .args(["check", "--update", "--baselines"])
        .arg(dir.join("baselines"))
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(check.status.success(), "{}", stderr(&check));
    let again = run(&[&good], &out_dir, true);
    assert!(again.status.success(), "{}", stderr(&again));
}

/// A folder command's `--out` is replaced whole by a sibling swapped in: the
/// working directory (`.`), a folder holding it (`..`) and `sub/..` are
/// refused before any work, and nothing is left beside them (a `..partial`
/// staging folder was left in the parent before).
#[test]
fn the_working_directory_is_no_output_folder() {
    let dir = common::scratch("output_safety", "working_directory");
    let _ = std::fs::remove_dir_all(&dir);
    let here = dir.join("here");
    std::fs::create_dir_all(here.join("sub")).unwrap();
    let sequence = dir.join("missing.igs.mha");
    for out in [".", "..", "sub/.."] {
        let o = common::probecal()
            .current_dir(&here)
            .arg("reconstruct")
            .arg(&sequence)
            .args(["--config", "none.xml", "--out", out])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{out}: {}", stderr(&o));
        assert!(stderr(&o).contains("is the working directory"), "{out}: {}", stderr(&o));
    }
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["here"], "left beside the working directory");
    assert_eq!(std::fs::read_dir(&here).unwrap().count(), 1, "left in it");
}
