//! Renders convex-probe B-scans of the hemisphere phantom in its water tank.
//!
//! Along each beam (a ray from the fan's virtual apex) the echoes are computed in
//! 3D at several elevation offsets across the beam's slice thickness: the specular
//! echo of the dome where the beam first meets it (strong at normal incidence),
//! the acoustic shadow behind it, the tank floor and its reverberation, the walls
//! where the slice cuts them, air bubbles with comet tails. Then lateral/axial
//! blur, multiplicative speckle, depth attenuation, near-field ringing, log
//! compression and noise. Outside the fan the image is 0; inside it is at least 1.

use nalgebra::{Point3, Vector3};

use super::bscan_geometry::BscanGeometry;
use super::scene::{FrameKind, Scene, Tank};
use super::shape::Shape;
use crate::core::geometry::Rigid;
use crate::core::rng::Rng;
use crate::io::image::{gaussian_blur_f32, Gray8, ImageError};

/// An air bubble in the water (world frame).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Bubble {
    pub centre_world_mm: [f64; 3],
    pub radius_mm: f64,
}

/// Settings of the echo model that the manifest exposes.
#[derive(Debug, Clone, Copy)]
pub struct EchoModel {
    pub slice_thickness_mm: f64,
    pub bubble_rate: f64,
    /// True range per displayed range from the transducer face (the medium's
    /// speed of sound over the scanner's; 1: they agree).
    pub range_scale: f64,
}

const AXIAL_SIGMA_MM: f64 = 0.30;
const ELEVATION_SAMPLES: usize = 7;

/// Draws the bubbles of one frame.
pub fn draw_bubbles(
    scene: &Scene,
    world_T_image: &Rigid,
    kind: FrameKind,
    model: EchoModel,
    rng: &mut Rng,
) -> Vec<Bubble> {
    let mut bubbles = Vec::new();
    let geometry = &scene.bscan;
    let c = scene.feature_centre_world.coords;
    let keep_off = match &scene.shape {
        Shape::Hemisphere { radius_mm } => radius_mm + 1.5,
        Shape::Point { head_radius_mm } => head_radius_mm + 4.0,
        Shape::Wires { .. } => 4.0,
        Shape::Spheres { .. } => 0.0,
    };
    // Bubbles float clear of every dome.
    let domes = scene.shape.domes(&scene.feature_centre_world);
    let clear_of_domes = |p: &Point3<f64>| domes.iter().all(|(centre, r)| (p - centre).norm() > r + 1.5);
    let normal = world_T_image.rotation * Vector3::z();
    if rng.chance(model.bubble_rate) {
        for _ in 0..1 + rng.below(4) {
            // Floating in the slice, somewhere in the fan above the floor.
            let u = rng.uniform(0.15, 0.85) * geometry.width_mm();
            let v = rng.uniform(8.0, geometry.depth_mm * 0.8);
            let e = rng.uniform(-0.5, 0.5) * model.slice_thickness_mm;
            let p = world_T_image * Point3::new(u, v, e);
            if (p.coords - c).norm() > keep_off && clear_of_domes(&p) && p.z > scene.tank.floor_z_mm + 2.0 {
                bubbles.push(Bubble {
                    centre_world_mm: p.coords.into(),
                    radius_mm: rng.uniform(0.3, 0.9),
                });
            }
        }
    }
    if kind == FrameKind::DomeBubbles {
        match &scene.shape {
            Shape::Hemisphere { radius_mm } => bubbles_on_dome(rng, world_T_image, &c, *radius_mm, &mut bubbles),
            Shape::Spheres { domes_world } => {
                // On one of the domes the plane cuts.
                let image_T_world = world_T_image.inverse();
                let cut: Vec<&(Point3<f64>, f64)> = domes_world
                    .iter()
                    .filter(|(centre, r)| (image_T_world * centre).z.abs() < *r)
                    .collect();
                if !cut.is_empty() {
                    let (centre, r) = cut[rng.below(cut.len())];
                    bubbles_on_dome(rng, world_T_image, &centre.coords, *r, &mut bubbles);
                }
            }
            Shape::Point { head_radius_mm } => {
                // Caught on the pin and the block around the head.
                for _ in 0..2 + rng.below(3) {
                    let around = rng.uniform(0.0, std::f64::consts::TAU);
                    let distance = head_radius_mm + rng.uniform(2.5, 6.0);
                    let in_plane = world_T_image.rotation * Vector3::new(around.cos(), around.sin(), 0.0);
                    let p = c + in_plane * distance + normal * rng.uniform(-0.3, 0.3);
                    bubbles.push(Bubble {
                        centre_world_mm: p.into(),
                        radius_mm: rng.uniform(0.4, 0.9),
                    });
                }
            }
            Shape::Wires { wires_world, radius_mm } => {
                // Stuck on the wires near where the plane crosses them.
                for _ in 0..2 + rng.below(3) {
                    let (a, b) = &wires_world[rng.below(wires_world.len())];
                    let Some(p) = super::shape::segment_in_plane(world_T_image, a, b) else {
                        continue;
                    };
                    let around = rng.uniform(0.0, std::f64::consts::TAU);
                    let r = rng.uniform(0.4, 0.8);
                    let offset = Vector3::new(around.cos(), around.sin(), 0.0) * (radius_mm + r + 0.3);
                    let p = world_T_image * (p + offset);
                    bubbles.push(Bubble {
                        centre_world_mm: p.coords.into(),
                        radius_mm: r,
                    });
                }
            }
        }
    }
    bubbles
}

/// Bubbles stuck on a dome near where the plane cuts it.
fn bubbles_on_dome(rng: &mut Rng, world_T_image: &Rigid, c: &Vector3<f64>, radius_mm: f64, bubbles: &mut Vec<Bubble>) {
    let normal = world_T_image.rotation * Vector3::z();
    for _ in 0..3 + rng.below(4) {
        let around = rng.uniform(-60f64, 60.0).to_radians();
        let in_plane = world_T_image.rotation * Vector3::new(around.sin(), -around.cos(), 0.0);
        let dir = (in_plane + normal * rng.uniform(-0.08, 0.08)).normalize();
        let r = rng.uniform(0.6, 1.4);
        let p = c + dir * (radius_mm + r);
        bubbles.push(Bubble {
            centre_world_mm: p.into(),
            radius_mm: r,
        });
    }
}

/// First intersection distance of a ray with a sphere, if any.
fn ray_sphere(origin: &Vector3<f64>, dir: &Vector3<f64>, centre: &Vector3<f64>, radius: f64) -> Option<f64> {
    let oc = origin - centre;
    let b = dir.dot(&oc);
    let disc = b * b - (oc.norm_squared() - radius * radius);
    (disc >= 0.0).then(|| -b - disc.sqrt())
}

/// First intersection distance of a ray with a cylinder around the segment `a`–`b`,
/// within the segment, and the cosine of the incidence.
fn ray_cylinder(
    origin: &Vector3<f64>,
    dir: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    radius: f64,
) -> Option<(f64, f64)> {
    let length = (b - a).norm();
    let axis = (b - a) / length;
    let w = origin - a;
    let d_perp = dir - axis * dir.dot(&axis);
    let w_perp = w - axis * w.dot(&axis);
    let qa = d_perp.norm_squared();
    if qa < 1e-12 {
        return None;
    }
    let qb = 2.0 * d_perp.dot(&w_perp);
    let qc = w_perp.norm_squared() - radius * radius;
    let disc = qb * qb - 4.0 * qa * qc;
    if disc < 0.0 {
        return None;
    }
    let lambda = (-qb - disc.sqrt()) / (2.0 * qa);
    let hit = origin + dir * lambda;
    let along = (hit - a).dot(&axis);
    if lambda <= 0.0 || along < 0.0 || along > length {
        return None;
    }
    let normal = ((hit - a) - axis * along) / radius;
    Some((lambda, dir.dot(&normal).abs()))
}

/// Where a ray meets a horizontal surface at height `z` inside `[x0, x1] x [y0, y1]`
/// (world frame), coming from above.
fn ray_surface(origin: &Vector3<f64>, dir: &Vector3<f64>, z: f64, bounds: [f64; 4]) -> Option<f64> {
    if dir.z > -1e-6 || origin.z < z {
        return None;
    }
    let lambda = (z - origin.z) / dir.z;
    let hit = origin + dir * lambda;
    let [x0, x1, y0, y1] = bounds;
    (hit.x > x0 && hit.x < x1 && hit.y > y0 && hit.y < y1).then_some(lambda)
}

/// The point phantom's silicone block (top surface height below the pin head) and
/// the weights lying on it, relative to the head; the wire box's floor below the wires.
const BLOCK_TOP_BELOW_HEAD_MM: f64 = 12.0;
const WEIGHTS_ON_BLOCK_MM: [[f64; 3]; 2] = [[-24.0, 1.5, 3.5], [27.0, -2.0, 3.0]];
const PIN_RADIUS_MM: f64 = 0.3;
const WIRE_BOX_FLOOR_BELOW_MM: f64 = 20.0;

fn gauss(x: f64, sigma: f64) -> f64 {
    (-(x / sigma).powi(2) / 2.0).exp()
}

/// The echo (summed over several reflections) and where the beam is blocked, for one
/// ray through the phantom's parts other than the hemisphere.
fn phantom_echo(scene: &Scene, origin: &Vector3<f64>, dir: &Vector3<f64>, r: f64, near_mm: f64) -> (f64, f64) {
    let c = scene.feature_centre_world.coords;
    let mut echo = 0.0;
    let mut blocked_at = f64::INFINITY;
    match &scene.shape {
        Shape::Hemisphere { .. } | Shape::Spheres { .. } => {}
        Shape::Point { head_radius_mm } => {
            if let Some(lambda) = ray_sphere(origin, dir, &c, *head_radius_mm).filter(|l| *l > near_mm) {
                let n = (origin + dir * lambda - c) / *head_radius_mm;
                let strength = 0.25 + 0.75 * dir.dot(&n).abs().powi(2);
                echo += 1.8 * strength * gauss(r - lambda, AXIAL_SIGMA_MM);
                // The comet tail: reverberation inside the head, fading with depth.
                for k in 1..=8 {
                    let at = lambda + 2.0 * head_radius_mm + 0.6 * k as f64;
                    echo += 0.9 * strength * 0.68f64.powi(k) * gauss(r - at, AXIAL_SIGMA_MM);
                }
                blocked_at = lambda + 2.0 * head_radius_mm;
            }
            let block_top = c.z - BLOCK_TOP_BELOW_HEAD_MM;
            // The pin, from the head down into the block.
            let pin_top = c - Vector3::z() * *head_radius_mm;
            let pin_bottom = Vector3::new(c.x, c.y, block_top);
            if let Some((lambda, incidence)) = ray_cylinder(origin, dir, &pin_top, &pin_bottom, PIN_RADIUS_MM) {
                if lambda < blocked_at {
                    echo += 0.35 * (0.2 + 0.8 * incidence) * gauss(r - lambda, AXIAL_SIGMA_MM);
                }
            }
            for w in WEIGHTS_ON_BLOCK_MM {
                let centre = Vector3::new(c.x + w[0], c.y + w[1], block_top + w[2]);
                if let Some(lambda) = ray_sphere(origin, dir, &centre, w[2]).filter(|l| *l > near_mm) {
                    if lambda < blocked_at {
                        let n = (origin + dir * lambda - centre) / w[2];
                        echo += 1.5 * (0.2 + 0.8 * dir.dot(&n).abs().powi(2)) * gauss(r - lambda, AXIAL_SIGMA_MM);
                        blocked_at = lambda + AXIAL_SIGMA_MM * 2.0;
                    }
                }
            }
            let bounds = [c.x - 40.0, c.x + 40.0, c.y - 30.0, c.y + 30.0];
            if let Some(lambda) = ray_surface(origin, dir, block_top, bounds) {
                if lambda < blocked_at {
                    echo += 0.6 * (0.3 + 0.7 * dir.z.powi(2)) * gauss(r - lambda, AXIAL_SIGMA_MM * 1.5);
                    // Silicone attenuates: what lies below is fainter but not hidden.
                    if r > lambda {
                        echo += 0.01;
                    }
                }
            }
        }
        Shape::Wires { wires_world, radius_mm } => {
            let mut hits: Vec<(f64, f64)> = wires_world
                .iter()
                .filter_map(|(a, b)| ray_cylinder(origin, dir, &a.coords, &b.coords, *radius_mm))
                .filter(|(l, _)| *l > near_mm)
                .collect();
            hits.sort_by(|a, b| a.0.total_cmp(&b.0));
            if let Some(&(first, _)) = hits.first() {
                blocked_at = first + 2.0 * radius_mm;
            }
            for (lambda, incidence) in hits {
                let strength = 0.3 + 0.7 * incidence.powi(2);
                echo += 1.6 * strength * gauss(r - lambda, AXIAL_SIGMA_MM);
                // A wire thicker than the wavelength rings: echoes from inside the wire.
                for (k, level) in [0.55, 0.3, 0.15].iter().enumerate() {
                    let at = lambda + 1.1 * (k + 1) as f64;
                    echo += level * strength * gauss(r - at, AXIAL_SIGMA_MM);
                }
            }
            let floor = c.z - WIRE_BOX_FLOOR_BELOW_MM;
            let bounds = [c.x - 45.0, c.x + 45.0, c.y - 45.0, c.y + 45.0];
            if let Some(lambda) = ray_surface(origin, dir, floor, bounds) {
                if lambda < blocked_at {
                    echo += 0.7 * (0.3 + 0.7 * dir.z.powi(2)) * gauss(r - lambda, AXIAL_SIGMA_MM * 1.5);
                    blocked_at = lambda + 2.0 * AXIAL_SIGMA_MM;
                }
            }
        }
    }
    (echo, blocked_at)
}

/// The beam's elevation profile: sample offsets across the slice (mm, within
/// ±`half`) with their Gaussian weights.
fn elevation_profile(half: f64) -> Vec<(f64, f64)> {
    (0..ELEVATION_SAMPLES)
        .map(|j| {
            let e = if ELEVATION_SAMPLES > 1 {
                -half + 2.0 * half * j as f64 / (ELEVATION_SAMPLES - 1) as f64
            } else {
                0.0
            };
            let weight = if half > 0.0 {
                (-(e / (half / 1.5)).powi(2) / 2.0).exp()
            } else {
                1.0
            };
            (e, weight)
        })
        .collect()
}

/// Bubbles: bright spots with a reverberation tail down the beam.
fn add_bubbles(
    scene: &Scene,
    world_T_image: &Rigid,
    bubbles: &[Bubble],
    model: EchoModel,
    half: f64,
    inside: &[bool],
    echo: &mut [f32],
) {
    let g = &scene.bscan;
    let (w, h) = (g.width_px, g.height_px);
    let [sx, sy] = g.spacing_mm_per_px;
    let image_T_world = world_T_image.inverse();
    for bubble in bubbles {
        let centre = image_T_world * Point3::from(Vector3::from(bubble.centre_world_mm));
        if centre.z.abs() > half + bubble.radius_mm {
            continue;
        }
        let (rb, ab) = g.polar(centre.x, centre.y);
        let rb = if model.range_scale == 1.0 {
            rb
        } else {
            g.convex_radius_mm + (rb - g.convex_radius_mm) / model.range_scale
        };
        let size = bubble.radius_mm.max(0.35);
        let x0 = ((centre.x - 4.0) / sx).floor().max(0.0) as usize;
        let x1 = (((centre.x + 4.0) / sx).ceil() as usize).min(w);
        let y0 = ((centre.y - 3.0) / sy).floor().max(0.0) as usize;
        for y in y0..h {
            for x in x0..x1 {
                let i = y * w + x;
                if !inside[i] {
                    continue;
                }
                let (u_mm, v_mm) = (x as f64 * sx, y as f64 * sy);
                let (r, a) = g.polar(u_mm, v_mm);
                let lateral = (a - ab) * rb;
                let along = r - rb;
                let spot = (-(lateral * lateral + along * along) / (2.0 * size * size)).exp();
                let tail = if along > 0.0 {
                    0.45 * (-along / 4.0).exp()
                        * (std::f64::consts::PI * along / 0.9).cos().powi(2)
                        * (-(lateral / size).powi(2) / 2.0).exp()
                } else {
                    0.0
                };
                echo[i] += (1.4 * spot + tail) as f32;
            }
        }
    }
}

/// The grey levels: echo and base under speckle (the magnitude of a blurred
/// complex Gaussian field, mean 1), attenuated, log-compressed, with noise.
fn speckled_levels(
    g: &BscanGeometry,
    base: &[f32],
    echo: &[f32],
    inside: &[bool],
    rng: &mut Rng,
) -> Result<Vec<f32>, ImageError> {
    let (w, h) = (g.width_px, g.height_px);
    let [sx, sy] = g.spacing_mm_per_px;
    let mut re: Vec<f32> = (0..w * h).map(|_| rng.normal(0.0, 1.0) as f32).collect();
    let mut im: Vec<f32> = (0..w * h).map(|_| rng.normal(0.0, 1.0) as f32).collect();
    gaussian_blur_f32(w, h, &mut re, 0.35 / sx, 0.15 / sy)?;
    gaussian_blur_f32(w, h, &mut im, 0.35 / sx, 0.15 / sy)?;
    let mut speckle: Vec<f32> = re.iter().zip(&im).map(|(a, b)| (a * a + b * b).sqrt()).collect();
    let mean = speckle.iter().map(|v| *v as f64).sum::<f64>() / speckle.len() as f64;
    for v in speckle.iter_mut() {
        *v /= mean as f32;
    }

    let mut levels = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !inside[i] {
                continue;
            }
            let (r, _) = g.polar(x as f64 * sx, y as f64 * sy);
            let attenuation = (-0.004 * (r - g.convex_radius_mm)).exp() as f32;
            let intensity = ((base[i] + echo[i]) * speckle[i] * attenuation).max(0.0);
            let compressed = (1.0 + 60.0 * intensity).log10() / 61f32.log10();
            let noisy = 235.0 * compressed + rng.normal(0.0, 2.0) as f32;
            levels[i] = noisy.clamp(1.0, 255.0);
        }
    }
    Ok(levels)
}

/// The tank floor's echo and its reverberation for a beam going down, added to
/// `e_sum` with `weight`; the range past which the beam is now blocked.
#[allow(clippy::too_many_arguments)]
fn add_floor_echo(
    tank: &Tank,
    g: &BscanGeometry,
    origin: &Vector3<f64>,
    dir: &Vector3<f64>,
    r: f64,
    weight: f64,
    e_sum: &mut f64,
    blocked_at: f64,
) -> f64 {
    let lambda_floor = (tank.floor_z_mm - origin.z) / dir.z;
    let floor_hit = origin + dir * lambda_floor;
    let inside_walls = floor_hit.x.abs() < tank.wall_x_mm && floor_hit.y.abs() < tank.wall_y_mm;
    if lambda_floor < blocked_at && inside_walls {
        let strength = 0.3 + 0.7 * dir.z.powi(2);
        *e_sum += weight * 0.9 * strength * (-((r - lambda_floor) / (AXIAL_SIGMA_MM * 1.5)).powi(2) / 2.0).exp();
        let reverb = g.convex_radius_mm + 2.0 * (lambda_floor - g.convex_radius_mm);
        *e_sum += weight * 0.25 * strength * (-((r - reverb) / (AXIAL_SIGMA_MM * 2.0)).powi(2) / 2.0).exp();
        return blocked_at.min(lambda_floor + 2.0 * AXIAL_SIGMA_MM);
    }
    blocked_at
}

/// The echo of the nearest dome the beam meets on its upper half, added to
/// `e_sum` with `weight`; the range past which the dome blocks the beam.
fn add_dome_echo(
    domes: &[(Vector3<f64>, f64)],
    origin: &Vector3<f64>,
    dir: &Vector3<f64>,
    r: f64,
    convex_radius_mm: f64,
    weight: f64,
    e_sum: &mut f64,
) -> Option<f64> {
    // The nearest dome the beam meets on its upper half.
    let dome_hit = domes
        .iter()
        .filter_map(|(centre, radius)| {
            let lambda = ray_sphere(origin, dir, centre, *radius)?;
            let hit = origin + dir * lambda;
            (lambda > convex_radius_mm && hit.z >= centre.z - 0.5).then_some((centre, *radius, lambda, hit))
        })
        .min_by(|a, b| a.2.total_cmp(&b.2));
    let (centre, radius, lambda, hit) = dome_hit?;
    let n = (hit - centre) / radius;
    let incidence = dir.dot(&n).abs();
    let strength = 0.15 + 0.85 * incidence.powi(4);
    *e_sum += weight * 1.6 * strength * (-((r - lambda) / AXIAL_SIGMA_MM).powi(2) / 2.0).exp();
    Some(lambda + 2.0 * AXIAL_SIGMA_MM)
}

/// Renders one B-scan.
pub fn render_bscan(
    scene: &Scene,
    world_T_image: &Rigid,
    bubbles: &[Bubble],
    model: EchoModel,
    rng: &mut Rng,
) -> Result<Gray8, ImageError> {
    let g = &scene.bscan;
    let (w, h) = (g.width_px, g.height_px);
    let [sx, sy] = g.spacing_mm_per_px;
    let domes: Vec<(Vector3<f64>, f64)> = scene
        .shape
        .domes(&scene.feature_centre_world)
        .into_iter()
        .map(|(centre, r)| (centre.coords, r))
        .collect();
    let tank = scene.tank;
    let rotation = world_T_image.rotation;
    let normal = rotation * Vector3::z();
    let apex_world = world_T_image * Point3::new(g.apex_mm[0], g.apex_mm[1], 0.0);

    let half = model.slice_thickness_mm / 2.0;
    let offsets = elevation_profile(half);
    let weight_sum: f64 = offsets.iter().map(|o| o.1).sum();

    let mut echo = vec![0f32; w * h];
    let mut base = vec![0f32; w * h];
    let mut inside = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (u_mm, v_mm) = (x as f64 * sx, y as f64 * sy);
            if !g.inside_fan(u_mm, v_mm) {
                continue;
            }
            let i = y * w + x;
            inside[i] = true;
            let (r, angle) = g.polar(u_mm, v_mm);
            // The echo displayed at this range comes from the true range.
            let r = if model.range_scale == 1.0 {
                r
            } else {
                g.convex_radius_mm + (r - g.convex_radius_mm) * model.range_scale
            };
            let dir = rotation * Vector3::new(angle.sin(), angle.cos(), 0.0);
            let mut e_sum = 0.0;
            let mut shadow = 0.0;
            for &(e, weight) in &offsets {
                let origin = apex_world.coords + normal * e;
                let mut blocked_at = f64::INFINITY;
                if let Some(blocked) = add_dome_echo(&domes, &origin, &dir, r, g.convex_radius_mm, weight, &mut e_sum) {
                    blocked_at = blocked;
                }
                if domes.is_empty() {
                    let (echo, blocked) = phantom_echo(scene, &origin, &dir, r, g.convex_radius_mm);
                    e_sum += weight * echo;
                    blocked_at = blocked;
                }
                if dir.z < -1e-6 {
                    blocked_at = add_floor_echo(&tank, g, &origin, &dir, r, weight, &mut e_sum, blocked_at);
                }
                if r > blocked_at {
                    shadow += weight;
                }
            }
            let point = apex_world.coords + dir * r;
            let wall_distance = (tank.wall_x_mm - point.x.abs()).min(tank.wall_y_mm - point.y.abs());
            let outside_tank = wall_distance < 0.0 || point.z < tank.floor_z_mm;
            let wall_echo = if point.z >= tank.floor_z_mm {
                0.7 * (-(wall_distance / 0.7).powi(2) / 2.0).exp()
            } else {
                0.0
            };
            e_sum = e_sum / weight_sum + wall_echo;
            let shadow = shadow / weight_sum;
            let mut b = if outside_tank {
                0.004
            } else {
                0.015 * (1.0 - 0.85 * shadow)
            };
            // Ringing of the transducer face.
            let near = r - g.convex_radius_mm;
            b += 0.5 * (-near / 1.2).exp() + 0.12 * (-near / 5.0).exp();
            base[i] = b as f32;
            echo[i] = e_sum as f32;
        }
    }

    add_bubbles(scene, world_T_image, bubbles, model, half, &inside, &mut echo);

    // Lateral and axial resolution of the beam.
    gaussian_blur_f32(w, h, &mut echo, 0.45 / sx, 0.2 / sy)?;
    let levels = speckled_levels(g, &base, &echo, &inside, rng)?;
    Ok(Gray8::from_levels(w, h, &levels))
}
