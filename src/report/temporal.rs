//! Outputs of `probecal temporal`: `summary.json` (`tracker_lag_s` in PLUS's
//! sign convention), `lines.csv` (each B-scan's line, or why none) and
//! `report.html` (the correlation curve over the lags searched).

use std::fmt::Write as _;
use std::path::Path;

use crate::io::fs::{display_path, write_all_atomic};
use crate::pipeline::time::temporal::TemporalRun;
use crate::report::error::OutputError;

/// `lines.csv`: frame, found, origin and direction in pixels, or the reason.
pub fn lines_csv(run: &TemporalRun) -> String {
    let mut out = String::from("frame,timestamp_s,found,origin_u_px,origin_v_px,direction_u,direction_v,reason\n");
    for f in &run.frames {
        match &f.line {
            Ok(l) => {
                let _ = writeln!(
                    out,
                    "{},{:.6},1,{:.3},{:.3},{:.6},{:.6},",
                    f.index, f.timestamp_s, l.origin_px[0], l.origin_px[1], l.direction[0], l.direction[1]
                );
            }
            Err(e) => {
                let _ = writeln!(
                    out,
                    "{},{:.6},0,,,,,{}",
                    f.index,
                    f.timestamp_s,
                    e.to_string().replace(',', ";")
                );
            }
        }
    }
    out
}

pub fn summary(run: &TemporalRun) -> serde_json::Value {
    serde_json::json!({
        "video": display_path(&run.video),
        "tracker": display_path(&run.tracker),
        "tracker_lag_s": run.tracker_lag_s,
        "peak_correlation": run.peak_correlation,
        "frames": run.frames.len(),
        "frames_with_line": run.frames.iter().filter(|f| f.line.is_ok()).count(),
        "tracker_samples": run.tracker_samples,
        "lag_step_s": crate::pipeline::time::temporal::STEP_S,
        "lag_range_s": crate::pipeline::time::temporal::MAX_LAG_S,
    })
}

/// The correlation over the lags as an inline SVG polyline.
fn curve_svg(run: &TemporalRun) -> String {
    let (w, h) = (640.0, 240.0);
    let lags = run.curve.iter().map(|(l, _)| *l);
    let (lo, hi) = lags.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), l| (a.min(l), b.max(l)));
    let x = |l: f64| (l - lo) / (hi - lo).max(1e-9) * w;
    let y = |c: f64| (1.0 - (c + 1.0) / 2.0) * h;
    let points: Vec<String> = run
        .curve
        .iter()
        .map(|(l, c)| format!("{:.1},{:.1}", x(*l), y(*c)))
        .collect();
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\
         <line x1=\"0\" y1=\"{:.1}\" x2=\"{w}\" y2=\"{:.1}\" stroke=\"#bbb\"/>\
         <line x1=\"{:.1}\" y1=\"0\" x2=\"{:.1}\" y2=\"{h}\" stroke=\"#c00\"/>\
         <polyline fill=\"none\" stroke=\"#124\" stroke-width=\"1.5\" points=\"{}\"/></svg>",
        y(0.0),
        y(0.0),
        x(run.tracker_lag_s),
        x(run.tracker_lag_s),
        points.join(" ")
    )
}

pub fn html(run: &TemporalRun) -> String {
    let with_line = run.frames.iter().filter(|f| f.line.is_ok()).count();
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\"><title>temporal calibration</title>\n\
         <style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}</style></head>\n<body>\n\
         <h1>Temporal calibration</h1>\n<p>Video {} ({} frames, a line in {}), tracker {} ({} samples).</p>\n\
         <p id=\"lag\">The tracker lags the video by <b>{:.1} ms</b> (PLUS's TrackerLagSec {:.4} s); normalised cross-correlation at the peak {:.3}.</p>\n\
         <h2>Correlation over the lag (−{} s to +{} s; red: the estimate)</h2>\n{}\n\
         <p>Each B-scan's line is in <code>lines.csv</code>.</p>\n</body>\n</html>\n",
        display_path(&run.video),
        run.frames.len(),
        with_line,
        display_path(&run.tracker),
        run.tracker_samples,
        run.tracker_lag_s * 1000.0,
        run.tracker_lag_s,
        run.peak_correlation,
        crate::pipeline::time::temporal::MAX_LAG_S,
        crate::pipeline::time::temporal::MAX_LAG_S,
        curve_svg(run),
    )
}

/// Writes `summary.json`, `lines.csv` and `report.html` into `out` (whole, or nothing).
pub fn write(run: &TemporalRun, out: &Path) -> Result<(), OutputError> {
    let text = crate::report::summary::to_text(&summary(run))?;
    let files = [
        ("summary.json".to_string(), text.into_bytes()),
        ("lines.csv".to_string(), lines_csv(run).into_bytes()),
        ("report.html".to_string(), html(run).into_bytes()),
    ];
    Ok(write_all_atomic(out, &files)?)
}
