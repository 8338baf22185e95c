//! `probecal reconstruct` against PLUS's own volume-reconstruction regression
//! data (`../shared/data/plus-volume-reconstruction`): the same geometry as
//! PLUS's reference volumes, voxels within one grey level, the nonzero masks
//! agreeing; the volume independent of the thread count; the other settings of
//! the class (compounding, clipping, skipping, hole filling, float input) on
//! the same sweep; and inputs that cannot be used refused with nothing written.

mod common;

use std::path::{Path, PathBuf};

use common::{probecal, scratch, shared_data};
use probecal::io::volume_file::read_metaimage;
use probecal::pipeline::reconstruct::{run, AnyVolume, ReconstructInputs};

const SET: &str = "plus-volume-reconstruction";
const SWEEP: &str = "SpinePhantomFreehand.igs.mha";

fn config(name: &str) -> PathBuf {
    shared_data(SET, &format!("PlusDeviceSet_VolumeReconstructionOnly_{name}.xml"))
}

fn inputs(sequence: &Path, config: &Path, threads: usize) -> ReconstructInputs {
    ReconstructInputs {
        sequence: sequence.to_path_buf(),
        config: config.to_path_buf(),
        threads: Some(threads),
        wires: None,
        image_to_probe: None,
        tracker_lag_s: None,
    }
}

/// Agreement of two 8-bit volumes of the same size.
#[derive(Debug)]
struct Agreement {
    /// Voxels nonzero in either.
    union: usize,
    /// Of those, the share within one grey level.
    within_one: f64,
    dice: f64,
    equal_voxels: usize,
}

fn agreement(ours: &[u8], theirs: &[u8]) -> Agreement {
    assert_eq!(ours.len(), theirs.len());
    let (mut union, mut close, mut a, mut b, mut both, mut equal) = (0, 0, 0, 0, 0, 0);
    for (&o, &t) in ours.iter().zip(theirs) {
        a += usize::from(o > 0);
        b += usize::from(t > 0);
        both += usize::from(o > 0 && t > 0);
        equal += usize::from(o == t);
        if o > 0 || t > 0 {
            union += 1;
            close += usize::from(o.abs_diff(t) <= 1);
        }
    }
    Agreement {
        union,
        within_one: close as f64 / union as f64,
        dice: 2.0 * both as f64 / (a + b) as f64,
        equal_voxels: equal,
    }
}

fn u8_voxels(volume: &AnyVolume) -> &[u8] {
    match volume {
        AnyVolume::U8(v) => &v.voxels,
        AnyVolume::F32(_) => panic!("an 8-bit sweep gives an 8-bit volume"),
    }
}

/// One of PLUS's three regression cases: geometry equal, voxels as close as
/// measured (`docs/reconstruction.md`), the written file byte for byte where
/// probecal reproduces PLUS exactly.
fn plus_case(config_name: &str, reference: &str, least_within_one: f64, least_dice: f64, identical: bool) {
    let out = scratch("reconstruct_plus", config_name);
    let r = probecal()
        .arg("reconstruct")
        .arg(shared_data(SET, SWEEP))
        .arg("--config")
        .arg(config(config_name))
        .arg("--compare")
        .arg(shared_data(SET, reference))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (ours, our_voxels) = read_metaimage(&out.join("volume.mha")).unwrap();
    let (theirs, their_voxels) = read_metaimage(&shared_data(SET, reference)).unwrap();
    assert_eq!(ours.dims, theirs.dims, "{config_name}: DimSize");
    assert_eq!(ours.spacing_mm, theirs.spacing_mm, "{config_name}: ElementSpacing");
    for a in 0..3 {
        // PLUS writes 6 significant digits; ours are written the same way.
        assert!(
            (ours.origin_mm[a] - theirs.origin_mm[a]).abs() <= 1e-3,
            "{config_name}: Offset"
        );
    }
    let m = agreement(&our_voxels, &their_voxels);
    eprintln!("{config_name}: {m:?}");
    assert!(m.within_one >= least_within_one, "{config_name}: {m:?}");
    assert!(m.dice >= least_dice, "{config_name}: {m:?}");
    assert!(m.union > 100_000, "{config_name}: the sweep fills a volume");
    if identical {
        assert_eq!(m.equal_voxels, our_voxels.len(), "{config_name}: every voxel");
    }
    let written = std::fs::read(out.join("volume.mha")).unwrap();
    let plus = std::fs::read(shared_data(SET, reference)).unwrap();
    assert_eq!(written == plus, identical, "{config_name}: byte-identical file");
    for file in [
        "summary.json",
        "report.html",
        "slice_x.png",
        "slice_y.png",
        "slice_z.png",
        "mean_z.png",
        "outlines_xy.png",
        "outlines_xz.png",
    ] {
        assert!(out.join(file).is_file(), "{file}");
    }
    // --compare: agreement.json holds the test's own figures, and the page says them.
    let agreed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("agreement.json")).unwrap()).unwrap();
    assert_eq!(agreed["voxels_equal"].as_u64().unwrap() as usize, m.equal_voxels);
    assert!((agreed["within_one_grey_level"].as_f64().unwrap() - m.within_one).abs() < 1e-12);
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    let said = format!(
        "{:.2} % of the voxels nonzero in either volume are within one grey level",
        m.within_one * 100.0
    );
    assert!(
        page.contains("id=\"agreement\"") && page.contains(&said),
        "{config_name}: the page does not say {said}"
    );
    assert!(page.contains(&format!("{} of {} voxels are equal", m.equal_voxels, our_voxels.len())));
    // The frames' outlines: every one of the 21 frames drawn, in both views.
    assert!(
        page.contains("outlines_xy.png") && page.contains("outlines_xz.png") && page.contains("21 of 21 drawn"),
        "{config_name}: the page shows no outlines of its frames"
    );
    assert_eq!(page.contains("<b>byte-identical files</b>"), identical, "{config_name}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"]["used"], 21);
    assert_eq!(summary["frames"]["skipped"].as_array().unwrap().len(), 0);
    let before = summary["voxels_filled"]["before_hole_filling"].as_u64().unwrap();
    let after = summary["voxels_filled"]["after_hole_filling"].as_u64().unwrap();
    assert!(after >= before && before > 0);
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn nearest_neighbour_mean_with_stick_hole_filling_matches_plus() {
    plus_case(
        "SpinePhantom_NN_MEAN",
        "vtkVolumeReconstructorTestNNMEANvolumeRef.mha",
        1.0,
        1.0,
        false,
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn linear_maximum_is_plus_byte_for_byte() {
    plus_case(
        "SpinePhantom_LN_MAXI",
        "vtkVolumeReconstructorTestLNMAXIvolumeRef.mha",
        1.0,
        1.0,
        true,
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn linear_mean_with_fan_and_holes_is_within_one_grey_level_of_plus() {
    plus_case(
        "SonixRP_TRUS_D70mm_LN_MEAN",
        "vtkVolumeReconstructorTestLNMEANvolumeRef.mha",
        0.9995,
        1.0,
        false,
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn the_volume_does_not_depend_on_the_thread_count() {
    for name in ["SpinePhantom_NN_MEAN", "SonixRP_TRUS_D70mm_LN_MEAN"] {
        let one = run(&inputs(&shared_data(SET, SWEEP), &config(name), 1)).unwrap();
        let three = run(&inputs(&shared_data(SET, SWEEP), &config(name), 3)).unwrap();
        assert_eq!(one.volume, three.volume, "{name}");
        assert_eq!(one.pixels_inserted, three.pixels_inserted, "{name}");
        assert_eq!(one.holes, three.holes, "{name}");
    }
}

/// A device set derived from a shared one with `<VolumeReconstruction ...>`'s
/// attributes replaced and the hole-filling block given.
fn variant(dir: &Path, name: &str, attributes: &str, holes: &str) -> PathBuf {
    let text = std::fs::read_to_string(config("SpinePhantom_NN_MEAN")).unwrap();
    let start = text.find("<VolumeReconstruction").unwrap();
    let end = text.find("</VolumeReconstruction>").unwrap() + "</VolumeReconstruction>".len();
    let element =
        format!("<VolumeReconstruction OutputSpacing=\"0.5 0.5 0.5\" {attributes}>{holes}</VolumeReconstruction>");
    let path = dir.join(format!("{name}.xml"));
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(&path, format!("{}{element}{}", &text[..start], &text[end..])).unwrap();
    path
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn other_settings_of_the_class_behave_as_documented() {
    let dir = scratch("reconstruct_plus", "variants");
    let sweep = shared_data(SET, SWEEP);
    let get = |name: &str, attributes: &str, holes: &str| {
        run(&inputs(&sweep, &variant(&dir, name, attributes, holes), 2)).unwrap()
    };
    let mean = get(
        "nn_mean",
        "Interpolation=\"NEAREST_NEIGHBOR\" CompoundingMode=\"MEAN\"",
        "",
    );
    let maximum = get(
        "nn_max",
        "Interpolation=\"NEAREST_NEIGHBOR\" CompoundingMode=\"MAXIMUM\"",
        "",
    );
    let latest = get(
        "nn_latest",
        "Interpolation=\"NEAREST_NEIGHBOR\" CompoundingMode=\"LATEST\"",
        "",
    );
    let (mean_v, max_v, latest_v) = (
        u8_voxels(&mean.volume),
        u8_voxels(&maximum.volume),
        u8_voxels(&latest.volume),
    );
    // The same voxels are reached; the maximum bounds the mean and the latest value.
    assert_eq!(mean.voxels_filled_before_holes, maximum.voxels_filled_before_holes);
    assert!(mean_v.iter().zip(max_v).all(|(m, x)| m <= x));
    assert!(latest_v.iter().zip(max_v).all(|(l, x)| l <= x));
    assert!(mean_v != latest_v);

    // Every second frame: frames 0, 2, …, 20.
    let skip = get("skip", "SkipInterval=\"2\"", "");
    assert_eq!(skip.frames_used, (0..21).step_by(2).collect::<Vec<_>>());

    // Pixels darker than the threshold are not inserted: fewer pixels, and the
    // maximum compounding of the rest has no voxel below it but empty ones.
    let rejected = get(
        "reject",
        "CompoundingMode=\"MAXIMUM\" PixelRejectionThreshold=\"30\"",
        "",
    );
    assert!(rejected.pixels_inserted < maximum.pixels_inserted);
    assert!(u8_voxels(&rejected.volume).iter().all(|v| *v == 0 || *v >= 30));

    // A given grid: origin and extent as written.
    let boxed = get(
        "extent",
        "OutputOrigin=\"-50 170 40\" OutputExtent=\"0 39 0 29 0 19\"",
        "",
    );
    assert_eq!(boxed.volume.grid().dims, [40, 30, 20]);
    assert_eq!(boxed.volume.grid().origin_mm, [-50.0, 170.0, 40.0]);

    // Each hole-filling element fills holes; a cube element fills only where enough is known.
    for (name, element) in [
        (
            "gaussian",
            "Type=\"GAUSSIAN\" Size=\"5\" Stdev=\"1\" MinimumKnownVoxelsRatio=\"0.1\"",
        ),
        (
            "gaussian_acc",
            "Type=\"GAUSSIAN_ACCUMULATION\" Size=\"5\" Stdev=\"1\" MinimumKnownVoxelsRatio=\"0.1\"",
        ),
        (
            "nearest",
            "Type=\"NEAREST_NEIGHBOR\" Size=\"5\" MinimumKnownVoxelsRatio=\"0.1\"",
        ),
        (
            "inverse",
            "Type=\"DISTANCE_WEIGHT_INVERSE\" Size=\"5\" MinimumKnownVoxelsRatio=\"0.1\"",
        ),
        (
            "sticks3",
            "Type=\"STICK\" StickLengthLimit=\"9\" NumberOfSticksToUse=\"3\"",
        ),
    ] {
        let filled = get(
            name,
            "FillHoles=\"ON\"",
            &format!("<HoleFilling><HoleFillingElement {element}/></HoleFilling>"),
        );
        let by_element = filled.holes.filled_by_element[0];
        assert!(by_element > 10_000, "{name}: {by_element} holes filled");
        assert_eq!(
            filled.voxels_filled_after_holes,
            filled.voxels_filled_before_holes + by_element
        );
        assert_eq!(
            filled.voxels_filled_before_holes, mean.voxels_filled_before_holes,
            "{name}"
        );
    }
}

/// The sweep rewritten with float pixels (the same values).
fn float_sweep(dir: &Path) -> PathBuf {
    let bytes = std::fs::read(shared_data(SET, SWEEP)).unwrap();
    let sequence = probecal::io::plus::sequence::Sequence::parse(Path::new(SWEEP), &bytes).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header = String::from_utf8_lossy(&bytes[..end])
        .replace("ElementType = MET_UCHAR", "ElementType = MET_FLOAT")
        .replace("CompressedData = True", "CompressedData = False")
        .lines()
        .filter(|l| !l.starts_with("CompressedDataSize"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = format!("{header}\nElementDataFile = LOCAL\n").into_bytes();
    for i in 0..sequence.frames.len() {
        for p in sequence.pixels(i) {
            out.extend_from_slice(&f32::from(*p).to_le_bytes());
        }
    }
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("float.igs.mha");
    std::fs::write(&path, out).unwrap();
    path
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn float_input_gives_a_float_volume_of_the_same_means() {
    let dir = scratch("reconstruct_plus", "float");
    let cfg = variant(
        &dir,
        "nn_mean",
        "Interpolation=\"NEAREST_NEIGHBOR\" CompoundingMode=\"MEAN\"",
        "",
    );
    let bytes = run(&inputs(&shared_data(SET, SWEEP), &cfg, 2)).unwrap();
    let floats = run(&inputs(&float_sweep(&dir), &cfg, 2)).unwrap();
    let (AnyVolume::U8(b), AnyVolume::F32(f)) = (&bytes.volume, &floats.volume) else {
        panic!("8-bit in, 8-bit out; float in, float out");
    };
    assert_eq!(b.grid, f.grid);
    // The 8-bit mean is floored at every step, so it never exceeds the exact
    // float one and stays near it on average.
    assert!(b
        .voxels
        .iter()
        .zip(&f.voxels)
        .all(|(b, f)| f64::from(*f) >= f64::from(*b) - 1e-3));
    let (sum, n) = b
        .voxels
        .iter()
        .zip(&f.voxels)
        .filter(|(b, _)| **b > 0)
        .fold((0.0, 0usize), |(s, n), (b, f)| {
            (s + f64::from(*f) - f64::from(*b), n + 1)
        });
    // On this sweep the floors cost 4.8 grey levels on average (PLUS's 8-bit
    // arithmetic, reproduced): a documented bias, bounded here.
    assert!(sum / n as f64 <= 6.0, "mean difference {}", sum / n as f64);
    assert!(
        f.voxels.iter().any(|v| v.fract() != 0.0),
        "float means keep their fractions"
    );
    let out = dir.join("out");
    let r = probecal()
        .arg("reconstruct")
        .arg(float_sweep(&dir))
        .arg("--config")
        .arg(&cfg)
        .arg("--out")
        .arg(&out)
        .arg("--nrrd")
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (header, voxels) = read_metaimage(&out.join("volume.mha")).unwrap();
    assert_eq!(
        (header.element_type.as_str(), voxels.len()),
        ("MET_FLOAT", f.voxels.len() * 4)
    );
    let nrrd = std::fs::read(out.join("volume.nrrd")).unwrap();
    assert!(nrrd.starts_with(b"NRRD0004\n") && nrrd.ends_with(&voxels[voxels.len() - 64..]));
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_run_folders_calibration_replaces_the_device_sets() {
    let dir = scratch("reconstruct_plus", "calibration");
    let cfg = config("SpinePhantom_LN_MAXI");
    let same = dir.join("same");
    let shifted = dir.join("shifted");
    let matrix = |x: f64| {
        common::tracked_summary_with_matrix(serde_json::json!([
            [-0.00157821, 0.0785919, -0.00803285, 15.3978 + x],
            [-0.0839128, 0.00372697, 0.0153803, 49.5705],
            [0.0159024, 0.00714276, 0.0803604, -8.63446],
            [0.0, 0.0, 0.0, 1.0]
        ]))
    };
    for (folder, x) in [(&same, 0.0), (&shifted, 5.0)] {
        std::fs::create_dir_all(folder).unwrap();
        std::fs::write(folder.join("summary.json"), matrix(x)).unwrap();
    }
    let given = |calibration: &Path| probecal::results::calibration::read(calibration);
    let with = |calibration: Option<&Path>| {
        let mut i = inputs(&shared_data(SET, SWEEP), &cfg, 2);
        i.image_to_probe = calibration.map(|c| {
            let g = given(c).unwrap();
            (g.image_to_probe, g.source)
        });
        run(&i).unwrap()
    };
    let device = with(None);
    assert_eq!(with(Some(&same)).volume, device.volume);
    let moved = with(Some(&shifted));
    assert_ne!(moved.volume, device.volume);
    assert!(moved.image_to_probe_source.ends_with("shifted/summary.json"));
    // The same run's lag comes with its matrix.
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(same.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        given(&same).unwrap().tracker_lag_s.map(|(lag, _)| lag),
        written["time_offset_s"].as_f64()
    );
    // No matrix in the folder: a clear error naming the file and the field.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    std::fs::write(empty.join("summary.json"), "{\"kind\": \"camera\"}").unwrap();
    let e = given(&empty).unwrap_err().to_string();
    assert!(
        e.contains("empty/summary.json") && e.contains("not a probecal summary"),
        "{e}"
    );
    // A camera-rig run's summary: it has no ImageToProbe.
    let camera = dir.join("camera");
    std::fs::create_dir_all(&camera).unwrap();
    std::fs::copy(
        common::root().join("reports/hemisphere_checkerboard/dataset3/summary.json"),
        camera.join("summary.json"),
    )
    .unwrap();
    let e = given(&camera).unwrap_err().to_string();
    assert!(
        e.contains("camera/summary.json") && e.contains("image_to_probe.matrix"),
        "{e}"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn unusable_inputs_are_refused_and_nothing_is_written() {
    let dir = scratch("reconstruct_plus", "bad");
    std::fs::create_dir_all(&dir).unwrap();
    let sweep = shared_data(SET, SWEEP);
    let refused = |sequence: &Path, config: &Path, out: &Path, want: &str| {
        let r = probecal()
            .arg("reconstruct")
            .arg(sequence)
            .arg("--config")
            .arg(config)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(want), "want `{want}` in: {stderr}");
    };
    // A sequence cut short.
    let bytes = std::fs::read(&sweep).unwrap();
    let cut = dir.join("cut.igs.mha");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = dir.join("out");
    refused(&cut, &config("SpinePhantom_NN_MEAN"), &out, "cut.igs.mha");
    assert!(!out.exists());
    // A sequence damaged in its last frames, whose first frames are pasted
    // while the rest are decoded: refused as a whole read refuses it.
    let mut damaged = bytes.clone();
    let n = damaged.len();
    damaged[n - 200_000..n - 100_000].iter_mut().for_each(|b| *b ^= 0x5A);
    let damaged_path = dir.join("damaged.igs.mha");
    std::fs::write(&damaged_path, &damaged).unwrap();
    refused(
        &damaged_path,
        &config("SpinePhantom_NN_MEAN"),
        &out,
        "damaged.igs.mha: compressed data is corrupt or truncated after",
    );
    assert!(!out.exists());
    // No <VolumeReconstruction>.
    let bare = dir.join("bare.xml");
    std::fs::write(
        &bare,
        "<PlusConfiguration>\n<CoordinateDefinitions/>\n</PlusConfiguration>\n",
    )
    .unwrap();
    refused(&sweep, &bare, &out, "no <VolumeReconstruction> element");
    // No ImageToProbe: no frame can be placed, and each frame says why.
    let text = std::fs::read_to_string(config("SpinePhantom_NN_MEAN")).unwrap();
    let no_calibration = dir.join("no_calibration.xml");
    std::fs::write(
        &no_calibration,
        text.replace("From=\"Image\" To=\"Probe\"", "From=\"Image\" To=\"Elsewhere\""),
    )
    .unwrap();
    refused(
        &sweep,
        &no_calibration,
        &out,
        "no chain of usable transforms from Image to Reference",
    );
    // A volume beyond the bound.
    let tiny = variant(&dir, "tiny", "OutputSpacing=\"0.01 0.01 0.01\"", "").to_path_buf();
    let tiny_text = std::fs::read_to_string(&tiny)
        .unwrap()
        .replacen("OutputSpacing=\"0.5 0.5 0.5\" ", "", 1);
    std::fs::write(&tiny, tiny_text).unwrap();
    refused(&sweep, &tiny, &out, "more than the 1073741824 allowed");
    assert!(!out.exists());
    // An --out that is somebody else's folder is left alone.
    let theirs = dir.join("theirs");
    std::fs::create_dir_all(&theirs).unwrap();
    std::fs::write(theirs.join("notes.txt"), "mine").unwrap();
    refused(
        &sweep,
        &config("SpinePhantom_LN_MAXI"),
        &theirs,
        "exists and was not written by this command",
    );
    assert_eq!(std::fs::read_to_string(theirs.join("notes.txt")).unwrap(), "mine");
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn frames_whose_transforms_are_not_ok_are_skipped_and_counted() {
    let dir = scratch("reconstruct_plus", "status");
    std::fs::create_dir_all(&dir).unwrap();
    let bytes = std::fs::read(shared_data(SET, SWEEP)).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header = String::from_utf8_lossy(&bytes[..end]).replace(
        "Seq_Frame0003_ProbeToTrackerTransformStatus = OK",
        "Seq_Frame0003_ProbeToTrackerTransformStatus = INVALID",
    );
    let path = dir.join("invalid.igs.mha");
    std::fs::write(&path, [header.as_bytes(), &bytes[end..]].concat()).unwrap();
    let r = run(&inputs(&path, &config("SpinePhantom_LN_MAXI"), 2)).unwrap();
    assert_eq!(r.frames_used.len(), 20);
    assert_eq!(r.skipped.len(), 1);
    assert_eq!(r.skipped[0].index, 3);
    assert!(
        r.skipped[0].reason.contains("ProbeToTrackerTransformStatus"),
        "{}",
        r.skipped[0].reason
    );
}

/// `reconstruct --calibration` takes a `run --out` folder at any level: the one
/// tracked run below it is used; several are named and refused; none is said.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_calibration_folder_is_found_at_any_level_of_a_runs_output() {
    let dir = common::scratch("reconstruct_plus", "calibration_levels");
    let summary = common::root().join("reports/plus_fcal2_nwire/fcal2_3nwires/summary.json");
    let runs = dir.join("runs");
    std::fs::create_dir_all(runs.join("fcal/sweep")).unwrap();
    std::fs::copy(&summary, runs.join("fcal/sweep/summary.json")).unwrap();
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    let reconstruct = |calibration: &std::path::Path, out: &str| {
        common::probecal()
            .arg("reconstruct")
            .arg(common::shared_data(
                "plus-fcal2.0-3nwires",
                "fCal_Test_Validation_3NWires_fCal2.0.igs.mha",
            ))
            .arg("--config")
            .arg(common::root().join("experiments/plus/fcal2_volume.xml"))
            .arg("--calibration")
            .arg(calibration)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    let o = reconstruct(&runs, "top");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("top/summary.json")).unwrap()).unwrap();
    let source = s["image_to_probe_source"].as_str().unwrap();
    assert!(source.ends_with("runs/fcal/sweep/summary.json"), "{source}");
    std::fs::create_dir_all(runs.join("fcal/other")).unwrap();
    std::fs::copy(&summary, runs.join("fcal/other/summary.json")).unwrap();
    let o = reconstruct(&runs, "two");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("holds 2 tracked runs"), "{stderr}");
    assert!(
        stderr.contains("fcal/other") && stderr.contains("fcal/sweep"),
        "{stderr}"
    );
    let o = reconstruct(&dir.join("empty"), "none");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("holds no probecal run with an ImageToProbe"),
        "{stderr}"
    );
}
