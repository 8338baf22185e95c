//! Applies a rig's error sources (`spec::realism`) to the ideal lab: the lens
//! and its calibration set, the phantom as built against the phantom as
//! measured, the boards as printed, and per frame the probe board's wobble on
//! its mount, the hand's motion between the B-scan and the photo, and during the
//! photo's exposure.

use nalgebra::Vector3;

use super::camera_render::BoardMotion;
use super::scene::Scene;
use crate::core::geometry::Rigid;
use crate::core::rng::Rng;
use crate::spec::phantom::Phantom;
use crate::spec::realism::Realism;
use crate::spec::render::RenderSpec;

/// Stream labels of the realism draws (apart from the ideal lab's streams).
const SYSTEMATIC_STREAM: u64 = 1 << 40;
const FRAME_STREAM: u64 = 1 << 41;

/// The spec as rendered: the lens's distortion and calibration views, and the
/// beam's width, replace the ideal rig's.
pub fn effective_spec(spec: &RenderSpec) -> RenderSpec {
    let mut spec = spec.clone();
    if let Some(lens) = spec.realism.as_ref().and_then(|r| r.lens.clone()) {
        spec.camera.distortion = lens.distortion;
        spec.calibration_views = lens.calibration_views;
    }
    if let Some(beam) = spec.realism.as_ref().and_then(|r| r.beam_width.clone()) {
        spec.bscan.slice_thickness_mm = beam.slice_thickness_mm;
    }
    spec
}

/// The rig's error sources (none for the ideal lab).
pub fn of(spec: &RenderSpec) -> Realism {
    spec.realism.clone().unwrap_or_default()
}

/// Systematic draws of one dataset: the phantom as built and the boards' print scales.
pub struct Systematic {
    /// The phantom as it is (the manifest has it as measured).
    pub phantom: Phantom,
    /// True size per nominal size of the probe board and the phantom board.
    pub print_scale: [f64; 2],
    /// Bow (sagitta over the width, mm) of the probe board and the phantom board.
    pub bow_mm: [f64; 2],
}

fn shifted(p: [f64; 3], rng: &mut Rng, sd: f64) -> [f64; 3] {
    p.map(|v| v + rng.normal(0.0, sd))
}

pub fn systematic(spec: &RenderSpec, measured: &Phantom) -> Systematic {
    let realism = of(spec);
    let mut rng = Rng::fork(spec.seed, SYSTEMATIC_STREAM);
    let mut board_rng = Rng::fork(spec.seed, SYSTEMATIC_STREAM + 1);
    let phantom = match &realism.phantom_measurement {
        None => measured.clone(),
        Some(m) => {
            let (sd, rsd) = (m.position_sd_mm, m.radius_sd_mm);
            let mut p = measured.clone();
            match &mut p {
                Phantom::Hemisphere {
                    centre_in_phantom_mm,
                    radius_mm,
                } => {
                    *centre_in_phantom_mm = shifted(*centre_in_phantom_mm, &mut rng, sd);
                    *radius_mm += rng.normal(0.0, rsd);
                }
                Phantom::Point {
                    position_in_phantom_mm, ..
                } => *position_in_phantom_mm = shifted(*position_in_phantom_mm, &mut rng, sd),
                Phantom::Spheres { spheres } => {
                    for s in spheres.iter_mut() {
                        s.centre_in_phantom_mm = shifted(s.centre_in_phantom_mm, &mut rng, sd);
                        s.radius_mm += rng.normal(0.0, rsd);
                    }
                }
                Phantom::FourWire { wires, .. } => {
                    for w in wires.iter_mut() {
                        w.start_in_phantom_mm = shifted(w.start_in_phantom_mm, &mut rng, sd);
                        w.end_in_phantom_mm = shifted(w.end_in_phantom_mm, &mut rng, sd);
                    }
                }
            }
            p
        }
    };
    let print_scale = match &realism.board_print {
        None => [1.0, 1.0],
        Some(b) => [0, 1].map(|_| 1.0 + board_rng.normal(0.0, b.scale_sd)),
    };
    let mut warp_rng = Rng::fork(spec.seed, SYSTEMATIC_STREAM + 2);
    let bow_mm = match &realism.board_warp {
        None => [0.0, 0.0],
        Some(w) => [0, 1].map(|_| warp_rng.normal(0.0, w.bow_sd_mm)),
    };
    Systematic {
        phantom,
        print_scale,
        bow_mm,
    }
}

/// The true range per displayed range of the B-scans.
pub fn range_scale(spec: &RenderSpec) -> f64 {
    of(spec).speed_of_sound.map(|s| s.range_scale()).unwrap_or(1.0)
}

fn gaussian3(rng: &mut Rng, sd: f64) -> Vector3<f64> {
    Vector3::new(rng.normal(0.0, sd), rng.normal(0.0, sd), rng.normal(0.0, sd))
}

/// Moves each frame's photo pose of the probe board by the mount's wobble and
/// the hand's motion over the shutter's asynchrony; returns each frame's board
/// motion during the exposure (when the photos are blurred by it), and puts the
/// feature's projection where the scanner displays it.
pub fn apply_to_frames(spec: &RenderSpec, scene: &mut Scene) -> Vec<Option<BoardMotion>> {
    let realism = of(spec);
    let range = range_scale(spec);
    let mut motions = Vec::with_capacity(scene.frames.len());
    for (k, plan) in scene.frames.iter_mut().enumerate() {
        // Each source draws from a stream of its own, so that leaving one out
        // does not change what the others draw.
        let stream = |source: u64| Rng::fork(spec.seed, FRAME_STREAM + 4 * k as u64 + source);
        if let Some(mount) = &realism.marker_mount {
            let mut rng = stream(0);
            let wobble = Rigid::new(
                gaussian3(&mut rng, mount.position_sd_mm),
                gaussian3(&mut rng, mount.rotation_sd_deg.to_radians()),
            );
            plan.world_T_marker_photo *= wobble;
        }
        // The hand's velocity in the probe board's frame: each component Gaussian,
        // so that the RMS speeds are the stated ones.
        let (velocity, spin) = match &realism.hand {
            Some(h) => (
                gaussian3(&mut stream(1), h.speed_mm_per_s / 3f64.sqrt()),
                gaussian3(&mut stream(2), h.rotation_deg_per_s.to_radians() / 3f64.sqrt()),
            ),
            None => (Vector3::zeros(), Vector3::zeros()),
        };
        if let Some(shutter) = &realism.shutter {
            let dt = stream(3).normal(0.0, shutter.asynchrony_sd_s);
            plan.world_T_marker_photo *= Rigid::new(velocity * dt, spin * dt);
        }
        motions.push(realism.motion_blur.as_ref().map(|m| BoardMotion {
            rotation_rad_per_s: spin,
            translation_mm_per_s: velocity,
            exposure_s: m.exposure_s,
        }));
        if range != 1.0 {
            let [sx, sy] = scene.bscan.spacing_mm_per_px;
            let [u, v] = plan.centre_projection_px;
            let (u, v) = scene.bscan.displayed(u * sx, v * sy, range);
            plan.centre_projection_px = [u / sx, v / sy];
        }
    }
    motions
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::TrueCalibration;
    use crate::synth::scene::BscanGeometry;

    #[test]
    fn the_evaluation_undoes_where_the_scanner_displays_an_echo() {
        let g = BscanGeometry::new([0.2, 0.2], 120.0, 60.0, 40.0);
        let k = 1482.0 / 1540.0;
        let truth = TrueCalibration {
            marker_T_image: Rigid::identity(),
            image_size_px: [g.width_px, g.height_px],
            range_scale: k,
            apex_mm: g.apex_mm,
        };
        for (u, v) in [(80.0, 60.0), (30.0, 10.0), (120.0, 100.0), (g.apex_mm[0], 5.0)] {
            let (su, sv) = g.displayed(u, v, k);
            // Shown deeper along the same beam, by the speeds' ratio.
            let (r, angle) = g.polar(u, v);
            let (sr, sangle) = g.polar(su, sv);
            assert!((angle - sangle).abs() < 1e-12);
            assert!(((sr - 40.0) * k - (r - 40.0)).abs() < 1e-9, "{sr} {r}");
            let [tu, tv] = truth.true_point_of_displayed([su, sv]);
            assert!((tu - u).abs() < 1e-9 && (tv - v).abs() < 1e-9, "{tu},{tv} vs {u},{v}");
        }
        // A scanner that assumes the medium's speed shows every echo where it is.
        assert_eq!(g.displayed(80.0, 60.0, 1.0), (80.0, 60.0));
    }

    #[test]
    fn the_sources_draw_from_streams_of_their_own() {
        let yaml = "seed: 5\nrealism:\n  marker_mount: {position_sd_mm: 0.1, rotation_sd_deg: 0.1}\n  \
                    shutter: {asynchrony_sd_s: 0.1}\n  hand: {speed_mm_per_s: 3.0, rotation_deg_per_s: 1.0}\n  \
                    board_print: {scale_sd: 0.003}\n  phantom_measurement: {position_sd_mm: 0.5}\n";
        let spec: RenderSpec = serde_yaml::from_str(yaml).unwrap();
        let phantom = Phantom::Hemisphere {
            centre_in_phantom_mm: [1.0, 2.0, 3.0],
            radius_mm: 15.0,
        };
        let all = systematic(&spec, &phantom);
        let mut no_phantom = spec.clone();
        no_phantom.realism = spec.realism.as_ref().map(|r| r.without("phantom_measurement"));
        let fewer = systematic(&no_phantom, &phantom);
        // Leaving the measurement error out leaves the boards' draws as they were.
        assert_eq!(all.print_scale, fewer.print_scale);
        assert_ne!(all.print_scale, [1.0, 1.0]);
        assert_eq!(fewer.phantom, phantom);
        assert_ne!(all.phantom, phantom);
        // The same spec draws the same.
        assert_eq!(systematic(&spec, &phantom).phantom, all.phantom);
    }
}
