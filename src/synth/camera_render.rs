//! Renders camera photos of printed boards through the distorted pinhole model.
//!
//! Each pixel is integrated over 3x3 sub-samples; each sub-sample's viewing ray
//! comes from inverting the lens distortion (precomputed once per camera on the
//! pixel-corner lattice and interpolated), so straight board edges bend exactly
//! as the distortion model says. Then: uneven lighting and vignetting, optical
//! blur, sensor noise, 8-bit quantisation.

use nalgebra::{Point3, Vector3};

use super::scene::Occluder;
use crate::core::geometry::Rigid;
use crate::core::rng::Rng;
use crate::detect::board::{Ink, PrintedBoard};
use crate::io::camera_model::CameraIntrinsics;
use crate::io::image::{gaussian_blur_f32, Gray8, ImageError};

/// Viewing rays of the pixel-corner lattice of one camera.
pub struct RayMap {
    width: usize,
    height: usize,
    /// (w+1) x (h+1) normalised undistorted coordinates of the pixel corners.
    corners: Vec<[f32; 2]>,
}

impl RayMap {
    pub fn new(camera: &CameraIntrinsics) -> RayMap {
        let (width, height) = (camera.image_size_px[0] as usize, camera.image_size_px[1] as usize);
        let mut corners = Vec::with_capacity((width + 1) * (height + 1));
        for y in 0..=height {
            for x in 0..=width {
                let (nx, ny) = camera.undistort_pixel([x as f64 - 0.5, y as f64 - 0.5]);
                corners.push([nx as f32, ny as f32]);
            }
        }
        RayMap { width, height, corners }
    }

    /// Normalised ray of a point inside pixel (x, y) at fractions (fx, fy) of its extent.
    #[inline]
    fn ray(&self, x: usize, y: usize, fx: f32, fy: f32) -> [f32; 2] {
        let stride = self.width + 1;
        let a = self.corners[y * stride + x];
        let b = self.corners[y * stride + x + 1];
        let c = self.corners[(y + 1) * stride + x];
        let d = self.corners[(y + 1) * stride + x + 1];
        let top = [a[0] + (b[0] - a[0]) * fx, a[1] + (b[1] - a[1]) * fx];
        let bottom = [c[0] + (d[0] - c[0]) * fx, c[1] + (d[1] - c[1]) * fx];
        [top[0] + (bottom[0] - top[0]) * fy, top[1] + (bottom[1] - top[1]) * fy]
    }
}

/// Photometric settings of one photo.
#[derive(Debug, Clone, Copy)]
pub struct Photometry {
    pub noise_grey_levels: f64,
    pub blur_sigma_px: f64,
    pub lighting_gradient: f64,
}

/// A board placed in front of the camera.
pub struct PlacedBoard<'a> {
    pub camera_T_board: Rigid,
    pub layout: &'a PrintedBoard,
    /// Things lying across the board (a finger, a cable, a rim), relative to its centre.
    pub occluders: Vec<Occluder>,
    /// The printed board's true size per nominal size (1: printed exactly).
    pub print_scale: f64,
    /// The board's bow along its x axis: the sagitta (mm, along the board's z)
    /// of a parabola over the paper's width (0: flat).
    pub bow_mm: f64,
    /// The board's motion during the exposure: its pose at time `t` (s, from the
    /// middle of the exposure) is `camera_T_board * exp(t * twist)`.
    pub motion: Option<BoardMotion>,
}

/// A board's velocity in its own frame, and the exposure time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardMotion {
    pub rotation_rad_per_s: Vector3<f64>,
    pub translation_mm_per_s: Vector3<f64>,
    pub exposure_s: f64,
}

/// The order in which the 3x3 sub-samples of a pixel take the exposure's 9
/// moments (so time does not run along the pixel's rows).
const TIME_OF_SUBSAMPLE: [usize; 9] = [4, 0, 7, 2, 8, 5, 1, 6, 3];

const BLACK_REFLECTANCE: f32 = 0.07;
const WHITE_REFLECTANCE: f32 = 0.88;
const OCCLUDER_REFLECTANCE: f32 = 0.22;
/// How far beyond a board's paper its occluders are drawn, mm (a long one,
/// as a tank rim, is cut there and does not hide the other board).
const OCCLUDER_REACH_MM: f64 = 40.0;

/// Each board as a plane in the camera frame: origin, normal, and the inverse pose.
struct Plane<'a> {
    origin: Vector3<f32>,
    normal: Vector3<f32>,
    board_T_camera: Rigid,
    layout: &'a PrintedBoard,
    occluders: &'a [Occluder],
    centre: [f64; 2],
    scale: f64,
    /// Sagitta, middle and half-width of the bow along x (board mm).
    bow: Option<(f64, f64, f64)>,
}

/// The boards' planes at `time_s` into the exposure (a moving board moved on).
fn planes_at<'a>(boards: &'a [PlacedBoard<'a>], time_s: f64) -> Vec<Plane<'a>> {
    boards
        .iter()
        .map(|b| {
            let pose = match b.motion {
                Some(m) if time_s != 0.0 => {
                    b.camera_T_board * Rigid::new(m.translation_mm_per_s * time_s, m.rotation_rad_per_s * time_s)
                }
                _ => b.camera_T_board,
            };
            Plane {
                origin: pose.translation.vector.cast::<f32>(),
                normal: (pose.rotation * Vector3::z()).cast::<f32>(),
                board_T_camera: pose.inverse(),
                layout: b.layout,
                occluders: &b.occluders,
                centre: {
                    let c = b.layout.centre_mm();
                    [c.x, c.y]
                },
                scale: b.print_scale,
                bow: (b.bow_mm != 0.0).then(|| {
                    let [x0, _, x1, _] = b.layout.paper_bounds_mm();
                    let [x0, x1] = [x0 * b.print_scale, x1 * b.print_scale];
                    (b.bow_mm, (x0 + x1) / 2.0, (x1 - x0) / 2.0)
                }),
            }
        })
        .collect()
}

/// The nearest board surface a camera ray meets: its distance along the ray and
/// its reflectance (ink, paper, or the occluder over it).
fn nearest_hit(planes: &[Plane<'_>], dir: &Vector3<f32>) -> Option<(f32, f32)> {
    let mut best: Option<(f32, f32)> = None;
    for plane in planes {
        let denom = plane.normal.dot(dir);
        if denom.abs() < 1e-6 {
            continue;
        }
        let mut t = plane.normal.dot(&plane.origin) / denom;
        let mut local = {
            let hit = dir * t;
            plane.board_T_camera * Point3::new(hit.x as f64, hit.y as f64, hit.z as f64)
        };
        if let Some((sagitta, middle, half)) = plane.bow {
            // The bowed surface is `z = h(x)` in the board's frame: two
            // fixed-point steps of the ray's meeting with it.
            for _ in 0..2 {
                let u = ((local.x - middle) / half).clamp(-1.0, 1.0);
                let height = sagitta * (1.0 - u * u);
                t = (plane.normal.dot(&plane.origin) + height as f32) / denom;
                let hit = dir * t;
                local = plane.board_T_camera * Point3::new(hit.x as f64, hit.y as f64, hit.z as f64);
            }
        }
        if t <= 0.0 || best.is_some_and(|(bt, _)| bt <= t) {
            continue;
        }
        let c = plane.centre;
        let [x0, y0, x1, y1] = plane.layout.paper_bounds_mm();
        let near_paper = local.x >= x0 - OCCLUDER_REACH_MM
            && local.x <= x1 + OCCLUDER_REACH_MM
            && local.y >= y0 - OCCLUDER_REACH_MM
            && local.y <= y1 + OCCLUDER_REACH_MM;
        let covered = near_paper && plane.occluders.iter().any(|o| o.covers(local.x - c[0], local.y - c[1]));
        if covered {
            best = Some((t, OCCLUDER_REFLECTANCE));
        } else if let Some(ink) = plane.layout.ink_at(local.x / plane.scale, local.y / plane.scale) {
            let r = if ink == Ink::Black {
                BLACK_REFLECTANCE
            } else {
                WHITE_REFLECTANCE
            };
            best = Some((t, r));
        }
    }
    best
}

/// Renders one photo. `rng` drives the lighting direction, exposure and noise.
pub fn render_photo(
    camera: &CameraIntrinsics,
    rays: &RayMap,
    boards: &[PlacedBoard<'_>],
    photometry: Photometry,
    rng: &mut Rng,
) -> Result<Gray8, ImageError> {
    let (w, h) = (rays.width, rays.height);
    let planes_at = |time_s: f64| planes_at(boards, time_s);
    // One set of planes when nothing moves; else one per moment of the exposure.
    let exposure_s = boards
        .iter()
        .filter_map(|b| b.motion.map(|m| m.exposure_s))
        .fold(0.0, f64::max);
    let planes_per_time: Vec<Vec<Plane<'_>>> = if exposure_s > 0.0 {
        (0..9)
            .map(|t| planes_at(((t as f64 + 0.5) / 9.0 - 0.5) * exposure_s))
            .collect()
    } else {
        vec![planes_at(0.0)]
    };

    // Lighting: a linear gradient in a random direction, a soft spot, and vignetting.
    let angle = rng.uniform(0.0, std::f64::consts::TAU);
    let (gx, gy) = (angle.cos() as f32, angle.sin() as f32);
    let gradient = photometry.lighting_gradient as f32;
    let spot = [
        rng.uniform(0.2, 0.8) as f32 * w as f32,
        rng.uniform(0.2, 0.8) as f32 * h as f32,
    ];
    let exposure = rng.uniform(0.9, 1.05) as f32;
    let diag = ((w * w + h * h) as f32).sqrt();
    let (fx, cx, fy, cy) = (
        camera.fx() as f32,
        camera.cx() as f32,
        camera.fy() as f32,
        camera.cy() as f32,
    );

    let mut levels = vec![0f32; w * h];
    const SUB: [f32; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];
    for y in 0..h {
        for x in 0..w {
            let mut reflectance = 0f32;
            for (iy, &sy) in SUB.iter().enumerate() {
                for (ix, &sx) in SUB.iter().enumerate() {
                    let planes = &planes_per_time[TIME_OF_SUBSAMPLE[iy * 3 + ix] % planes_per_time.len()];
                    let [nx, ny] = rays.ray(x, y, sx, sy);
                    let dir = Vector3::new(nx, ny, 1.0);
                    let best = nearest_hit(planes, &dir);
                    reflectance += match best {
                        Some((_, r)) => r,
                        None => {
                            // Background: a dull surface with a slow texture.
                            let u = fx * nx + cx;
                            let v = fy * ny + cy;
                            0.30 + 0.06 * ((u * 0.011).sin() * (v * 0.007).cos()) + 0.03 * ((u + v) * 0.031).sin()
                        }
                    };
                }
            }
            reflectance /= 9.0;
            let (xf, yf) = (x as f32, y as f32);
            let ramp =
                1.0 - gradient * (0.5 + 0.5 * ((xf - w as f32 / 2.0) * gx + (yf - h as f32 / 2.0) * gy) / (diag / 2.0));
            let d2 = ((xf - spot[0]).powi(2) + (yf - spot[1]).powi(2)) / (diag * diag);
            let spot_light = 0.15 * (-d2 / 0.05).exp();
            let r2 = ((xf - cx).powi(2) + (yf - cy).powi(2)) / (fx * fx);
            let vignette = 1.0 / (1.0 + r2).powi(2);
            levels[y * w + x] = 255.0 * exposure * reflectance * (ramp + spot_light) * vignette;
        }
    }
    gaussian_blur_f32(w, h, &mut levels, photometry.blur_sigma_px, photometry.blur_sigma_px)?;
    for v in levels.iter_mut() {
        *v += rng.normal(0.0, photometry.noise_grey_levels) as f32;
    }
    Ok(Gray8::from_levels(w, h, &levels))
}
