//! The reports' B-scan gallery: frames with their detections drawn (the arc's
//! circle and centre, the compact echoes, the features used), used frames first,
//! then rejected ones with their reasons.

use opencv::core::{Mat, Point, Scalar, Size};
use opencv::imgproc;
use opencv::prelude::*;

use crate::pipeline::record::DatasetRun;

/// One picture of the gallery.
#[derive(Debug, Clone)]
pub struct GalleryImage {
    pub frame: usize,
    pub caption: String,
    /// JPEG bytes, `WIDTH_PX` wide (speckle makes PNG five times larger).
    pub jpeg: Vec<u8>,
}

/// Width of a gallery picture, px.
pub const WIDTH_PX: i32 = 360;
/// Used and rejected frames shown, at most.
pub const USED_SHOWN: usize = 6;
pub const REJECTED_SHOWN: usize = 3;
const JPEG_QUALITY: u8 = 80;

fn point(p: [f64; 2]) -> Point {
    Point::new(p[0].round() as i32, p[1].round() as i32)
}

fn draw(run: &DatasetRun, record: &crate::pipeline::record::FrameRecord) -> Result<Option<Vec<u8>>, opencv::Error> {
    let Ok(grey) = crate::io::image::read_gray(&record.files.bscan_image) else {
        return Ok(None);
    };
    let mut bgr = Mat::default();
    imgproc::cvt_color(&grey, &mut bgr, imgproc::COLOR_GRAY2BGR, 0)?;
    let yellow = Scalar::new(0.0, 220.0, 255.0, 0.0);
    let green = Scalar::new(60.0, 220.0, 60.0, 0.0);
    let red = Scalar::new(60.0, 60.0, 255.0, 0.0);
    let thickness = (bgr.cols() / WIDTH_PX).max(1) + 1;
    for s in &record.spots {
        imgproc::circle(
            &mut bgr,
            point(s.echo_px),
            3 * thickness,
            yellow,
            thickness,
            imgproc::LINE_AA,
            0,
        )?;
    }
    if let Some(arc) = &record.arc {
        for p in &arc.arc_points_px {
            imgproc::circle(&mut bgr, point(*p), 1, yellow, -1, imgproc::LINE_8, 0)?;
        }
        let radius_px = arc.radius_mm / run.spacing_mm_per_px[0];
        imgproc::circle(
            &mut bgr,
            point(arc.centre_px),
            radius_px.round() as i32,
            green,
            thickness,
            imgproc::LINE_AA,
            0,
        )?;
    }
    let colour = if record.rejection.is_none() { green } else { red };
    for f in &record.features_px {
        let c = point(*f);
        let arm = 6 * thickness;
        imgproc::line(
            &mut bgr,
            Point::new(c.x - arm, c.y),
            Point::new(c.x + arm, c.y),
            colour,
            thickness,
            imgproc::LINE_AA,
            0,
        )?;
        imgproc::line(
            &mut bgr,
            Point::new(c.x, c.y - arm),
            Point::new(c.x, c.y + arm),
            colour,
            thickness,
            imgproc::LINE_AA,
            0,
        )?;
    }
    let height = (bgr.rows() as f64 * WIDTH_PX as f64 / bgr.cols().max(1) as f64).round() as i32;
    let mut small = Mat::default();
    imgproc::resize(
        &bgr,
        &mut small,
        Size::new(WIDTH_PX, height.max(1)),
        0.0,
        0.0,
        imgproc::INTER_AREA,
    )?;
    Ok(Some(crate::io::image::mat_to_jpeg(&small, JPEG_QUALITY)?))
}

/// The gallery of a run (deterministic: the first frames of each kind, in frame order).
pub fn gallery(run: &DatasetRun) -> Result<Vec<GalleryImage>, opencv::Error> {
    let used = run.frames.iter().filter(|f| f.rejection.is_none()).take(USED_SHOWN);
    let rejected = run.frames.iter().filter(|f| f.rejection.is_some()).take(REJECTED_SHOWN);
    let shown: Vec<&crate::pipeline::record::FrameRecord> = used.chain(rejected).collect();
    // Drawn on every core, in frame order.
    let drawn = crate::core::parallel::parallel_map(shown.len(), |i| draw(run, shown[i]));
    let mut out = Vec::new();
    for (record, jpeg) in shown.into_iter().zip(drawn) {
        let Some(jpeg) = jpeg? else { continue };
        let caption = match (&record.rejection, record.bre_mm) {
            (Some(reason), _) => {
                format!(
                    "frame {}: rejected ({}): {reason}",
                    record.files.frame,
                    reason.stage().label()
                )
            }
            (None, Some((_, norm))) => format!("frame {}: used, BRE {norm:.3} mm", record.files.frame),
            (None, None) => format!("frame {}: used", record.files.frame),
        };
        out.push(GalleryImage {
            frame: record.files.frame,
            caption,
            jpeg,
        });
    }
    Ok(out)
}

/// `data:image/jpeg;base64,...` for a self-contained HTML page.
pub fn data_uri(jpeg: &[u8]) -> String {
    data_uri_of("image/jpeg", jpeg)
}

/// `data:<mime>;base64,...` for a self-contained HTML page.
pub fn data_uri_of(mime: &str, bytes: &[u8]) -> String {
    const TABLE: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = format!("data:{mime};base64,");
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(TABLE[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_examples() {
        let strip = |s: String| s.trim_start_matches("data:image/jpeg;base64,").to_string();
        assert_eq!(strip(data_uri(b"")), "");
        assert_eq!(strip(data_uri(b"f")), "Zg==");
        assert_eq!(strip(data_uri(b"fo")), "Zm8=");
        assert_eq!(strip(data_uri(b"foo")), "Zm9v");
        assert_eq!(strip(data_uri(b"foobar")), "Zm9vYmFy");
    }
}
