//! The tracker's lag as part of the calibration, on PLUS's fCal 2.0 recording
//! (`../shared/data/plus-fcal2.0-3nwires`) and copies of it whose tracker is
//! shifted by whole frames: frame `i` carries the transforms recorded with frame
//! `i + k` (exact poses, `k` frame periods later), so the lag moves by the time
//! between those frames. The estimate must follow the shift, and with the known
//! lag the calibration must score the validation frames as the unshifted run
//! does. A sweep whose poses do not move is refused with its reason.

mod common;

use std::path::{Path, PathBuf};

use common::{scratch, shared_data};
use probecal::io::plus::sequence::Sequence;
use probecal::manifest::tracked::{TimeOffset, TrackedManifest};
use probecal::pipeline::tracked::{self, Role, TrackedInputs, TrackedRun};

const SET: &str = "plus-fcal2.0-3nwires";
const CALIBRATION: &str = "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha";
const VALIDATION: &str = "fCal_Test_Validation_3NWires_fCal2.0.igs.mha";

/// A copy of `source` whose per-frame transforms (and their statuses) are
/// replaced by `pick(i)`'s, or marked INVALID where `pick` gives none.
fn retracked(source: &Path, out: &Path, pick: impl Fn(usize, usize) -> Option<usize>) -> PathBuf {
    let bytes = std::fs::read(source).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header = String::from_utf8(bytes[..end].to_vec()).unwrap();
    let field = |line: &str| -> Option<(usize, String, String)> {
        let rest = line.strip_prefix("Seq_Frame")?;
        let (frame, rest) = rest.split_once('_')?;
        let (name, value) = rest.split_once(" = ")?;
        (name.ends_with("Transform") || name.ends_with("TransformStatus"))
            .then(|| (frame.parse().ok(), name.to_string(), value.to_string()))
            .and_then(|(f, n, v)| Some((f?, n, v)))
    };
    let values: std::collections::HashMap<(usize, String), String> =
        header.lines().filter_map(field).map(|(f, n, v)| ((f, n), v)).collect();
    let frames = values.keys().map(|k| k.0).max().unwrap() + 1;
    let mut text = String::new();
    for line in header.lines() {
        match field(line) {
            Some((f, name, value)) => {
                let picked = pick(f, frames).and_then(|g| values.get(&(g, name.clone())));
                let value = match (picked, name.ends_with("Status")) {
                    (Some(v), _) => v.clone(),
                    (None, true) => "INVALID".to_string(),
                    (None, false) => value,
                };
                text.push_str(&format!("Seq_Frame{f:04}_{name} = {value}\n"));
            }
            None => {
                text.push_str(line);
                text.push('\n');
            }
        }
    }
    let mut data = text.into_bytes();
    data.extend_from_slice(&bytes[end..]);
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    std::fs::write(out, data).unwrap();
    out.to_path_buf()
}

/// The shared experiment's inputs on these sequences with this lag setting.
fn inputs(calibration: PathBuf, validation: PathBuf, lag: TimeOffset) -> TrackedInputs {
    let path = common::root().join("experiments/plus_fcal2_nwire.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let manifest = TrackedManifest::from_text(&path, &text).unwrap();
    let mut inputs = TrackedInputs::from_manifest(&manifest);
    inputs.calibration_sequence = calibration;
    inputs.validation_sequence = Some(validation);
    inputs.time_offset = lag;
    inputs
}

fn validation_pre3d(run: &TrackedRun) -> f64 {
    probecal::core::stats::best_95(&run.pre3d(Role::Validation))
        .unwrap()
        .mean
}

/// The median time from frame `i` to frame `i + k` of the calibration sequence, s.
fn shift_s(k: i64) -> f64 {
    let s = Sequence::read(&shared_data(SET, CALIBRATION)).unwrap();
    let mut d: Vec<f64> = (0..s.frames.len() as i64)
        .filter(|i| (0..s.frames.len() as i64).contains(&(i + k)))
        .map(|i| s.timestamp_s((i + k) as usize).unwrap() - s.timestamp_s(i as usize).unwrap())
        .collect();
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_tracker_shifted_by_whole_frames_moves_the_lag_by_as_much() {
    let dir = scratch("plus_lag", "shifted");
    let unshifted = tracked::run(
        &inputs(
            shared_data(SET, CALIBRATION),
            shared_data(SET, VALIDATION),
            TimeOffset::Estimate,
        ),
        20,
    )
    .unwrap();
    let estimate = unshifted.lag_estimate.clone().unwrap();
    let lag0 = estimate.lag_s.expect("the unshifted recording's lag is resolved");
    assert!(estimate.applied, "{}", estimate.decision);
    let pre3d0 = validation_pre3d(&unshifted);
    println!("unshifted: lag {:+.1} ms, validation PRE3D {pre3d0:.3} mm", lag0 * 1e3);
    let period = shift_s(1);
    for k in [-3i64, -2, -1, 1, 2, 3] {
        let pick = |i: usize, n: usize| {
            let j = i as i64 + k;
            (0..n as i64).contains(&j).then_some(j as usize)
        };
        let cal = retracked(
            &shared_data(SET, CALIBRATION),
            &dir.join(format!("cal_{k}.igs.mha")),
            pick,
        );
        let val = retracked(
            &shared_data(SET, VALIDATION),
            &dir.join(format!("val_{k}.igs.mha")),
            pick,
        );
        // Frame i now carries the poses recorded k frames later: the lag moves by -shift.
        let expected = lag0 - shift_s(k);
        let run = tracked::run(&inputs(cal.clone(), val.clone(), TimeOffset::Estimate), 20).unwrap();
        let e = run.lag_estimate.clone().unwrap();
        let lag = e
            .lag_s
            .unwrap_or_else(|| panic!("shift {k}: refused: {:?}", e.unresolved));
        println!(
            "shift {k:+}: lag {:+.1} ms (expected {:+.1} ms), validation PRE3D {:.3} mm; {}",
            lag * 1e3,
            expected * 1e3,
            validation_pre3d(&run),
            e.decision
        );
        // Two frames or more is far outside the noise: the lag must be applied
        // (one frame, 16 ms from the recording's own lag, may be kept out by
        // cross-validation).
        if k.abs() >= 2 {
            assert!(e.applied, "shift {k}: {}", e.decision);
            assert!(
                (run.time_offset_s - expected).abs() <= 0.030,
                "shift {k}: applied {}",
                run.time_offset_s
            );
        }
        assert!(
            (lag - expected).abs() <= period / 3.0,
            "shift {k}: {lag} against {expected} (a third of a frame period is {})",
            period / 3.0
        );
        // With the known lag given, the calibration scores as the unshifted one.
        let known = tracked::run(&inputs(cal, val, TimeOffset::Fixed(expected)), 20).unwrap();
        let pre3d = validation_pre3d(&known);
        assert!(
            (pre3d - pre3d0).abs() <= 0.05,
            "shift {k}: validation PRE3D {pre3d} with the known lag against {pre3d0}"
        );
    }
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_sweep_whose_poses_do_not_move_is_refused_with_its_reason() {
    let dir = scratch("plus_lag", "still");
    // Every frame carries frame 0's poses: the dots move, the tracker does not.
    let still = |_: usize, _: usize| Some(0);
    let cal = retracked(&shared_data(SET, CALIBRATION), &dir.join("cal.igs.mha"), still);
    let val = shared_data(SET, VALIDATION);
    let run = tracked::run(&inputs(cal, val, TimeOffset::Estimate), 20).unwrap();
    let e = run.lag_estimate.unwrap();
    assert_eq!(e.lag_s, None, "{}", e.decision);
    assert!(!e.applied && run.time_offset_s == 0.0);
    let why = e.unresolved.unwrap();
    assert!(why.contains("flat") || why.contains("too little motion"), "{why}");
    assert!(e.decision.starts_with("no lag applied"), "{}", e.decision);
}
