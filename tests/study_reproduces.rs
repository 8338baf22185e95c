//! The committed studies (`reports/study/`) take most of an hour to run, so CI
//! does not run them whole; it runs each one's first seed afresh and requires
//! the same per-method errors as the committed file. A change of the code that
//! moves a study's numbers fails here until the study is run again and committed.

mod common;

use common::{probecal, root, scratch};

/// (manifest, committed study folder under `reports/`).
const STUDIES: [(&str, &str); 12] = [
    ("experiments/hemisphere_checkerboard.yaml", "study"),
    ("experiments/studies/hemisphere_true_camera.yaml", "study/true_camera"),
    (
        "experiments/studies/hemisphere_planes_through_centre.yaml",
        "study/planes_through_centre",
    ),
    (
        "experiments/studies/hemisphere_off_centre_planes.yaml",
        "study/off_centre_planes",
    ),
    (
        "experiments/studies/hemisphere_more_outliers.yaml",
        "study/more_outliers",
    ),
    ("experiments/spheres_checkerboard.yaml", "study/spheres"),
    ("experiments/spheres_checkerboard.yaml", "study/spheres_choice/refine"),
    (
        "experiments/studies/spheres_views_only.yaml",
        "study/spheres_choice/views_only",
    ),
    (
        "experiments/studies/spheres_views_only.yaml",
        "study/spheres_views_only",
    ),
    ("experiments/studies/spheres_thin_beam.yaml", "study/spheres_thin_beam"),
    ("experiments/thesis_twin_dataset3.yaml", "study/thesis_twin_dataset3"),
    ("experiments/thesis_twin_aruco.yaml", "study/thesis_twin_aruco"),
];

fn first_seed(study: &serde_json::Value) -> &serde_json::Value {
    &study["monte_carlo"]["seeds"][0]
}

#[test]
#[ignore = "renders and runs one seed of each study (full tier: scripts/test.sh)"]
fn the_first_seed_of_every_committed_study_reproduces() {
    let mut differ = Vec::new();
    for (manifest, folder) in STUDIES {
        let committed_path = root().join("reports").join(folder).join("study.json");
        let committed: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&committed_path).unwrap()).unwrap();
        let seed = first_seed(&committed)["seed"].as_u64().unwrap();
        let out = scratch("study_reproduces", &folder.replace('/', "_"));
        let datasets = out.join("datasets");
        let r = probecal()
            .arg("study")
            .arg(root().join(manifest))
            .args(["--seeds", "1", "--first-seed", &seed.to_string(), "--out"])
            .arg(&out)
            .arg("--datasets")
            .arg(&datasets)
            .output()
            .unwrap();
        assert!(r.status.success(), "{manifest}: {}", String::from_utf8_lossy(&r.stderr));
        let fresh: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).unwrap()).unwrap();
        let (was, now) = (first_seed(&committed), first_seed(&fresh));
        if was["rms_error_mm"] != now["rms_error_mm"] || was["frames_used"] != now["frames_used"] {
            differ.push(format!(
                "{manifest}, seed {seed}:\n  committed {}\n  fresh     {}",
                was["rms_error_mm"], now["rms_error_mm"]
            ));
        }
    }
    assert!(
        differ.is_empty(),
        "a committed study no longer reproduces; run it again (README: Studies) and commit it:\n{}",
        differ.join("\n")
    );
}
