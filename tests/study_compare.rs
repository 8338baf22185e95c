//! `probecal study compare`: two studies paired on the seeds they share.

mod common;

use common::{probecal, scratch};
use serde_json::{json, Value};

/// A study file: per seed (seed, error of `a`, error of `b`, frames kept).
fn study(experiment: &str, seeds: &[(u64, f64, f64, usize)]) -> Value {
    let methods: Vec<Value> = ["cutoff_worst_first", "ransac"]
        .iter()
        .map(|m| json!({"method": m, "mean_mm": 0.0, "p95_mm": 0.0, "rms_mm": 0.0}))
        .collect();
    let seeds: Vec<Value> = seeds
        .iter()
        .map(|(seed, a, b, frames)| {
            json!({
                "seed": seed,
                "rms_error_mm": [["cutoff_worst_first", a], ["ransac", b]],
                "crlb_rms_mm": null,
                "frames_used": frames,
            })
        })
        .collect();
    json!({
        "sigma_table": [],
        "monte_carlo": {
            "experiment": experiment,
            "seeds": seeds,
            "methods": methods,
            "crlb_rms_mm": 0.0,
        }
    })
}

#[test]
fn pairs_on_common_seeds_and_says_when_the_interval_holds_zero() {
    let dir = scratch("study_compare", "pairs");
    std::fs::create_dir_all(dir.join("a")).unwrap();
    // Study b: cutoff_worst_first 0.10 mm higher on every seed; ransac ± 0.05 about a's.
    let a: Vec<(u64, f64, f64, usize)> = (1000..1012)
        .map(|s| (s, 0.5 + 0.01 * (s % 3) as f64, 0.4, 48))
        .collect();
    let b: Vec<(u64, f64, f64, usize)> = (1002..1016)
        .map(|s| {
            let wobble = if s % 2 == 0 { 0.05 } else { -0.05 };
            (s, 0.6 + 0.01 * (s % 3) as f64, 0.4 + wobble, 30 + (s % 4) as usize)
        })
        .collect();
    std::fs::write(dir.join("a/study.json"), study("first", &a).to_string()).unwrap();
    std::fs::write(dir.join("b.json"), study("second", &b).to_string()).unwrap();
    let out = dir.join("paired.json");
    let r = probecal()
        .args(["study", "compare"])
        .arg(dir.join("a"))
        .arg(dir.join("b.json"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let printed = String::from_utf8_lossy(&r.stdout);
    assert!(printed.contains("paired on 10 common seeds (1002–1011)"), "{printed}");
    let paired: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(paired["seeds"].as_array().unwrap().len(), 10);
    let method = |name: &str| {
        paired["methods"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["method"] == name)
            .unwrap()
            .clone()
    };
    let worse = method("cutoff_worst_first");
    assert!((worse["mean_difference_mm"].as_f64().unwrap() - 0.1).abs() < 1e-9);
    assert_eq!(worse["verdict"], "higher");
    assert_eq!(worse["a_lower_seeds"], 10);
    let same = method("ransac");
    let [lo, hi] = [0, 1].map(|i| same["interval_90_mm"][i].as_f64().unwrap());
    assert!(lo < 0.0 && hi > 0.0, "{lo} {hi}");
    assert_eq!(same["verdict"], "no difference shown");
    assert_eq!(paired["frames_kept"]["min_b"], 30);
    assert!(out.with_extension("md").is_file());

    // Too few common seeds, and a file that is not a study: clear errors, exit 2.
    std::fs::write(dir.join("far.json"), study("far", &[(5000, 0.1, 0.1, 10)]).to_string()).unwrap();
    std::fs::write(dir.join("not.json"), "{\"sigma_table\": 3}").unwrap();
    for (other, message) in [("far.json", "share 0 seeds"), ("not.json", "not.json")] {
        let r = probecal()
            .args(["study", "compare"])
            .arg(dir.join("a"))
            .arg(dir.join(other))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(message), "{stderr}");
    }
}

/// One method against another of the same study: each seed's error of the
/// one less the other's; a method missing from the study, or `--method-b`
/// alone, is refused.
#[test]
fn pairs_two_methods_of_one_study() {
    let dir = scratch("study_compare", "methods");
    std::fs::create_dir_all(&dir).unwrap();
    // ransac 0.05 mm under cutoff_worst_first on every seed.
    let seeds: Vec<(u64, f64, f64, usize)> = (1000..1008)
        .map(|s| (s, 0.5 + 0.02 * (s % 4) as f64, 0.45 + 0.02 * (s % 4) as f64, 40))
        .collect();
    let file = dir.join("study.json");
    std::fs::write(&file, study("one", &seeds).to_string()).unwrap();
    let out = dir.join("paired.json");
    let r = probecal()
        .args(["study", "compare"])
        .arg(&file)
        .arg(&file)
        .args(["--method", "cutoff_worst_first", "--method-b", "ransac", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let paired: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(paired["methods_paired"], json!(["cutoff_worst_first", "ransac"]));
    let methods = paired["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 1);
    assert!((methods[0]["mean_difference_mm"].as_f64().unwrap() + 0.05).abs() < 1e-9);
    assert_eq!(methods[0]["verdict"], "lower");
    assert_eq!(methods[0]["b_lower_seeds"], 8);
    // b over a seed by seed: the geometric mean of the ratios, its interval about it.
    let logs: Vec<f64> = seeds.iter().map(|(_, a, b, _)| (b / a).ln()).collect();
    let geometric = (logs.iter().sum::<f64>() / logs.len() as f64).exp();
    let ratio = &methods[0]["ratio_b_over_a"];
    assert!(
        (ratio["geometric_mean"].as_f64().unwrap() - geometric).abs() < 1e-12,
        "{ratio}"
    );
    let [lo, hi] = [0, 1].map(|i| ratio["interval_90"][i].as_f64().unwrap());
    assert!(lo < geometric && geometric < hi && hi < 1.0, "{ratio}");
    assert_eq!(methods[0]["interval_method"], "student_t");
    let md = std::fs::read_to_string(out.with_extension("md")).unwrap();
    assert!(md.contains("`one ransac` against `one cutoff_worst_first`"), "{md}");

    for (args, message) in [
        (
            vec!["--method", "cutoff_worst_first", "--method-b", "lmeds"],
            "`lmeds` is not in it",
        ),
        (vec!["--method-b", "ransac"], "--method"),
    ] {
        let r = probecal()
            .args(["study", "compare"])
            .arg(&file)
            .arg(&file)
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(message), "{stderr}");
    }
}

/// Every committed paired comparison (`reports/study/**/*_vs_*.json`).
fn committed_comparisons() -> Vec<std::path::PathBuf> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            if path.is_dir() {
                walk(&path, out);
            } else if name.ends_with(".json") && name.contains("_vs_") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&common::root().join("reports/study"), &mut out);
    out.sort();
    out
}

/// The committed paired comparisons are what `study compare` makes of the
/// committed studies today.
#[test]
fn committed_paired_comparisons_regenerate() {
    let dir = scratch("study_compare", "committed");
    std::fs::create_dir_all(&dir).unwrap();
    let mut checked = 0;
    for path in committed_comparisons() {
        let committed: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let out = dir.join(format!("{checked}.json"));
        let mut command = probecal();
        command
            .current_dir(common::root())
            .args(["study", "compare"])
            .arg(committed["a_file"].as_str().unwrap())
            .arg(committed["b_file"].as_str().unwrap())
            .arg("--out")
            .arg(&out);
        if let Some([m, n]) = committed.get("methods_paired").map(|p| [&p[0], &p[1]]) {
            command.args(["--method", m.as_str().unwrap(), "--method-b", n.as_str().unwrap()]);
        }
        let r = command.output().unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        assert_eq!(
            std::fs::read_to_string(&out).unwrap(),
            std::fs::read_to_string(&path).unwrap(),
            "{} does not regenerate",
            path.display()
        );
        checked += 1;
    }
    assert!(checked >= 3, "{checked} paired comparisons in reports/study");
}

/// Every committed comparison is the results model's `PairedStudies` whole:
/// read into it and written back, nothing is lost or added, and it says the
/// schema version it was written in.
#[test]
fn committed_comparisons_read_into_the_results_model_whole() {
    let mut checked = 0;
    for path in committed_comparisons() {
        let text = std::fs::read_to_string(&path).unwrap();
        let value: Value = serde_json::from_str(&text).unwrap();
        let model: probecal::results::comparison::PairedStudies =
            serde_json::from_value(value.clone()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(serde_json::to_value(&model).unwrap(), value, "{}", path.display());
        assert_eq!(
            model.schema_version,
            probecal::results::SCHEMA_VERSION,
            "{}",
            path.display()
        );
        checked += 1;
    }
    assert!(checked >= 3, "{checked}");
}

/// Every committed comparison names how its intervals were made, and none uses
/// the percentile bootstrap on fewer than 30 seeds (too narrow at that size).
#[test]
fn committed_comparisons_name_their_interval_method_fit_for_their_size() {
    let mut checked = 0;
    for path in committed_comparisons() {
        let c: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let seeds = c["seeds"].as_array().unwrap().len();
        for m in c["methods"].as_array().unwrap() {
            let method = m["interval_method"].as_str();
            let fit = match method {
                Some("student_t") => seeds < 30,
                Some("percentile_bootstrap") => seeds >= 30,
                _ => false,
            };
            assert!(
                fit,
                "{}: {} on {seeds} seeds ({})",
                path.display(),
                m["method"],
                m["interval_method"]
            );
            checked += 1;
        }
    }
    assert!(checked >= 40, "{checked}");
}

/// A study whose seeds are not a sample is refused with the file, the seed and
/// why: a seed listed twice (it would count twice), an error that is negative
/// or not finite.
#[test]
fn a_study_with_a_repeated_seed_or_an_impossible_error_is_refused() {
    let dir = scratch("study_compare", "refused");
    std::fs::create_dir_all(&dir).unwrap();
    let good: Vec<(u64, f64, f64, usize)> = (1000..1010).map(|s| (s, 0.5, 0.4, 40)).collect();
    std::fs::write(dir.join("good.json"), study("good", &good).to_string()).unwrap();
    let mut repeated = good.clone();
    repeated.extend(std::iter::repeat_n((1003, 0.1, 0.9, 40), 8));
    let mut negative = good.clone();
    negative[4].2 = -0.3;
    let mut text = study("nan", &good).to_string();
    text = text.replacen("0.4]", "1e999]", 1);
    for (name, body, message) in [
        (
            "repeated",
            study("repeated", &repeated).to_string(),
            "seed 1003 is listed twice",
        ),
        (
            "negative",
            study("negative", &negative).to_string(),
            "seed 1004, method `ransac`: rms error -0.3",
        ),
        // JSON has no infinity: a number past f64's range is refused where it stands.
        ("infinite", text, "number out of range at line 1"),
    ] {
        let file = dir.join(format!("{name}.json"));
        std::fs::write(&file, body).unwrap();
        let r = probecal()
            .args(["study", "compare"])
            .arg(dir.join("good.json"))
            .arg(&file)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains(&file.display().to_string()) && stderr.contains(message),
            "{name}: {stderr}"
        );
    }
}

/// `--out` is a single file: an existing one (or its .md) is replaced only with
/// `--force`, and a name that is not .json is refused before anything is written.
#[test]
fn an_existing_comparison_is_replaced_only_with_force() {
    let dir = scratch("study_compare", "force");
    std::fs::create_dir_all(&dir).unwrap();
    let seeds: Vec<(u64, f64, f64, usize)> = (1000..1005)
        .map(|s| (s, 0.5, 0.4 + 0.01 * (s % 2) as f64, 40))
        .collect();
    let file = dir.join("study.json");
    std::fs::write(&file, study("one", &seeds).to_string()).unwrap();
    let notes = dir.join("notes.md");
    std::fs::write(&notes, "my notes\n").unwrap();
    let compare = |out: &std::path::Path, force: bool| {
        let mut c = probecal();
        c.args(["study", "compare"]).arg(&file).arg(&file).arg("--out").arg(out);
        if force {
            c.arg("--force");
        }
        c.output().unwrap()
    };
    // notes.json would put its Markdown over notes.md.
    let r = compare(&dir.join("notes.json"), false);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("notes.md: exists; pass --force"));
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "my notes\n");
    let r = compare(&dir.join("paired.txt"), false);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("name it .json"));
    let out = dir.join("paired.json");
    assert!(compare(&out, false).status.success());
    assert_eq!(compare(&out, false).status.code(), Some(2));
    assert!(compare(&out, true).status.success());
}
