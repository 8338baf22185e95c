//! Stage 4 for wire phantoms: which B-scan dot is which wire, and the calibration
//! they give together.
//!
//! From a rough `marker_T_image` (the manifest's), each frame's wires are
//! predicted where their axes cross the B-scan plane. The predicted pattern is
//! slid over the detected dots (the in-plane shift that lines up the most dots
//! wins, which absorbs the start's error), dots are paired with the nearest
//! prediction within a gate, and `marker_T_image` is refined on point-to-line
//! distances. Prediction, pairing and refinement repeat until the pairing stops
//! changing. A dot where two wires' predictions meet (the plane passes their
//! crossing) constrains both lines: at the crossing that pins it to the crossing
//! point exactly.

use nalgebra::{Point3, Vector3};

use crate::core::geometry::{line_meets_image_plane, pixel_to_image_mm, Rigid};
use crate::estimate::correspondence::{self, Correspondence, Observed};
use crate::estimate::horn::{HornError, HornFit, Variant};
use crate::estimate::image_to_probe::Target;

/// A wire's axis in the phantom frame.
#[derive(Debug, Clone, PartialEq)]
pub struct WireAxis {
    pub name: String,
    pub start_in_phantom_mm: Point3<f64>,
    pub end_in_phantom_mm: Point3<f64>,
}

impl WireAxis {
    fn direction(&self) -> Vector3<f64> {
        (self.end_in_phantom_mm - self.start_in_phantom_mm).normalize()
    }
}

/// One frame's detected dots and poses.
#[derive(Debug, Clone)]
pub struct FrameWireDots {
    pub frame: usize,
    pub dots_px: Vec<[f64; 2]>,
    pub camera_T_marker: Rigid,
    pub camera_T_phantom: Rigid,
}

/// The outcome: frames with their paired dots, and frames left out with the reason.
#[derive(Debug, Clone)]
pub struct Matching {
    pub correspondences: Vec<Correspondence>,
    /// Per used frame: the wire name of each feature, in the order of its features.
    pub labels: Vec<(usize, Vec<String>)>,
    pub rejected: Vec<(usize, WireRejection)>,
    pub fit: HornFit,
    pub rounds: usize,
}

/// Why a frame's dots were not paired with the wires.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireRejection {
    #[error("{found} of {wires} wires found near their predicted dots ({dots} dots detected; {needed} needed)")]
    TooFewWires {
        found: usize,
        wires: usize,
        dots: usize,
        needed: usize,
    },
}

/// Fewest wires a frame must show near their predictions to be used.
pub const MIN_WIRES_PER_FRAME: usize = 3;
/// Largest in-plane shift between prediction and dots: first round, later rounds, mm.
const SHIFT_FIRST_MM: f64 = 25.0;
const SHIFT_LATER_MM: f64 = 3.0;
/// A dot pairs with a prediction within this distance after the shift, mm.
const GATE_MM: f64 = 2.5;
const MAX_ROUNDS: usize = 8;

/// Where each wire's axis crosses the image plane, in image millimetres.
fn predict(wires: &[WireAxis], image_T_phantom: &Rigid) -> Vec<Option<[f64; 2]>> {
    wires
        .iter()
        .map(|w| {
            let p = image_T_phantom * w.start_in_phantom_mm;
            let q = image_T_phantom * w.end_in_phantom_mm;
            let (_, hit) = line_meets_image_plane(&p, &q)?;
            Some([hit.x, hit.y])
        })
        .collect()
}

/// Pairs dots (mm) with predictions: returns, per dot, the wires it is paired with.
fn pair(dots_mm: &[[f64; 2]], predicted: &[Option<[f64; 2]>], max_shift: f64) -> Vec<Vec<usize>> {
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    // The shift that lines up the most predictions with dots (ties: smaller total distance).
    let mut best = (0usize, f64::MAX, [0.0, 0.0]);
    for d in dots_mm {
        for p in predicted.iter().flatten() {
            let shift = [d[0] - p[0], d[1] - p[1]];
            if shift[0].hypot(shift[1]) > max_shift {
                continue;
            }
            let mut count = 0;
            let mut total = 0.0;
            for q in predicted.iter().flatten() {
                let moved = [q[0] + shift[0], q[1] + shift[1]];
                if let Some(m) = dots_mm.iter().map(|d| dist(*d, moved)).min_by(f64::total_cmp) {
                    if m < GATE_MM {
                        count += 1;
                        total += m;
                    }
                }
            }
            if count > best.0 || (count == best.0 && total < best.1) {
                best = (count, total, shift);
            }
        }
    }
    let shift = best.2;
    let mut paired = vec![Vec::new(); dots_mm.len()];
    // Each wire takes its nearest dot within the gate; two wires may share a dot
    // (their crossing), a dot is never split between far-apart predictions.
    for (j, p) in predicted.iter().enumerate() {
        let Some(p) = p else { continue };
        let moved = [p[0] + shift[0], p[1] + shift[1]];
        let nearest = dots_mm
            .iter()
            .enumerate()
            .map(|(i, d)| (i, dist(*d, moved)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, m)) = nearest {
            if m < GATE_MM {
                paired[i].push(j);
            }
        }
    }
    paired
}

/// Pairs dots with wires and solves `marker_T_image`, from `start`.
pub fn match_and_solve(
    frames: &[FrameWireDots],
    wires: &[WireAxis],
    start: &Rigid,
    spacing: [f64; 2],
    min_frames: usize,
) -> Result<Matching, HornError> {
    let mut marker_T_image = *start;
    let mut previous: Option<Vec<(usize, Vec<String>)>> = None;
    for round in 1..=MAX_ROUNDS {
        let max_shift = if round == 1 { SHIFT_FIRST_MM } else { SHIFT_LATER_MM };
        let mut correspondences = Vec::new();
        let mut labels = Vec::new();
        let mut rejected = Vec::new();
        for f in frames {
            let image_T_phantom = marker_T_image.inverse() * f.camera_T_marker.inverse() * f.camera_T_phantom;
            let predicted = predict(wires, &image_T_phantom);
            let dots_mm: Vec<[f64; 2]> = f
                .dots_px
                .iter()
                .map(|d| {
                    let p = pixel_to_image_mm(*d, spacing);
                    [p.x, p.y]
                })
                .collect();
            let paired = pair(&dots_mm, &predicted, max_shift);
            let found: usize = paired.iter().map(Vec::len).sum();
            if found < MIN_WIRES_PER_FRAME.min(wires.len()) {
                rejected.push((
                    f.frame,
                    WireRejection::TooFewWires {
                        found,
                        wires: wires.len(),
                        dots: f.dots_px.len(),
                        needed: MIN_WIRES_PER_FRAME.min(wires.len()),
                    },
                ));
                continue;
            }
            let mut features = Vec::new();
            let mut names = Vec::new();
            for (i, js) in paired.iter().enumerate() {
                for &j in js {
                    let w = &wires[j];
                    features.push(Observed {
                        pixel: f.dots_px[i],
                        elevation_mm: 0.0,
                        target_in_phantom: Target::Line(w.start_in_phantom_mm, w.direction()),
                    });
                    names.push(w.name.clone());
                }
            }
            labels.push((f.frame, names));
            correspondences.push(Correspondence {
                frame: f.frame,
                features,
                camera_T_marker: f.camera_T_marker,
                camera_T_phantom: f.camera_T_phantom,
            });
        }
        if correspondences.len() < min_frames {
            return Err(HornError::TooFewPairs(correspondences.len()));
        }
        let fit = correspondence::solve(&correspondences, spacing, Variant::Rigid, Some(&marker_T_image))?;
        marker_T_image = fit.target_T_source;
        let stable = previous.as_ref() == Some(&labels);
        if stable || round == MAX_ROUNDS {
            return Ok(Matching {
                correspondences,
                labels,
                rejected,
                fit,
                rounds: round,
            });
        }
        previous = Some(labels);
    }
    Err(HornError::Refinement("no pairing rounds ran".into()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;

    #[test]
    fn pairs_a_shifted_pattern_and_shares_a_crossing_dot() {
        let predicted = vec![
            Some([10.0, 50.0]),
            Some([40.0, 55.0]),
            Some([24.0, 52.0]),
            Some([24.6, 52.0]),
        ];
        // The true dots sit 7 mm to the right; one clutter dot; the crossing wires share one dot.
        let dots = vec![[17.0, 50.0], [47.0, 55.0], [31.3, 52.0], [30.0, 70.0]];
        let paired = pair(&dots, &predicted, 25.0);
        assert_eq!(paired, vec![vec![0], vec![1], vec![2, 3], vec![]]);
        // Within the later rounds' small shift, the pattern is not found.
        let paired = pair(&dots, &predicted, 3.0);
        assert!(paired.iter().all(Vec::is_empty), "{paired:?}");
    }

    #[test]
    fn predicts_where_a_wire_crosses_the_plane() {
        let wire = WireAxis {
            name: "w".into(),
            start_in_phantom_mm: Point3::new(5.0, 7.0, -10.0),
            end_in_phantom_mm: Point3::new(5.0, 7.0, 10.0),
        };
        let p = predict(std::slice::from_ref(&wire), &Rigid::identity());
        assert_eq!(p, vec![Some([5.0, 7.0])]);
        let moved = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(1.0, 2.0, 0.0));
        assert_eq!(predict(&[wire], &moved), vec![Some([6.0, 9.0])]);
    }
}
