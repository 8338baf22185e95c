//! A tracked run's figures beside the lag's: PRE3D per validation frame (ours
//! and PLUS's matrix on the same dots and poses), the residuals in the
//! phantom's frame along the sweep, and the tilts the two sweeps cover. Each
//! is a [`Chart`]: SVG on the HTML page, `<id>.png` beside the LaTeX page.

use nalgebra::{Matrix4, Point3, Vector3};
use plotters::style::RGBColor;

use crate::core::geometry::Rigid;
use crate::io::plus::result::PlusResult;
use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::tracked::{Role, TrackedFrame, TrackedRun};
use crate::report::page::figures::{Chart, Series, Style};

const OURS: RGBColor = RGBColor(40, 70, 200);
const PLUS: RGBColor = RGBColor(200, 40, 40);
const AXES: [RGBColor; 3] = [RGBColor(200, 40, 40), RGBColor(40, 140, 40), RGBColor(40, 70, 200)];

/// The used frames of `role`.
fn used(run: &TrackedRun, role: Role) -> impl Iterator<Item = &TrackedFrame> {
    run.frames
        .iter()
        .filter(move |f| f.role == role && f.rejected.is_none())
}

fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// Every figure the run has data for, in page order.
pub fn charts(run: &TrackedRun, labels: &TrackedLabels, plus: Option<&PlusResult>) -> Vec<Chart> {
    [
        pre3d_per_frame(run, labels, plus),
        residuals_in_phantom(run, labels),
        tilts(run, labels),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// Each validation frame's PRE3D (the mean over its middle dots), ours and
/// PLUS's matrix on the same dots and poses.
pub fn pre3d_per_frame(run: &TrackedRun, labels: &TrackedLabels, plus: Option<&PlusResult>) -> Option<Chart> {
    let ours: Vec<(f64, f64)> = used(run, Role::Validation)
        .filter_map(|f| Some((f.index as f64, mean(&f.pre3d_mm)?)))
        .collect();
    if ours.len() < 2 {
        return None;
    }
    let mut series = vec![Series {
        name: "probecal".into(),
        colour: OURS,
        points: ours,
    }];
    if let Some(plus) = plus {
        let m = plus.image_to_probe;
        let map = |pixel: [f64; 2]| m.transform_point(&Point3::new(pixel[0], pixel[1], 0.0));
        let points = used(run, Role::Validation)
            .filter_map(|f| {
                let e = crate::pipeline::tracked::pre3d(f, &labels.nwires, map, &Rigid::identity());
                Some((f.index as f64, mean(&e)?))
            })
            .collect();
        series.push(Series {
            name: "PLUS's matrix".into(),
            colour: PLUS,
            points,
        });
    }
    Some(Chart {
        id: "pre3d_per_frame",
        caption: format!(
            "PRE3D of each validation frame: the mean over its {} middle dots, every dot counted (the table's best-95 % \
             figure leaves the worst out), {}under the lag applied. Look for frames where every matrix is high (the \
             frame's dots or its pose are off, not the calibration) and for stretches where one matrix alone is (the \
             two differ there, e.g. at tilts the calibration sweep did not hold).",
            labels.nwires.len(),
            if plus.is_some() {
                "probecal's matrix and PLUS's on the same dots and poses, "
            } else {
                ""
            }
        ),
        x_desc: "validation frame".into(),
        y_desc: "PRE3D (mm)".into(),
        style: Style::Points,
        series,
        equal_axes: false,
    })
}

/// The middle dot's error vector (mapped by our calibration, less its position
/// from the phantom's geometry), mm, in the phantom's frame; one per pattern.
fn residuals(f: &TrackedFrame, run: &TrackedRun, labels: &TrackedLabels) -> Vec<Vector3<f64>> {
    let Some(marker_T_phantom) = f.marker_T_phantom else {
        return Vec::new();
    };
    let marker_T_phantom: Matrix4<f64> = marker_T_phantom * run.fit.phantom_correction.to_homogeneous();
    let phantom_R_marker = marker_T_phantom.fixed_view::<3, 3>(0, 0).transpose();
    f.dots_px
        .iter()
        .zip(&labels.nwires)
        .map(|(dots, nwire)| {
            let expected = marker_T_phantom.transform_point(&nwire.middle_in_phantom_mm(dots));
            phantom_R_marker * (run.fit.image_to_probe.apply(dots[1]) - expected)
        })
        .collect()
}

/// The residuals' components in the phantom's frame along the validation sweep.
pub fn residuals_in_phantom(run: &TrackedRun, labels: &TrackedLabels) -> Option<Chart> {
    let mut axes: [Vec<(f64, f64)>; 3] = Default::default();
    for f in used(run, Role::Validation) {
        for r in residuals(f, run, labels) {
            for (k, axis) in axes.iter_mut().enumerate() {
                axis.push((f.index as f64, r[k]));
            }
        }
    }
    if axes[0].len() < 2 {
        return None;
    }
    let series = axes
        .into_iter()
        .zip(["x", "y", "z"])
        .zip(AXES)
        .map(|((points, axis), colour)| Series {
            name: format!("phantom {axis}"),
            colour,
            points,
        })
        .collect();
    Some(Chart {
        id: "residuals_in_phantom",
        caption:
            "The validation dots' errors in the phantom's frame, per axis (probecal's calibration: each middle dot \
                  mapped into the marker's frame, less its position from the phantom's geometry, turned into the \
                  phantom's axes). Look for an offset shared by the whole sweep on one axis (a bias of the calibration \
                  or of the phantom's registration) and for a drift along it (the tracker's lag or its accuracy \
                  changing across the volume)."
                .into(),
        x_desc: "validation frame".into(),
        y_desc: "error (mm)".into(),
        style: Style::Points,
        series,
        equal_axes: false,
    })
}

/// Each used frame's tilt of the wires against the image plane, calibration
/// and validation frames.
pub fn tilts(run: &TrackedRun, labels: &TrackedLabels) -> Option<Chart> {
    let of = |role: Role| -> Vec<(f64, f64)> {
        crate::pipeline::tracked::resolution::wires_in_image(run, &labels.nwires, role)
            .iter()
            .filter_map(crate::evaluate::pose_coverage::tilt_deg)
            .collect()
    };
    let (calibration, validation) = (of(Role::Calibration), of(Role::Validation));
    if calibration.is_empty() || validation.is_empty() {
        return None;
    }
    Some(Chart {
        id: "tilts",
        caption:
            "The probe's tilt in each frame: the wires' direction against the image plane, sideways (lateral) and \
                  along the beam (axial). The calibration is fitted on the first cloud and validated on the second; \
                  look for validation frames outside the calibration's cloud: there the score measures an \
                  extrapolation of the calibration."
                .into(),
        x_desc: "lateral tilt (deg)".into(),
        y_desc: "axial tilt (deg)".into(),
        style: Style::Points,
        series: vec![
            Series {
                name: "calibration frames".into(),
                colour: OURS,
                points: calibration,
            },
            Series {
                name: "validation frames".into(),
                colour: PLUS,
                points: validation,
            },
        ],
        equal_axes: true,
    })
}

/// Files to write beside a page: (file name, bytes).
pub type FigureFiles = Vec<(String, Vec<u8>)>;

/// The figures in a page's context (`figures`: id, SVG, caption) and their PNG
/// files' bytes, by file name.
pub fn insert(ctx: &mut tera::Context, charts: &[Chart]) -> Result<FigureFiles, crate::report::error::OutputError> {
    let mut context = Vec::new();
    let mut files = Vec::new();
    for c in charts {
        context.push(serde_json::json!({
            "id": c.id,
            "svg": crate::report::page::figures::svg(c)?,
            "caption": c.caption,
        }));
        files.push((format!("{}.png", c.id), crate::report::page::figures::png(c)?));
    }
    ctx.insert("figures", &context);
    Ok(files)
}
