//! Outputs of `probecal segment`: `segmentation.csv` (one row per found wire
//! point, PLUS's pixel convention after the flip to MF; one row with `found` = 0
//! for a frame not segmented), `summary.json`, `report.html` (the counts, every
//! failed frame with its reason in words, and a gallery) and `gallery/`: each
//! frame with its candidate spots (yellow), the chosen patterns (green, wire 1
//! marked) or the reason it failed (red), and the clip rectangle (blue).

use std::fmt::Write as _;

use opencv::core::{Mat, Point, Rect, Scalar};
use opencv::imgproc;
use opencv::prelude::*;

use crate::io::fs::write_all_atomic;
use crate::pipeline::tracked::segment::SegmentRun;
use crate::report::error::OutputError;
use crate::results::segmentation::{PlusBaseline, SegmentationSummary};

/// `segmentation.csv`.
pub fn csv(run: &SegmentRun) -> String {
    let mut out = String::from("frame,found,wire,x_px,y_px\n");
    for f in &run.frames {
        if f.rejected.is_some() {
            let _ = writeln!(out, "{},0,,,", f.index);
            continue;
        }
        for (pattern, dots) in f.dots_px.iter().enumerate() {
            for (k, dot) in dots.iter().enumerate() {
                let id = run.wire_ids.get(pattern * 3 + k).map(String::as_str).unwrap_or("");
                let _ = writeln!(out, "{},1,{id},{:.3},{:.3}", f.index, dot[0], dot[1]);
            }
        }
    }
    out
}

/// Frame `k` of the run drawn, as JPEG bytes.
fn picture(run: &SegmentRun, k: usize) -> Result<Vec<u8>, opencv::Error> {
    let frame = &run.frames[k];
    let [w, h] = run.image_size_px;
    let grey = Mat::new_rows_cols_with_data(h as i32, w as i32, run.images.pixels(frame.index))?;
    let mut bgr = Mat::default();
    imgproc::cvt_color(&grey, &mut bgr, imgproc::COLOR_GRAY2BGR, 0)?;
    let (yellow, green, red, blue) = (
        Scalar::new(0.0, 220.0, 255.0, 0.0),
        Scalar::new(60.0, 220.0, 60.0, 0.0),
        Scalar::new(60.0, 60.0, 255.0, 0.0),
        Scalar::new(255.0, 140.0, 40.0, 0.0),
    );
    if let Some(overlay) = &run.overlay {
        // The overlay left out, purple.
        let bytes = bgr.data_bytes_mut()?;
        for (pixel, _) in bytes.chunks_exact_mut(3).zip(&overlay.mask).filter(|(_, &m)| m) {
            pixel.copy_from_slice(&[160, 40, 160]);
        }
    }
    let at = |p: [f64; 2]| Point::new(p[0].round() as i32, p[1].round() as i32);
    let [u, v, cw, ch] = run.clip_rectangle_px.map(|x| x as i32);
    imgproc::rectangle(&mut bgr, Rect::new(u, v, cw, ch), blue, 1, imgproc::LINE_8, 0)?;
    for c in &frame.candidates_px {
        imgproc::circle(&mut bgr, at(*c), 7, yellow, 1, imgproc::LINE_AA, 0)?;
    }
    for dots in &frame.dots_px {
        for pair in dots.windows(2) {
            imgproc::line(&mut bgr, at(pair[0]), at(pair[1]), green, 1, imgproc::LINE_AA, 0)?;
        }
        imgproc::circle(&mut bgr, at(dots[0]), 4, green, -1, imgproc::LINE_AA, 0)?;
    }
    if let Some(reason) = &frame.rejected {
        // The whole reason, wrapped to the picture's width.
        let per_line = (w / 8).max(20);
        for (k, line) in wrap(&reason.to_string(), per_line).iter().enumerate() {
            imgproc::put_text(
                &mut bgr,
                line,
                Point::new(8, 20 + 18 * k as i32),
                imgproc::FONT_HERSHEY_SIMPLEX,
                0.45,
                red,
                1,
                imgproc::LINE_AA,
                false,
            )?;
        }
    }
    crate::io::image::mat_to_jpeg(&bgr, 80)
}

/// `text` in lines of at most `width` characters, broken at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split(' ') {
        let last = lines.last_mut().map(|l| l.chars().count()).unwrap_or(0);
        if last > 0 && last + 1 + word.chars().count() > width {
            lines.push(String::new());
        }
        let line = lines.last_mut().expect("one line at least");
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    lines
}

fn gallery_name(frame: usize) -> String {
    format!("gallery/frame_{frame:04}.jpg")
}

const TEMPLATE: &str = include_str!("../../../templates/segment.html.tera");

/// `report.html`, from `templates/segment.html.tera` (every value escaped there).
pub fn html(summary: &SegmentationSummary, run: &SegmentRun) -> Result<String, OutputError> {
    let [u, v, w, h] = summary.clip_rectangle_px;
    let region = match &summary.overlay {
        None => format!("clip rectangle {u} {v} {w} {h} px"),
        Some(o) => format!(
            "no clip rectangle given: the whole image, with the screen's overlay left out ({} px at grey {} or more in every one of the {} frames, purple in the gallery)",
            o.pixels,
            o.threshold_grey,
            o.frames
        ),
    };
    let mut order: Vec<&crate::pipeline::tracked::TrackedFrame> = run.frames.iter().collect();
    order.sort_by_key(|f| (f.rejected.is_none(), f.index));
    let gallery: Vec<serde_json::Value> = order
        .iter()
        .map(|f| {
            let caption = match &f.rejected {
                Some(r) => format!("frame {}: {r}", f.index),
                None => format!("frame {}: {} patterns", f.index, f.dots_px.len()),
            };
            serde_json::json!({"src": gallery_name(f.index), "frame": f.index, "caption": caption})
        })
        .collect();
    let mut ctx = tera::Context::new();
    ctx.insert("sequence", &summary.sequence);
    ctx.insert("config", &summary.config);
    ctx.insert("found", &summary.found);
    ctx.insert("total", &summary.frames);
    ctx.insert("nwires", &(run.wire_ids.len() / 3));
    ctx.insert(
        "size",
        &format!("{}x{}", summary.image_size_px[0], summary.image_size_px[1]),
    );
    ctx.insert("orientation", &format!("{:?}", run.orientation));
    ctx.insert("region", &region);
    ctx.insert("opening_px", &summary.opening_radius_px);
    ctx.insert("threshold_percent", &summary.threshold_percent);
    ctx.insert("plus", &summary.plus_baseline.as_ref().map(baseline_context));
    ctx.insert("by_check", &summary.not_found_by_check);
    ctx.insert("not_found", &summary.not_found);
    ctx.insert("gallery", &gallery);
    Ok(tera::Tera::one_off(TEMPLATE, &ctx, true)?)
}

/// The comparison with PLUS's segmentation, for the page.
fn baseline_context(b: &PlusBaseline) -> serde_json::Value {
    let s = &b.score;
    let list = |frames: &[usize]| {
        if frames.is_empty() {
            "none".to_string()
        } else {
            frames.iter().map(|f| f.to_string()).collect::<Vec<_>>().join(", ")
        }
    };
    serde_json::json!({
        "file": b.file,
        "section": b.section,
        "plus_frames": s.plus_frames,
        "both_frames": s.both_frames,
        "recall_percent": format!("{:.1}", 100.0 * s.recall),
        "missed": list(&s.missed_frames),
        "extra": list(&s.extra_frames),
        "distance": s.point_distance_px
            .map(|d| format!(
                "mean {:.3}, SD {:.3}, max {:.3} (n = {})",
                d.mean,
                d.std,
                s.point_distance_max_px.unwrap_or(f64::NAN),
                d.n
            ))
            .unwrap_or_else(|| "—".into()),
    })
}

/// Writes every output into `out` (whole, or nothing).
pub fn write(summary: &SegmentationSummary, run: &SegmentRun, out: &std::path::Path) -> Result<(), OutputError> {
    Ok(write_all_atomic(out, &outputs(summary, run)?)?)
}

/// Every output file: the gallery's pictures, then the tables and the page.
fn outputs(summary: &SegmentationSummary, run: &SegmentRun) -> Result<Vec<(String, Vec<u8>)>, OutputError> {
    let mut files = Vec::with_capacity(run.frames.len() + 3);
    for (k, f) in run.frames.iter().enumerate() {
        let jpeg = picture(run, k).map_err(|e| OutputError::figure(format!("frame {}: {e}", f.index)))?;
        files.push((gallery_name(f.index), jpeg));
    }
    let text = crate::results::summary::to_text(summary)?;
    files.push(("segmentation.csv".into(), csv(run).into_bytes()));
    files.push(("summary.json".into(), text.into_bytes()));
    files.push(("report.html".into(), html(summary, run)?.into_bytes()));
    Ok(files)
}
