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
    std::fs::read_to_string(summary)
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
    let values = volume.values();
    let [nx, ny, nz] = volume.grid().dims;
    let top = values.iter().copied().fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
    let grey = |v: f64| (v / top * 255.0).round().clamp(0.0, 255.0) as u8;
    let at = |x: usize, y: usize, z: usize| values[(z * ny + y) * nx + x];
    // Slices through the intensity-weighted centre (the middle of an empty volume).
    // In memory order, as one pass over the voxels would add them.
    let (mut sum, mut at_sum) = (0.0, [0.0f64; 3]);
    for (z, plane) in values.chunks_exact(nx * ny).enumerate() {
        for (y, row) in plane.chunks_exact(nx).enumerate() {
            for (x, v) in row.iter().enumerate() {
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
    for plane in values.chunks_exact(nx * ny) {
        for (m, v) in highest.iter_mut().zip(plane) {
            *m = m.max(*v);
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

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

pub fn html(r: &Reconstruction, pictures: &[Picture]) -> String {
    let g = r.volume.grid();
    let figures: String = pictures
        .iter()
        .map(|p| {
            let scale = (480 / p.width.max(p.height)).max(1);
            format!(
                "<figure><img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n",
                p.name,
                p.width * scale,
                p.height * scale,
                escape(&p.title),
                escape(&p.title)
            )
        })
        .collect();
    let skipped: String = r
        .skipped
        .iter()
        .map(|s| format!("<tr><td>{}</td><td>{}</td></tr>\n", s.index, escape(&s.reason)))
        .collect();
    let times: String = match r.timings.is_empty() {
        true => String::new(),
        false => {
            let stages: String = r.timings.iter().map(|(k, v)| format!("{k} {v:.3} s; ")).collect();
            format!("Time: {stages}{} thread(s).", r.threads)
        }
    };
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\"><title>reconstruction</title>\n\
         <style>body{{font-family:sans-serif;max-width:70em;margin:1em auto}} figure{{display:inline-block;margin:0.5em}} \
         img{{image-rendering:pixelated;background:#000}} td,th{{padding:0 0.6em;text-align:left}}</style></head>\n<body>\n\
         <h1>Volume of {seq}</h1>\n\
         <p><b>{used} of {total} frames</b> inserted into a {nx}x{ny}x{nz} volume of {sx} mm voxels \
         ({filled_after} voxels filled: {filled_before} by the frames, {by_holes} by hole filling). \
         <code>ImageToProbe</code> from {source}; tracker lag {lag_ms:+.0} ms ({lag_source}).</p>\n\
         {wires}<h2>Slices and projection</h2>\n{figures}\
         <h2>Settings</h2>\n<p>{interp:?} interpolation, {comp:?} compounding, {opt:?} optimization, \
         clip rectangle origin {co:?} size {cs:?}, fan {fan}, {holes} hole-filling element(s). \
         Origin (centre of the first voxel) {origin:?} mm.</p>\n\
         <h2>Frames left out</h2>\n<table><tr><th>frame</th><th>reason</th></tr>\n{skipped}</table>\n\
         <p>{times}</p>\n</body></html>\n",
        seq = escape(&display_path(&r.inputs.sequence)),
        used = r.frames_used.len(),
        total = r.frames_total,
        nx = g.dims[0],
        ny = g.dims[1],
        nz = g.dims[2],
        sx = g.spacing_mm.map(crate::io::volume_file::format_g6).join(" x "),
        filled_after = r.voxels_filled_after_holes,
        filled_before = r.voxels_filled_before_holes,
        by_holes = r.voxels_filled_after_holes - r.voxels_filled_before_holes,
        source = escape(&r.image_to_probe_source),
        lag_ms = r.tracker_lag_s * 1000.0,
        lag_source = escape(&r.tracker_lag_source),
        interp = r.settings.interpolation,
        comp = r.settings.compounding,
        opt = r.settings.optimization,
        co = r.settings.clip_origin_px,
        cs = r.settings.clip_size_px,
        fan = if r.settings.fan.is_some() { "on" } else { "off" },
        holes = r.settings.hole_filling.len(),
        origin = g.origin_mm,
        wires = wires_html(r),
    )
}

/// The wires' table: each wire's position error, straightness and thickness.
fn wires_html(r: &Reconstruction) -> String {
    use crate::evaluate::wire_profile as wp;
    let Some(w) = &r.wires else {
        return String::new();
    };
    let mm = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.2}"));
    let rows: String = w
        .wires
        .iter()
        .map(|f| {
            format!(
                "<tr><td>{}</td><td>{} of {}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                escape(&f.name),
                f.sections_counted,
                f.sections,
                mm(f.position_error_mm),
                mm(f.straightness_rms_mm),
                mm(f.thickness_fwhm_mm)
            )
        })
        .collect();
    format!(
        "<h2>The phantom's wires in the volume</h2>\n<p><b>{n} of {total} wires measured: position error {pos} mm \
         (mean), straightness {straight} mm (RMS), thickness {thick} mm (median FWHM).</b> The wires of \
         {set}, placed by its phantom registration. Every {step} mm along each wire (its ends' {end:.0} % left \
         out) a cross-section {width} mm wide is sampled; where the wire stands out (peak over the median by \
         {peak} MADs) its centre and FWHM are taken. Position error: the centres' mean distance from the wire's \
         line (it holds the registration's error too); straightness: their RMS distance from their own line. \
         A better <code>ImageToProbe</code> gives thinner, straighter wires nearer their lines.</p>\n\
         <table><tr><th>wire</th><th>sections with the wire</th><th>position error (mm)</th>\
         <th>straightness (mm)</th><th>thickness (mm)</th></tr>\n{rows}</table>\n",
        n = w.wires_measured,
        total = w.wires.len(),
        pos = mm(w.position_error_mm),
        straight = mm(w.straightness_rms_mm),
        thick = mm(w.thickness_fwhm_mm),
        set = escape(&r.inputs.wires.as_deref().map(display_path).unwrap_or_default()),
        step = wp::STEP_MM,
        end = wp::END_FRACTION * 100.0,
        width = 2.0 * wp::HALF_WIDTH_MM,
        peak = wp::PEAK_OVER_MAD,
    )
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
    let kind = std::fs::read_to_string(out.join("summary.json"))
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
        "identical_file": std::fs::read(path).map(|b| b == written).unwrap_or(false),
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
    if let Some((path, reference)) = options.compare {
        write(
            "agreement.json",
            serde_json::to_string_pretty(&agreement(r, &volume, path, reference))?.as_bytes(),
        )?;
    }
    if options.nrrd {
        write("volume.nrrd", &nrrd_bytes(&header, &data))?;
    }
    for p in &pictures {
        write(p.name, &png_bytes(p)?)?;
    }
    let json = serde_json::to_string_pretty(&summary(r))?;
    write("summary.json", json.as_bytes())?;
    write("report.html", html(r, &pictures).as_bytes())?;
    Ok(())
}
