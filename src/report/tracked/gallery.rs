//! A tracked run's gallery: B-scans of the recording with what the
//! segmentation found drawn on them (the bright spots searched among, each
//! pattern's three dots and the line through its outer two, which the middle
//! dot lies on for an N-wire), used frames spread over each sweep first, then
//! rejected ones with their reason. Read again from the sequence files the run
//! read; a file that cannot be read again gives no pictures, not a failure.

use opencv::core::{Mat, Point, Scalar, Size};
use opencv::imgproc;
use opencv::prelude::*;

use crate::io::plus::sequence::Sequence;
use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::tracked::{Role, TrackedFrame, TrackedRun};
use crate::report::page::gallery::{GalleryImage, WIDTH_PX};

/// Used frames shown per sweep, and rejected frames shown in all, at most.
pub const USED_PER_SWEEP: usize = 3;
pub const REJECTED_SHOWN: usize = 3;
const JPEG_QUALITY: u8 = 80;

/// The `k`-th picture's file beside the pages (the LaTeX page includes it).
pub fn file_name(k: usize) -> String {
    format!("gallery/frame_{k:02}.jpg")
}

fn point(p: [f64; 2]) -> Point {
    Point::new(p[0].round() as i32, p[1].round() as i32)
}

/// The frame's B-scan with its spots, dots and wire lines, `WIDTH_PX` wide (JPEG).
fn draw(pixels: &[u8], width: usize, height: usize, f: &TrackedFrame) -> Result<Vec<u8>, opencv::Error> {
    let grey = Mat::new_rows_cols_with_data(height as i32, width as i32, pixels)?;
    let mut bgr = Mat::default();
    imgproc::cvt_color(&grey, &mut bgr, imgproc::COLOR_GRAY2BGR, 0)?;
    let yellow = Scalar::new(0.0, 220.0, 255.0, 0.0);
    let cyan = Scalar::new(255.0, 200.0, 0.0, 0.0);
    let dot = if f.rejected.is_none() {
        Scalar::new(60.0, 220.0, 60.0, 0.0)
    } else {
        Scalar::new(60.0, 60.0, 255.0, 0.0)
    };
    let thickness = (bgr.cols() / WIDTH_PX).max(1);
    for c in &f.candidates_px {
        imgproc::circle(
            &mut bgr,
            point(*c),
            4 * thickness,
            yellow,
            thickness,
            imgproc::LINE_AA,
            0,
        )?;
    }
    for dots in &f.dots_px {
        imgproc::line(
            &mut bgr,
            point(dots[0]),
            point(dots[2]),
            cyan,
            thickness,
            imgproc::LINE_AA,
            0,
        )?;
        for d in dots {
            imgproc::circle(
                &mut bgr,
                point(*d),
                6 * thickness,
                dot,
                2 * thickness,
                imgproc::LINE_AA,
                0,
            )?;
        }
    }
    let small_height = (height as f64 * WIDTH_PX as f64 / width.max(1) as f64).round() as i32;
    let mut small = Mat::default();
    imgproc::resize(
        &bgr,
        &mut small,
        Size::new(WIDTH_PX, small_height.max(1)),
        0.0,
        0.0,
        imgproc::INTER_AREA,
    )?;
    crate::io::image::mat_to_jpeg(&small, JPEG_QUALITY)
}

/// `n` of `items` spread evenly (first and last included), in order.
fn spread<T: Copy>(items: &[T], n: usize) -> Vec<T> {
    match items.len() {
        0 => Vec::new(),
        len if len <= n => items.to_vec(),
        len => (0..n).map(|k| items[k * (len - 1) / (n - 1).max(1)]).collect(),
    }
}

fn role_name(role: Role) -> &'static str {
    match role {
        Role::Calibration => "calibration",
        Role::Validation => "validation",
    }
}

/// The frames shown: used ones spread over each sweep, then the first rejected.
fn shown(run: &TrackedRun) -> Vec<&TrackedFrame> {
    let mut out = Vec::new();
    for role in [Role::Calibration, Role::Validation] {
        let used: Vec<&TrackedFrame> = run
            .frames
            .iter()
            .filter(|f| f.role == role && f.rejected.is_none())
            .collect();
        out.extend(spread(&used, USED_PER_SWEEP));
    }
    out.extend(run.frames.iter().filter(|f| f.rejected.is_some()).take(REJECTED_SHOWN));
    out
}

fn caption(f: &TrackedFrame) -> String {
    let name = format!("{} frame {}", role_name(f.role), f.index);
    match &f.rejected {
        Some(reason) => format!("{name}: rejected: {reason}"),
        None if f.pre3d_mm.is_empty() => format!("{name}: used"),
        None => format!(
            "{name}: used, PRE3D {:.2} mm (mean of its {} middle dots)",
            f.pre3d_mm.iter().sum::<f64>() / f.pre3d_mm.len() as f64,
            f.pre3d_mm.len()
        ),
    }
}

/// The gallery of a tracked run (deterministic: the same frames, drawn the same).
pub fn gallery(run: &TrackedRun, labels: &TrackedLabels) -> Vec<GalleryImage> {
    let frames = shown(run);
    let mut out = Vec::new();
    for role in [Role::Calibration, Role::Validation] {
        let path = match role {
            Role::Calibration => Some(&labels.calibration_sequence),
            Role::Validation => labels.validation_sequence.as_ref(),
        };
        let of_role: Vec<&&TrackedFrame> = frames.iter().filter(|f| f.role == role).collect();
        let Some(sequence) = path
            .filter(|_| !of_role.is_empty())
            .and_then(|p| Sequence::read(p).ok())
        else {
            continue;
        };
        for f in of_role {
            if f.index >= sequence.frames.len() {
                continue;
            }
            if let Ok(jpeg) = draw(sequence.pixels(f.index), sequence.width, sequence.height, f) {
                out.push(GalleryImage {
                    frame: f.index,
                    caption: caption(f),
                    jpeg,
                });
            }
        }
    }
    // Used frames first (calibration, validation), then the rejected, as chosen.
    let order = |g: &GalleryImage| {
        frames
            .iter()
            .position(|f| caption(f) == g.caption)
            .unwrap_or(usize::MAX)
    };
    out.sort_by_key(order);
    out
}

/// The gallery in a page's context (`gallery`: caption, data URI, file).
pub fn insert(ctx: &mut tera::Context, gallery: &[GalleryImage]) {
    let pictures: Vec<serde_json::Value> = gallery
        .iter()
        .enumerate()
        .map(|(k, g)| {
            serde_json::json!({
                "caption": g.caption,
                "uri": crate::report::page::gallery::data_uri(&g.jpeg),
                "file": file_name(k),
            })
        })
        .collect();
    ctx.insert("gallery", &pictures);
}

#[cfg(test)]
mod tests {
    use super::spread;

    #[test]
    fn spread_takes_both_ends_and_keeps_order() {
        assert_eq!(spread(&[1, 2, 3, 4, 5, 6, 7], 3), vec![1, 4, 7]);
        assert_eq!(spread(&[1, 2], 3), vec![1, 2]);
        assert_eq!(spread::<u8>(&[], 3), Vec::<u8>::new());
        assert_eq!(spread(&[5, 6, 7, 8], 1), vec![5]);
    }
}
