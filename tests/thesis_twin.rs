//! The twin of the thesis's rig (`experiments/thesis_twin_*.yaml`): its values
//! come from their stated sources, and its committed error budget
//! (`reports/ablation/`) reproduces.

mod common;

use common::{probecal, root, scratch, shared_data};

const TWINS: [&str; 5] = [
    "thesis_twin_dataset1",
    "thesis_twin_dataset2",
    "thesis_twin_dataset3",
    "thesis_twin_aruco",
    "thesis_twin_spheres",
];

/// `key value` lines of a command's output.
fn value(output: &str, key: &str) -> f64 {
    output
        .lines()
        .find_map(|l| l.strip_prefix(key)?.trim().parse().ok())
        .unwrap_or_else(|| panic!("`{key}` not in:\n{output}"))
}

#[test]
#[ignore = "reads PLUS's fCal recording in ../shared/data (full tier: scripts/test.sh)"]
fn the_twins_hand_speed_is_the_one_measured_on_plus_recording() {
    let sequence = shared_data("plus-fcal2.0-3nwires", "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha");
    let out = std::process::Command::new("python3")
        .arg(root().join("scripts/hand-speed.py"))
        .arg(&sequence)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let (speed, spin) = (value(&text, "speed_mm_per_s"), value(&text, "rotation_deg_per_s"));
    assert!(speed > 0.5 && speed < 50.0 && spin > 0.1 && spin < 30.0, "{text}");
    for twin in TWINS {
        let yaml = std::fs::read_to_string(root().join(format!("experiments/{twin}.yaml"))).unwrap();
        let stated = format!("hand: {{speed_mm_per_s: {speed:.2}, rotation_deg_per_s: {spin:.2}}}");
        assert!(
            yaml.contains(&stated),
            "{twin}: the manifest's hand is not the measured `{stated}`"
        );
    }
}

/// The committed error budget is the results model's `AblationFile` whole:
/// read into it and written back, nothing is lost or added, and it says its
/// schema version.
#[test]
fn the_committed_error_budget_reads_into_the_results_model_whole() {
    let path = root().join("reports/ablation/thesis_twin_dataset3/ablation.json");
    let text = std::fs::read_to_string(&path).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let file: probecal::results::ablation::AblationFile = serde_json::from_value(value.clone()).unwrap();
    assert_eq!(file.schema_version, probecal::results::SCHEMA_VERSION);
    assert!(
        serde_json::to_value(&file).unwrap() == value,
        "{}: read into the model and written back, it differs",
        path.display()
    );
}

#[test]
#[ignore = "renders and runs one variant of the committed ablation (full tier: scripts/test.sh)"]
fn a_variant_of_the_committed_error_budget_reproduces() {
    let committed_path = root().join("reports/ablation/thesis_twin_dataset3/ablation.json");
    let committed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&committed_path).unwrap()).unwrap();
    let variant = "only speed_of_sound";
    let row = committed["variants"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["variant"] == variant)
        .unwrap_or_else(|| panic!("{variant} not in {}", committed_path.display()));
    let out = scratch("thesis_twin", "ablation");
    let datasets = out.join("datasets");
    let r = probecal()
        .arg("ablate")
        .arg(root().join("experiments/thesis_twin_dataset3.yaml"))
        .args(["--only", variant, "--keep-datasets", "--out"])
        .arg(out.join("ablation"))
        .arg("--datasets")
        .arg(&datasets)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let fresh: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("ablation/ablation.json")).unwrap()).unwrap();
    assert_eq!(
        &fresh["variants"][0], row,
        "the committed row of `{variant}` does not reproduce"
    );

    // The scanner's 1540 m/s against water's 1482 m/s: the truth knows where
    // each displayed echo really is.
    let truth_path = datasets.join("thesis_twin_dataset3__ablation_only_speed_of_sound/ground_truth.json");
    let truth: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&truth_path).unwrap()).unwrap();
    let k = truth["range_scale"].as_f64().unwrap();
    assert!((k - 1482.0 / 1540.0).abs() < 1e-12, "range_scale {k}");

    // An unknown variant is refused by name.
    let r = probecal()
        .arg("ablate")
        .arg(root().join("experiments/thesis_twin_dataset3.yaml"))
        .args(["--only", "only fog", "--out"])
        .arg(out.join("nothing"))
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no variant `only fog`"));
}

#[test]
fn the_multi_sphere_twin_has_the_hemisphere_twins_error_sources() {
    let realism = |name: &str| {
        let path = root().join(format!("experiments/{name}.yaml"));
        let yaml: serde_yaml::Value = serde_yaml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        yaml["datasets"][0]["render"]["realism"].clone()
    };
    let hemisphere = realism("thesis_twin_dataset3");
    assert!(hemisphere.as_mapping().is_some_and(|m| m.len() >= 10), "{hemisphere:?}");
    assert_eq!(realism("thesis_twin_spheres"), hemisphere);
}
