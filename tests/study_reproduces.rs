//! The committed studies (`reports/study/`) take most of an hour to run, so CI
//! does not run them whole; it runs each one's first seed afresh and requires
//! the same per-method errors as the committed file. A change of the code that
//! moves a study's numbers fails here until the study is run again and committed.

mod common;

use common::{probecal, root, scratch};

/// (manifest, committed study folder under `reports/`).
const STUDIES: [(&str, &str); 37] = [
    ("experiments/hemisphere_charuco.yaml", "study/rigs/charuco"),
    ("experiments/hemisphere_aruco.yaml", "study/rigs/aruco"),
    (
        "experiments/hemisphere_charuco_occluded.yaml",
        "study/rigs/charuco_occluded",
    ),
    (
        "experiments/hemisphere_checkerboard_occluded.yaml",
        "study/rigs/checkerboard_occluded",
    ),
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
    ("experiments/spheres_checkerboard.yaml", "study/spheres_30"),
    ("experiments/spheres_checkerboard.yaml", "study/spheres_choice/refine"),
    (
        "experiments/studies/spheres_views_only.yaml",
        "study/spheres_choice/views_only",
    ),
    (
        "experiments/studies/spheres_views_only.yaml",
        "study/spheres_views_only",
    ),
    ("experiments/spheres_checkerboard.yaml", "study/spheres_design_seeds"),
    ("experiments/studies/spheres_thin_beam.yaml", "study/spheres_thin_beam"),
    (
        "experiments/studies/spheres_uniform_arcs.yaml",
        "study/spheres_uniform_arcs",
    ),
    (
        "experiments/studies/spheres_uniform_arcs.yaml",
        "study/spheres_edge/none",
    ),
    (
        "experiments/studies/spheres_normal_peak.yaml",
        "study/spheres_normal_peak",
    ),
    (
        "experiments/studies/spheres_edge_obliquity.yaml",
        "study/spheres_edge/obliquity",
    ),
    (
        "experiments/studies/spheres_edge_slice.yaml",
        "study/spheres_edge/slice",
    ),
    (
        "experiments/studies/spheres_edge_constant.yaml",
        "study/spheres_edge/constant",
    ),
    (
        "experiments/studies/spheres_edge_constant_and_obliquity.yaml",
        "study/spheres_edge/constant_and_obliquity",
    ),
    (
        "experiments/studies/spheres_prior_half.yaml",
        "study/spheres_prior/prior_half",
    ),
    (
        "experiments/studies/spheres_prior_double.yaml",
        "study/spheres_prior/prior_double",
    ),
    (
        "experiments/studies/spheres_blur_half.yaml",
        "study/spheres_prior/blur_half",
    ),
    (
        "experiments/studies/spheres_blur_double.yaml",
        "study/spheres_prior/blur_double",
    ),
    (
        "experiments/studies/spheres_uniform_arcs.yaml",
        "study/spheres_heldout/uniform_arcs",
    ),
    (
        "experiments/studies/spheres_edge_slice.yaml",
        "study/spheres_heldout/edge_slice",
    ),
    ("experiments/thesis_twin_dataset3.yaml", "study/thesis_twin_dataset3"),
    ("experiments/thesis_twin_aruco.yaml", "study/thesis_twin_aruco"),
    ("experiments/thesis_twin_spheres.yaml", "study/thesis_twin_spheres"),
    (
        "experiments/thesis_twin_spheres.yaml",
        "study/thesis_twin_spheres_choice/chosen",
    ),
    (
        "experiments/studies/thesis_twin_spheres_refine.yaml",
        "study/thesis_twin_spheres_choice/refine",
    ),
    (
        "experiments/studies/thesis_twin_spheres_nominal_pixels.yaml",
        "study/thesis_twin_spheres_choice/nominal_pixels",
    ),
    (
        "experiments/studies/thesis_twin_spheres_refine.yaml",
        "study/thesis_twin_spheres_heldout/refine",
    ),
    (
        "experiments/studies/thesis_twin_spheres_nominal_pixels.yaml",
        "study/thesis_twin_spheres_heldout/nominal_pixels",
    ),
];

fn first_seed(study: &serde_json::Value) -> &serde_json::Value {
    &study["monte_carlo"]["seeds"][0]
}

#[test]
#[ignore = "renders and runs one seed of each study (long reproductions: scripts/reproduce.sh)"]
fn the_first_seed_of_every_committed_study_reproduces() {
    let mut differ = Vec::new();
    // Studies of one manifest from one seed share that seed's run: it is run once.
    let mut fresh_seeds: Vec<(&str, u64, serde_json::Value)> = Vec::new();
    // Studies of one rig's seed under other manifests (estimator settings) copy
    // its render (fresh for this run: the cache is keyed by inputs, not code).
    let render_cache = scratch("study_reproduces", "render_cache");
    for (manifest, folder) in STUDIES {
        let committed_path = root().join("reports").join(folder).join("study.json");
        let committed: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&committed_path).unwrap()).unwrap();
        let seed = first_seed(&committed)["seed"].as_u64().unwrap();
        if !fresh_seeds.iter().any(|(m, s, _)| *m == manifest && *s == seed) {
            let out = scratch("study_reproduces", &folder.replace('/', "_"));
            let datasets = out.join("datasets");
            let r = probecal()
                .arg("study")
                .arg(root().join(manifest))
                .args(["--seeds", "1", "--first-seed", &seed.to_string(), "--out"])
                .arg(&out)
                .arg("--datasets")
                .arg(&datasets)
                .env(probecal::synth::render_cache::ENV, &render_cache)
                .output()
                .unwrap();
            assert!(r.status.success(), "{manifest}: {}", String::from_utf8_lossy(&r.stderr));
            let fresh: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).unwrap()).unwrap();
            fresh_seeds.push((manifest, seed, first_seed(&fresh).clone()));
        }
        let (_, _, now) = fresh_seeds
            .iter()
            .find(|(m, s, _)| *m == manifest && *s == seed)
            .unwrap();
        let was = first_seed(&committed);
        if was["rms_error_mm"] != now["rms_error_mm"] || was["frames_used"] != now["frames_used"] {
            differ.push(format!(
                "{manifest} ({folder}), seed {seed}:\n  committed {}\n  fresh     {}",
                was["rms_error_mm"], now["rms_error_mm"]
            ));
        }
    }
    assert!(
        differ.is_empty(),
        "a committed study no longer reproduces; run it again (docs/results/estimators-and-studies.md) and commit it:\n{}",
        differ.join("\n")
    );
}

/// `a` and `b` alike: the same structure and text, numbers equal to within
/// 1e-12 of their size (`serde_json` reads a number to within its last bit,
/// so a number read and written again may move there).
fn alike(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            (x - y).abs() <= 1e-12 * x.abs().max(1.0)
        }
        (Value::Array(x), Value::Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(x, y)| alike(x, y)),
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| alike(v, w)))
        }
        _ => a == b,
    }
}

/// What a study writes beyond its seeds (each method's mean, percentile, RMS,
/// its ratio to the bound and that ratio's interval, the pages) is a function
/// of the seeds alone: every committed study must be what the current code
/// makes of its own seeds (the pages byte for byte), or its summary has drifted.
#[test]
fn every_committed_study_is_the_summary_of_its_own_seeds() {
    let mut differ = Vec::new();
    for (_, folder) in STUDIES {
        let committed = root().join("reports").join(folder);
        let file = probecal::report::study::StudyFile::read(&committed.join("study.json")).unwrap();
        let mc = file.monte_carlo.expect("a committed study has seeds");
        let again = probecal::pipeline::study::summarise(&mc.experiment, mc.bound, mc.seeds.clone());
        let out = scratch("study_summary", &folder.replace('/', "_"));
        probecal::report::study::write(&out, &file.sigma_table, Some(&again)).unwrap();
        let json = |dir: &std::path::Path| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(dir.join("study.json")).unwrap()).unwrap()
        };
        if !alike(&json(&committed), &json(&out)) {
            differ.push(format!("reports/{folder}/study.json"));
        }
        for name in ["study.md", "study.html"] {
            let made = std::fs::read(out.join(name)).unwrap();
            if std::fs::read(committed.join(name)).unwrap() != made {
                // UPDATE_STUDY_PAGES=1 writes the pages the code makes (after a page's template changed).
                if std::env::var_os("UPDATE_STUDY_PAGES").is_some() {
                    std::fs::write(committed.join(name), &made).unwrap();
                } else {
                    differ.push(format!("reports/{folder}/{name}"));
                }
            }
        }
    }
    assert!(
        differ.is_empty(),
        "not what the code makes of the study's own seeds (probecal study merge of its seeds rewrites them):\n{}",
        differ.join("\n")
    );
}

/// The committed error budget's page is its own Markdown's, as the code renders
/// it now (UPDATE_STUDY_PAGES=1 rewrites it).
#[test]
fn the_committed_ablation_page_is_its_markdowns() {
    let folder = root().join("reports/ablation/thesis_twin_dataset3");
    let md = std::fs::read_to_string(folder.join("ablation.md")).unwrap();
    let made = probecal::report::study::html(&md).unwrap();
    if std::env::var_os("UPDATE_STUDY_PAGES").is_some() {
        std::fs::write(folder.join("ablation.html"), &made).unwrap();
    }
    assert_eq!(std::fs::read_to_string(folder.join("ablation.html")).unwrap(), made);
}
