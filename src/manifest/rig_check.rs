//! The manifest's `rig` section: boards that can be told apart, known
//! dictionaries, sizes within bounds; ChArUco dictionary and detector files
//! resolved relative to the manifest.

use std::path::Path;

use super::checker::Checker;
use super::raw;
use crate::core::limits::{MAX_BOARD_CORNERS, MAX_BOARD_MARKERS};
use crate::spec::rig::{ArucoBoard, CharucoBoard, Rig};
use opencv::prelude::*;

/// The rig section: boards that can be told apart, known ArUco dictionaries.
pub(super) fn rig_section(c: &mut Checker<'_>, base: &Path, raw: &raw::RawManifest) -> Rig {
    match &raw.rig {
        Rig::Checkerboard {
            probe_board,
            phantom_board,
        } => {
            c.board("rig.checkerboard.probe_board", probe_board);
            c.board("rig.checkerboard.phantom_board", phantom_board);
            if probe_board.id_dots == phantom_board.id_dots {
                c.fail(
                    "rig.checkerboard.phantom_board.id_dots",
                    "the probe board and the phantom board must carry a different number of identification dots",
                );
            }
            for (name, b) in [("probe_board", probe_board), ("phantom_board", phantom_board)] {
                if !(1..=2).contains(&b.id_dots) {
                    c.fail(&format!("rig.checkerboard.{name}.id_dots"), "must be 1 or 2");
                }
            }
        }
        Rig::Aruco { .. } | Rig::Charuco { .. } => {}
    }
    aruco_section(c, &raw.rig);
    charuco_section(c, base, &raw.rig).unwrap_or_else(|| raw.rig.clone())
}

/// An ArUco grid rig: a known dictionary that holds both boards' ids, apart.
fn aruco_section(c: &mut Checker<'_>, rig: &Rig) {
    if let Rig::Aruco {
        dictionary,
        probe_board,
        phantom_board,
        min_markers,
        ..
    } = rig
    {
        let size = crate::detect::aruco::predefined_size(dictionary).filter(|_| {
            crate::detect::aruco::DICTIONARY_NAMES
                .iter()
                .any(|(n, _)| n == dictionary)
        });
        if size.is_none() {
            c.fail(
                "rig.aruco.dictionary",
                format!("unknown ArUco dictionary `{dictionary}` (OpenCV's names, e.g. DICT_4X4_50)"),
            );
        }
        for (name, b) in [("probe_board", probe_board), ("phantom_board", phantom_board)] {
            let field = format!("rig.aruco.{name}");
            if b.markers[0] < 1 || b.markers[1] < 1 || b.markers.iter().any(|&n| n > MAX_BOARD_MARKERS) {
                c.fail(
                    &format!("{field}.markers"),
                    format!("1x1 to {MAX_BOARD_MARKERS}x{MAX_BOARD_MARKERS} markers"),
                );
                continue;
            }
            c.positive(&format!("{field}.marker_mm"), b.marker_mm);
            c.at_least(&format!("{field}.separation_mm"), b.separation_mm, 0.0);
            let last = b.first_id as usize + b.markers[0] as usize * b.markers[1] as usize;
            if let Some((count, _)) = size {
                if last > count {
                    c.fail(
                        &format!("{field}.first_id"),
                        format!(
                            "ids {}..{} do not fit in {dictionary} ({count} markers)",
                            b.first_id,
                            last - 1
                        ),
                    );
                }
            }
        }
        let range = |b: &ArucoBoard| {
            let first = b.first_id as u64;
            first..first + b.markers[0].min(MAX_BOARD_MARKERS) as u64 * b.markers[1].min(MAX_BOARD_MARKERS) as u64
        };
        let (p, q) = (range(probe_board), range(phantom_board));
        if p.start < q.end && q.start < p.end {
            c.fail(
                "rig.aruco.phantom_board.first_id",
                format!(
                    "marker ids {}..{} overlap the probe board's {}..{}: the boards are told apart by id",
                    q.start,
                    q.end - 1,
                    p.start,
                    p.end - 1
                ),
            );
        }
        if *min_markers < 1 {
            c.fail("rig.aruco.min_markers", "must be at least 1");
        }
    }
}

/// A ChArUco rig, its files resolved relative to the manifest.
fn charuco_section(c: &mut Checker<'_>, base: &Path, rig: &Rig) -> Option<Rig> {
    if let Rig::Charuco {
        probe_board,
        phantom_board,
        min_corners,
        detector_params,
    } = rig
    {
        let probe = charuco_board(c, base, "rig.charuco.probe_board", probe_board);
        let phantom = charuco_board(c, base, "rig.charuco.phantom_board", phantom_board);
        let ids = |b: &CharucoBoard| b.first_id as u64..b.first_id as u64 + b.markers() as u64;
        let (p, q) = (ids(&probe), ids(&phantom));
        if probe.dictionary == phantom.dictionary && p.start < q.end && q.start < p.end {
            c.fail(
                "rig.charuco.phantom_board.first_id",
                format!(
                    "marker ids {}..{} overlap the probe board's {}..{} in one dictionary: the boards are told apart by id",
                    q.start,
                    q.end.saturating_sub(1),
                    p.start,
                    p.end.saturating_sub(1)
                ),
            );
        }
        if *min_corners < 4 {
            c.fail(
                "rig.charuco.min_corners",
                format!("a pose needs at least 4 corners, got {min_corners}"),
            );
        }
        let detector_params = detector_params.as_ref().map(|file| {
            let path = c.existing("rig.charuco.detector_params", base, file, false);
            if path.is_file() {
                if let Err(e) = crate::detect::aruco::detector_parameters(Some(&path)) {
                    c.fail("rig.charuco.detector_params", e.to_string());
                }
            }
            path.to_string_lossy().into_owned()
        });
        return Some(Rig::Charuco {
            probe_board: probe,
            phantom_board: phantom,
            min_corners: *min_corners,
            detector_params,
        });
    }
    None
}

/// One ChArUco board's sizes, dictionary and ids; a dictionary file comes back
/// resolved relative to the manifest.
fn charuco_board(c: &mut Checker<'_>, base: &Path, field: &str, board: &CharucoBoard) -> CharucoBoard {
    let mut resolved = board.clone();
    let [x, y] = board.squares;
    let most = MAX_BOARD_CORNERS + 1;
    if x < 2 || y < 2 || x > most || y > most {
        c.fail(
            &format!("{field}.squares"),
            format!("2x2 to {most}x{most} squares, got {x}x{y}"),
        );
        return resolved;
    }
    c.positive(&format!("{field}.square_mm"), board.square_mm);
    if !(board.marker_mm.is_finite() && board.marker_mm > 0.0 && board.marker_mm < board.square_mm) {
        c.fail(
            &format!("{field}.marker_mm"),
            format!(
                "a marker is smaller than its square ({} mm), got {}",
                board.square_mm, board.marker_mm
            ),
        );
    }
    let dictionary = if board.dictionary.starts_with("DICT_") {
        crate::detect::aruco::predefined(&board.dictionary)
    } else {
        let path = c.existing(&format!("{field}.dictionary"), base, &board.dictionary, false);
        resolved.dictionary = path.to_string_lossy().into_owned();
        if !path.is_file() {
            return resolved;
        }
        crate::detect::aruco::dictionary_file(&path)
    };
    match dictionary {
        Ok(d) => {
            let available = d.bytes_list().rows().max(0) as u64;
            let last = board.first_id as u64 + board.markers() as u64;
            if last > available {
                c.fail(
                    &format!("{field}.first_id"),
                    format!(
                        "a {x}x{y} board from id {} needs ids up to {}, the dictionary `{}` has {available}",
                        board.first_id,
                        last - 1,
                        board.dictionary
                    ),
                );
            }
        }
        Err(e) => c.fail(&format!("{field}.dictionary"), e.to_string()),
    }
    resolved
}
