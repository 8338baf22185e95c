//! The point and 4-wire phantoms from rendered pixels: the spot detector against
//! the true pin heads and wire dots, and the whole command line against the true
//! calibration.

use std::path::{Path, PathBuf};
use std::process::Command;

use probecal::detect::spot::{self, SpotSettings};
use probecal::manifest::{DatasetSource, Manifest};
use serde_json::Value;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures").join(name)
}

/// Renders a fixture's dataset once per test binary and returns its folder and truth.
fn rendered(name: &str) -> (PathBuf, Value) {
    let manifest = Manifest::load(&fixture(name)).expect("fixture");
    let DatasetSource::Render(spec) = &manifest.datasets[0].source else {
        panic!("fixture renders")
    };
    let folder = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("point_and_wires")
        .join(&manifest.experiment);
    probecal::synth::ensure_rendered(&probecal::pipeline::settings::lab(&manifest), spec, &folder).expect("render");
    let truth = serde_json::from_str(&std::fs::read_to_string(folder.join("ground_truth.json")).unwrap()).unwrap();
    (folder, truth)
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

fn pixel(v: &Value) -> [f64; 2] {
    serde_json::from_value(v.clone()).unwrap()
}

#[test]
#[ignore = "renders and runs experiments (full tier: scripts/test.sh)"]
fn pin_heads_are_found_at_their_centre() {
    let (folder, truth) = rendered("point_small.yaml");
    let settings = SpotSettings {
        spacing_mm_per_px: [0.2, 0.2],
        object_radius_mm: 1.0,
    };
    let mut errors = Vec::new();
    for frame in truth["frames"].as_array().unwrap() {
        if frame["kind"] != "normal" {
            continue;
        }
        let k = frame["frame"].as_u64().unwrap();
        let image = probecal::io::image::read_gray(&folder.join(format!("frames/bscan_{k:03}.png"))).unwrap();
        let spots = spot::detect(&image, &settings).unwrap();
        // The fan's apex is found from the image's own mask.
        let apex = spots.apex_px.expect("convex probe");
        let true_apex: [f64; 2] = pixel(&truth["bscan_apex_mm"]).map(|v| v / 0.2);
        assert!(distance(apex, true_apex) < 1.0, "apex {apex:?} vs {true_apex:?}");
        let centre = pixel(&frame["centre_projection_px"]);
        // The head is among the compact echoes; its centre is one radius behind its echo.
        let nearest = spots
            .spots
            .iter()
            .map(|s| distance(s.centre_px, centre))
            .fold(f64::MAX, f64::min);
        errors.push(nearest);
    }
    assert!(errors.len() >= 10, "{} normal frames", errors.len());
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    // 0.2 mm/px: a median within 0.3 mm, and most frames within 0.5 mm.
    assert!(median < 1.5, "median {median} px, {errors:?}");
    let within = errors.iter().filter(|e| **e < 2.5).count();
    assert!(within * 10 >= errors.len() * 8, "{errors:?}");
}

#[test]
#[ignore = "renders and runs experiments (full tier: scripts/test.sh)"]
fn wire_dots_are_found_on_their_wires() {
    let (folder, truth) = rendered("four_wire_small.yaml");
    let settings = SpotSettings {
        spacing_mm_per_px: [0.2, 0.2],
        object_radius_mm: 0.75,
    };
    let (mut found, mut total, mut errors) = (0, 0, Vec::new());
    for frame in truth["frames"].as_array().unwrap() {
        if frame["kind"] != "normal" {
            continue;
        }
        let k = frame["frame"].as_u64().unwrap();
        let image = probecal::io::image::read_gray(&folder.join(format!("frames/bscan_{k:03}.png"))).unwrap();
        let spots = spot::detect(&image, &settings).unwrap();
        let dots: Vec<[f64; 2]> = frame["wire_dots_px"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| pixel(&d["pixel"]))
            .collect();
        assert_eq!(dots.len(), 4, "frame {k}: every wire crosses the plane");
        for (i, dot) in dots.iter().enumerate() {
            // Dots of wires closer than 3 mm merge into one echo; they are not counted.
            if dots
                .iter()
                .enumerate()
                .any(|(j, o)| j != i && distance(*o, *dot) < 15.0)
            {
                continue;
            }
            total += 1;
            let nearest = spots
                .spots
                .iter()
                .map(|s| distance(s.centre_px, *dot))
                .fold(f64::MAX, f64::min);
            if nearest < 2.5 {
                found += 1;
                errors.push(nearest);
            }
        }
    }
    assert!(total >= 30, "{total} separate dots");
    assert!(found * 10 >= total * 9, "{found} of {total} dots found within 0.5 mm");
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    assert!(mean < 1.25, "mean dot error {mean} px");
}

fn run(name: &str) -> Value {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("point_and_wires_runs")
        .join(name);
    let result = Command::new(env!("CARGO_BIN_EXE_probecal"))
        .arg("run")
        .arg(fixture(name))
        .arg("--out")
        .arg(&out)
        .arg("--force")
        .arg("--datasets")
        .arg(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("point_and_wires_datasets"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&result.stdout);
    assert!(
        result.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let experiment = name.trim_end_matches(".yaml");
    serde_json::from_str(&std::fs::read_to_string(out.join(experiment).join("small/summary.json")).unwrap()).unwrap()
}

#[test]
#[ignore = "renders and runs experiments (full tier: scripts/test.sh)"]
fn point_phantom_calibrates_from_pixels() {
    // 17 frames of a short sweep and 8 camera views: looser than the default
    // experiment (50 frames, 0.23 mm), which the baselines hold.
    let summary = run("point_small.yaml");
    let error = summary["truth"]["corner_error_mm"]["mean"].as_f64().unwrap();
    assert!(error < 2.0, "image corners off by {error} mm");
}

#[test]
#[ignore = "renders and runs experiments (full tier: scripts/test.sh)"]
fn four_wire_phantom_calibrates_from_pixels_started_off_the_truth() {
    let summary = run("four_wire_small.yaml");
    let error = summary["truth"]["corner_error_mm"]["mean"].as_f64().unwrap();
    assert!(error < 2.0, "image corners off by {error} mm");
    assert!(
        summary["frames"]["used"].as_u64().unwrap() >= 12,
        "{}",
        summary["frames"]
    );
    // The start's offset is measured, and the basin shrinks with the offset:
    // every start close by converges, none from far away.
    let guess = &summary["start_guess"];
    assert!(guess["offset_translation_mm"].as_f64().unwrap() > 1.0, "{guess}");
    let basin = guess["basin"].as_array().unwrap();
    let rate = |row: &serde_json::Value| row["converged"].as_f64().unwrap() / row["trials"].as_f64().unwrap();
    assert_eq!(basin.len(), 7);
    assert!(rate(&basin[0]) >= 0.9, "{guess}");
    assert!(rate(&basin[6]) <= 0.2, "{guess}");
}
