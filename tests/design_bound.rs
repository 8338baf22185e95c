//! The committed design table and printable model are what the code writes now
//! (a change of the bound, the candidates or the manifest fails here until
//! `probecal design` and `probecal phantom` are run again and committed), and
//! the experiment's layout is one of the table's candidates, at the rank the
//! table gives it (`docs/results/multi-sphere.md` states that rank).

mod common;

use common::{probecal, root, scratch};
use probecal::pipeline::run::design::{self, DESIGN_SEEDS};

fn bound_mm(v: &serde_json::Value) -> f64 {
    v["Ok"]["rms_mm"].as_f64().unwrap_or(f64::INFINITY)
}

#[test]
fn the_committed_table_is_current_and_ranks_the_experiments_layout() {
    let path = root().join("experiments/spheres_checkerboard.yaml");
    let (manifest, spec) = probecal::pipeline::run::lab::rendered_lab(&path).unwrap();
    let committed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root().join("reports/design/design.json")).unwrap()).unwrap();
    let layouts = committed["layouts"].as_array().unwrap();
    // Ranked: the bounds ascend.
    let bounds: Vec<f64> = layouts.iter().map(|r| bound_mm(&r["bound"])).collect();
    assert!(bounds.windows(2).all(|w| w[0] <= w[1]), "{bounds:?}");
    // The experiment's phantom is one of the candidates, and its page states its rank.
    let ours = serde_json::to_value(&manifest.phantom).unwrap();
    let rank = 1 + layouts
        .iter()
        .position(|r| r["phantom"] == ours)
        .expect("the experiment's domes are not a layout of reports/design/design.json");
    let page = std::fs::read_to_string(root().join("docs/results/multi-sphere.md")).unwrap();
    let stated = format!("ranks {rank} of {}", layouts.len());
    assert!(
        page.contains(&stated),
        "docs/results/multi-sphere.md does not say the layout {stated}"
    );
    // Its bound, recomputed now, is the committed one.
    let fresh = design::bound_over_sweeps(&manifest, &manifest.phantom, &spec, DESIGN_SEEDS).unwrap();
    let stored = bound_mm(&committed["manifest_phantom"]);
    assert!(
        (fresh.rms_mm - stored).abs() < 1e-9,
        "bound {} now, {stored} committed",
        fresh.rms_mm
    );
    assert!((fresh.rms_mm - bounds[rank - 1]).abs() < 1e-9);
    // The hemisphere cannot observe the planes' elevation: its bound is far higher.
    assert!(bound_mm(&committed["hemisphere"]) > 5.0 * fresh.rms_mm, "{committed:#}");
}

#[test]
fn the_committed_printable_model_is_what_probecal_phantom_writes() {
    let dir = scratch("design_bound", "stl");
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("spheres_checkerboard.stl");
    let out = probecal()
        .args([
            "phantom",
            root().join("experiments/spheres_checkerboard.yaml").to_str().unwrap(),
            "--stl",
            stl.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let committed = std::fs::read(root().join("reports/design/spheres_checkerboard.stl")).unwrap();
    assert!(
        std::fs::read(&stl).unwrap() == committed,
        "reports/design/spheres_checkerboard.stl is not what `probecal phantom` writes now"
    );
    let sheet = std::fs::read(stl.with_extension("json")).unwrap();
    assert!(
        sheet == std::fs::read(root().join("reports/design/spheres_checkerboard.json")).unwrap(),
        "reports/design/spheres_checkerboard.json is not the sheet `probecal phantom` writes now"
    );
}
