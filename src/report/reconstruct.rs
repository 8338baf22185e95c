//! Outputs of `probecal reconstruct`: `volume.mha` (PLUS's MetaImage layout),
//! optionally `volume.nrrd`, `summary.json` (frames used and skipped with their
//! reasons, voxels filled before and after hole filling, time per stage) and
//! `report.html` with three orthogonal slices and a windowed mean-intensity projection, each with a scale bar.
//!
//! Everything is written into a staging folder and swapped in only when all of
//! it is written; an existing `--out` that is not a reconstruction is refused.

use std::path::Path;

use crate::io::volume_file::{metaimage_bytes, nrrd_bytes, VolumeHeader};
use crate::pipeline::reconstruct::{AnyVolume, Reconstruction};
use crate::report::error::OutputError;
use crate::report::page::figures::{Chart, Series, Style};
use crate::results::reconstruction::{header, is_reconstruction, Agreement, ReconstructionSummary, VolumeWires};
use plotters::style::RGBColor;

/// The frames' outlines seen along z and along y, each frame's clip rectangle
/// placed by its pose (every `k`-th frame, so that at most 40 are drawn; the
/// first and the last always), with the volume's extent around them.
pub fn outline_charts(r: &Reconstruction) -> Vec<Chart> {
    let outlines = &r.frame_outlines_mm;
    let (Some(first), Some(last)) = (outlines.first(), outlines.last()) else {
        return Vec::new();
    };
    let step = outlines.len().div_ceil(40).max(1);
    let grid = r.volume.grid();
    let low = grid.origin_mm;
    let high: [f64; 3] = std::array::from_fn(|a| low[a] + (grid.dims[a].saturating_sub(1)) as f64 * grid.spacing_mm[a]);
    let views = [
        ("outlines_xy", [0, 1], "seen along z (x across, y up)"),
        ("outlines_xz", [0, 2], "seen along y (x across, z up)"),
    ];
    views
        .into_iter()
        .map(|(id, [a, b], seen)| {
            let edges = |corners: &[[f64; 3]; 4]| -> Vec<(f64, f64)> {
                (0..4)
                    .flat_map(|k| [corners[k], corners[(k + 1) % 4]])
                    .map(|p| (p[a], p[b]))
                    .collect()
            };
            let box_corners = [
                [low[a], low[b]],
                [high[a], low[b]],
                [high[a], high[b]],
                [low[a], high[b]],
            ]
            .map(|[x, y]| {
                let mut p = [0.0; 3];
                (p[a], p[b]) = (x, y);
                p
            });
            let series = vec![
                Series {
                    name: if step == 1 {
                        "each frame's clip rectangle".to_string()
                    } else {
                        format!("one frame's clip rectangle in {step}")
                    },
                    colour: RGBColor(150, 170, 220),
                    points: outlines.iter().step_by(step).flat_map(edges).collect(),
                },
                Series {
                    name: format!("first inserted frame ({})", r.frames_used.first().copied().unwrap_or(0)),
                    colour: RGBColor(40, 140, 40),
                    points: edges(first),
                },
                Series {
                    name: format!("last inserted frame ({})", r.frames_used.last().copied().unwrap_or(0)),
                    colour: RGBColor(200, 40, 40),
                    points: edges(last),
                },
                Series {
                    name: "the volume's extent (voxel centres)".into(),
                    colour: RGBColor(0, 0, 0),
                    points: edges(&box_corners),
                },
            ];
            let names = ["x", "y", "z"];
            Chart {
                id,
                caption: format!(
                    "The frames' clip rectangles in the volume's frame ({} mm), {seen}, {} of {} drawn: the sweep's \
                     path and coverage. Look for frames that leave the volume (an extent set too small), jumps \
                     between neighbouring frames (a tracker glitch the poses let through) and regions no frame \
                     reached (filled by hole filling, or left empty).",
                    r.settings.reference_frame,
                    outlines.iter().step_by(step).count(),
                    outlines.len()
                ),
                x_desc: format!("{} (mm)", names[a]),
                y_desc: format!("{} (mm)", names[b]),
                style: Style::Segments,
                series,
                equal_axes: true,
            }
        })
        .collect()
}

/// An 8-bit picture: `width` x `height`, row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    pub name: &'static str,
    pub title: String,
    pub width: usize,
    pub height: usize,
    /// Its extent across and down, mm: the page shows it at this aspect.
    pub size_mm: [f64; 2],
    pub pixels: Vec<u8>,
}

/// Slices across each axis through the intensity-weighted centre (grey levels
/// scaled so that the brightest voxel is white) and the mean-intensity
/// projection along z (windowed: see [`window`]; a maximum over a sweep's
/// speckle is white almost everywhere), each with a scale bar and
/// its physical size, so that the page shows it at its true aspect.
pub fn pictures(volume: &AnyVolume) -> Vec<Picture> {
    match volume {
        AnyVolume::U8(v) => pictures_of(&v.grid, &v.voxels),
        AnyVolume::F32(v) => pictures_of(&v.grid, &v.voxels),
    }
}

/// [`pictures`] of voxels as they are (read one by one, never copied whole).
fn pictures_of<T: Copy + Into<f64>>(grid: &crate::reconstruct::grid::Grid, voxels: &[T]) -> Vec<Picture> {
    let [nx, ny, nz] = grid.dims;
    let [sx, sy, sz] = grid.spacing_mm;
    let value = |v: &T| -> f64 { (*v).into() };
    let top = voxels.iter().map(value).fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
    let grey = |v: f64| (v / top * 255.0).round().clamp(0.0, 255.0) as u8;
    let at = |x: usize, y: usize, z: usize| value(&voxels[(z * ny + y) * nx + x]);
    let [cx, cy, cz] = weighted_centre(grid, voxels);
    // The mean along z of the voxels with a value, plane after plane (in memory order).
    let (mut total, mut count) = (vec![0.0f64; nx * ny], vec![0u32; nx * ny]);
    for plane in voxels.chunks_exact(nx * ny) {
        for ((t, c), v) in total.iter_mut().zip(count.iter_mut()).zip(plane) {
            let v = value(v);
            if v > 0.0 {
                *t += v;
                *c += 1;
            }
        }
    }
    let mean: Vec<f64> = total
        .iter()
        .zip(&count)
        .map(|(t, c)| if *c > 0 { t / f64::from(*c) } else { 0.0 })
        .collect();
    let (low, high) = window(&mean);
    let projection: Vec<u8> = mean
        .iter()
        .map(|&v| {
            if v > 0.0 {
                (((v - low) / (high - low).max(f64::MIN_POSITIVE)) * 255.0)
                    .round()
                    .clamp(0.0, 255.0) as u8
            } else {
                0
            }
        })
        .collect();
    let slice = |name: &'static str, title: String, size: [usize; 2], mm: [f64; 2], pixels: Vec<u8>| {
        Picture::with_scale_bar(name, title, size, mm, pixels)
    };
    vec![
        slice(
            "slice_z.png",
            format!("z = {cz} (x across, y down)"),
            [nx, ny],
            [sx, sy],
            (0..ny)
                .flat_map(|y| (0..nx).map(move |x| (x, y)))
                .map(|(x, y)| grey(at(x, y, cz)))
                .collect(),
        ),
        slice(
            "slice_y.png",
            format!("y = {cy} (x across, z down)"),
            [nx, nz],
            [sx, sz],
            (0..nz)
                .flat_map(|z| (0..nx).map(move |x| (x, z)))
                .map(|(x, z)| grey(at(x, cy, z)))
                .collect(),
        ),
        slice(
            "slice_x.png",
            format!("x = {cx} (y across, z down)"),
            [ny, nz],
            [sy, sz],
            (0..nz)
                .flat_map(|z| (0..ny).map(move |y| (y, z)))
                .map(|(y, z)| grey(at(cx, y, z)))
                .collect(),
        ),
        slice(
            "mean_z.png",
            format!(
                "mean-intensity projection along z (x across, y down) of the voxels with a value, windowed: \
                 grey {low:.0} and below black, {high:.0} and above white (the 1st and 99th percentiles of its \
                 nonzero pixels); where a column saw tissue along much of its length it is bright"
            ),
            [nx, ny],
            [sx, sy],
            projection,
        ),
    ]
}

/// The voxel nearest the intensity-weighted centre (the middle of an empty
/// volume), summed in memory order as one pass over the voxels adds them.
fn weighted_centre<T: Copy + Into<f64>>(grid: &crate::reconstruct::grid::Grid, voxels: &[T]) -> [usize; 3] {
    let [nx, ny, _] = grid.dims;
    let (mut sum, mut at_sum) = (0.0, [0.0f64; 3]);
    for (z, plane) in voxels.chunks_exact(nx * ny).enumerate() {
        for (y, row) in plane.chunks_exact(nx).enumerate() {
            for (x, v) in row.iter().map(|v| -> f64 { (*v).into() }).enumerate() {
                sum += v;
                at_sum[0] += v * x as f64;
                at_sum[1] += v * y as f64;
                at_sum[2] += v * z as f64;
            }
        }
    }
    std::array::from_fn(|a| {
        let n = grid.dims[a];
        if sum > 0.0 {
            ((at_sum[a] / sum).round() as usize).min(n - 1)
        } else {
            n / 2
        }
    })
}

/// A projection's grey window: the 1st and 99th percentiles of its nonzero
/// values; 0 and the largest value when fewer than two are nonzero.
fn window(values: &[f64]) -> (f64, f64) {
    let mut nonzero: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0).collect();
    if nonzero.len() < 2 {
        return (0.0, values.iter().copied().fold(0.0, f64::max).max(1.0));
    }
    nonzero.sort_by(f64::total_cmp);
    let at = |q: f64| nonzero[((nonzero.len() - 1) as f64 * q).round() as usize];
    let (low, high) = (at(0.01), at(0.99));
    if high > low {
        (low, high)
    } else {
        (0.0, high.max(1.0))
    }
}

impl Picture {
    /// A picture of `size` pixels of `mm` each (across, down), with a white
    /// scale bar in its lower left corner, about a fifth of its width long in
    /// round millimetres; the title says the bar's length.
    fn with_scale_bar(
        name: &'static str,
        title: String,
        size: [usize; 2],
        mm: [f64; 2],
        mut pixels: Vec<u8>,
    ) -> Picture {
        let [w, h] = size;
        let width_mm = w as f64 * mm[0];
        let bar_mm = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]
            .into_iter()
            .rev()
            .find(|b| *b <= width_mm / 5.0)
            .unwrap_or(1.0);
        let bar_px = ((bar_mm / mm[0]).round() as usize).min(w.saturating_sub(8));
        let thick = (h / 60).clamp(1, 4);
        let bottom = h.saturating_sub(4 + thick);
        for y in bottom..(bottom + thick).min(h) {
            for x in 4..(4 + bar_px).min(w) {
                pixels[y * w + x] = 255;
            }
        }
        Picture {
            name,
            title: format!("{title}; the white bar is {bar_mm:.0} mm"),
            width: w,
            height: h,
            size_mm: [width_mm, h as f64 * mm[1]],
            pixels,
        }
    }
}

pub fn png_bytes(p: &Picture) -> Result<Vec<u8>, OutputError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, p.width as u32, p.height as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let fail = |e: png::EncodingError| OutputError::Figure(format!("{}: {e}", p.name));
    let mut writer = encoder.write_header().map_err(fail)?;
    writer.write_image_data(&p.pixels).map_err(fail)?;
    writer.finish().map_err(fail)?;
    Ok(out)
}

const TEMPLATE: &str = include_str!("../../templates/reconstruct.html.tera");

/// The page: `agreement` is `agreement.json`'s value when a reference was given.
pub fn html(
    summary: &ReconstructionSummary,
    pictures: &[Picture],
    outlines: &[Chart],
    agreement: Option<&Agreement>,
) -> Result<String, OutputError> {
    let g = &summary.volume;
    let filled = &summary.voxels_filled;
    let mut ctx = tera::Context::new();
    ctx.insert("sequence", &summary.sequence);
    ctx.insert("used", &summary.frames.used);
    ctx.insert("total", &summary.frames.total);
    ctx.insert("dims", &format!("{}x{}x{}", g.dims[0], g.dims[1], g.dims[2]));
    let spacing: Vec<String> = g
        .spacing_mm
        .iter()
        .map(|v| crate::io::volume_file::format_g6(*v))
        .collect();
    ctx.insert("spacing", &spacing.join(" x "));
    ctx.insert("filled_after", &filled.after_hole_filling);
    ctx.insert("filled_before", &filled.before_hole_filling);
    ctx.insert(
        "by_holes",
        &filled.after_hole_filling.saturating_sub(filled.before_hole_filling),
    );
    ctx.insert("voxels", &g.voxels);
    ctx.insert("pixels", &summary.pixels_inserted);
    ctx.insert("holes_left", &filled.holes_left);
    let by_element: Vec<String> = filled.holes_filled_by_element.iter().map(u64::to_string).collect();
    ctx.insert("by_element", &(by_element.len() > 1).then(|| by_element.join(", ")));
    ctx.insert("source", &summary.image_to_probe_source);
    ctx.insert("lag_ms", &format!("{:+.0}", summary.tracker_lag_s * 1000.0));
    ctx.insert("lag_source", &summary.tracker_lag_source);
    ctx.insert("saturated", &summary.accumulator_saturated);
    ctx.insert("agreement", &agreement.map(agreement_context));
    ctx.insert("wires", &summary.wires.as_ref().map(wires_context));
    let pictures: Vec<serde_json::Value> = pictures
        .iter()
        .map(|p| {
            // 480 px for the longer side, at the physical aspect.
            let px_per_mm = 480.0 / p.size_mm[0].max(p.size_mm[1]).max(f64::MIN_POSITIVE);
            let shown = |mm: f64| (mm * px_per_mm).round().max(1.0) as usize;
            serde_json::json!({"name": p.name, "title": p.title, "width": shown(p.size_mm[0]), "height": shown(p.size_mm[1])})
        })
        .collect();
    ctx.insert("pictures", &pictures);
    let outlines: Vec<serde_json::Value> = outlines
        .iter()
        .map(|c| serde_json::json!({"name": format!("{}.png", c.id), "caption": c.caption}))
        .collect();
    ctx.insert("outlines", &outlines);
    let s = &summary.settings;
    ctx.insert(
        "settings",
        &format!(
            "{:?} interpolation, {:?} compounding, {:?} optimization, clip rectangle origin {:?} size {:?}, fan {}, \
             {} hole-filling element(s).",
            s.interpolation,
            s.compounding,
            s.optimization,
            s.clip_origin_px,
            s.clip_size_px,
            if s.fan.is_some() { "on" } else { "off" },
            s.hole_filling.len()
        ),
    );
    let origin: Vec<String> = g.origin_mm.iter().map(|v| format!("{v:.3}")).collect();
    ctx.insert("origin", &format!("[{}]", origin.join(", ")));
    ctx.insert("skipped", &summary.frames.skipped);
    let times = match (&summary.time_s, summary.threads) {
        (Some(time_s), Some(threads)) => {
            let stages: String = time_s.iter().map(|(k, v)| format!("{k} {v:.3} s; ")).collect();
            format!("Time: {stages}{threads} thread(s).")
        }
        _ => String::new(),
    };
    ctx.insert("times", &times);
    Ok(tera::Tera::one_off(TEMPLATE, &ctx, true)?)
}

/// `agreement.json`'s figures in words for the page.
fn agreement_context(a: &Agreement) -> serde_json::Value {
    let mut out = serde_json::json!({
        "reference": a.reference,
        "identical_file": a.identical_file,
        "dims": format!(
            "{} (ours) and {} (the reference)",
            serde_json::json!(a.dims.ours),
            serde_json::json!(a.dims.reference)
        ),
        "element_type": format!("{} (ours) and {} (the reference)", a.element_type.ours, a.element_type.reference),
        "spacing_equal": a.spacing_equal,
        "offset_mm": format!("{:.4}", a.offset_max_difference_mm),
    });
    if let Some(v) = &a.voxels {
        out["voxels"] = v.voxels.into();
        out["equal"] = v.voxels_equal.into();
        out["nonzero"] = v.nonzero_in_either.into();
        out["within"] = format!("{:.2} %", v.within_one_grey_level * 100.0).into();
        out["dice"] = format!("{:.5}", v.dice_nonzero).into();
    }
    out
}

/// The wires' table: each wire's position error, straightness and thickness.
fn wires_context(wires: &VolumeWires) -> serde_json::Value {
    use crate::evaluate::wire_profile as wp;
    let w = &wires.figures;
    let mm = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.2}"));
    let rows: Vec<serde_json::Value> = w
        .wires
        .iter()
        .map(|f| {
            serde_json::json!({
                "name": f.name,
                "counted": f.sections_counted,
                "sections": f.sections,
                "position": mm(f.position_error_mm),
                "straightness": mm(f.straightness_rms_mm),
                "thickness": mm(f.thickness_fwhm_mm),
            })
        })
        .collect();
    serde_json::json!({
        "measured": w.wires_measured,
        "total": w.wires.len(),
        "position": mm(w.position_error_mm),
        "straightness": mm(w.straightness_rms_mm),
        "thickness": mm(w.thickness_fwhm_mm),
        "set": wires.device_set.clone().unwrap_or_default(),
        "step": wp::STEP_MM,
        "end": format!("{:.0}", wp::END_FRACTION * 100.0),
        "width": 2.0 * wp::HALF_WIDTH_MM,
        "peak": wp::PEAK_OVER_MAD,
        "rows": rows,
    })
}

/// Refuses an `--out` that exists and holds something other than a reconstruction.
fn check_out(out: &Path) -> Result<(), OutputError> {
    if !out.exists() {
        return Ok(());
    }
    let refuse = |why: &str| OutputError::io(out, format!("{why}; give a new folder or a previous reconstruction's"));
    if !out.is_dir() {
        return Err(refuse("exists and is not a folder"));
    }
    let empty = std::fs::read_dir(out).map(|mut d| d.next().is_none()).unwrap_or(false);
    if empty {
        return Ok(());
    }
    if !is_reconstruction(&out.join("summary.json")) {
        return Err(refuse(
            "is a folder that does not hold a reconstruction (no summary.json of kind \"reconstruction\")",
        ));
    }
    Ok(())
}

/// What `write` adds to the volume, summary, report and pictures.
#[derive(Debug, Default)]
pub struct WriteOptions<'a> {
    pub nrrd: bool,
    /// A reference volume's path, header and voxel bytes: agreement.json.
    pub compare: Option<(&'a Path, &'a (VolumeHeader, Vec<u8>))>,
}

/// Whether `out` holds a reconstruction already (its summary.json is of kind
/// "reconstruction"): one `reconstruct` may replace.
pub fn holds_reconstruction(out: &Path) -> bool {
    out.is_dir() && check_out(out).is_ok()
}

/// Writes all outputs into `dir` (a claimed output folder, swapped in by its
/// owner).
pub fn write(r: &Reconstruction, dir: &Path, options: &WriteOptions) -> Result<(), OutputError> {
    let header = header(&r.volume);
    let summary = ReconstructionSummary::of(r);
    let data = r.volume.bytes();
    let pictures = pictures(&r.volume);
    let write = |name: &str, bytes: &[u8]| crate::io::fs::write_atomic(&dir.join(name), bytes);
    let volume = metaimage_bytes(&header, &data);
    write("volume.mha", &volume)?;
    let agreement = options
        .compare
        .map(|(path, reference)| Agreement::of(r, &volume, path, reference));
    if let Some(a) = &agreement {
        // Keys sorted, as every summary's.
        write(
            "agreement.json",
            serde_json::to_string_pretty(&serde_json::to_value(a)?)?.as_bytes(),
        )?;
    }
    if options.nrrd {
        write("volume.nrrd", &nrrd_bytes(&header, &data))?;
    }
    for p in &pictures {
        write(p.name, &png_bytes(p)?)?;
    }
    let outlines = outline_charts(r);
    for c in &outlines {
        write(&format!("{}.png", c.id), &crate::report::page::figures::png(c)?)?;
    }
    write("summary.json", crate::results::summary::to_text(&summary)?.as_bytes())?;
    write(
        "report.html",
        html(&summary, &pictures, &outlines, agreement.as_ref())?.as_bytes(),
    )?;
    Ok(())
}
