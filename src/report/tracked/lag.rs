//! The tracker's lag on a tracked run's page and console: the estimate in one
//! line, the objective against the lag with both estimates, and PRE3D with no
//! lag beside the lagged figures.

use crate::core::geometry::Rigid;
use crate::core::stats::best_95;
use crate::estimate::image_to_probe::Fit;
use crate::io::plus::result::PlusResult;
use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::tracked::time::lag_joint::LagEstimate;
use crate::pipeline::tracked::{Role, TrackedFrame, TrackedRun};
use crate::report::page::figures::{Chart, Series, Style};
use crate::results::summary::{NoLagPre3d, Pre3dAtLag};

/// The lag in one console line: the estimate, its intervals, what was
/// applied, and the motion's estimate.
pub fn lag_line(e: &LagEstimate) -> String {
    let ms = |s: f64| format!("{:+.0} ms", s * 1000.0);
    let interval = |i: Option<[f64; 2]>, what: &str| i.map(|[a, b]| format!("; {what} {} to {}", ms(a), ms(b)));
    let boot = e.coarse.bootstrap_lag_s.map(|b| [b.p5, b.p95]);
    let motion = match e.motion.as_ref() {
        Some(m) => match m.lag_s {
            Some(l) => format!("; the sweep's motion gives {}", ms(l)),
            None => "; the sweep's motion gives none".into(),
        },
        None => String::new(),
    };
    format!(
        "tracker lag {} (90 %{}{}){motion}: {}",
        e.lag_s.map(ms).unwrap_or_else(|| "unresolved".into()),
        interval(e.interval_90_s, "curvature").unwrap_or_default(),
        interval(boot, "resamples").unwrap_or_default(),
        e.decision
    )
    .replacen("(90 %; ", "(90 %: ", 1)
    .replace(" (90 %)", "")
}

/// PRE3D of `fit` and of PLUS's matrix (on the frames `keep` admits) over
/// `frames`, each placed with the poses it carries.
fn scored(
    frames: &[TrackedFrame],
    labels: &TrackedLabels,
    plus: Option<&PlusResult>,
    fit: &Fit,
    keep: &impl Fn(usize) -> bool,
) -> NoLagPre3d {
    let ours: Vec<f64> = frames
        .iter()
        .flat_map(|f| {
            crate::pipeline::tracked::pre3d(
                f,
                &labels.nwires,
                |pixel| fit.image_to_probe.apply(pixel),
                &fit.phantom_correction,
            )
        })
        .collect();
    let theirs = plus.map(|plus| {
        let map = |pixel: [f64; 2]| {
            plus.image_to_probe
                .transform_point(&nalgebra::Point3::new(pixel[0], pixel[1], 0.0))
        };
        frames
            .iter()
            .filter(|f| keep(f.index))
            .flat_map(|f| crate::pipeline::tracked::pre3d(f, &labels.nwires, map, &Rigid::identity()))
            .collect::<Vec<f64>>()
    });
    NoLagPre3d {
        pre3d_mm: best_95(&ours),
        plus_matrix_pre3d_mm: theirs.and_then(|t| best_95(&t)),
    }
}

/// PRE3D with no lag of our model refitted without it, and of PLUS's matrix on
/// the frames `keep` admits; and the same at each lag of the run's span across
/// the lag's interval, on the frames posed at all of them.
pub fn other_lags_pre3d(
    run: &TrackedRun,
    labels: &TrackedLabels,
    plus: Option<&PlusResult>,
    role: Role,
    keep: impl Fn(usize) -> bool,
) -> (Option<NoLagPre3d>, Vec<Pre3dAtLag>) {
    let of_role = |f: &&TrackedFrame| f.role == role && f.rejected.is_none();
    let no_lag = run.no_lag_fit.as_ref().map(|fit| {
        let frames: Vec<TrackedFrame> = run
            .frames
            .iter()
            .filter(of_role)
            .map(|f| TrackedFrame {
                marker_T_phantom: f.marker_T_phantom_no_lag,
                ..f.clone()
            })
            .collect();
        scored(&frames, labels, plus, fit, &keep)
    });
    let posed: Vec<usize> = (0..run.frames.len())
        .filter(|&i| of_role(&&run.frames[i]) && run.lag_span.iter().all(|p| p.poses[i].is_some()))
        .collect();
    let span = run
        .lag_span
        .iter()
        .map(|p| {
            let frames: Vec<TrackedFrame> = posed
                .iter()
                .map(|&i| TrackedFrame {
                    marker_T_phantom: p.poses[i],
                    ..run.frames[i].clone()
                })
                .collect();
            let s = scored(&frames, labels, plus, &p.fit, &keep);
            Pre3dAtLag {
                lag_s: p.lag_s,
                applied: p.lag_s == run.time_offset_s,
                pre3d_mm: s.pre3d_mm,
                plus_matrix_pre3d_mm: s.plus_matrix_pre3d_mm,
            }
        })
        .collect();
    (no_lag, span)
}

/// How much the validation PRE3D moves across the lag's interval, in a
/// sentence; none without a span.
pub fn span_sentence(span: &[Pre3dAtLag]) -> Option<String> {
    let range = |pick: &dyn Fn(&Pre3dAtLag) -> Option<f64>| {
        let values: Vec<f64> = span.iter().filter_map(pick).collect();
        (values.len() == span.len() && !values.is_empty()).then(|| {
            (
                values.iter().copied().fold(f64::INFINITY, f64::min),
                values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            )
        })
    };
    let (first, last) = (span.first()?, span.last()?);
    let (lo, hi) = range(&|p| p.pre3d_mm.map(|s| s.mean))?;
    let plus = range(&|p| p.plus_matrix_pre3d_mm.map(|s| s.mean))
        .map(|(a, b)| format!("; PLUS's matrix at the same lags, {a:.3} to {b:.3} mm"))
        .unwrap_or_default();
    Some(format!(
        "Across the lag's 90 % interval ({:+.0} to {:+.0} ms, {} lags), the calibration refitted at each lag scores a validation PRE3D of {lo:.3} to {hi:.3} mm (best 95 %){plus}: what the lag's uncertainty alone can move the reported figure by.",
        first.lag_s * 1000.0,
        last.lag_s * 1000.0,
        span.len()
    ))
}

/// The coarse search's objective against the lag, with the estimate applied
/// (or found) and the motion's, each with its 90 % interval drawn at the
/// objective's floor.
pub fn lag_chart(e: &LagEstimate) -> Option<Chart> {
    let curve: Vec<(f64, f64)> = e.coarse.objective.iter().map(|o| (o[0] * 1000.0, o[1])).collect();
    if curve.len() < 3 {
        return None;
    }
    let lo = curve.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let hi = curve.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let mark = |lag_s: f64, interval: Option<[f64; 2]>, level: f64| {
        let mut points = vec![(lag_s * 1000.0, lo), (lag_s * 1000.0, hi)];
        if let Some([a, b]) = interval {
            let y = lo + (hi - lo) * level;
            points.extend([
                (lag_s * 1000.0, y),
                (a * 1000.0, y),
                (b * 1000.0, y),
                (lag_s * 1000.0, y),
            ]);
        }
        points
    };
    let mut series = vec![Series {
        name: "calibration frames' RMS error of the affine fit (mm)".into(),
        colour: plotters::style::RGBColor(40, 70, 200),
        points: curve,
    }];
    if let Some(lag) = e.lag_s {
        series.push(Series {
            name: format!("spatio-temporal estimate {:+.0} ms", lag * 1000.0),
            colour: plotters::style::RGBColor(200, 40, 40),
            points: mark(lag, e.interval_s(), 0.1),
        });
    }
    if let Some(m) = e.motion.as_ref() {
        if let Some(lag) = m.lag_s {
            series.push(Series {
                name: format!("motion estimate {:+.0} ms", lag * 1000.0),
                colour: plotters::style::RGBColor(40, 140, 40),
                points: mark(lag, m.bootstrap_lag_s.map(|b| [b.p5, b.p95]), 0.2),
            });
        }
    }
    Some(Chart {
        id: "lag_objective",
        caption: format!(
            "The tracker's lag: at each lag the calibration frames' dots are placed with the poses read at the image's time plus the lag and PLUS's affine ImageToProbe is fitted; the curve is its RMS error. Look for one clear valley: its floor is the lag, and the horizontal bars are the 90 % intervals (resamples of the sweep, the curvature). {}{}",
            e.decision,
            e.disagreement
                .as_ref()
                .map(|d| format!(" Warning: {d}."))
                .unwrap_or_default()
        ),
        x_desc: "tracker lag (ms)".into(),
        y_desc: "RMS error (mm)".into(),
        style: Style::Lines,
        series,
        equal_axes: false,
    })
}

/// The lag's figure (SVG) and caption in a page's context, with what the
/// lag's interval does to the validation PRE3D (`span`); none without an
/// estimate.
pub fn insert_figure(
    ctx: &mut tera::Context,
    run: &TrackedRun,
    span: &[Pre3dAtLag],
) -> Result<(), crate::report::error::OutputError> {
    ctx.insert("lag_span", &span_sentence(span));
    let chart = run.lag_estimate.as_ref().and_then(lag_chart);
    ctx.insert(
        "lag_figure",
        &chart.as_ref().map(crate::report::page::figures::svg).transpose()?,
    );
    ctx.insert("lag_caption", &chart.as_ref().map(|c| c.caption.clone()));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::tracked::time::lag::Coarse;

    #[test]
    fn the_figure_says_when_the_two_estimates_disagree() {
        let mut e = LagEstimate {
            lag_s: Some(0.4),
            decision: "+400 ms applied".into(),
            coarse: Coarse {
                objective: (0..5)
                    .map(|k| [k as f64 * 0.1, 1.0 + (k as f64 - 4.0).powi(2)])
                    .collect(),
                ..Default::default()
            },
            ..Default::default()
        };
        let quiet = lag_chart(&e).unwrap().caption;
        assert!(
            quiet.ends_with("+400 ms applied") && !quiet.contains("Warning"),
            "{quiet}"
        );
        e.disagreement = Some("the two estimates disagree".into());
        let loud = lag_chart(&e).unwrap().caption;
        assert!(loud.ends_with("Warning: the two estimates disagree."), "{loud}");
        assert_eq!(lag_chart(&e).unwrap().series.len(), 2);
    }
}
