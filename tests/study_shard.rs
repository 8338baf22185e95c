//! A study spread over processes: `study --shard K/N` slices run at the same
//! time, and `study merge` joins them into the files one unsharded run writes,
//! byte for byte; shards that are not the slices of one study are refused.

mod common;

use std::path::Path;
use std::process::Output;

use common::{probecal, root, scratch};

fn study(args: &[&str], out: &Path, datasets: &Path) -> std::process::Command {
    let mut cmd = probecal();
    cmd.arg("study")
        .arg(root().join("tests/fixtures/hemisphere_small.yaml"))
        .args(["--seeds", "3", "--first-seed", "2000"])
        .args(args)
        .arg("--out")
        .arg(out)
        .arg("--datasets")
        .arg(datasets);
    cmd
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

#[test]
#[ignore = "runs a study (long reproductions: scripts/reproduce.sh)"]
fn sharded_and_merged_gives_the_unsharded_study_byte_for_byte() {
    let dir = scratch("study_shard", "three_seeds");
    let whole = study(&[], &dir.join("whole"), &dir.join("datasets")).output().unwrap();
    assert!(whole.status.success(), "{}", stderr(&whole));
    // Two slices at once, sharing one datasets folder.
    let shards = dir.join("shards");
    let slices: Vec<_> = ["1/2", "2/2"]
        .iter()
        .map(|k| {
            study(&["--shard", k], &shards, &dir.join("datasets"))
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for slice in slices {
        let out = slice.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let merged = dir.join("merged");
    let merge = probecal()
        .args(["study", "merge"])
        .arg(shards.join("shard_2_of_2.yaml"))
        .arg(shards.join("shard_1_of_2.yaml"))
        .arg("--out")
        .arg(&merged)
        .output()
        .unwrap();
    assert!(merge.status.success(), "{}", stderr(&merge));
    for file in ["study.json", "study.md", "study.html"] {
        assert_eq!(
            std::fs::read(dir.join("whole").join(file)).unwrap(),
            std::fs::read(merged.join(file)).unwrap(),
            "{file} differs"
        );
    }
    // A missing slice is named, and nothing is written.
    let partial = probecal()
        .args(["study", "merge"])
        .arg(shards.join("shard_1_of_2.yaml"))
        .arg("--out")
        .arg(dir.join("partial"))
        .output()
        .unwrap();
    assert_eq!(partial.status.code(), Some(2));
    assert!(
        stderr(&partial).contains("shards 2/2 are missing"),
        "{}",
        stderr(&partial)
    );
    assert!(!dir.join("partial").exists());
}

#[test]
fn a_shard_that_is_not_k_of_n_is_refused_before_any_work() {
    let dir = scratch("study_shard", "bad_shard");
    let out = study(&["--shard", "3/2"], &dir.join("out"), &dir.join("datasets"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("`3/2` is not K/N"), "{}", stderr(&out));
    assert!(!dir.join("datasets").exists() && !dir.join("out").exists());
}
