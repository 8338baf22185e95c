//! `probecal calibrate-camera`: intrinsics from chessboard or ChArUco views,
//! printed and written as OpenCV FileStorage YAML with every image's fate; 0
//! written, 2 bad options (an existing output file without `--force`), 1 when
//! no calibration could be solved or written.

use std::path::{Path, PathBuf};

use super::failure::Failure;
use crate::io::camera_model::ViewFate;

pub fn command(images: &[PathBuf], board: [u32; 2], square_mm: f64, out: &Path, force: bool) -> Result<(), Failure> {
    output_file(out, images, force)?;
    let cal = crate::detect::camera_calibration::calibrate_from(
        images,
        board,
        square_mm,
        crate::detect::corners::Search::OpenCvSample,
    )
    .map_err(Failure::failed)?;
    crate::report::console::camera_calibration(&cal);
    let views: Vec<ViewFate> = cal
        .views
        .iter()
        .map(|v| ViewFate {
            image: v.image.display().to_string(),
            used: v.used,
            how: match (&v.reason, v.found_by) {
                (Some(r), _) => r.clone(),
                (None, Some(f)) => format!("board found by {f}"),
                (None, None) => String::new(),
            },
        })
        .collect();
    cal.intrinsics
        .save_with_views(out, Some((board, square_mm)), &views)
        .map_err(Failure::failed)?;
    println!("written to {}", out.display());
    Ok(())
}

/// `calibrate-camera --charuco XxY --square-mm S --marker-mm M --dictionary D`.
pub fn charuco_command(
    images: &[PathBuf],
    spec: &crate::detect::charuco_calibration::CharucoSpec,
    out: &Path,
    force: bool,
) -> Result<(), Failure> {
    spec.board().map_err(Failure::bad_input)?;
    output_file(out, images, force)?;
    let images = crate::detect::camera_calibration::collect_images(images).map_err(Failure::failed)?;
    let cal = crate::detect::charuco_calibration::calibrate(&images, spec).map_err(Failure::failed)?;
    crate::report::console::camera_calibration(&cal);
    let views: Vec<ViewFate> = cal
        .views
        .iter()
        .map(|v| ViewFate {
            image: v.image.display().to_string(),
            used: v.used,
            how: v.reason.clone().unwrap_or_else(|| "ChArUco corners found".into()),
        })
        .collect();
    cal.intrinsics
        .save_with_views(out, None, &views)
        .map_err(Failure::failed)?;
    println!("written to {}", out.display());
    Ok(())
}

/// Refuses an output that is one of the images (or their folder's images), or
/// a folder; makes `out`'s folder before the work, so a finished calibration
/// has somewhere to go.
fn output_file(out: &Path, images: &[PathBuf], force: bool) -> Result<(), Failure> {
    let listed = crate::detect::camera_calibration::collect_images(images).unwrap_or_default();
    let read: Vec<&Path> = images.iter().chain(&listed).map(PathBuf::as_path).collect();
    if let Some(why) = crate::io::output::file_refusal(out, "calibrate-camera", &read, force) {
        return Err(Failure::bad_input(format!("--out {}: {why}", out.display())));
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| Failure::failed(format!("{}: cannot create the output's folder: {e}", parent.display())))?;
    }
    Ok(())
}

/// Largest board square, mm (a ten-metre square is no printed board).
const MAX_SQUARE_MM: f64 = 10_000.0;

/// `--square-mm`: a positive size up to [`MAX_SQUARE_MM`].
pub(crate) fn parse_square_mm(text: &str) -> Result<f64, super::failure::ValueError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= MAX_SQUARE_MM => Ok(v),
        _ => Err(super::failure::ValueError::SquareMm {
            text: text.to_string(),
            most: MAX_SQUARE_MM,
        }),
    }
}
