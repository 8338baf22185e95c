//! Outputs of `probecal reconstruct`: `volume.mha` (PLUS's MetaImage layout),
//! optionally `volume.nrrd`, `summary.json` (frames used and skipped with their
//! reasons, voxels filled before and after hole filling, time per stage) and
//! `report.html` with three orthogonal slices and a maximum-intensity projection.
//!
//! Everything is written into a staging folder and swapped in only when all of
//! it is written; an existing `--out` that is not a reconstruction is refused.

use std::path::Path;

use crate::io::fs::{display_path, Staged};
use crate::io::volume_file::{metaimage_bytes, nrrd_bytes, VolumeHeader};
use crate::pipeline::reconstruct::{AnyVolume, Reconstruction};
use crate::report::error::OutputError;

/// `summary.json`'s `kind`, which marks a folder as a reconstruction's.
pub const KIND: &str = "reconstruction";

pub fn header(volume: &AnyVolume) -> VolumeHeader {
    let g = volume.grid();
    VolumeHeader {
        dims: g.dims,
        origin_mm: g.origin_mm,
        spacing_mm: g.spacing_mm,
        element_type: volume.element_type().to_string(),
    }
}

pub fn summary(r: &Reconstruction) -> serde_json::Value {
    let g = r.volume.grid();
    serde_json::json!({
        "kind": KIND,
        "sequence": display_path(&r.inputs.sequence),
        "config": display_path(&r.inputs.config),
        "image_to_probe_source": r.image_to_probe_source,
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
        "threads": r.threads,
        "time_s": r.timings.iter().map(|(k, v)| (k.clone(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
    })
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

/// The middle slices across each axis and the maximum-intensity projection
/// along z, grey levels scaled so that the brightest voxel is white.
pub fn pictures(volume: &AnyVolume) -> Vec<Picture> {
    let values = volume.values();
    let [nx, ny, nz] = volume.grid().dims;
    let top = values.iter().copied().fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
    let grey = |v: f64| (v / top * 255.0).round().clamp(0.0, 255.0) as u8;
    let at = |x: usize, y: usize, z: usize| values[(z * ny + y) * nx + x];
    let (cx, cy, cz) = (nx / 2, ny / 2, nz / 2);
    let mip: Vec<u8> = (0..ny)
        .flat_map(|y| (0..nx).map(move |x| (x, y)))
        .map(|(x, y)| grey((0..nz).map(|z| at(x, y, z)).fold(0.0, f64::max)))
        .collect();
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
    let times: String = r.timings.iter().map(|(k, v)| format!("{k} {v:.3} s; ")).collect();
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\"><title>reconstruction</title>\n\
         <style>body{{font-family:sans-serif;max-width:70em;margin:1em auto}} figure{{display:inline-block;margin:0.5em}} \
         img{{image-rendering:pixelated;background:#000}} td,th{{padding:0 0.6em;text-align:left}}</style></head>\n<body>\n\
         <h1>Volume of {seq}</h1>\n\
         <p><b>{used} of {total} frames</b> inserted into a {nx}x{ny}x{nz} volume of {sx} mm voxels \
         ({filled_after} voxels filled: {filled_before} by the frames, {by_holes} by hole filling). \
         <code>ImageToProbe</code> from {source}.</p>\n\
         <h2>Slices and projection</h2>\n{figures}\
         <h2>Settings</h2>\n<p>{interp:?} interpolation, {comp:?} compounding, {opt:?} optimization, \
         clip rectangle origin {co:?} size {cs:?}, fan {fan}, {holes} hole-filling element(s). \
         Origin (centre of the first voxel) {origin:?} mm.</p>\n\
         <h2>Frames left out</h2>\n<table><tr><th>frame</th><th>reason</th></tr>\n{skipped}</table>\n\
         <p>Time: {times}{threads} thread(s).</p>\n</body></html>\n",
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
        interp = r.settings.interpolation,
        comp = r.settings.compounding,
        opt = r.settings.optimization,
        co = r.settings.clip_origin_px,
        cs = r.settings.clip_size_px,
        fan = if r.settings.fan.is_some() { "on" } else { "off" },
        holes = r.settings.hole_filling.len(),
        origin = g.origin_mm,
        threads = r.threads,
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

/// Writes all outputs into `out` (swapped in whole).
pub fn write(r: &Reconstruction, out: &Path, nrrd: bool) -> Result<(), OutputError> {
    check_out(out)?;
    let header = header(&r.volume);
    let data = r.volume.bytes();
    let pictures = pictures(&r.volume);
    let staged = Staged::begin(out)?;
    let dir = staged.path().to_path_buf();
    let write = |name: &str, bytes: &[u8]| crate::io::fs::write_atomic(&dir.join(name), bytes);
    let result = (|| -> Result<(), OutputError> {
        write("volume.mha", &metaimage_bytes(&header, &data))?;
        if nrrd {
            write("volume.nrrd", &nrrd_bytes(&header, &data))?;
        }
        for p in &pictures {
            write(p.name, &png_bytes(p)?)?;
        }
        let json = serde_json::to_string_pretty(&summary(r))?;
        write("summary.json", json.as_bytes())?;
        write("report.html", html(r, &pictures).as_bytes())?;
        Ok(())
    })();
    match result {
        Ok(()) => Ok(staged.commit()?),
        Err(e) => {
            let _ = staged.abandon();
            Err(e)
        }
    }
}
