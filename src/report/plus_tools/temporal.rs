//! Outputs of `probecal temporal`: `summary.json` (`tracker_lag_s` in PLUS's
//! sign convention), `lines.csv` (each B-scan's line, or why none) and
//! `report.html` (the correlation curve over the lags searched).

use std::fmt::Write as _;
use std::path::Path;

use crate::io::fs::write_all_atomic;
use crate::pipeline::tracked::time::temporal::TemporalRun;
use crate::report::error::OutputError;
use crate::report::page::figures::{svg, Chart, Series, Style};
use crate::results::temporal::TemporalSummary;
use plotters::style::RGBColor;

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

/// The correlation over the lags searched, and the estimate as its own series.
fn curve_chart(run: &TemporalRun) -> Chart {
    let lowest = run.curve.iter().map(|(_, c)| *c).fold(1.0f64, f64::min);
    Chart {
        id: "correlation",
        caption: format!(
            "The normalised cross-correlation of the reflector line's position in the video with the tracker's, \
             over the lags searched (step {} ms); the estimate (red) is the interpolated peak, {:.1} ms. \
             Look for one clear peak: several of nearly equal height, or a flat curve, mean the motion could not \
             tell the lag.",
            crate::pipeline::tracked::time::temporal::STEP_S * 1000.0,
            run.tracker_lag_s * 1000.0
        ),
        x_desc: "tracker lag (s)".into(),
        y_desc: "correlation".into(),
        style: Style::Lines,
        series: vec![
            Series {
                name: "correlation".into(),
                colour: RGBColor(20, 40, 80),
                points: run.curve.clone(),
            },
            Series {
                name: "estimate".into(),
                colour: RGBColor(200, 0, 0),
                points: vec![
                    (run.tracker_lag_s, lowest.min(0.0)),
                    (run.tracker_lag_s, run.peak_correlation),
                ],
            },
        ],
        equal_axes: false,
    }
}

const TEMPLATE: &str = include_str!("../../../templates/temporal.html.tera");

/// `report.html`, from `templates/temporal.html.tera`: the summary's figures
/// and the run's correlation curve.
pub fn html(summary: &TemporalSummary, run: &TemporalRun) -> Result<String, OutputError> {
    let chart = curve_chart(run);
    let mut ctx = tera::Context::new();
    ctx.insert("video", &summary.video);
    ctx.insert("frames", &summary.frames);
    ctx.insert("with_line", &summary.frames_with_line);
    ctx.insert("tracker", &summary.tracker);
    ctx.insert("tracker_samples", &summary.tracker_samples);
    ctx.insert("lag_ms", &format!("{:.1}", summary.tracker_lag_s * 1000.0));
    ctx.insert("lag_s", &format!("{:.4}", summary.tracker_lag_s));
    ctx.insert("peak", &format!("{:.3}", summary.peak_correlation));
    ctx.insert("range_s", &summary.lag_range_s);
    ctx.insert("curve_svg", &svg(&chart)?);
    ctx.insert("curve_caption", &chart.caption);
    Ok(tera::Tera::one_off(TEMPLATE, &ctx, true)?)
}

/// Writes `summary.json`, `lines.csv` and `report.html` into `out` (whole, or nothing).
pub fn write(run: &TemporalRun, out: &Path) -> Result<(), OutputError> {
    let summary = TemporalSummary::of(run);
    let text = crate::results::summary::to_text(&summary)?;
    let files = [
        ("summary.json".to_string(), text.into_bytes()),
        ("lines.csv".to_string(), lines_csv(run).into_bytes()),
        ("report.html".to_string(), html(&summary, run)?.into_bytes()),
    ];
    Ok(write_all_atomic(out, &files)?)
}
