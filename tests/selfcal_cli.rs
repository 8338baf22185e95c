//! `probecal selfcal` as a command: its refusals, and on PLUS's fCal 2.0
//! recording its outputs (a summary the results model reads whole, an
//! `ImageToProbe.xml` that `--calibration` takes back).

mod common;

use common::{probecal, scratch, shared_data};
use probecal::estimate::selfcal::check::Verdict;
use probecal::results::selfcal::SelfcalSummary;

const SET: &str = "plus-fcal2.0-3nwires";

#[test]
fn one_sweep_is_a_usage_error() {
    let out = scratch("selfcal_cli", "one_sweep");
    let r = probecal()
        .args([
            "selfcal",
            "a.mha",
            "--config",
            "c.xml",
            "--calibration",
            "r.xml",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("SEQUENCES"), "{err}");
    assert!(!out.exists());
}

#[test]
fn a_missing_start_is_named_and_nothing_is_written() {
    let dir = scratch("selfcal_cli", "missing_start");
    std::fs::create_dir_all(&dir).unwrap();
    let missing = dir.join("no-such-result.xml");
    let out = dir.join("out");
    let r = probecal()
        .args(["selfcal", "a.mha", "b.mha", "--config", "c.xml", "--calibration"])
        .arg(&missing)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("no-such-result.xml"), "{err}");
    assert!(!out.join("summary.json").exists());
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn fcal_sweeps_refine_plus_matrix_and_say_what_they_hold() {
    let out = scratch("selfcal_cli", "fcal");
    let plus = shared_data(SET, "FreehandCalibration3NWires_fCal2.0.results.xml");
    let r = probecal()
        .arg("selfcal")
        .arg(shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha"))
        .arg(shared_data(SET, "fCal_Test_Validation_3NWires_fCal2.0.igs.mha"))
        .arg("--config")
        .arg(shared_data(SET, "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml"))
        .arg("--calibration")
        .arg(&plus)
        .args(["--lag-range-ms", "30", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}{stdout}", String::from_utf8_lossy(&r.stderr));
    println!("{stdout}");
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let summary: SelfcalSummary = serde_json::from_str(&text).unwrap();
    assert_eq!(summary.directions.len(), 6);
    assert_eq!(summary.sweeps.len(), 2);
    assert!(summary.correlation_end >= summary.correlation_start - 1e-9);
    // Every direction not held is left where the start had it: the correction
    // has no part along it.
    let q = [
        summary.move_mm[0],
        summary.move_mm[1],
        summary.move_mm[2],
        summary.turn_deg[0].to_radians() * summary.radius_mm,
        summary.turn_deg[1].to_radians() * summary.radius_mm,
        summary.turn_deg[2].to_radians() * summary.radius_mm,
    ];
    for d in summary.directions.iter().filter(|d| !d.held) {
        let along: f64 = d.vector.iter().zip(&q).map(|(a, b)| a * b).sum();
        assert!(along.abs() < 1e-6, "{} moved {along} mm", d.mostly);
    }
    // The refined matrix is a calibration `--calibration` reads.
    let back = probecal::results::calibration::read(&out.join("ImageToProbe.xml")).unwrap();
    for (r, row) in summary.image_to_probe.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            assert!((back.image_to_probe[(r, c)] - v).abs() < 1e-6);
        }
    }
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    for d in &summary.directions {
        assert!(page.contains(&d.mostly), "the page names {}", d.mostly);
    }
    // The check of the start: the statistic is the refinement's corner change,
    // the verdict follows it and the page says it.
    let check = &summary.check;
    assert!((check.offset_mm - summary.corner_change_mm).abs() < 1e-9);
    assert_eq!(
        check.verdict == Verdict::Consistent,
        check.offset_mm <= check.tolerance_mm
    );
    assert!(page.contains(check.verdict.words()), "the page says the verdict");
    assert!((0.0..=1.0).contains(&check.false_alarm_rate));
    // The profiles: one per direction, all through the refined calibration
    // (the same value at 0, compared over the same voxels), drawn on the page.
    assert_eq!(summary.profiles.len(), 6);
    let centre = summary.profiles[0].points.iter().find(|p| p.0 == 0.0).unwrap().1;
    for p in &summary.profiles {
        assert_eq!(p.points.len(), 9);
        let at_zero = p.points.iter().find(|q| q.0 == 0.0).unwrap().1;
        assert!((at_zero - centre).abs() < 1e-12, "{}: {at_zero} vs {centre}", p.mostly);
        assert!(p.points.iter().all(|q| q.1.is_finite() && q.1 <= 1.0));
    }
    assert!(page.contains("<svg"), "the page draws the profiles");
    // The lag profile: 7 lags, 10 ms apart, centred on the lag refined at; a
    // best lag inside the range, or the reason there is none.
    let lag = summary.lag_profile.as_ref().expect("a lag profile was asked for");
    assert_eq!(lag.points.len(), 7);
    for (k, p) in lag.points.iter().enumerate() {
        let want = summary.tracker_lag_s + (k as f64 - 3.0) * 0.01;
        assert!((p.0 - want).abs() < 1e-12, "lag {} vs {want}", p.0);
        assert!(p.1.is_finite() && p.2 >= 100);
    }
    match lag.best_s {
        Some(best) => assert!(best > lag.points[0].0 && best < lag.points[6].0, "{best}"),
        None => assert!(lag.no_best.is_some()),
    }
    // The best lag's standard error from resampled sweeps: only with a best
    // lag and at least half of the resamples peaking inside the range.
    assert_eq!(lag.resamples, 8);
    assert!(lag.resamples_peaked <= lag.resamples);
    if let Some(se) = lag.standard_error_s {
        assert!(lag.best_s.is_some() && lag.resamples_peaked >= 4);
        assert!(se.is_finite() && se > 0.0, "{se}");
    }
    assert!(page.contains("against the tracker's lag"));
    // The overlaid slices: a plane normal to each Reference axis, its
    // agreement before and after in the summary, its two pictures inline as
    // PNG that decodes to the size the page shows them at (enlarged by
    // a whole factor).
    assert_eq!(summary.overlays.len(), 3);
    let normals: Vec<char> = summary.overlays.iter().map(|o| o.normal).collect();
    assert_eq!(normals, ['z', 'y', 'x']);
    for o in &summary.overlays {
        assert!(o.pixels_before > 100 && o.pixels_after > 100, "{o:?}");
        for c in [o.correlation_before, o.correlation_after].into_iter().flatten() {
            assert!((-1.0..=1.0).contains(&c), "{o:?}");
        }
    }
    let images: Vec<&str> = page.split("<img src=\"data:image/png;base64,").skip(1).collect();
    assert_eq!(images.len(), 6, "before and after in each of three planes");
    for img in images {
        let data = img.split('"').next().unwrap();
        let bytes = base64_decode(data);
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
        let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut pixels).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        let (cols, rows) = (info.width as usize, info.height as usize);
        assert!(
            pixels[..cols * rows * 3].iter().any(|&v| v > 0),
            "a picture with nothing in it"
        );
        let shown = |attr: &str| -> usize {
            img.split(&format!("{attr}=\""))
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .parse()
                .unwrap()
        };
        assert!(cols > 10 && rows > 10, "{cols}x{rows}");
        assert_eq!(shown("width") % cols, 0);
        assert_eq!(shown("width") / cols, shown("height") / rows);
    }
}

/// RFC 4648 base64 (the page's data URIs), written here so that the test does
/// not read the page with the code that wrote it.
fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => u32::from(c - b'A'),
            b'a'..=b'z' => u32::from(c - b'a') + 26,
            b'0'..=b'9' => u32::from(c - b'0') + 52,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        }
    };
    let mut out = Vec::new();
    for chunk in text.as_bytes().chunks(4) {
        let pad = chunk.iter().filter(|&&c| c == b'=').count();
        let n = chunk
            .iter()
            .map(|&c| if c == b'=' { 0 } else { value(c) })
            .fold(0u32, |n, v| n << 6 | v);
        out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
    }
    out
}

#[test]
fn a_lag_range_outside_its_bounds_is_a_usage_error() {
    let out = scratch("selfcal_cli", "lag_range");
    let r = probecal()
        .args([
            "selfcal",
            "a.mha",
            "b.mha",
            "--config",
            "c.xml",
            "--calibration",
            "r.xml",
            "--lag-range-ms",
            "500",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("--lag-range-ms") && err.contains("10 to 200"), "{err}");
    assert!(!out.exists());
}

/// PLUS's matrix moved 3 mm along the probe's y axis (which the fCal sweeps
/// hold, mostly) is flagged by `--check`: exit 1, the outputs written, the
/// reason on stderr.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn check_flags_plus_matrix_moved_3_mm() {
    let dir = scratch("selfcal_cli", "check_moved");
    std::fs::create_dir_all(&dir).unwrap();
    let plus = probecal::io::plus::result::PlusResult::read(&shared_data(
        SET,
        "FreehandCalibration3NWires_fCal2.0.results.xml",
    ))
    .unwrap()
    .image_to_probe;
    let moved = nalgebra::Matrix4::new_translation(&nalgebra::Vector3::new(0.0, 3.0, 0.0)) * plus;
    let start = dir.join("moved.xml");
    std::fs::write(&start, probecal::report::tracked::transform_files::plus_xml(&moved)).unwrap();
    let out = dir.join("out");
    let r = probecal()
        .arg("selfcal")
        .arg(shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha"))
        .arg(shared_data(SET, "fCal_Test_Validation_3NWires_fCal2.0.igs.mha"))
        .arg("--config")
        .arg(shared_data(SET, "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml"))
        .arg("--calibration")
        .arg(&start)
        .args(["--check", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    println!("{}{err}", String::from_utf8_lossy(&r.stdout));
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("NOT consistent"), "{err}");
    let summary: SelfcalSummary =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary.check.verdict, Verdict::Inconsistent);
    assert!(summary.check.offset_mm > summary.check.tolerance_mm);
}
