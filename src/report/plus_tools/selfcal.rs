//! Outputs of `probecal selfcal`: `summary.json`, `ImageToProbe.xml` (PLUS's
//! Transform element, as `run` writes it) and `report.html` (the correction and
//! which directions were refined).

use std::path::Path;

use crate::estimate::selfcal::overlay::OverlaySlice;
use crate::io::fs::write_all_atomic;
use crate::pipeline::selfcal::lag::LagProfile;
use crate::pipeline::selfcal::SelfcalRun;
use crate::report::error::OutputError;
use crate::report::page::figures::{svg, Chart, Series, Style};
use crate::report::tracked::transform_files::plus_xml;
use crate::results::selfcal::SelfcalSummary;

const TEMPLATE: &str = include_str!("../../../templates/selfcal.html.tera");

fn html(summary: &SelfcalSummary, overlays: &[OverlaySlice]) -> Result<String, OutputError> {
    let mut ctx = tera::Context::new();
    ctx.insert("overlays", &super::selfcal_overlay::figures(overlays)?);
    ctx.insert("sweeps", &summary.sweeps);
    ctx.insert("start_source", &summary.start_source);
    ctx.insert("lag_ms", &format!("{:.1}", summary.tracker_lag_s * 1e3));
    ctx.insert("correlation_start", &format!("{:.4}", summary.correlation_start));
    ctx.insert("correlation_end", &format!("{:.4}", summary.correlation_end));
    ctx.insert("voxels", &summary.voxels_compared);
    ctx.insert("voxel_mm", &summary.settings.comparison.voxel_mm);
    ctx.insert("corner_mm", &format!("{:.2}", summary.corner_change_mm));
    ctx.insert("move_mm", &summary.move_mm.map(|v| format!("{v:+.2}")));
    ctx.insert("turn_deg", &summary.turn_deg.map(|v| format!("{v:+.2}")));
    ctx.insert("radius_mm", &format!("{:.1}", summary.radius_mm));
    ctx.insert("ratio", &summary.settings.min_curvature_ratio);
    let resamples = match summary.resamples_used {
        n if n == summary.settings.resamples => n.to_string(),
        n => format!(
            "{n} (of {}; the others' halves share too few voxels)",
            summary.settings.resamples
        ),
    };
    ctx.insert("resamples", &resamples);
    ctx.insert("max_se", &summary.settings.max_standard_error_mm);
    let directions: Vec<serde_json::Value> = summary
        .directions
        .iter()
        .map(|d| {
            serde_json::json!({
                "mostly": d.mostly,
                "curvature": format!("{:.4}", d.curvature_per_mm2),
                "standard_error": d.standard_error_mm.map_or("—".to_string(), |se| format!("{se:.2}")),
                "held": d.held,
            })
        })
        .collect();
    ctx.insert("directions", &directions);
    let c = &summary.check;
    ctx.insert("verdict", &c.verdict.words());
    ctx.insert("offset_mm", &format!("{:.2}", c.offset_mm));
    ctx.insert("tolerance_mm", &format!("{:.2}", c.tolerance_mm));
    ctx.insert("alarm_pct", &format!("{:.1} %", c.false_alarm_rate * 100.0));
    ctx.insert("noise_95_mm", &format!("{:.2}", c.noise_95_mm));
    ctx.insert("draws", &c.draws);
    ctx.insert("not_checked", &c.not_checked);
    ctx.insert("profile_svg", &profile_chart(summary)?);
    match &summary.lag_profile {
        Some(p) => {
            ctx.insert("lag_svg", &lag_chart(p)?);
            ctx.insert(
                "lag_best",
                &match (p.best_s, &p.no_best) {
                    (Some(best), _) => format!(
                        "the sweeps agree best at {:.1} ms{}",
                        best * 1e3,
                        p.standard_error_s.map_or(
                            format!(
                                " (no standard error: {} of {} resamples peak inside the range)",
                                p.resamples_peaked, p.resamples
                            ),
                            |se| format!(
                                " ± {:.1} ms (standard error over {} resamples of the sweeps)",
                                se * 1e3,
                                p.resamples
                            )
                        )
                    ),
                    (None, why) => format!("no lag is preferred: {}", why.as_deref().unwrap_or("")),
                },
            );
            ctx.insert("lag_caution", &lag_caution(p, summary.tracker_lag_s));
            ctx.insert(
                "lag_range",
                &format!(
                    "{:.0} to {:.0} ms",
                    p.points.first().map_or(0.0, |x| x.0 * 1e3),
                    p.points.last().map_or(0.0, |x| x.0 * 1e3)
                ),
            );
        }
        None => ctx.insert("lag_svg", &""),
    }
    Ok(tera::Tera::one_off(TEMPLATE, &ctx, true)?)
}

/// The preferred lag is said to differ from the one refined at when it is
/// more than this many standard errors from it (about one time in twenty by
/// chance, for a normal spread).
pub const LAG_APART_SES: f64 = 2.0;

/// A caution when the sweeps prefer a lag more than [`LAG_APART_SES`]
/// standard errors from `given_s`, the lag the calibration was refined at and
/// checked at: a right matrix read at a wrong lag can look inconsistent.
pub fn lag_caution(p: &LagProfile, given_s: f64) -> Option<String> {
    let (best, se) = (p.best_s?, p.standard_error_s?);
    let apart = (best - given_s) / se;
    (apart.abs() > LAG_APART_SES).then(|| {
        format!(
            "the sweeps prefer a lag {:.1} standard errors from the {:.1} ms the calibration was refined and checked at; \
             a right calibration read at a wrong lag can look inconsistent with the sweeps, so the check may be flagging the lag",
            apart.abs(),
            given_s * 1e3
        )
    })
}

const PROFILE_COLOURS: [plotters::style::RGBColor; 6] = [
    plotters::style::RGBColor(200, 40, 40),
    plotters::style::RGBColor(40, 140, 40),
    plotters::style::RGBColor(40, 70, 200),
    plotters::style::RGBColor(200, 130, 0),
    plotters::style::RGBColor(130, 50, 160),
    plotters::style::RGBColor(110, 110, 110),
];

/// The agreement along each direction through the refined calibration, as SVG.
fn profile_chart(summary: &SelfcalSummary) -> Result<String, OutputError> {
    let series = summary
        .profiles
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let first_two: Vec<&str> = p.mostly.split(", ").take(2).collect();
            Series {
                name: format!(
                    "{}: {}{}",
                    k + 1,
                    first_two.join(", "),
                    if p.held { " (refined)" } else { " (left)" }
                ),
                colour: PROFILE_COLOURS[k % PROFILE_COLOURS.len()],
                points: p.points.clone(),
            }
        })
        .collect();
    svg(&Chart {
        id: "selfcal_profiles",
        caption: "The sweeps' agreement along each direction through the refined calibration".into(),
        x_desc: "distance from the refined calibration along the direction (mm)".into(),
        y_desc: "mean normalised correlation".into(),
        style: Style::Lines,
        series,
        equal_axes: false,
    })
}

/// The agreement against the tracker's lag, as SVG.
fn lag_chart(p: &LagProfile) -> Result<String, OutputError> {
    svg(&Chart {
        id: "selfcal_lag",
        caption: "The sweeps' agreement against the tracker's lag at the refined calibration".into(),
        x_desc: "tracker lag (ms)".into(),
        y_desc: "mean normalised correlation".into(),
        style: Style::Lines,
        series: vec![Series {
            name: "at the refined calibration".into(),
            colour: PROFILE_COLOURS[2],
            points: p.points.iter().map(|(lag, ncc, _)| (lag * 1e3, *ncc)).collect(),
        }],
        equal_axes: false,
    })
}

/// Writes `summary.json`, `ImageToProbe.xml` and `report.html` into `out` (whole, or nothing).
pub fn write(run: &SelfcalRun, out: &Path) -> Result<SelfcalSummary, OutputError> {
    let summary = SelfcalSummary::of(run);
    let text = crate::results::summary::to_text(&summary)?;
    let files = [
        ("summary.json".to_string(), text.into_bytes()),
        (
            "ImageToProbe.xml".to_string(),
            plus_xml(&run.image_to_probe()).into_bytes(),
        ),
        ("report.html".to_string(), html(&summary, &run.overlays)?.into_bytes()),
    ];
    write_all_atomic(out, &files)?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile(best_s: Option<f64>, standard_error_s: Option<f64>) -> LagProfile {
        LagProfile {
            points: Vec::new(),
            best_s,
            no_best: None,
            standard_error_s,
            resamples_peaked: 8,
            resamples: 8,
        }
    }

    #[test]
    fn a_lag_is_cautioned_only_beyond_two_standard_errors_of_the_one_given() {
        // 38.5 ± 6.5 ms against 60.4 ms: 3.4 standard errors apart.
        let far = lag_caution(&profile(Some(0.0385), Some(0.0065)), 0.0604).unwrap();
        assert!(far.contains("3.4 standard errors") && far.contains("60.4 ms"), "{far}");
        // 25.9 ± 15.5 ms against 0: 1.7 apart, no caution.
        assert_eq!(lag_caution(&profile(Some(0.0259), Some(0.0155)), 0.0), None);
        // No standard error, or no best lag: nothing to say.
        assert_eq!(lag_caution(&profile(Some(0.09), None), 0.0), None);
        assert_eq!(lag_caution(&profile(None, Some(0.001)), 0.0), None);
    }
}
