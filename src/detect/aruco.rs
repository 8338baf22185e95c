//! ArUco markers through OpenCV's contrib `aruco` module (OpenCV 4.6): predefined
//! and custom dictionaries, marker detection with optional sub-pixel corner
//! refinement and marker cell patterns (for rendering); ChArUco boards are in
//! `charuco_calibration`.

use std::path::Path;

use opencv::aruco::{self, DetectorParameters, Dictionary, PREDEFINED_DICTIONARY_NAME};
use opencv::core::{FileStorage, Mat, Point2f, Ptr, Vector};
use opencv::prelude::*;

/// The names the manifests use, OpenCV's own.
pub const DICTIONARY_NAMES: [(&str, PREDEFINED_DICTIONARY_NAME); 21] = [
    ("DICT_4X4_50", PREDEFINED_DICTIONARY_NAME::DICT_4X4_50),
    ("DICT_4X4_100", PREDEFINED_DICTIONARY_NAME::DICT_4X4_100),
    ("DICT_4X4_250", PREDEFINED_DICTIONARY_NAME::DICT_4X4_250),
    ("DICT_4X4_1000", PREDEFINED_DICTIONARY_NAME::DICT_4X4_1000),
    ("DICT_5X5_50", PREDEFINED_DICTIONARY_NAME::DICT_5X5_50),
    ("DICT_5X5_100", PREDEFINED_DICTIONARY_NAME::DICT_5X5_100),
    ("DICT_5X5_250", PREDEFINED_DICTIONARY_NAME::DICT_5X5_250),
    ("DICT_5X5_1000", PREDEFINED_DICTIONARY_NAME::DICT_5X5_1000),
    ("DICT_6X6_50", PREDEFINED_DICTIONARY_NAME::DICT_6X6_50),
    ("DICT_6X6_100", PREDEFINED_DICTIONARY_NAME::DICT_6X6_100),
    ("DICT_6X6_250", PREDEFINED_DICTIONARY_NAME::DICT_6X6_250),
    ("DICT_6X6_1000", PREDEFINED_DICTIONARY_NAME::DICT_6X6_1000),
    ("DICT_7X7_50", PREDEFINED_DICTIONARY_NAME::DICT_7X7_50),
    ("DICT_7X7_100", PREDEFINED_DICTIONARY_NAME::DICT_7X7_100),
    ("DICT_7X7_250", PREDEFINED_DICTIONARY_NAME::DICT_7X7_250),
    ("DICT_7X7_1000", PREDEFINED_DICTIONARY_NAME::DICT_7X7_1000),
    ("DICT_ARUCO_ORIGINAL", PREDEFINED_DICTIONARY_NAME::DICT_ARUCO_ORIGINAL),
    ("DICT_APRILTAG_16h5", PREDEFINED_DICTIONARY_NAME::DICT_APRILTAG_16h5),
    ("DICT_APRILTAG_25h9", PREDEFINED_DICTIONARY_NAME::DICT_APRILTAG_25h9),
    ("DICT_APRILTAG_36h10", PREDEFINED_DICTIONARY_NAME::DICT_APRILTAG_36h10),
    ("DICT_APRILTAG_36h11", PREDEFINED_DICTIONARY_NAME::DICT_APRILTAG_36h11),
];

/// Markers of a dictionary file.
const MAX_DICTIONARY_MARKERS: i32 = 10_000;
/// Bits a side of a dictionary file's markers (OpenCV's dictionaries have 4 to 7).
const MAX_MARKER_BITS: i32 = 16;

#[derive(Debug, thiserror::Error)]
pub enum ArucoError {
    #[error("unknown ArUco dictionary `{0}` (expected one of OpenCV's names, e.g. DICT_4X4_50)")]
    UnknownDictionary(String),
    #[error("{path}: not an OpenCV ArUco dictionary file (nmarkers, markersize, marker_N)")]
    BadDictionaryFile { path: String },
    #[error("{path}: {reason}")]
    Refused { path: String, reason: String },
    #[error("{path}: not an OpenCV ArUco detector parameters file ({reason})")]
    BadParametersFile { path: String, reason: String },
    #[error("{0}")]
    Board(String),
    #[error("opencv: {0}")]
    OpenCv(#[from] opencv::Error),
}

/// A dictionary by OpenCV name (`DICT_...`) or from a dictionary file.
pub fn dictionary(name_or_path: &str) -> Result<Ptr<Dictionary>, ArucoError> {
    if name_or_path.starts_with("DICT_") {
        predefined(name_or_path)
    } else {
        dictionary_file(Path::new(name_or_path))
    }
}

/// OpenCV's detector parameters: its defaults, or read from a FileStorage file
/// as OpenCV's samples write it (`detector_params.yml`). A key the file lacks
/// keeps its default; a value out of OpenCV's meaning is refused.
pub fn detector_parameters(file: Option<&Path>) -> Result<Ptr<DetectorParameters>, ArucoError> {
    let mut parameters = DetectorParameters::create()?;
    let Some(path) = file else {
        return Ok(parameters);
    };
    let bad = |reason: String| ArucoError::BadParametersFile {
        path: path.display().to_string(),
        reason,
    };
    if !path.is_file() {
        return Err(bad("no such file".into()));
    }
    if let Some(why) = crate::io::storage::refusal(path) {
        return Err(bad(why));
    }
    let fs = FileStorage::new_def(
        path.to_string_lossy().as_ref(),
        opencv::core::FileStorage_Mode::READ as i32,
    )
    .map_err(|e| bad(e.message))?;
    let root = fs.root_def()?;
    if !parameters.read_detector_parameters(&root).map_err(|e| bad(e.message))? {
        return Err(bad("no detector parameters in it".into()));
    }
    let windows = [
        parameters.adaptive_thresh_win_size_min(),
        parameters.adaptive_thresh_win_size_max(),
    ];
    if windows[0] < 3 || windows[1] < windows[0] || parameters.adaptive_thresh_win_size_step() < 1 {
        return Err(bad(format!(
            "adaptiveThreshWinSizeMin {} / Max {} / Step {}: windows of at least 3 px, min <= max, step >= 1",
            windows[0],
            windows[1],
            parameters.adaptive_thresh_win_size_step()
        )));
    }
    let rates = [
        parameters.min_marker_perimeter_rate(),
        parameters.max_marker_perimeter_rate(),
    ];
    if !(rates[0] > 0.0 && rates[1] >= rates[0] && rates.iter().all(|r| r.is_finite())) {
        return Err(bad(format!(
            "minMarkerPerimeterRate {} / maxMarkerPerimeterRate {}: positive, min <= max",
            rates[0], rates[1]
        )));
    }
    Ok(parameters)
}

/// A predefined dictionary by its OpenCV name.
pub fn predefined(name: &str) -> Result<Ptr<Dictionary>, ArucoError> {
    let (_, id) = DICTIONARY_NAMES
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| ArucoError::UnknownDictionary(name.to_string()))?;
    Ok(aruco::get_predefined_dictionary(*id)?)
}

/// Size (markers in it, bits per side) of a predefined dictionary name, for validation.
pub fn predefined_size(name: &str) -> Option<(usize, usize)> {
    let rest = name.strip_prefix("DICT_")?;
    let (bits, count) = rest.split_once('_')?;
    let side = bits.split_once('X')?.0.parse().ok()?;
    Some((count.parse().ok()?, side))
}

/// A custom dictionary from an OpenCV FileStorage file (as `tutorial_dict.yml`).
pub fn dictionary_file(path: &Path) -> Result<Ptr<Dictionary>, ArucoError> {
    let bad = || ArucoError::BadDictionaryFile {
        path: path.display().to_string(),
    };
    if !path.is_file() {
        return Err(bad());
    }
    if let Some(reason) = crate::io::storage::refusal(path) {
        return Err(ArucoError::Refused {
            path: path.display().to_string(),
            reason,
        });
    }
    let fs = FileStorage::new_def(
        path.to_string_lossy().as_ref(),
        opencv::core::FileStorage_Mode::READ as i32,
    )
    .map_err(|_| bad())?;
    let mut dictionary = Dictionary::new_def()?;
    let root = fs.root_def()?;
    // The sizes first: OpenCV allocates for them before it reads a marker.
    let count = |key: &str| root.get(key).and_then(|n| n.to_i32()).unwrap_or(-1);
    let (markers, bits) = (count("nmarkers"), count("markersize"));
    if !(1..=MAX_DICTIONARY_MARKERS).contains(&markers) || !(2..=MAX_MARKER_BITS).contains(&bits) {
        return Err(ArucoError::Refused {
            path: path.display().to_string(),
            reason: format!(
                "`nmarkers: {markers}`, `markersize: {bits}`: a dictionary holds 1 to {MAX_DICTIONARY_MARKERS} markers of 2 to {MAX_MARKER_BITS} bits a side (OpenCV's own hold up to 1024 markers of 4 to 7 bits)"
            ),
        });
    }
    if !dictionary.read_dictionary(&root).map_err(|_| bad())? {
        return Err(bad());
    }
    Ok(Ptr::new(dictionary))
}

/// Cells of a marker with its one-cell black border, row by row: `true` is black.
pub fn marker_cells(dictionary: &Ptr<Dictionary>, id: i32) -> Result<(usize, Vec<bool>), ArucoError> {
    let side = dictionary.marker_size() as usize + 2;
    let mut image = Mat::default();
    aruco::draw_marker(dictionary, id, side as i32, &mut image, 1)?;
    let mut cells = Vec::with_capacity(side * side);
    for r in 0..side {
        for c in 0..side {
            cells.push(*image.at_2d::<u8>(r as i32, c as i32)? < 128);
        }
    }
    Ok((side, cells))
}

/// One detected marker: id and corners (clockwise from top-left), pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    pub id: i32,
    pub corners_px: [[f64; 2]; 4],
}

/// Detects markers. With `subpixel_half_window_px`, corners are refined by OpenCV's
/// CORNER_REFINE_SUBPIX with that window (it must stay below a marker cell, or a
/// corner snaps to a bit's corner); without, they come out as OpenCV's defaults give
/// them (whole pixels).
pub fn detect(
    image: &Mat,
    dictionary: &Ptr<Dictionary>,
    subpixel_half_window_px: Option<i32>,
) -> Result<Vec<Marker>, ArucoError> {
    let mut parameters = DetectorParameters::create()?;
    if let Some(window) = subpixel_half_window_px {
        parameters.set_corner_refinement_method(aruco::CORNER_REFINE_SUBPIX);
        parameters.set_corner_refinement_win_size(window);
    }
    detect_with(image, dictionary, &parameters)
}

/// Detects markers with the given detector parameters, ids ascending.
pub fn detect_with(
    image: &Mat,
    dictionary: &Ptr<Dictionary>,
    parameters: &Ptr<DetectorParameters>,
) -> Result<Vec<Marker>, ArucoError> {
    let mut corners = Vector::<Vector<Point2f>>::new();
    let mut ids = Vector::<i32>::new();
    let mut rejected = Vector::<Vector<Point2f>>::new();
    aruco::detect_markers(image, dictionary, &mut corners, &mut ids, parameters, &mut rejected)?;
    let mut markers: Vec<Marker> = ids
        .iter()
        .zip(corners.iter())
        .map(|(id, c)| {
            let mut corners_px = [[0.0; 2]; 4];
            for (k, p) in c.iter().take(4).enumerate() {
                corners_px[k] = [p.x as f64, p.y as f64];
            }
            Marker { id, corners_px }
        })
        .collect();
    markers.sort_by_key(|m| m.id);
    Ok(markers)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detector_parameters_are_read_from_opencvs_file_and_checked() {
        let dir = std::env::temp_dir().join(format!("probecal-aruco-params-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = dir.join("detector_params.yml");
        // As OpenCV's samples write it; a key left out keeps its default.
        std::fs::write(
            &good,
            "%YAML:1.0\nadaptiveThreshWinSizeMin: 5\nadaptiveThreshWinSizeMax: 31\nadaptiveThreshWinSizeStep: 4\ncornerRefinementMethod: 1\n",
        )
        .unwrap();
        let p = detector_parameters(Some(&good)).unwrap();
        assert_eq!(p.adaptive_thresh_win_size_min(), 5);
        assert_eq!(p.adaptive_thresh_win_size_max(), 31);
        assert_eq!(p.corner_refinement_method(), 1);
        let defaults = detector_parameters(None).unwrap();
        assert_eq!(p.min_marker_perimeter_rate(), defaults.min_marker_perimeter_rate());
        let bad = dir.join("bad.yml");
        std::fs::write(&bad, "%YAML:1.0\nadaptiveThreshWinSizeMin: 1\n").unwrap();
        let e = detector_parameters(Some(&bad)).err().unwrap().to_string();
        assert!(e.contains("bad.yml") && e.contains("adaptiveThreshWinSizeMin 1"), "{e}");
        let e = detector_parameters(Some(&dir.join("none.yml")))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("no such file"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
