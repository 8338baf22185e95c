//! What the terminal shows: the thesis's tables as text, a run's summary, the
//! camera calibration's views.

use crate::detect::camera_calibration::CameraCalibration;
use crate::evaluate::{cutoff_label, BreStats, STAT_ROWS};
use crate::pipeline::record::DatasetRun;
use crate::pipeline::tracked::{Role, TrackedRun};
use crate::results::summary::{Summary, TrackedSummary};

/// The thesis's BRE table (rows Std./Mean/Min/Max, columns x, y, z) as text.
pub fn bre_table_text(stats: &BreStats) -> String {
    let mut s = format!("{:<6} {:>9} {:>9} {:>9}\n", "", "x", "y", "z");
    for (name, get) in STAT_ROWS {
        let [x, y, z] = stats.axes().map(|a| get(&a));
        s.push_str(&format!("{name:<6} {x:>9.3} {y:>9.3} {z:>9.3}\n"));
    }
    s
}

/// The thesis's threshold table (axis x parameter rows, one column per cut-off) as text.
pub fn threshold_table_text(run: &DatasetRun) -> String {
    let mut s = format!("{:<5} {:<6}", "Axis", "");
    for r in &run.thresholds {
        s.push_str(&format!(
            " {:>11}",
            format!("{} ({})", cutoff_label(r.cutoff_mm), r.frames.len())
        ));
    }
    s.push('\n');
    for (axis, axis_name) in ["X", "Y", "Z"].iter().enumerate() {
        for (i, (name, get)) in STAT_ROWS.iter().enumerate() {
            s.push_str(&format!("{:<5} {:<6}", if i == 0 { *axis_name } else { "" }, name));
            for r in &run.thresholds {
                match &r.stats {
                    Some(st) => s.push_str(&format!(" {:>11.3}", get(&st.axes()[axis]))),
                    None => s.push_str(&format!(" {:>11}", "—")),
                }
            }
            s.push('\n');
        }
    }
    s
}

/// A dataset run's lines: timings (stderr), frames used, the BRE and threshold
/// tables and the truth (stdout).
pub fn dataset_run(run: &DatasetRun, summary: &Summary, folder: &std::path::Path) {
    for (stage, seconds) in &run.timings_s {
        eprintln!("  {stage}: {seconds:.1} s");
    }
    let primary = &run.thresholds[run.primary];
    println!(
        "\n{} / {}: {} of {} frames used; calibration at cut-off {} mm from {} frames",
        summary.experiment,
        summary.dataset,
        summary.frames.used,
        summary.frames.total,
        cutoff_label(primary.cutoff_mm),
        primary.frames.len()
    );
    if let Some(stats) = &primary.stats {
        println!("BRE along axes (mm)\n{}", bre_table_text(stats));
    }
    println!(
        "BRE after removing frames above each cut-off (mm, frames)\n{}",
        threshold_table_text(run)
    );
    if let Some(t) = &summary.truth {
        println!(
            "ground truth: image corners {:.3} mm mean, {:.3} mm max; rotation {:.3}°; translation {:.3} mm",
            t.corner_error_mm.mean, t.corner_error_mm.max, t.rotation_error_deg, t.translation_error_mm
        );
    }
    println!("written to {}", folder.display());
}

/// A tracked run's lines.
pub fn tracked_run(run: &TrackedRun, summary: &TrackedSummary, folder: &std::path::Path) {
    let f3 = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into());
    let n = |v: Option<crate::core::stats::MeanSd>| v.map(|s| s.n.to_string()).unwrap_or_else(|| "null".into());
    let frames = &summary.frames;
    println!(
        "\n{} / {}: calibration frames segmented {}/{}, validation {}/{}; tracker offset {:.0} ms",
        summary.experiment,
        summary.dataset,
        frames.calibration.segmented,
        frames.calibration.total,
        frames.validation.segmented,
        frames.validation.total,
        run.time_offset_s * 1000.0
    );
    if let Some(e) = &run.lag_estimate {
        match &e.unresolved {
            Some(why) => eprintln!("warning: the tracker's lag could not be estimated, none is applied: {why}"),
            None => println!("{}", crate::report::tracked::lag::lag_line(e)),
        }
        if let Some(d) = &e.disagreement {
            eprintln!("warning: {d}");
        }
    }
    for (role, what) in [(Role::Calibration, "calibration"), (Role::Validation, "validation")] {
        if let Some(w) = crate::pipeline::sequence_frames::rejection_warning(&run.frames, role, what) {
            eprintln!("warning: {w}");
        }
    }
    println!("ImageToProbe\n{}", run.fit.image_to_probe.matrix());
    let (best, all) = (summary.validation.pre3d_mm, summary.validation.pre3d_all_mm);
    println!(
        "validation PRE3D: {} ± {} mm (best 95 %, n = {}); all points {} ± {} mm (n = {})",
        f3(best.map(|s| s.mean)),
        f3(best.map(|s| s.std)),
        n(best),
        f3(all.map(|s| s.mean)),
        f3(all.map(|s| s.std)),
        n(all),
    );
    if let Some(plus) = &summary.plus_result {
        let v = &summary.validation;
        let c = v.frames_compared.unwrap_or_default();
        println!(
            "on the {} validation frames both segmented (ours {}, PLUS's {}): probecal {} mm, PLUS's matrix {} mm (same dots and poses, best 95 %)",
            c.both,
            c.ours,
            c.plus.map(|n| n.to_string()).unwrap_or_else(|| "not listed".into()),
            f3(v.same_frames_pre3d_mm.map(|s| s.mean)),
            f3(v.plus_matrix_pre3d_mm.map(|s| s.mean)),
        );
        if let Some(d) = v.ours_minus_plus_matrix_mm {
            println!("{}", d.sentence("probecal", "PLUS's matrix"));
        }
        if let Some(span) = crate::report::tracked::lag::span_sentence(&v.across_lag_interval) {
            println!("{span}");
        }
        println!(
            "PLUS's published validation PRE3D: {} mm on its own dots{}",
            f3(plus.published_validation_pre3d_mm.mean),
            c.plus.map(|n| format!(" ({n} frames)")).unwrap_or_default(),
        );
    }
    println!("written to {}", folder.display());
}

/// The camera calibration's views (stderr) and intrinsics (stdout).
pub fn camera_calibration(cal: &CameraCalibration) {
    for v in &cal.views {
        match (&v.reason, v.rms_px) {
            (None, Some(rms)) => eprintln!(
                "  {}: used, RMS {rms:.3} px{}",
                v.image.display(),
                v.found_by.map(|f| format!(" (found by {f})")).unwrap_or_default()
            ),
            (Some(r), _) => eprintln!("  {}: not used: {r}", v.image.display()),
            _ => {}
        }
    }
    for w in &cal.warnings {
        eprintln!("warning: {w}");
    }
    let k = &cal.intrinsics;
    println!(
        "fx {:.4} fy {:.4} cx {:.4} cy {:.4} px; distortion {:?}; RMS {:.6} px",
        k.fx(),
        k.fy(),
        k.cx(),
        k.cy(),
        k.distortion,
        k.rms_px.unwrap_or(f64::NAN)
    );
}
