//! `probecal phantom` writes the multi-sphere phantom as an STL that an
//! independent reader (ADMesh, as slicers use) finds closed, consistently
//! oriented, of the model's volume and of the manifest's size.

mod common;

use common::{probecal, root, scratch};

/// A number after `label` in ADMesh's report.
fn field(report: &str, label: &str) -> f64 {
    let line = report
        .lines()
        .find(|l| l.contains(label))
        .unwrap_or_else(|| panic!("`{label}` not in ADMesh's report:\n{report}"));
    let after = &line[line.find(label).unwrap() + label.len()..];
    after
        .split(|c: char| c == ':' || c == ',' || c.is_whitespace())
        .find_map(|w| w.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no number after `{label}` in `{line}`"))
}

#[test]
fn the_spheres_phantom_is_a_closed_printable_mesh_of_its_manifests_size() {
    let dir = scratch("phantom_stl", "spheres");
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("spheres.stl");
    let manifest = root().join("experiments/spheres_checkerboard.yaml");
    let out = probecal()
        .args(["phantom", manifest.to_str().unwrap(), "--stl", stl.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let admesh = std::process::Command::new("admesh")
        .arg(&stl)
        .output()
        .expect("ADMesh (Debian package admesh, installed by scripts/setup.sh) reads the STL");
    assert!(admesh.status.success());
    let report = String::from_utf8_lossy(&admesh.stdout).to_string();

    // The model as the library builds it from the manifest.
    let (m, render) = probecal::report::phantom::rendered_lab(&manifest).unwrap();
    let rig = probecal::detect::board_pose::RigBoards::from_rig(&m.rig).unwrap();
    let model = probecal::synth::printable::model(&m.phantom, &rig.phantom, &render).unwrap();
    let probecal::spec::phantom::Phantom::Spheres { spheres } = &m.phantom else {
        panic!("a spheres phantom");
    };
    assert_eq!(model.domes.len(), spheres.len());

    // Closed shells (no open edge), consistently oriented, nothing to repair:
    // the plate and one pillar with its dome per sphere.
    for label in [
        "Total disconnected facets",
        "Degenerate facets",
        "Edges fixed",
        "Facets removed",
        "Facets added",
        "Facets reversed",
        "Backwards edges",
        "Normals fixed",
    ] {
        assert_eq!(field(&report, label), 0.0, "{label}:\n{report}");
    }
    assert_eq!(
        field(&report, "Number of parts"),
        (1 + spheres.len()) as f64,
        "{report}"
    );
    // Outward normals give a positive volume, the smooth model's within 0.5 %.
    let volume = field(&report, "Volume");
    assert!(
        (volume / model.volume_mm3() - 1.0).abs() < 0.005,
        "ADMesh volume {volume} mm³ vs the model's {} mm³",
        model.volume_mm3()
    );
    // Size: the plate's footprint, and the tallest dome's top.
    let top = model
        .domes
        .iter()
        .map(|d| d.centre_mm.z + d.radius_mm)
        .fold(0.0, f64::max);
    for (label, want) in [
        ("Min X =", model.plate_min_mm.x),
        ("Max X =", model.plate_max_mm.x),
        ("Min Y =", model.plate_min_mm.y),
        ("Max Y =", model.plate_max_mm.y),
        ("Min Z =", 0.0),
        ("Max Z =", top),
    ] {
        let got = field(&report, label);
        assert!((got - want).abs() < 0.05, "{label} {got} vs {want}");
    }
    // The domes keep the manifest's geometry: their radii and the distances
    // between their centres (the frame is the lab's, upright).
    for (i, (a, sa)) in model.domes.iter().zip(spheres).enumerate() {
        assert_eq!(a.radius_mm, sa.radius_mm);
        for (b, sb) in model.domes.iter().zip(spheres).skip(i + 1) {
            let printed = (a.centre_mm - b.centre_mm).norm();
            let manifest = (nalgebra::Vector3::from(sa.centre_in_phantom_mm)
                - nalgebra::Vector3::from(sb.centre_in_phantom_mm))
            .norm();
            assert!((printed - manifest).abs() < 1e-9, "{printed} vs {manifest}");
        }
    }
}

#[test]
fn a_phantom_without_domes_is_refused_naming_the_field() {
    let dir = scratch("phantom_stl", "refused");
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("wires.stl");
    let manifest = root().join("experiments/four_wire_checkerboard.yaml");
    let out = probecal()
        .args(["phantom", manifest.to_str().unwrap(), "--stl", stl.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("four_wire_checkerboard.yaml") && stderr.contains("phantom"),
        "{stderr}"
    );
    assert!(!stl.exists());
}
