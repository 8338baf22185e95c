//! Outputs of `probecal reconstruct`: `volume.mha` (PLUS's MetaImage layout),
//! optionally `volume.nrrd`, `summary.json` (frames used and skipped with their
//! reasons, voxels filled before and after hole filling, time per stage) and
//! `report.html` with three orthogonal slices and a maximum-intensity projection.
//!
//! Everything is written into a staging folder and swapped in only when all of
//! it is written; an existing `--out` that is not a reconstruction is refused.

use std::path::Path;

use crate::io::volume_file::{metaimage_bytes, nrrd_bytes, VolumeHeader};
use crate::pipeline::reconstruct::{AnyVolume, Reconstruction};
use crate::report::error::OutputError;
use crate::results::reconstruction::{header, is_reconstruction, Agreement, ReconstructionSummary, VolumeWires};

/// An 8-bit picture: `width` x `height`, row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    pub name: &'static str,
    pub title: String,
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
}

/// Slices across each axis through the intensity-weighted centre and the
/// maximum-intensity projection along z, grey levels scaled so that the
/// brightest voxel is white.
pub fn pictures(volume: &AnyVolume) -> Vec<Picture> {
    match volume {
        AnyVolume::U8(v) => pictures_of(&v.grid, &v.voxels),
        AnyVolume::F32(v) => pictures_of(&v.grid, &v.voxels),
    }
}

/// [`pictures`] of voxels as they are (read one by one, never copied whole).
fn pictures_of<T: Copy + Into<f64>>(grid: &crate::reconstruct::grid::Grid, voxels: &[T]) -> Vec<Picture> {
    let [nx, ny, nz] = grid.dims;
    let value = |v: &T| -> f64 { (*v).into() };
    let top = voxels.iter().map(value).fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
    let grey = |v: f64| (v / top * 255.0).round().clamp(0.0, 255.0) as u8;
    let at = |x: usize, y: usize, z: usize| value(&voxels[(z * ny + y) * nx + x]);
    // Slices through the intensity-weighted centre (the middle of an empty volume).
    // In memory order, as one pass over the voxels would add them.
    let (mut sum, mut at_sum) = (0.0, [0.0f64; 3]);
    for (z, plane) in voxels.chunks_exact(nx * ny).enumerate() {
        for (y, row) in plane.chunks_exact(nx).enumerate() {
            for (x, v) in row.iter().map(value).enumerate() {
                sum += v;
                at_sum[0] += v * x as f64;
                at_sum[1] += v * y as f64;
                at_sum[2] += v * z as f64;
            }
        }
    }
    let centre = |a: usize, n: usize| {
        if sum > 0.0 {
            ((at_sum[a] / sum).round() as usize).min(n - 1)
        } else {
            n / 2
        }
    };
    let (cx, cy, cz) = (centre(0, nx), centre(1, ny), centre(2, nz));
    // The maximum along z, plane after plane (in memory order).
    let mut highest = vec![0.0f64; nx * ny];
    for plane in voxels.chunks_exact(nx * ny) {
        for (m, v) in highest.iter_mut().zip(plane) {
            *m = m.max(value(v));
        }
    }
    let mip: Vec<u8> = highest.into_iter().map(grey).collect();
    vec![
        Picture {
            name: "slice_z.png",
            title: format!("z = {cz} (x across, y down)"),
            width: nx,
            height: ny,
            pixels: (0..ny)
                .flat_map(|y| (0..nx).map(move |x| (x, y)))
                .map(|(x, y)| grey(at(x, y, cz)))
                .collect(),
        },
        Picture {
            name: "slice_y.png",
            title: format!("y = {cy} (x across, z down)"),
            width: nx,
            height: nz,
            pixels: (0..nz)
                .flat_map(|z| (0..nx).map(move |x| (x, z)))
                .map(|(x, z)| grey(at(x, cy, z)))
                .collect(),
        },
        Picture {
            name: "slice_x.png",
            title: format!("x = {cx} (y across, z down)"),
            width: ny,
            height: nz,
            pixels: (0..nz)
                .flat_map(|z| (0..ny).map(move |y| (y, z)))
                .map(|(y, z)| grey(at(cx, y, z)))
                .collect(),
        },
        Picture {
            name: "mip_z.png",
            title: "maximum-intensity projection along z".into(),
            width: nx,
            height: ny,
            pixels: mip,
        },
    ]
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
    ctx.insert("source", &summary.image_to_probe_source);
    ctx.insert("lag_ms", &format!("{:+.0}", summary.tracker_lag_s * 1000.0));
    ctx.insert("lag_source", &summary.tracker_lag_source);
    ctx.insert("saturated", &summary.accumulator_saturated);
    ctx.insert("agreement", &agreement.map(agreement_context));
    ctx.insert("wires", &summary.wires.as_ref().map(wires_context));
    let pictures: Vec<serde_json::Value> = pictures
        .iter()
        .map(|p| {
            let scale = (480 / p.width.max(p.height)).max(1);
            serde_json::json!({"name": p.name, "title": p.title, "width": p.width * scale, "height": p.height * scale})
        })
        .collect();
    ctx.insert("pictures", &pictures);
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
    write("summary.json", crate::results::summary::to_text(&summary)?.as_bytes())?;
    write("report.html", html(&summary, &pictures, agreement.as_ref())?.as_bytes())?;
    Ok(())
}
