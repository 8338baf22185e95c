//! Reproducible runs and the accuracy gate: thread count does not change a byte
//! of the outputs; `probecal check` passes an unchanged run and fails a worse one
//! naming the metric.

mod common;

use common::probecal;

use std::path::{Path, PathBuf};

fn fixture_text() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hemisphere_small.yaml")).unwrap()
}

fn fresh(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("reproducibility")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(manifest: &Path, out: &Path, datasets: &Path, threads: usize) -> std::process::Output {
    probecal()
        .arg("run")
        .arg(manifest)
        .arg("--out")
        .arg(out)
        .arg("--datasets")
        .arg(datasets)
        .arg("--threads")
        .arg(threads.to_string())
        .arg("--quiet")
        .output()
        .unwrap()
}

#[test]
#[ignore = "runs an experiment twice (full tier: scripts/test.sh)"]
fn thread_count_does_not_change_a_byte() {
    let base = fresh("threads");
    let manifest = base.join("small.yaml");
    std::fs::write(&manifest, fixture_text()).unwrap();
    // Each run renders its own copy of the dataset, with its own thread count.
    for threads in [1, 2] {
        let r = run(
            &manifest,
            &base.join(format!("out{threads}")),
            &base.join(format!("datasets{threads}")),
            threads,
        );
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    let one = base.join("out1/hemisphere_small/small");
    let two = base.join("out2/hemisphere_small/small");
    for file in [
        "frames.csv",
        "frames.parquet",
        "summary.json",
        "report.html",
        "report_context.json",
        "camera_intrinsics.yml",
    ] {
        assert!(
            std::fs::read(one.join(file)).unwrap() == std::fs::read(two.join(file)).unwrap(),
            "{file} differs between 1 and 2 threads"
        );
    }
    for file in ["frames/camera_005.png", "frames/bscan_005.png", "ground_truth.json"] {
        let a = std::fs::read(base.join("datasets1/hemisphere_small__small").join(file)).unwrap();
        let b = std::fs::read(base.join("datasets2/hemisphere_small__small").join(file)).unwrap();
        assert!(a == b, "rendered {file} differs between 1 and 2 threads");
    }
    // Provenance is written beside the outputs and records the thread count.
    let provenance: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(one.join("provenance.json")).unwrap()).unwrap();
    assert_eq!(provenance["threads"], 1);
    assert_eq!(provenance["seed"], 11);
    assert!(provenance["inputs"].as_array().unwrap().len() > 28);
    assert_eq!(
        provenance["opencv_version"].as_str().unwrap().split('.').next(),
        Some("4")
    );
}

#[test]
#[ignore = "runs an experiment (full tier: scripts/test.sh)"]
fn check_passes_unchanged_and_fails_planted_regressions() {
    let base = fresh("check");
    let datasets = base.join("datasets");
    let manifest = base.join("small.yaml");
    std::fs::write(&manifest, fixture_text()).unwrap();
    let r = run(&manifest, &base.join("reference"), &datasets, 0);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let baselines = base.join("baselines");
    let update = probecal()
        .arg("check")
        .arg(base.join("reference"))
        .arg("--baselines")
        .arg(&baselines)
        .arg("--update")
        .output()
        .unwrap();
    assert!(update.status.success(), "{}", String::from_utf8_lossy(&update.stderr));
    assert!(baselines.join("hemisphere_small.yaml").is_file());

    // The unchanged run passes.
    let r = run(&manifest, &base.join("again"), &datasets, 0);
    assert!(r.status.success());
    let ok = probecal()
        .arg("check")
        .arg(base.join("again"))
        .arg("--baselines")
        .arg(&baselines)
        .output()
        .unwrap();
    assert!(
        ok.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&ok.stdout),
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(String::from_utf8_lossy(&ok.stdout).contains("no regression"));

    // A worse setting: calibrate from all frames, outliers included.
    let worse = base.join("worse.yaml");
    std::fs::write(
        &worse,
        fixture_text()
            .replace("calibration_cutoff_mm: 2.0", "calibration_cutoff_mm: .inf")
            .replace("truth_corner_error_mm: 3.0", "truth_corner_error_mm: 9.0"),
    )
    .unwrap();
    let r = run(&worse, &base.join("worse"), &datasets, 0);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let bad = probecal()
        .arg("check")
        .arg(base.join("worse"))
        .arg("--baselines")
        .arg(&baselines)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("REGRESSED: hemisphere_small / small: truth_corner_error_mm"),
        "{stderr}"
    );
    assert!(
        stderr.contains("report.html"),
        "the message says where to look: {stderr}"
    );

    // A perturbed solution: the summary of the unchanged run with a worse rotation.
    let summary = base.join("again/hemisphere_small/small/summary.json");
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let rotation = json["truth"]["rotation_error_deg"].as_f64().unwrap();
    json["truth"]["rotation_error_deg"] = serde_json::json!(rotation + 0.2);
    std::fs::write(&summary, serde_json::to_string(&json).unwrap()).unwrap();
    let bad = probecal()
        .arg("check")
        .arg(&summary)
        .arg("--baselines")
        .arg(&baselines)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("truth_rotation_error_deg") && !stderr.contains("truth_corner_error_mm"),
        "{stderr}"
    );
}

#[test]
fn committed_baselines_cover_every_default_experiment() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for entry in std::fs::read_dir(root.join("experiments")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "yaml") {
            let experiment = probecal::manifest::Experiment::load(&path).unwrap();
            let baseline = probecal::report::runs::check::load_baseline(
                &probecal::report::runs::check::baseline_path(
                    &root.join("experiments/baselines"),
                    experiment.experiment(),
                ),
                experiment.experiment(),
            )
            .unwrap_or_else(|e| panic!("{e}"));
            let datasets: Vec<String> = match &experiment {
                probecal::manifest::Experiment::Camera(m) => m.datasets.iter().map(|d| d.name.clone()).collect(),
                probecal::manifest::Experiment::Tracked(m) => vec![m.dataset.clone()],
            };
            for d in datasets {
                assert!(
                    baseline.datasets.contains_key(&d),
                    "baseline of {} lacks dataset {d}",
                    experiment.experiment()
                );
            }
        }
    }
}

#[test]
fn study_manifests_load() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/studies");
    let mut loaded = 0;
    for entry in std::fs::read_dir(&root).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "yaml") {
            probecal::manifest::Experiment::load(&path).unwrap_or_else(|e| panic!("{e}"));
            loaded += 1;
        }
    }
    assert!(loaded > 0, "experiments/studies/ holds no study manifest");
}

#[test]
fn every_study_manifest_says_how_it_is_run_and_its_study_is_committed() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for entry in std::fs::read_dir(root.join("experiments/studies")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "yaml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let command = text
            .lines()
            .find_map(|l| l.trim_start_matches('#').trim().strip_prefix("probecal study "))
            .unwrap_or_else(|| panic!("{name}: no `probecal study` command in its header"));
        assert!(
            command.starts_with(&format!("experiments/studies/{name} ")),
            "{name}: its command runs another manifest: {command}"
        );
        let out = command
            .split_whitespace()
            .skip_while(|w| *w != "--out")
            .nth(1)
            .unwrap_or_else(|| panic!("{name}: its command names no --out"));
        assert!(
            root.join(out).join("study.json").is_file(),
            "{name}: {out}/study.json is not committed"
        );
    }
}
