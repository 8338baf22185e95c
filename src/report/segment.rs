//! Outputs of `probecal segment`: `segmentation.csv` (one row per found wire
//! point, PLUS's pixel convention after the flip to MF; one row with `found` = 0
//! for a frame not segmented), `summary.json` and `report.html` (the counts and
//! every failed frame with its reason in words).

use std::fmt::Write as _;
use std::path::Path;

use crate::io::fs::write_atomic;
use crate::pipeline::segment::SegmentRun;

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

fn failures(run: &SegmentRun) -> Vec<(usize, String)> {
    run.frames
        .iter()
        .filter_map(|f| f.rejected.as_ref().map(|r| (f.index, r.to_string())))
        .collect()
}

/// `summary.json`.
pub fn summary(run: &SegmentRun) -> serde_json::Value {
    let found = run.frames.iter().filter(|f| f.rejected.is_none()).count();
    serde_json::json!({
        "sequence": crate::io::fs::display_path(&run.sequence),
        "config": crate::io::fs::display_path(&run.config),
        "image_size_px": run.image_size_px,
        "orientation": format!("{:?}", run.orientation).to_uppercase(),
        "clip_rectangle_px": run.clip_rectangle_px,
        "approximate_spacing_mm_per_px": run.spacing_guess_mm_per_px,
        "opening_radius_px": run.segmentation.opening_radius_for(run.spacing_guess_mm_per_px),
        "threshold_percent": run.segmentation.threshold_percent,
        "frames": run.frames.len(),
        "found": found,
        "not_found": failures(run)
            .into_iter()
            .map(|(frame, reason)| serde_json::json!({"frame": frame, "reason": reason}))
            .collect::<Vec<_>>(),
    })
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// `report.html`.
pub fn html(run: &SegmentRun) -> String {
    let found = run.frames.iter().filter(|f| f.rejected.is_none()).count();
    let mut rows = String::new();
    for (frame, reason) in failures(run) {
        let _ = writeln!(
            rows,
            "<tr><td>{frame}</td><td class=\"key\">{}</td></tr>",
            escape(&reason)
        );
    }
    let [u, v, w, h] = run.clip_rectangle_px;
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\"><title>segmentation</title>\n\
         <style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}td,th{{padding:.2em .6em;text-align:right}}.key{{text-align:left}}</style></head>\n\
         <body>\n<h1>N-wire segmentation</h1>\n<p>{} with {}: {} of {} frames segmented ({} N-wires, {} px images read as MF from {:?}, \
         clip rectangle {u} {v} {w} {h} px, opening {} px, each frame's threshold {} % of its brightest opened pixel).</p>\n\
         <h2>Frames not segmented</h2>\n<table id=\"not-found\"><thead><tr><th>frame</th><th class=\"key\">reason</th></tr></thead><tbody>\n{rows}</tbody></table>\n\
         <p>Every found point is in <code>segmentation.csv</code> (frame, found, wire id, x, y in pixels).</p>\n</body>\n</html>\n",
        escape(&crate::io::fs::display_path(&run.sequence)),
        escape(&crate::io::fs::display_path(&run.config)),
        found,
        run.frames.len(),
        run.wire_ids.len() / 3,
        format_args!("{}x{}", run.image_size_px[0], run.image_size_px[1]),
        run.orientation,
        run.segmentation.opening_radius_for(run.spacing_guess_mm_per_px),
        run.segmentation.threshold_percent,
    )
}

/// `probecal segment`: exit code 0 on success, 1 when the inputs cannot be read
/// or the outputs written.
pub fn command(sequence: &Path, config: &Path, out: &Path) -> u8 {
    let run = match crate::pipeline::segment::run(sequence, config) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return 1;
        }
    };
    let written = crate::report::summary::to_text(&summary(&run))
        .map_err(|e| e.to_string())
        .and_then(|text| {
            std::fs::create_dir_all(out)
                .map(|_| text)
                .map_err(|e| format!("{}: {e}", out.display()))
        })
        .and_then(|text| {
            for (name, bytes) in [
                ("segmentation.csv", csv(&run).into_bytes()),
                ("summary.json", text.into_bytes()),
                ("report.html", html(&run).into_bytes()),
            ] {
                write_atomic(&out.join(name), &bytes).map_err(|e| e.to_string())?;
            }
            Ok(())
        });
    match written {
        Ok(()) => {
            let found = run.frames.iter().filter(|f| f.rejected.is_none()).count();
            println!(
                "{found} of {} frames segmented; written to {}",
                run.frames.len(),
                out.display()
            );
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            1
        }
    }
}
