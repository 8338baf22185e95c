//! Outputs of `probecal reconstruct`: `volume.mha` (PLUS's MetaImage layout),
//! optionally `volume.nrrd`, `summary.json` (frames used and skipped with their
//! reasons, voxels filled before and after hole filling, time per stage) and
//! `report.html` with three orthogonal slices and a maximum-intensity projection.
//!
//! Everything is written into a staging folder and swapped in only when all of
//! it is written; an existing `--out` that is not a reconstruction is refused.

use std::path::Path;

use crate::io::fs::display_path;
use crate::io::volume_file::{metaimage_bytes, nrrd_bytes, VolumeHeader};
use crate::pipeline::reconstruct::{AnyVolume, Reconstruction};
use crate::report::error::OutputError;

/// `summary.json`'s `kind`, which marks a folder as a reconstruction's.
pub const KIND: &str = "reconstruction";

/// Whether a `summary.json` is a reconstruction's (`kind: reconstruction`), not a
/// calibration run's.
pub fn is_reconstruction(summary: &Path) -> bool {
    crate::io::fs::read_text_capped(summary, crate::core::limits::MAX_TEXT_FILE_BYTES)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .is_some_and(|j| j.get("kind").and_then(|k| k.as_str()) == Some(KIND))
}

pub fn header(volume: &AnyVolume) -> VolumeHeader {
    let g = volume.grid();
    VolumeHeader {
        dims: g.dims,
        origin_mm: g.origin_mm,
        spacing_mm: g.spacing_mm,
        element_type: volume.element_type().to_string(),
    }
}

/// `summary.json`; the times and thread count only where the run kept them.
pub fn summary(r: &Reconstruction) -> serde_json::Value {
    let g = r.volume.grid();
    let mut out = serde_json::json!({
        "kind": KIND,
        "sequence": display_path(&r.inputs.sequence),
        "config": display_path(&r.inputs.config),
        "image_to_probe_source": r.image_to_probe_source,
        "tracker_lag_s": r.tracker_lag_s,
        "tracker_lag_source": r.tracker_lag_source,
        "image_to_probe": r.image_to_probe.map(|m| (0..4).map(|i| (0..4).map(|j| m[(i, j)]).collect::<Vec<f64>>()).collect::<Vec<_>>()),
        "settings": r.settings,
        "volume": {
            "file": "volume.mha",
            "dims": g.dims,
            "origin_mm": g.origin_mm,
            "spacing_mm": g.spacing_mm,
            "element_type": r.volume.element_type(),
            "voxels": g.voxels(),
        },
        "frames": {
            "total": r.frames_total,
            "used": r.frames_used.len(),
            "used_indices": r.frames_used,
            "skipped": r.skipped,
        },
        "pixels_inserted": r.pixels_inserted,
        "accumulator_saturated": r.accumulator_saturated,
        "voxels_filled": {
            "before_hole_filling": r.voxels_filled_before_holes,
            "after_hole_filling": r.voxels_filled_after_holes,
            "holes_filled_by_element": r.holes.filled_by_element,
            "holes_left": r.holes.holes_after,
        },
    });
    if let Some(wires) = &r.wires {
        out["wires"] = serde_json::json!({
            "device_set": r.inputs.wires.as_deref().map(display_path),
            "figures": wires,
        });
    }
    if !r.timings.is_empty() {
        out["threads"] = serde_json::json!(r.threads);
        out["time_s"] = r
            .timings
            .iter()
            .map(|(k, v)| (k.clone(), serde_json::json!(v)))
            .collect();
    }
    out
}

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
    r: &Reconstruction,
    pictures: &[Picture],
    agreement: Option<&serde_json::Value>,
) -> Result<String, OutputError> {
    let g = r.volume.grid();
    let mut ctx = tera::Context::new();
    ctx.insert("sequence", &display_path(&r.inputs.sequence));
    ctx.insert("used", &r.frames_used.len());
    ctx.insert("total", &r.frames_total);
    ctx.insert("dims", &format!("{}x{}x{}", g.dims[0], g.dims[1], g.dims[2]));
    let spacing: Vec<String> = g
        .spacing_mm
        .iter()
        .map(|v| crate::io::volume_file::format_g6(*v))
        .collect();
    ctx.insert("spacing", &spacing.join(" x "));
    ctx.insert("filled_after", &r.voxels_filled_after_holes);
    ctx.insert("filled_before", &r.voxels_filled_before_holes);
    ctx.insert(
        "by_holes",
        &(r.voxels_filled_after_holes - r.voxels_filled_before_holes),
    );
    ctx.insert("source", &r.image_to_probe_source);
    ctx.insert("lag_ms", &format!("{:+.0}", r.tracker_lag_s * 1000.0));
    ctx.insert("lag_source", &r.tracker_lag_source);
    ctx.insert("saturated", &r.accumulator_saturated);
    ctx.insert("agreement", &agreement.map(agreement_context));
    ctx.insert("wires", &wires_context(r));
    let pictures: Vec<serde_json::Value> = pictures
        .iter()
        .map(|p| {
            let scale = (480 / p.width.max(p.height)).max(1);
            serde_json::json!({"name": p.name, "title": p.title, "width": p.width * scale, "height": p.height * scale})
        })
        .collect();
    ctx.insert("pictures", &pictures);
    let s = &r.settings;
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
    let skipped: Vec<serde_json::Value> = r
        .skipped
        .iter()
        .map(|s| serde_json::json!({"index": s.index, "reason": s.reason}))
        .collect();
    ctx.insert("skipped", &skipped);
    let times = if r.timings.is_empty() {
        String::new()
    } else {
        let stages: String = r.timings.iter().map(|(k, v)| format!("{k} {v:.3} s; ")).collect();
        format!("Time: {stages}{} thread(s).", r.threads)
    };
    ctx.insert("times", &times);
    Ok(tera::Tera::one_off(TEMPLATE, &ctx, true)?)
}

/// `agreement.json`'s figures in words for the page.
fn agreement_context(a: &serde_json::Value) -> serde_json::Value {
    let pair = |key: &str| format!("{} (ours) and {} (the reference)", a[key]["ours"], a[key]["reference"]);
    let mut out = serde_json::json!({
        "reference": a["reference"],
        "identical_file": a["identical_file"],
        "dims": pair("dims"),
        "element_type": pair("element_type").replace('"', ""),
        "spacing_equal": a["spacing_equal"],
        "offset_mm": format!("{:.4}", a["offset_max_difference_mm"].as_f64().unwrap_or(f64::NAN)),
    });
    if let Some(voxels) = a.get("voxels") {
        out["voxels"] = voxels.clone();
        out["equal"] = a["voxels_equal"].clone();
        out["nonzero"] = a["nonzero_in_either"].clone();
        let f = |k: &str, d: usize| format!("{:.*}", d, a[k].as_f64().unwrap_or(f64::NAN));
        let within = a["within_one_grey_level"].as_f64().unwrap_or(f64::NAN);
        out["within"] = format!("{:.2} %", within * 100.0).into();
        out["dice"] = f("dice_nonzero", 5).into();
    }
    out
}

/// The wires' table: each wire's position error, straightness and thickness.
fn wires_context(r: &Reconstruction) -> Option<serde_json::Value> {
    use crate::evaluate::wire_profile as wp;
    let w = r.wires.as_ref()?;
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
    Some(serde_json::json!({
        "measured": w.wires_measured,
        "total": w.wires.len(),
        "position": mm(w.position_error_mm),
        "straightness": mm(w.straightness_rms_mm),
        "thickness": mm(w.thickness_fwhm_mm),
        "set": r.inputs.wires.as_deref().map(display_path).unwrap_or_default(),
        "step": wp::STEP_MM,
        "end": format!("{:.0}", wp::END_FRACTION * 100.0),
        "width": 2.0 * wp::HALF_WIDTH_MM,
        "peak": wp::PEAK_OVER_MAD,
        "rows": rows,
    }))
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
    let kind = crate::io::fs::read_text_capped(&out.join("summary.json"), crate::core::limits::MAX_TEXT_FILE_BYTES)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|j| j.get("kind").and_then(|k| k.as_str()).map(str::to_string));
    if kind.as_deref() != Some(KIND) {
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

/// How a volume agrees with a reference of the same inputs (PLUS's, say).
pub fn agreement(
    r: &Reconstruction,
    written: &[u8],
    path: &Path,
    reference: &(VolumeHeader, Vec<u8>),
) -> serde_json::Value {
    let (theirs, their_voxels) = reference;
    let ours = header(&r.volume);
    let same_grid = ours.dims == theirs.dims && ours.element_type == theirs.element_type;
    let offset_mm = (0..3)
        .map(|a| (ours.origin_mm[a] - theirs.origin_mm[a]).abs())
        .fold(0.0, f64::max);
    let mut out = serde_json::json!({
        "reference": display_path(path),
        "dims": {"ours": ours.dims, "reference": theirs.dims},
        "element_type": {"ours": ours.element_type, "reference": theirs.element_type},
        "offset_max_difference_mm": offset_mm,
        "spacing_equal": ours.spacing_mm == theirs.spacing_mm,
        "identical_file": crate::io::fs::read_capped(path, written.len() as u64).map(|b| b == written).unwrap_or(false),
    });
    if same_grid && ours.element_type == "MET_UCHAR" {
        let mine = r.volume.bytes();
        let (mut union, mut close, mut a, mut b, mut both, mut equal) = (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
        for (&o, &t) in mine.iter().zip(their_voxels) {
            a += u64::from(o > 0);
            b += u64::from(t > 0);
            both += u64::from(o > 0 && t > 0);
            equal += u64::from(o == t);
            if o > 0 || t > 0 {
                union += 1;
                close += u64::from(o.abs_diff(t) <= 1);
            }
        }
        out["voxels"] = serde_json::json!(mine.len());
        out["voxels_equal"] = serde_json::json!(equal);
        out["nonzero_in_either"] = serde_json::json!(union);
        out["within_one_grey_level"] = serde_json::json!(close as f64 / union.max(1) as f64);
        out["dice_nonzero"] = serde_json::json!(2.0 * both as f64 / (a + b).max(1) as f64);
    }
    out
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
    let data = r.volume.bytes();
    let pictures = pictures(&r.volume);
    let write = |name: &str, bytes: &[u8]| crate::io::fs::write_atomic(&dir.join(name), bytes);
    let volume = metaimage_bytes(&header, &data);
    write("volume.mha", &volume)?;
    let agreement = options
        .compare
        .map(|(path, reference)| agreement(r, &volume, path, reference));
    if let Some(a) = &agreement {
        write("agreement.json", serde_json::to_string_pretty(a)?.as_bytes())?;
    }
    if options.nrrd {
        write("volume.nrrd", &nrrd_bytes(&header, &data))?;
    }
    for p in &pictures {
        write(p.name, &png_bytes(p)?)?;
    }
    let json = serde_json::to_string_pretty(&summary(r))?;
    write("summary.json", json.as_bytes())?;
    write("report.html", html(r, &pictures, agreement.as_ref())?.as_bytes())?;
    Ok(())
}
