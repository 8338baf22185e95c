//! Stage 4 for multi-sphere phantoms: which arc is which sphere, and the
//! calibration every arc's edge gives on its own sphere.
//!
//! From a rough `marker_T_image` (the manifest's) each frame's spheres are
//! predicted where the plane cuts them: the circle centred on the sphere
//! centre's projection, of radius `√(R² − d²)` for a plane `d` from the centre.
//! In the first round the predicted layout is slid over the detected arcs (the
//! in-plane shift that lines up the most arcs of matching radius wins, which
//! absorbs the start's error; a frame needs two arcs for that); arcs are paired
//! with the nearest prediction of similar radius within a gate, and
//! `marker_T_image` is refined on every paired arc's edge points at once (the
//! sphere fit, each arc on its own sphere), starting from the rough calibration
//! moved by the frames' median shift (a start ten millimetres off in the plane
//! would otherwise settle in a false minimum). Prediction, pairing and
//! refinement repeat, without the shift, until the pairing stops changing.
//! With `fit_pixel_size` the fit also estimates the pixel size, and the next
//! round places the arcs with it.
//!
//! Each paired arc becomes a point pair: its centre, placed off the image plane
//! at its sphere centre's elevation under the fit, and the sphere centre.

use nalgebra::Point3;

use crate::core::geometry::Rigid;
use crate::estimate::correspondence::{Correspondence, Observed};
use crate::estimate::image_to_probe::Target;
use crate::estimate::sphere_fit::{self, ArcFrame, KnownSphere, SphereFit, SphereFitError, SphereSettings};

/// A detected arc: its circle and edge pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct SeenArc {
    pub centre_px: [f64; 2],
    pub radius_mm: f64,
    pub edge_px: Vec<[f64; 2]>,
}

/// One frame's arcs and poses.
#[derive(Debug, Clone)]
pub struct FrameArcs {
    pub frame: usize,
    pub arcs: Vec<SeenArc>,
    pub camera_T_marker: Rigid,
    pub camera_T_phantom: Rigid,
}

impl FrameArcs {
    fn phantom_T_marker(&self) -> Rigid {
        self.camera_T_phantom.inverse() * self.camera_T_marker
    }
}

/// A sphere of the phantom with its name.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedSphere {
    pub name: String,
    pub sphere: KnownSphere,
}

/// Why a frame's arcs were not paired with spheres.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SphereRejection {
    #[error("none of the {arcs} arcs lies near a sphere the plane cuts ({predicted} predicted)")]
    NoArcOnASphere { arcs: usize, predicted: usize },
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SphereMatchError {
    #[error("only {found} frames have arcs paired with spheres (need {needed})")]
    TooFewFrames { found: usize, needed: usize },
    #[error(transparent)]
    Fit(#[from] SphereFitError),
}

/// The outcome: frames with their paired arcs, frames left out with the reason.
#[derive(Debug, Clone)]
pub struct SphereMatching {
    pub correspondences: Vec<Correspondence>,
    /// Per used frame: the sphere name and arc index (into the frame's arcs) of
    /// each feature, in the order of its features.
    pub labels: Vec<(usize, Vec<(String, usize)>)>,
    pub rejected: Vec<(usize, SphereRejection)>,
    pub fit: SphereFit,
    pub rounds: usize,
}

/// An arc's centre must lie this close to its sphere's predicted centre (mm).
const GATE_MM: f64 = 3.0;
/// And its radius this close to the predicted radius (mm).
const RADIUS_GATE_MM: f64 = 2.5;
/// The first round's shift absorbs a start at most this far off in the plane (mm).
const MAX_SHIFT_MM: f64 = 15.0;
const MAX_ROUNDS: usize = 12;
/// Edge points of one arc count as this many points in the fit.
const POINTS_PER_ARC: f64 = 20.0;

/// A sphere's circle in the plane under a calibration: centre (image mm),
/// radius (mm) and the centre's elevation (image z, mm); `None` when the plane
/// misses it.
fn predict(frame: &FrameArcs, marker_T_image: &Rigid, sphere: &KnownSphere) -> Option<([f64; 2], f64, f64)> {
    let image_T_phantom = (frame.phantom_T_marker() * marker_T_image).inverse();
    let p = image_T_phantom * sphere.centre_in_phantom_mm;
    let r2 = sphere.radius_mm.powi(2) - p.z * p.z;
    (r2 > 0.0).then(|| ([p.x, p.y], r2.sqrt(), p.z))
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// `(arc, sphere)` pairs of one frame, sorted by arc.
fn pair_frame(
    frame: &FrameArcs,
    marker_T_image: &Rigid,
    spheres: &[NamedSphere],
    spacing: [f64; 2],
    radius_scale: f64,
    shift: bool,
) -> (Vec<(usize, usize)>, usize, Option<[f64; 2]>) {
    let predicted: Vec<(usize, [f64; 2], f64)> = spheres
        .iter()
        .enumerate()
        .filter_map(|(k, s)| predict(frame, marker_T_image, &s.sphere).map(|(c, r, _)| (k, c, r)))
        .collect();
    let seen: Vec<([f64; 2], f64)> = frame
        .arcs
        .iter()
        .map(|a| {
            (
                [a.centre_px[0] * spacing[0], a.centre_px[1] * spacing[1]],
                a.radius_mm * radius_scale,
            )
        })
        .collect();
    let candidates = |offset: [f64; 2]| {
        let mut c: Vec<(f64, usize, usize)> = Vec::new();
        for (j, (centre, radius)) in seen.iter().enumerate() {
            for (k, p, r) in &predicted {
                let d = distance(*centre, [p[0] + offset[0], p[1] + offset[1]]);
                if d < GATE_MM && (radius - r).abs() < RADIUS_GATE_MM {
                    c.push((d, j, *k));
                }
            }
        }
        c.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        let mut total = 0.0;
        for (d, j, k) in c {
            if pairs.iter().all(|(pj, pk)| *pj != j && *pk != k) {
                pairs.push((j, k));
                total += d;
            }
        }
        pairs.sort();
        (pairs, total)
    };
    let mut offset = [0.0, 0.0];
    if shift {
        // Every arc-to-prediction offset is a candidate shift; the one pairing the
        // most arcs (then the closest) wins. One arc alone cannot fix a shift.
        let mut best: Option<(usize, f64, [f64; 2])> = None;
        for (centre, radius) in &seen {
            for (_, p, r) in &predicted {
                let s = [centre[0] - p[0], centre[1] - p[1]];
                if (radius - r).abs() >= RADIUS_GATE_MM || distance(s, [0.0, 0.0]) > MAX_SHIFT_MM {
                    continue;
                }
                let (pairs, total) = candidates(s);
                let better = match best {
                    None => true,
                    Some((n, t, _)) => pairs.len() > n || (pairs.len() == n && total < t),
                };
                if better {
                    best = Some((pairs.len(), total, s));
                }
            }
        }
        match best {
            Some((n, _, s)) if n >= 2 => offset = s,
            _ => return (Vec::new(), predicted.len(), None),
        }
    }
    (candidates(offset).0, predicted.len(), shift.then_some(offset))
}

/// Every paired arc as the sphere fit takes it.
fn paired_arcs(frames: &[FrameArcs], pairs: &[Vec<(usize, usize)>]) -> Vec<ArcFrame> {
    frames
        .iter()
        .zip(pairs)
        .flat_map(|(f, p)| {
            p.iter().map(move |(j, k)| ArcFrame {
                frame: f.frame,
                sphere: *k,
                edge_px: f.arcs[*j].edge_px.clone(),
                camera_T_marker: f.camera_T_marker,
                camera_T_phantom: f.camera_T_phantom,
            })
        })
        .collect()
}

/// The point pairs of the frames with a paired arc (each arc's centre on its
/// sphere's centre, at the fit's elevation), their arcs' sphere names, and the
/// frames with none.
#[allow(clippy::type_complexity)]
fn paired(
    frames: &[FrameArcs],
    spheres: &[NamedSphere],
    pairs: &[Vec<(usize, usize)>],
    predicted_counts: &[usize],
    fit: &SphereFit,
) -> (
    Vec<Correspondence>,
    Vec<(usize, Vec<(String, usize)>)>,
    Vec<(usize, SphereRejection)>,
) {
    let mut correspondences = Vec::new();
    let mut labels = Vec::new();
    let mut rejected = Vec::new();
    for ((f, p), predicted) in frames.iter().zip(pairs).zip(predicted_counts) {
        if p.is_empty() {
            rejected.push((
                f.frame,
                SphereRejection::NoArcOnASphere {
                    arcs: f.arcs.len(),
                    predicted: *predicted,
                },
            ));
            continue;
        }
        let mut features = Vec::new();
        let mut names = Vec::new();
        for (j, k) in p {
            let sphere = &spheres[*k].sphere;
            let elevation_mm = predict(f, &fit.marker_T_image, sphere).map_or(0.0, |(_, _, z)| z);
            features.push(Observed {
                pixel: f.arcs[*j].centre_px,
                elevation_mm,
                target_in_phantom: Target::Point(Point3::from(sphere.centre_in_phantom_mm.coords)),
            });
            names.push((spheres[*k].name.clone(), *j));
        }
        correspondences.push(Correspondence {
            frame: f.frame,
            features,
            camera_T_marker: f.camera_T_marker,
            camera_T_phantom: f.camera_T_phantom,
        });
        labels.push((f.frame, names));
    }
    (correspondences, labels, rejected)
}

/// Pairs arcs with spheres and fits `marker_T_image` on every paired arc's edge.
pub fn match_and_solve(
    frames: &[FrameArcs],
    spheres: &[NamedSphere],
    start: &Rigid,
    spacing: [f64; 2],
    fit_pixel_size: bool,
    min_frames: usize,
) -> Result<SphereMatching, SphereMatchError> {
    let settings = SphereSettings {
        spheres: spheres.iter().map(|s| s.sphere).collect(),
        spacing_mm_per_px: spacing,
        elevation_prior_sd_mm: None,
        fit_radius_offset: false,
        points_per_frame: POINTS_PER_ARC,
        fit_pixel_size,
    };
    let mut marker_T_image = *start;
    // The pixel size arcs are placed with (the fitted one, with `fit_pixel_size`);
    // the detector's radii, measured with `spacing`, scale with it.
    let mut current = spacing;
    let mut radius_scale = 1.0;
    let mut previous: Option<Vec<Vec<(usize, usize)>>> = None;
    let mut fit: Option<SphereFit> = None;
    let mut rounds = 0;
    let mut predicted_counts = vec![0; frames.len()];
    for round in 0..MAX_ROUNDS {
        rounds = round + 1;
        let mut shifts: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
        let pairs: Vec<Vec<(usize, usize)>> = frames
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let (pairs, predicted, shift) =
                    pair_frame(f, &marker_T_image, spheres, current, radius_scale, round == 0);
                predicted_counts[i] = predicted;
                if let Some(s) = shift.filter(|_| !pairs.is_empty()) {
                    shifts[0].push(s[0]);
                    shifts[1].push(s[1]);
                }
                pairs
            })
            .collect();
        if round == 0 && !shifts[0].is_empty() {
            // The fit starts where the frames' shifts put the plane: the image
            // origin moved by their median against it.
            let [x, y] = shifts.map(|mut v| crate::core::stats::median(&mut v));
            marker_T_image *= Rigid::translation(-x, -y, 0.0);
        }
        if previous.as_ref() == Some(&pairs) && fit.is_some() {
            break;
        }
        let found = pairs.iter().filter(|p| !p.is_empty()).count();
        if found < min_frames.max(3) {
            return Err(SphereMatchError::TooFewFrames {
                found,
                needed: min_frames.max(3),
            });
        }
        let arcs = paired_arcs(frames, &pairs);
        let refined = sphere_fit::refine(&marker_T_image, &arcs, &settings)?;
        marker_T_image = refined.marker_T_image;
        current = refined.spacing_mm_per_px;
        radius_scale = ((current[0] * current[1]) / (spacing[0] * spacing[1])).sqrt();
        fit = Some(refined);
        previous = Some(pairs);
    }
    let (Some(fit), Some(pairs)) = (fit, previous) else {
        return Err(SphereMatchError::TooFewFrames {
            found: 0,
            needed: min_frames.max(3),
        });
    };
    let (correspondences, labels, rejected) = paired(frames, spheres, &pairs, &predicted_counts, &fit);
    Ok(SphereMatching {
        correspondences,
        labels,
        rejected,
        fit,
        rounds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::{pixel_to_image_mm, rigid_from_axis_angle};
    use crate::core::rng::Rng;
    use nalgebra::Vector3;

    /// Three spheres; frames whose planes cut them at their own offsets, with
    /// each cut sphere's arc (the dome's upper half) and its circle.
    fn planted(seed: u64) -> (Rigid, Vec<NamedSphere>, Vec<FrameArcs>) {
        let marker_T_image = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 0.01), Vector3::new(-20.0, 160.0, 25.0));
        let camera_T_phantom = rigid_from_axis_angle(Vector3::new(2.0, 0.1, 0.2), Vector3::new(-100.0, 80.0, 500.0));
        let spheres: Vec<NamedSphere> = [(-22.0, -5.0, -3.0), (0.0, 0.0, 3.0), (22.0, 5.0, 0.0)]
            .iter()
            .enumerate()
            .map(|(k, (x, y, z))| NamedSphere {
                name: format!("s{k}"),
                sphere: KnownSphere {
                    centre_in_phantom_mm: Point3::new(60.0 + x, 45.0 + y, -40.0 + z),
                    radius_mm: 10.0,
                },
            })
            .collect();
        let spacing = [0.2, 0.2];
        let mut rng = Rng::new(seed);
        let mut frames = Vec::new();
        for frame in 0..30 {
            // The plane: image x along the phantom's x, image z along its y, the
            // middle sphere's centre at an image point, tilted a little.
            let tilt = Vector3::new(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.1, 0.1));
            let base = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0,
            ));
            let phantom_R_image = nalgebra::UnitQuaternion::from_rotation_matrix(&base)
                * rigid_from_axis_angle(tilt, Vector3::zeros()).rotation;
            let at = pixel_to_image_mm([rng.uniform(300.0, 400.0), rng.uniform(200.0, 300.0)], spacing).coords
                + Vector3::new(0.0, 0.0, rng.normal(0.0, 0.5));
            let t = spheres[1].sphere.centre_in_phantom_mm.coords - phantom_R_image * at;
            let phantom_T_image = Rigid::from_parts(t.into(), phantom_R_image);
            let camera_T_marker = camera_T_phantom * phantom_T_image * marker_T_image.inverse();
            let image_T_phantom = phantom_T_image.inverse();
            let mut arcs = Vec::new();
            for s in &spheres {
                let p = image_T_phantom * s.sphere.centre_in_phantom_mm;
                if p.z.abs() >= 0.85 * s.sphere.radius_mm {
                    continue;
                }
                let r = (s.sphere.radius_mm.powi(2) - p.z * p.z).sqrt();
                let edge_px = (0..50)
                    .map(|i| {
                        let a = std::f64::consts::PI * (1.2 + 0.6 * i as f64 / 49.0);
                        [
                            (p.x + r * a.cos()) / spacing[0] + rng.normal(0.0, 0.2),
                            (p.y + r * a.sin()) / spacing[1] + rng.normal(0.0, 0.2),
                        ]
                    })
                    .collect();
                arcs.push(SeenArc {
                    centre_px: [p.x / spacing[0], p.y / spacing[1]],
                    radius_mm: r,
                    edge_px,
                });
            }
            // The detector lists arcs strongest first, not in the spheres' order.
            arcs.reverse();
            frames.push(FrameArcs {
                frame,
                arcs,
                camera_T_marker,
                camera_T_phantom,
            });
        }
        (marker_T_image, spheres, frames)
    }

    #[test]
    fn arcs_find_their_spheres_from_a_start_5_mm_and_1_4_degrees_off() {
        let (truth, spheres, frames) = planted(4);
        let off = rigid_from_axis_angle(Vector3::new(0.01, -0.01, 0.02), Vector3::new(4.0, -3.0, 2.0));
        let m = match_and_solve(&frames, &spheres, &(truth * off), [0.2, 0.2], false, 10).unwrap();
        assert!(m.rejected.is_empty(), "{:?}", m.rejected);
        // Every arc is paired with the sphere it was drawn from (arcs were listed
        // in reverse: the first arc of a frame is its last cut sphere).
        for (frame, labels) in &m.labels {
            let f = &frames[*frame];
            assert_eq!(labels.len(), f.arcs.len(), "frame {frame}");
            for (name, j) in labels {
                let k: usize = name[1..].parse().unwrap();
                let s = &spheres[k].sphere;
                let p = (f.phantom_T_marker() * truth).inverse() * s.centre_in_phantom_mm;
                let c = f.arcs[*j].centre_px;
                assert!(
                    (c[0] * 0.2 - p.x).abs() < 1e-6 && (c[1] * 0.2 - p.y).abs() < 1e-6,
                    "frame {frame}: {name}"
                );
            }
        }
        let t = (m.fit.marker_T_image.translation.vector - truth.translation.vector).norm();
        let a = m.fit.marker_T_image.rotation.angle_to(&truth.rotation).to_degrees();
        assert!(t < 0.1 && a < 0.05, "{t} mm, {a}°");
        // The pairs carry each sphere centre's elevation under the fit.
        let horn = crate::estimate::correspondence::solve(
            &m.correspondences,
            [0.2, 0.2],
            crate::estimate::horn::Variant::Rigid,
            None,
        )
        .unwrap();
        let th = (horn.target_T_source.translation.vector - truth.translation.vector).norm();
        assert!(th < 0.2, "Horn on the elevated pairs: {th} mm");
    }

    /// How far `m`'s fit is from `truth`: mm and degrees.
    fn off_by(m: &SphereMatching, truth: &Rigid) -> (f64, f64) {
        let t = (m.fit.marker_T_image.translation.vector - truth.translation.vector).norm();
        (t, m.fit.marker_T_image.rotation.angle_to(&truth.rotation).to_degrees())
    }

    #[test]
    fn a_start_11_mm_off_in_the_plane_is_moved_by_the_frames_shift_before_the_first_fit() {
        let (truth, spheres, frames) = planted(6);
        let off = rigid_from_axis_angle(Vector3::new(0.0, 0.0, 0.02), Vector3::new(7.0, 9.0, 0.0));
        let m = match_and_solve(&frames, &spheres, &(truth * off), [0.2, 0.2], false, 10).unwrap();
        assert!(m.rejected.is_empty(), "{:?}", m.rejected);
        let (t, a) = off_by(&m, &truth);
        assert!(t < 0.1 && a < 0.05, "{t} mm, {a}°");
    }

    #[test]
    fn depths_shown_4_percent_too_deep_are_absorbed_by_the_fitted_pixel_size() {
        let (truth, spheres, mut frames) = planted(7);
        // A medium 4 % slower than the scanner assumes: every echo shown 4 % deeper.
        for f in &mut frames {
            for a in &mut f.arcs {
                a.centre_px[1] *= 1.04;
                a.radius_mm *= 1.02;
                for p in &mut a.edge_px {
                    p[1] *= 1.04;
                }
            }
        }
        let off = rigid_from_axis_angle(Vector3::new(0.01, -0.01, 0.02), Vector3::new(4.0, -3.0, 2.0));
        let m = match_and_solve(&frames, &spheres, &(truth * off), [0.2, 0.2], true, 10).unwrap();
        assert!(m.rejected.is_empty(), "{:?}", m.rejected);
        let [sx, sy] = m.fit.spacing_mm_per_px;
        assert!(
            (sx / 0.2 - 1.0).abs() < 2e-3 && (sy * 1.04 / 0.2 - 1.0).abs() < 2e-3,
            "{sx} {sy}"
        );
        let (t, a) = off_by(&m, &truth);
        assert!(t < 0.1 && a < 0.05, "{t} mm, {a}°");
        // Held at the nominal size, the same arcs pull the fit millimetres off.
        let nominal = match_and_solve(&frames, &spheres, &(truth * off), [0.2, 0.2], false, 10);
        let (t, _) = off_by(&nominal.unwrap(), &truth);
        assert!(t > 1.0, "{t} mm");
    }

    #[test]
    fn a_start_beyond_the_shift_pairs_nothing() {
        let (truth, spheres, frames) = planted(5);
        let off = rigid_from_axis_angle(Vector3::zeros(), Vector3::new(40.0, 0.0, 0.0));
        assert!(matches!(
            match_and_solve(&frames, &spheres, &(truth * off), [0.2, 0.2], false, 10),
            Err(SphereMatchError::TooFewFrames { .. })
        ));
    }
}
