//! The tracker's lag recovered from rendered tracked sweeps
//! ([`probecal::synth::tracked_sweep`]): B-scans of the fCal 2.0 phantom's N-wires
//! rendered along a moving probe's path with PLUS's `ImageToProbe` as the truth,
//! the tracker recording each pose a known lag late, written as PLUS sequence
//! files and calibrated from their pixels as a recording is. Every lag of the
//! grid (0, 40, 150, 400 ms) with slow and fast motion at 10 and 30 frames a
//! second is recovered within 10 ms; a sweep whose probe stands still is refused.

#![allow(non_snake_case)]

mod common;

use std::path::PathBuf;

use common::{scratch, shared_data};
use probecal::io::plus::result::PlusResult;
use probecal::io::plus::sequence::Sequence;
use probecal::manifest::tracked::{TimeOffset, TrackedManifest};
use probecal::pipeline::tracked::{self, TrackedInputs};
use probecal::synth::tracked_sweep::{self, SweepMotion, SweepScene, SweepSpec};

const SET: &str = "plus-fcal2.0-3nwires";

/// The shared experiment's inputs (phantom, segmentation, model family).
fn inputs() -> TrackedInputs {
    let path = common::root().join("experiments/plus_fcal2_nwire.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    TrackedInputs::from_manifest(&TrackedManifest::from_text(&path, &text).unwrap())
}

/// A still probe over the phantom: frame 95 of PLUS's calibration recording.
fn scene(inputs: &TrackedInputs) -> (SweepScene<'_>, [usize; 4]) {
    let recording = Sequence::read(&shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha")).unwrap();
    let tracker_T_probe = recording.transform(95, "ProbeToTracker").unwrap();
    let tracker_T_reference = recording.transform(95, "ReferenceToTracker").unwrap();
    let truth = PlusResult::read(&shared_data(SET, "FreehandCalibration3NWires_fCal2.0.results.xml")).unwrap();
    let clip = inputs.clip_rectangle_px.expect("the device set's clip rectangle");
    let margin = 30.0;
    (
        SweepScene {
            nwires: &inputs.nwires,
            reference_T_phantom: inputs.reference_T_phantom,
            image_to_probe: truth.image_to_probe,
            reference_T_probe: tracker_T_reference.inverse() * tracker_T_probe,
            tracker_T_reference,
            width: recording.width,
            height: recording.height,
            keep_within_px: [
                clip[0] as f64 + margin,
                clip[1] as f64 + margin,
                (clip[0] + clip[2]) as f64 - margin,
                (clip[1] + clip[3]) as f64 - margin,
            ],
        },
        clip,
    )
}

fn motion(period_s: f64) -> SweepMotion {
    SweepMotion {
        period_s,
        along_mm: 4.0,
        across_mm: 3.0,
        tilt_deg: 3.0,
    }
}

/// Renders `spec` and runs the tracked pipeline on it (lag estimated): the
/// estimate, and the lag applied.
fn estimate(name: &str, spec: SweepSpec) -> (Option<f64>, f64, String) {
    let mut inputs = inputs();
    let (scene, _) = scene(&inputs);
    let dir = scratch("rendered_lag", name);
    std::fs::create_dir_all(&dir).unwrap();
    let path: PathBuf = dir.join("sweep.igs.mha");
    tracked_sweep::render(&scene, &spec, &path).unwrap();
    inputs.calibration_sequence = path;
    inputs.validation_sequence = None;
    inputs.time_offset = TimeOffset::Estimate;
    let run = tracked::run(&inputs, 20).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let e = run.lag_estimate.unwrap();
    (
        e.lag_s,
        run.time_offset_s,
        format!("{}; {:?}", e.decision, e.unresolved),
    )
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn every_lag_of_the_grid_is_recovered_within_10_ms() {
    // Each lag with slow (6 s) and fast (2 s) sweeps, at 10 and 30 frames a second.
    let cases = [
        (0.0, 6.0, 10.0),
        (0.0, 2.0, 30.0),
        (0.040, 2.0, 30.0),
        (0.040, 6.0, 10.0),
        (0.150, 6.0, 30.0),
        (0.150, 2.0, 10.0),
        (0.400, 2.0, 10.0),
        (0.400, 6.0, 30.0),
    ];
    let mut failures = Vec::new();
    for (k, (lag, period, rate)) in cases.into_iter().enumerate() {
        let spec = SweepSpec {
            frames_per_s: rate,
            duration_s: 8.0,
            tracker_lag_s: lag,
            motion: motion(period),
            tracker_noise_rms_mm: tracked_sweep::TRACKER_NOISE_RMS_MM,
            seed: 100 + k as u64,
        };
        let (found, applied, why) = estimate(&format!("case_{k}"), spec);
        println!(
            "lag {:.0} ms, period {period} s, {rate} frames/s: estimate {:?} ms, applied {:.1} ms ({why})",
            lag * 1e3,
            found.map(|f| (f * 1e4).round() / 10.0),
            applied * 1e3
        );
        let recovered = found.is_some_and(|f| (f - lag).abs() <= 0.010) && (applied - lag).abs() <= 0.010;
        if !recovered {
            failures.push(format!(
                "lag {lag} s, period {period} s, {rate}/s: {found:?}, applied {applied}: {why}"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_sweep_without_motion_is_refused_with_its_reason() {
    let spec = SweepSpec {
        frames_per_s: 15.0,
        duration_s: 6.0,
        tracker_lag_s: 0.1,
        motion: SweepMotion {
            period_s: 4.0,
            along_mm: 0.0,
            across_mm: 0.0,
            tilt_deg: 0.0,
        },
        tracker_noise_rms_mm: tracked_sweep::TRACKER_NOISE_RMS_MM,
        seed: 7,
    };
    let (found, applied, why) = estimate("still", spec);
    assert_eq!(found, None, "{why}");
    assert_eq!(applied, 0.0);
    assert!(why.contains("flat") || why.contains("motion"), "{why}");
}
