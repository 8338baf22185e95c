//! The reports' figures besides the per-frame BRE: BRE histograms, the boards'
//! reprojection error per frame, the camera calibration's error per view, and a
//! projected overview of the probe poses in the phantom frame. Each is drawn
//! once by plotters on any backend: SVG inline in the HTML page, PNG beside the
//! LaTeX report.

use crate::report::error::OutputError;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::core::geometry::pixel_to_image_mm;
use crate::pipeline::record::DatasetRun;

/// A named set of points of one chart.
pub struct Series {
    pub name: String,
    pub colour: RGBColor,
    pub points: Vec<(f64, f64)>,
}

/// How a chart shows its series.
#[derive(Clone, Copy, PartialEq)]
pub enum Style {
    /// Points joined by lines.
    Lines,
    /// Points only (scatter, e.g. positions seen from above).
    Points,
    /// Bars from 0 at each x, `width` wide.
    Bars { width: f64 },
    /// Line segments: the points taken two by two as each segment's ends.
    Segments,
}

/// One figure: its file stem, caption, axes and series.
pub struct Chart {
    pub id: &'static str,
    pub caption: String,
    pub x_desc: String,
    pub y_desc: String,
    pub style: Style,
    pub series: Vec<Series>,
    /// Equal scales on both axes (views of positions).
    pub equal_axes: bool,
}

const COLOURS: [RGBColor; 3] = [RGBColor(200, 40, 40), RGBColor(40, 140, 40), RGBColor(40, 70, 200)];

fn range(values: impl Iterator<Item = f64>, from_zero: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if from_zero {
        lo = lo.min(0.0);
    }
    let pad = ((hi - lo) * 0.06).max(1e-3);
    (lo - pad, hi + pad)
}

/// Draws a chart on any plotters backend; sizes scale with the area's width
/// (760 px is the reference).
pub fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, chart: &Chart) -> Result<(), OutputError> {
    let (width, height) = root.dim_in_pixel();
    let scale = width as f64 / 760.0;
    let px = |v: f64| (v * scale).round() as u32;
    let font = ("sans-serif", 13.0 * scale);
    root.fill(&WHITE).map_err(OutputError::figure)?;
    let all = || chart.series.iter().flat_map(|s| s.points.iter());
    let bars = matches!(chart.style, Style::Bars { .. });
    let (mut x0, mut x1) = range(all().map(|p| p.0), false);
    let (mut y0, mut y1) = range(all().map(|p| p.1), bars);
    if let Style::Bars { width } = chart.style {
        x0 -= width;
        x1 += width;
    }
    if chart.equal_axes {
        // Widen the narrower range so a millimetre is as long on both axes.
        let plot_w = width as f64 - 70.0 * scale;
        let plot_h = height as f64 - 60.0 * scale;
        let per_px = ((x1 - x0) / plot_w).max((y1 - y0) / plot_h);
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        (x0, x1) = (cx - per_px * plot_w / 2.0, cx + per_px * plot_w / 2.0);
        (y0, y1) = (cy - per_px * plot_h / 2.0, cy + per_px * plot_h / 2.0);
    }
    let mut c = ChartBuilder::on(root)
        .margin(px(12.0))
        .x_label_area_size(px(36.0))
        .y_label_area_size(px(58.0))
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(OutputError::figure)?;
    c.configure_mesh()
        .x_desc(chart.x_desc.as_str())
        .y_desc(chart.y_desc.as_str())
        .label_style(font)
        .axis_desc_style(font)
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(OutputError::figure)?;
    let n = chart.series.len().max(1) as f64;
    for (k, s) in chart.series.iter().enumerate() {
        let colour = s.colour;
        let legend_len = px(16.0) as i32;
        let legend_width = px(2.0);
        let anno = match chart.style {
            Style::Lines => {
                c.draw_series(s.points.iter().map(|p| Circle::new(*p, px(3.0), colour.filled())))
                    .map_err(OutputError::figure)?;
                c.draw_series(LineSeries::new(s.points.clone(), colour.stroke_width(px(1.0))))
                    .map_err(OutputError::figure)?
            }
            Style::Points => c
                .draw_series(s.points.iter().map(|p| Circle::new(*p, px(3.0), colour.filled())))
                .map_err(OutputError::figure)?,
            Style::Segments => c
                .draw_series(
                    s.points
                        .chunks_exact(2)
                        .map(|ends| PathElement::new(ends.to_vec(), colour.stroke_width(px(1.0)))),
                )
                .map_err(OutputError::figure)?,
            Style::Bars { width } => {
                // Series side by side within each bin.
                let w = width / n;
                c.draw_series(s.points.iter().map(|(x, y)| {
                    let left = x - width / 2.0 + k as f64 * w;
                    Rectangle::new([(left, 0.0), (left + w, *y)], colour.mix(0.8).filled())
                }))
                .map_err(OutputError::figure)?
            }
        };
        anno.label(s.name.clone()).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + legend_len, y)], colour.stroke_width(legend_width))
        });
    }
    c.configure_series_labels()
        .label_font(font)
        .border_style(BLACK)
        .background_style(WHITE.mix(0.9))
        .draw()
        .map_err(OutputError::figure)?;
    root.present().map_err(OutputError::figure)?;
    Ok(())
}

/// The chart as SVG text (760 x 320).
pub fn svg(chart: &Chart) -> Result<String, OutputError> {
    crate::report::templating::register_font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (760, 320)).into_drawing_area();
        draw(&root, chart)?;
    }
    Ok(text)
}

/// The chart as PNG bytes (1140 x 480).
pub fn png(chart: &Chart) -> Result<Vec<u8>, OutputError> {
    crate::report::templating::register_font()?;
    let (w, h) = (1140u32, 480u32);
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw(&root, chart)?;
    }
    for px in rgb.chunks_exact_mut(3) {
        px.swap(0, 2);
    }
    crate::io::image::encode_png_bgr(&rgb, w as usize, h as usize).map_err(OutputError::figure)
}

/// Histograms of the per-frame BRE per axis (all-frames calibration), 0.25 mm bins.
fn bre_histogram(run: &DatasetRun) -> Option<Chart> {
    let values: Vec<[f64; 3]> = run.frames.iter().filter_map(|f| f.bre_mm.map(|b| b.0)).collect();
    if values.is_empty() {
        return None;
    }
    let bin = 0.25;
    let max = values.iter().flatten().cloned().fold(0.0, f64::max);
    // Frames beyond 5 mm share the last bin.
    let bins = ((max.min(5.0) / bin).floor() as usize) + 1;
    let series = ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(a, name)| {
            let mut counts = vec![0.0; bins];
            for v in &values {
                counts[((v[a] / bin).floor() as usize).min(bins - 1)] += 1.0;
            }
            Series {
                name: name.to_string(),
                colour: COLOURS[a],
                points: counts
                    .iter()
                    .enumerate()
                    .map(|(i, c)| ((i as f64 + 0.5) * bin, *c))
                    .collect(),
            }
        })
        .collect();
    Some(Chart {
        id: "bre_histogram",
        caption: "Histogram of the per-frame BRE along each axis (all-frames calibration; 0.25 mm bins, the last holds everything above).".into(),
        x_desc: "BRE (mm)".into(),
        y_desc: "frames".into(),
        style: Style::Bars { width: bin },
        series,
        equal_axes: false,
    })
}

/// The boards' reprojection RMS per frame (camera poses only).
fn board_reprojection(run: &DatasetRun) -> Option<Chart> {
    let probe: Vec<(f64, f64)> = run
        .frames
        .iter()
        .filter_map(|f| {
            Some((
                f.files.frame as f64,
                f.poses.as_ref()?.camera_T_marker.reprojection_rms_px,
            ))
        })
        .collect();
    let phantom: Vec<(f64, f64)> = run
        .frames
        .iter()
        .filter_map(|f| {
            Some((
                f.files.frame as f64,
                f.poses.as_ref()?.camera_T_phantom.reprojection_rms_px,
            ))
        })
        .collect();
    (!probe.is_empty()).then(|| Chart {
        id: "board_reprojection",
        caption: "Reprojection RMS of each board's pose per frame (frames whose boards were found).".into(),
        x_desc: "frame".into(),
        y_desc: "RMS (px)".into(),
        style: Style::Lines,
        series: vec![
            Series {
                name: "probe board".into(),
                colour: COLOURS[0],
                points: probe,
            },
            Series {
                name: "phantom board".into(),
                colour: COLOURS[2],
                points: phantom,
            },
        ],
        equal_axes: false,
    })
}

/// The camera calibration's RMS per view.
fn camera_views(run: &DatasetRun) -> Option<Chart> {
    let cal = run.camera.calibration.as_ref()?;
    let points: Vec<(f64, f64)> = cal
        .views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| Some((i as f64, v.rms_px?)))
        .collect();
    (!points.is_empty()).then(|| Chart {
        id: "camera_views",
        caption: format!(
            "Camera calibration: reprojection RMS per board view ({} of {} views used).",
            cal.views.iter().filter(|v| v.used).count(),
            cal.views.len()
        ),
        x_desc: "view".into(),
        y_desc: "RMS (px)".into(),
        style: Style::Bars { width: 0.8 },
        series: vec![Series {
            name: "RMS".into(),
            colour: COLOURS[2],
            points,
        }],
        equal_axes: false,
    })
}

/// The probe poses projected onto two planes of the phantom frame (`axes`: 0 = x,
/// 1 = y, 2 = z): the marker's origin and the B-scan's centre and corners in
/// each used frame, the phantom feature, and the phantom's origin.
fn pose_view(run: &DatasetRun, axes: [usize; 2], id: &'static str, seen_from: &str) -> Option<Chart> {
    let fit = run.primary_fit();
    let [w, h] = run.frames.iter().find_map(|f| f.bscan_size_px)?;
    let (wf, hf) = (w as f64 - 1.0, h as f64 - 1.0);
    let centre = pixel_to_image_mm([wf / 2.0, hf / 2.0], run.spacing_mm_per_px);
    let corners = [[0.0, 0.0], [wf, 0.0], [0.0, hf], [wf, hf]].map(|p| pixel_to_image_mm(p, run.spacing_mm_per_px));
    let [a, b] = axes;
    let mut markers = Vec::new();
    let mut centres = Vec::new();
    let mut image_corners = Vec::new();
    for f in run.frames.iter().filter(|f| f.rejection.is_none()) {
        let Some((camera_T_marker, camera_T_phantom)) = f.pose_pair() else {
            continue;
        };
        let phantom_T_marker = camera_T_phantom.inverse() * camera_T_marker;
        let m = phantom_T_marker.translation.vector;
        markers.push((m[a], m[b]));
        let c = phantom_T_marker * fit.apply(&centre);
        centres.push((c[a], c[b]));
        for q in &corners {
            let p = phantom_T_marker * fit.apply(q);
            image_corners.push((p[a], p[b]));
        }
    }
    if markers.is_empty() {
        return None;
    }
    let names = ["x", "y", "z"];
    let mut series = vec![
        Series {
            name: "marker origin".into(),
            colour: COLOURS[0],
            points: markers,
        },
        Series {
            name: "B-scan corners".into(),
            colour: RGBColor(150, 170, 220),
            points: image_corners,
        },
        Series {
            name: "B-scan centre".into(),
            colour: COLOURS[2],
            points: centres,
        },
        Series {
            name: "phantom origin".into(),
            colour: BLACK,
            points: vec![(0.0, 0.0)],
        },
    ];
    if let Some(p) = run.feature_in_phantom_mm {
        series.push(Series {
            name: "phantom feature".into(),
            colour: COLOURS[1],
            points: vec![(p[a], p[b])],
        });
    }
    Some(Chart {
        id,
        caption: format!(
            "Coordinate systems and probe poses in the phantom frame, seen {seen_from} ({}-{} plane): the probe marker's origin, the B-scan's corners and centre through the calibration (used frames), the phantom feature and the phantom frame's origin.",
            names[a], names[b]
        ),
        x_desc: format!("{} in the phantom frame (mm)", names[a]),
        y_desc: format!("{} (mm)", names[b]),
        style: Style::Points,
        series,
        equal_axes: true,
    })
}

/// Every extra figure a run has.
pub fn charts(run: &DatasetRun) -> Vec<Chart> {
    [
        bre_histogram(run),
        board_reprojection(run),
        camera_views(run),
        pose_view(run, [0, 1], "pose_overview", "from above"),
        pose_view(run, [0, 2], "pose_side_view", "from the side"),
    ]
    .into_iter()
    .flatten()
    .collect()
}

fn bre_chart(run: &DatasetRun) -> Chart {
    let points: Vec<(usize, [f64; 3])> = run
        .frames
        .iter()
        .filter_map(|f| f.bre_mm.map(|b| (f.files.frame, b.0)))
        .collect();
    let colours = [RGBColor(200, 40, 40), RGBColor(40, 140, 40), RGBColor(40, 70, 200)];
    Chart {
        id: "bre_per_frame",
        caption: "Per-frame BRE along each axis of the phantom frame, all-frames calibration.".into(),
        x_desc: "frame".into(),
        y_desc: "BRE (mm)".into(),
        style: Style::Lines,
        series: ["x", "y", "z"]
            .iter()
            .enumerate()
            .map(|(a, name)| Series {
                name: name.to_string(),
                colour: colours[a],
                points: points.iter().map(|(f, b)| (*f as f64, b[a])).collect(),
            })
            .collect(),
        equal_axes: false,
    }
}

pub fn bre_figure(run: &DatasetRun) -> Result<String, OutputError> {
    svg(&bre_chart(run))
}

/// The per-frame BRE plot as a PNG (for LaTeX, which cannot include SVG).
pub fn bre_figure_png(run: &DatasetRun) -> Result<Vec<u8>, OutputError> {
    png(&bre_chart(run))
}
