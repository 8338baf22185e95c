//! `probecal phantom` writes the multi-sphere phantom as an STL that an
//! independent reader (ADMesh, as slicers use) finds closed, consistently
//! oriented, of the model's volume and of the manifest's size, and whose board
//! seat, read back from the file's own facets, holds the board's mount where
//! the phantom frame puts the pattern relative to the domes.

mod common;

use common::{probecal, root, scratch};
use nalgebra::{Matrix3, Vector3};

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

/// `probecal phantom` on the multi-sphere experiment into a scratch folder of
/// `test`: the STL's path, the manifest, the phantom board, and the model as
/// the library builds it from the manifest.
struct Written {
    stl: std::path::PathBuf,
    manifest: Box<probecal::manifest::Manifest>,
    board: probecal::detect::board::PrintedBoard,
    model: probecal::synth::printable::PrintableModel,
}

fn written(test: &str) -> Written {
    let dir = scratch("phantom_stl", test);
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("spheres.stl");
    let path = root().join("experiments/spheres_checkerboard.yaml");
    let out = probecal()
        .args(["phantom", path.to_str().unwrap(), "--stl", stl.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (manifest, render) = probecal::pipeline::run::lab::rendered_lab(&path).unwrap();
    let board = probecal::detect::board_pose::RigBoards::from_rig(&manifest.rig)
        .unwrap()
        .phantom;
    let model = probecal::synth::printable::model(&manifest.phantom, &board, &render).unwrap();
    Written {
        stl,
        manifest,
        board,
        model,
    }
}

#[test]
fn the_spheres_phantom_is_a_closed_printable_mesh_of_its_manifests_size() {
    let Written {
        stl,
        manifest: m,
        model,
        ..
    } = written("spheres");
    let admesh = std::process::Command::new("admesh")
        .arg(&stl)
        .output()
        .expect("ADMesh (Debian package admesh, installed by scripts/setup.sh) reads the STL");
    assert!(admesh.status.success());
    let report = String::from_utf8_lossy(&admesh.stdout).to_string();

    let probecal::spec::phantom::Phantom::Spheres { spheres } = &m.phantom else {
        panic!("a spheres phantom");
    };
    assert_eq!(model.domes.len(), spheres.len());

    // Closed shells (no open edge), consistently oriented, nothing to repair:
    // the plate, the riser, one pillar with its dome per sphere, the seat's two parts.
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
        model.shells(),
        1 + usize::from(model.riser.is_some()) + spheres.len() + 2
    );
    assert_eq!(field(&report, "Number of parts"), model.shells() as f64, "{report}");
    // Outward normals give a positive volume, the smooth model's within 0.5 %.
    let volume = field(&report, "Volume");
    assert!(
        (volume / model.volume_mm3() - 1.0).abs() < 0.005,
        "ADMesh volume {volume} mm³ vs the model's {} mm³",
        model.volume_mm3()
    );
    // Size: the plate's footprint, and the tallest dome's or the backrest's top.
    let top = model.top_mm();
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

/// The triangles of a binary STL, read here on their own (f32 as stored).
fn read_stl(path: &std::path::Path) -> Vec<[Vector3<f64>; 3]> {
    let bytes = std::fs::read(path).unwrap();
    let count = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
    assert_eq!(bytes.len(), 84 + 50 * count, "binary STL size");
    let f = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as f64;
    (0..count)
        .map(|i| {
            let at = 84 + 50 * i + 12;
            [0, 1, 2].map(|v| Vector3::new(f(at + 12 * v), f(at + 12 * v + 4), f(at + 12 * v + 8)))
        })
        .collect()
}

/// The rigid transform taking `from` onto `to` (least squares, Kabsch).
fn fit_rigid(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> (Matrix3<f64>, Vector3<f64>) {
    let n = from.len() as f64;
    let (cf, ct) = (
        from.iter().sum::<Vector3<f64>>() / n,
        to.iter().sum::<Vector3<f64>>() / n,
    );
    let h: Matrix3<f64> = from.iter().zip(to).map(|(a, b)| (a - cf) * (b - ct).transpose()).sum();
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    d[(2, 2)] = (v_t.transpose() * u.transpose()).determinant().signum();
    let r = v_t.transpose() * d * u.transpose();
    (r, ct - r * cf)
}

#[test]
fn the_board_seat_holds_the_mount_where_the_phantom_frame_puts_the_pattern() {
    let Written {
        stl,
        manifest: m,
        board,
        model,
    } = written("seat");
    let facets = read_stl(&stl);
    let probecal::spec::phantom::Phantom::Spheres { spheres } = &m.phantom else {
        panic!("a spheres phantom");
    };

    // The phantom frame in the file: from the domes' tops found among its
    // vertices to the manifest's centres.
    let mut in_phantom = Vec::new();
    let mut in_file = Vec::new();
    for (dome, sphere) in model.domes.iter().zip(spheres) {
        let top = dome.centre_mm.coords + Vector3::z() * dome.radius_mm;
        let found = facets
            .iter()
            .flatten()
            .find(|v| (*v - top).norm() < 1e-3)
            .unwrap_or_else(|| panic!("no dome top at {top:?} in the file"));
        in_file.push(found - Vector3::z() * sphere.radius_mm);
        in_phantom.push(Vector3::from(sphere.centre_in_phantom_mm));
    }
    let (r, t) = fit_rigid(&in_file, &in_phantom);
    let to_phantom = |v: &Vector3<f64>| r * v + t;
    for (a, b) in in_file.iter().zip(&in_phantom) {
        assert!(
            (to_phantom(a) - b).norm() < 1e-3,
            "the domes are not rigidly the manifest's"
        );
    }

    // The mount: the scene's plate around the pattern's centre, 3 mm thick.
    let centre = board.centre_mm();
    let half = probecal::synth::scene::PLATE_HALF_MM;
    let (left, right) = (centre.x - half, centre.x + half);
    let (top, bottom) = (centre.y - half, centre.y + half);
    let thick = probecal::synth::board_seat::MOUNT_MM;

    // The facets facing the mount on each of its three locating planes, in the
    // phantom frame: the backrest (facing −z at z = thick), the ledge (facing
    // −y at y = bottom) and the fence (facing +x at x = left).
    let on_plane = |normal: Vector3<f64>, axis: usize, at: f64| -> Vec<[Vector3<f64>; 3]> {
        facets
            .iter()
            .map(|f| f.map(|v| to_phantom(&v)))
            .filter(|f| {
                let n = (f[1] - f[0]).cross(&(f[2] - f[0])).normalize();
                n.dot(&normal) > 0.9999 && f.iter().all(|v| (v[axis] - at).abs() < 1e-3)
            })
            .collect()
    };
    let span = |faces: &[[Vector3<f64>; 3]], axis: usize| {
        let values = faces.iter().flatten().map(|v| v[axis]);
        (
            values.clone().fold(f64::INFINITY, f64::min),
            values.fold(f64::NEG_INFINITY, f64::max),
        )
    };
    let backrest = on_plane(-Vector3::z(), 2, thick);
    let ledge = on_plane(-Vector3::y(), 1, bottom);
    let fence = on_plane(Vector3::x(), 0, left);
    assert!(!backrest.is_empty(), "no backrest 3 mm behind the print");
    assert!(!ledge.is_empty(), "no ledge at the mount's bottom edge");
    assert!(!fence.is_empty(), "no fence at the mount's left edge");
    // The backrest spans the mount's width, from its bottom edge to its centre.
    let (x0, x1) = span(&backrest, 0);
    let (y0, y1) = span(&backrest, 1);
    assert!(x0 <= left + 1e-3 && x1 >= right - 1e-3, "backrest x {x0}..{x1}");
    assert!(y1 >= bottom - 1e-3 && y0 <= centre.y + 1e-3, "backrest y {y0}..{y1}");
    // The ledge carries the mount's whole bottom edge, front to back.
    let (z0, z1) = span(&ledge, 2);
    let (x0, x1) = span(&ledge, 0);
    assert!(z0 <= 1e-3 && z1 >= thick - 1e-3, "ledge z {z0}..{z1}");
    assert!(x0 <= left + 1e-3 && x1 >= right - 1e-3, "ledge x {x0}..{x1}");
    // The fence meets the mount's left edge across its thickness, up from the ledge.
    let (z0, z1) = span(&fence, 2);
    let (y0, y1) = span(&fence, 1);
    assert!(z0 <= 1e-3 && z1 >= thick - 1e-3, "fence z {z0}..{z1}");
    assert!(y1 >= bottom - 1e-3 && y0 < bottom - 10.0, "fence y {y0}..{y1}");
    // The sheet beside the STL gives the same corner, and the origin's distances
    // from the fence and the ledge, for checking the print with calipers.
    let sheet: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(stl.with_extension("json")).unwrap()).unwrap();
    let seat = &sheet["board_seat"];
    let corner: Vec<f64> = serde_json::from_value(seat["front_corner_mm"].clone()).unwrap();
    let corner = Vector3::new(corner[0], corner[1], corner[2]);
    assert!(
        (to_phantom(&corner) - Vector3::new(left, bottom, 0.0)).norm() < 1e-3,
        "the sheet's corner {corner:?} is not the seat's"
    );
    assert_eq!(seat["origin_from_fence_mm"].as_f64(), Some(-left));
    assert_eq!(seat["origin_above_ledge_mm"].as_f64(), Some(bottom));
    assert_eq!(seat["mount_thickness_mm"].as_f64(), Some(thick));
    assert_eq!(sheet["shells"].as_u64(), Some(model.shells() as u64));
    // Nothing of the model is inside the mount, nor in front of the pattern.
    for v in facets.iter().flatten().map(to_phantom) {
        let inside = v.x > left + 1e-3 && v.x < right - 1e-3 && v.y > top + 1e-3 && v.y < bottom - 1e-3;
        assert!(
            !(inside && v.z < thick - 1e-3),
            "a vertex at {v:?} (phantom frame) is in the mount's way"
        );
    }
}

/// The sheet goes beside the STL as <name>.json: a file of that name that is
/// already there (another model's sheet, one's notes) is replaced only with
/// --force, and nothing is written without it.
#[test]
fn an_existing_file_beside_the_stl_is_replaced_only_with_force() {
    let dir = scratch("phantom_stl", "force");
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("k.stl");
    std::fs::write(dir.join("k.json"), "{\"mine\": true}\n").unwrap();
    let manifest = root().join("experiments/spheres_checkerboard.yaml");
    let phantom = |force: bool| {
        let mut c = probecal();
        c.args(["phantom", manifest.to_str().unwrap(), "--stl", stl.to_str().unwrap()]);
        if force {
            c.arg("--force");
        }
        c.output().unwrap()
    };
    let out = phantom(false);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("k.json: exists; pass --force"));
    assert_eq!(
        std::fs::read_to_string(dir.join("k.json")).unwrap(),
        "{\"mine\": true}\n"
    );
    assert!(!stl.exists());
    assert!(phantom(true).status.success());
    assert!(
        stl.is_file()
            && std::fs::read_to_string(dir.join("k.json"))
                .unwrap()
                .contains("triangles")
    );
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
