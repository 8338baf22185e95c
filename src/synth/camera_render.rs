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
    /// Per pixel, the sum over its 9 sub-samples of the background's reflectance
    /// (what a pixel whose rays meet no board sees; the same for every photo).
    background_sum: Vec<f32>,
}

/// The sub-samples of a pixel, as fractions of its extent.
const SUB: [f32; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];

/// The background's reflectance along a normalised ray: a dull surface with a slow texture.
#[inline]
fn background(ray: [f32; 2], focal: [f32; 2], principal: [f32; 2]) -> f32 {
    let u = focal[0] * ray[0] + principal[0];
    let v = focal[1] * ray[1] + principal[1];
    0.30 + 0.06 * ((u * 0.011).sin() * (v * 0.007).cos()) + 0.03 * ((u + v) * 0.031).sin()
}

/// How far outside a board's reach (in normalised coordinates, about a pixel)
/// a ray is still traced: far beyond the rounding of the ray and the hit.
const REACH_MARGIN: f32 = 2e-3;

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
        let mut map = RayMap {
            width,
            height,
            corners,
            background_sum: Vec::new(),
        };
        let (focal, principal) = focal_and_principal(camera);
        let mut background_sum = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let mut sum = 0f32;
                for &sy in &SUB {
                    for &sx in &SUB {
                        sum += background(map.ray(x, y, sx, sy), focal, principal);
                    }
                }
                background_sum.push(sum);
            }
        }
        map.background_sum = background_sum;
        map
    }

    /// The box (min x, min y, max x, max y) of the normalised rays through pixel (x, y).
    #[inline]
    fn pixel_box(&self, x: usize, y: usize) -> [f32; 4] {
        let stride = self.width + 1;
        let corners = [
            self.corners[y * stride + x],
            self.corners[y * stride + x + 1],
            self.corners[(y + 1) * stride + x],
            self.corners[(y + 1) * stride + x + 1],
        ];
        corners.iter().fold(
            [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY],
            |b, c| [b[0].min(c[0]), b[1].min(c[1]), b[2].max(c[0]), b[3].max(c[1])],
        )
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

fn focal_and_principal(camera: &CameraIntrinsics) -> ([f32; 2], [f32; 2]) {
    (
        [camera.fx() as f32, camera.fy() as f32],
        [camera.cx() as f32, camera.cy() as f32],
    )
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
    /// The box of normalised rays that can meet the board's paper or its
    /// occluders (`None`: the board reaches behind the camera; every ray is traced).
    reach: Option<Reach>,
}

/// The normalised rays that can meet a board: the box around them and their
/// convex hull (counter-clockwise), both widened by [`REACH_MARGIN`].
struct Reach {
    bounds: [f32; 4],
    hull: Vec<[f32; 2]>,
}

impl Reach {
    /// Whether some ray inside `rays` (a box of normalised coordinates) may be in reach.
    #[inline]
    fn may_meet(&self, rays: &[f32; 4]) -> bool {
        let r = &self.bounds;
        if rays[0] > r[2] || rays[2] < r[0] || rays[1] > r[3] || rays[3] < r[1] {
            return false;
        }
        // Separated when all four corners of the box lie outside one edge of the hull.
        let corners = [
            [rays[0], rays[1]],
            [rays[2], rays[1]],
            [rays[0], rays[3]],
            [rays[2], rays[3]],
        ];
        let n = self.hull.len();
        !(0..n).any(|i| {
            let (a, b) = (self.hull[i], self.hull[(i + 1) % n]);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            let margin = REACH_MARGIN * (ex * ex + ey * ey).sqrt();
            corners
                .iter()
                .all(|c| ex * (c[1] - a[1]) - ey * (c[0] - a[0]) < -margin)
        })
    }
}

/// The convex hull of points, counter-clockwise (Andrew's monotone chain).
fn convex_hull(mut points: Vec<[f32; 2]>) -> Vec<[f32; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross = |o: [f32; 2], a: [f32; 2], b: [f32; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut hull: Vec<[f32; 2]> = Vec::with_capacity(2 * points.len());
    for pass in [points.clone(), points.iter().rev().copied().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

impl Plane<'_> {
    /// Whether a ray inside `rays` (a box of normalised coordinates) can meet the board.
    #[inline]
    fn may_meet(&self, rays: &[f32; 4]) -> bool {
        self.reach.as_ref().is_none_or(|r| r.may_meet(rays))
    }
}

/// The normalised rays that can meet what a ray is traced for on a board: its
/// paper (scaled as printed) and, if it has occluders, their reach around it,
/// over the bow's heights. The projection of that box, if it lies in front of the camera.
fn reach_of(pose: &Rigid, board: &PlacedBoard<'_>) -> Option<Reach> {
    let [x0, y0, x1, y1] = board.layout.paper_bounds_mm();
    let (scale, bow_mm) = (board.print_scale, board.bow_mm);
    let mut xs = [x0 * scale, x1 * scale];
    let mut ys = [y0 * scale, y1 * scale];
    if !board.occluders.is_empty() {
        xs = [xs[0].min(x0 - OCCLUDER_REACH_MM), xs[1].max(x1 + OCCLUDER_REACH_MM)];
        ys = [ys[0].min(y0 - OCCLUDER_REACH_MM), ys[1].max(y1 + OCCLUDER_REACH_MM)];
    }
    let zs = [bow_mm.min(0.0), bow_mm.max(0.0)];
    let mut reach = [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY];
    let mut projected = Vec::with_capacity(8);
    for x in xs {
        for y in ys {
            for z in zs {
                let p = pose * Point3::new(x, y, z);
                if p.z.is_nan() || p.z <= 1.0 {
                    return None;
                }
                let (nx, ny) = ((p.x / p.z) as f32, (p.y / p.z) as f32);
                reach = [reach[0].min(nx), reach[1].min(ny), reach[2].max(nx), reach[3].max(ny)];
                projected.push([nx, ny]);
            }
        }
    }
    let hull = convex_hull(projected);
    Some(Reach {
        bounds: [
            reach[0] - REACH_MARGIN,
            reach[1] - REACH_MARGIN,
            reach[2] + REACH_MARGIN,
            reach[3] + REACH_MARGIN,
        ],
        // A degenerate hull (a board seen edge-on) separates nothing: only the box counts.
        hull: if hull.len() >= 3 { hull } else { Vec::new() },
    })
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
                reach: reach_of(&pose, b),
            }
        })
        .collect()
}

/// The nearest board surface a camera ray meets: its distance along the ray and
/// its reflectance (ink, paper, or the occluder over it).
fn nearest_hit(planes: &[Plane<'_>], dir: &Vector3<f32>, pixel_rays: &[f32; 4]) -> Option<(f32, f32)> {
    let mut best: Option<(f32, f32)> = None;
    for plane in planes {
        if !plane.may_meet(pixel_rays) {
            continue;
        }
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
    let (focal, principal) = focal_and_principal(camera);
    let ([fx, _], [cx, cy]) = (focal, principal);

    let mut levels = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let pixel_rays = rays.pixel_box(x, y);
            let mut reflectance = if planes_per_time.iter().flatten().any(|p| p.may_meet(&pixel_rays)) {
                let mut sum = 0f32;
                for (iy, &sy) in SUB.iter().enumerate() {
                    for (ix, &sx) in SUB.iter().enumerate() {
                        let planes = &planes_per_time[TIME_OF_SUBSAMPLE[iy * 3 + ix] % planes_per_time.len()];
                        let ray = rays.ray(x, y, sx, sy);
                        let dir = Vector3::new(ray[0], ray[1], 1.0);
                        sum += match nearest_hit(planes, &dir, &pixel_rays) {
                            Some((_, r)) => r,
                            None => background(ray, focal, principal),
                        };
                    }
                }
                sum
            } else {
                rays.background_sum[y * w + x]
            };
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_in_reach_unless_outside_the_hull() {
        let hull = convex_hull(vec![[0.0, 0.0], [1.0, 0.0], [0.5, 0.5], [1.0, 1.0], [0.0, 1.0]]);
        assert_eq!(hull.len(), 4, "the inner point is not on the hull: {hull:?}");
        // A diamond: the box's corners outside it but inside its bounds.
        let diamond = Reach {
            bounds: [-1.0, -1.0, 1.0, 1.0],
            hull: convex_hull(vec![[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]),
        };
        assert!(diamond.may_meet(&[-0.1, -0.1, 0.1, 0.1]), "the middle");
        assert!(diamond.may_meet(&[0.4, 0.4, 0.6, 0.6]), "across an edge");
        assert!(
            !diamond.may_meet(&[0.8, 0.8, 0.9, 0.9]),
            "a corner of the bounds, off the diamond"
        );
        assert!(!diamond.may_meet(&[2.0, 0.0, 2.1, 0.1]), "off the bounds");
    }
}
