//! Crossing sweeps rendered by slicing a textured volume, with the truth
//! known: the B-scans of a tracked probe moving through tissue-like texture,
//! for calibration from the images ([`crate::estimate::selfcal`]).
//!
//! What is rendered, each at a stated value:
//! - **The tissue**: echogenicity 0.3 with [`BLOBS`] ellipsoidal inclusions of
//!   radius 1–6 mm, each brighter or darker by up to 0.5 (a smooth Gaussian
//!   profile), placed uniformly at random in the volume from the seed.
//! - **The beam**: the echogenicity averaged across the image plane over the
//!   slice thickness (elevation FWHM [`ELEVATION_FWHM_MM`]) and blurred in the
//!   plane by the point-spread function (axial FWHM [`AXIAL_FWHM_MM`], lateral
//!   [`LATERAL_FWHM_MM`]): textbook values for a 7.5 MHz linear array
//!   (axial resolution about half a pulse length, lateral about a millimetre at
//!   the focus, a slice 1–2 mm thick), not measured on one scanner.
//! - **Speckle**: fully developed (the magnitude of a complex Gaussian field
//!   blurred by the same point-spread function: Rayleigh-distributed, unit mean),
//!   multiplying the echogenicity; drawn afresh for every frame.
//! - **Grey levels**: echogenicity 1 at grey 200, rounded, clipped to 0–255.
//!
//! Left out: speckle that stays with the tissue between frames (real speckle
//! of overlapping frames is partly the same, here it never is: harder than real),
//! shadowing and attenuation with depth, reverberation, view-dependent specular
//! echoes, the speed of sound, tracker noise and lag.

use nalgebra::{Matrix4, Point3, Rotation3, Vector3};

use crate::core::rng::Rng;

/// Inclusions in the volume.
pub const BLOBS: usize = 400;
/// The beam: slice thickness and in-plane resolution (FWHM, mm).
pub const ELEVATION_FWHM_MM: f64 = 1.5;
pub const AXIAL_FWHM_MM: f64 = 0.4;
pub const LATERAL_FWHM_MM: f64 = 1.0;
const FWHM_PER_SD: f64 = 2.354_820_045;

/// Echogenicity on a grid (Reference mm), 0 outside.
#[derive(Debug, Clone)]
pub struct TexturedVolume {
    pub origin_mm: [f64; 3],
    pub voxel_mm: f64,
    pub dims: [usize; 3],
    pub values: Vec<f32>,
}

impl TexturedVolume {
    /// A cube of side `size_mm` centred on the origin, textured from `seed`.
    pub fn blobs(seed: u64, size_mm: f64, voxel_mm: f64) -> TexturedVolume {
        let n = (size_mm / voxel_mm).ceil() as usize + 1;
        let origin = -size_mm / 2.0;
        let mut values = vec![0.3f32; n * n * n];
        let mut rng = Rng::new(seed);
        for _ in 0..BLOBS {
            let c = [0, 1, 2].map(|_| rng.uniform(origin, -origin));
            let radii = [0, 1, 2].map(|_| rng.uniform(1.0, 6.0));
            let amplitude = rng.uniform(-0.5, 0.5) as f32;
            let reach = radii.map(|r| (2.0 * r / voxel_mm).ceil() as i64);
            let centre = c.map(|x| ((x - origin) / voxel_mm).round() as i64);
            for z in (centre[2] - reach[2]).max(0)..(centre[2] + reach[2] + 1).min(n as i64) {
                for y in (centre[1] - reach[1]).max(0)..(centre[1] + reach[1] + 1).min(n as i64) {
                    for x in (centre[0] - reach[0]).max(0)..(centre[0] + reach[0] + 1).min(n as i64) {
                        let p = [x, y, z].map(|i| origin + i as f64 * voxel_mm);
                        let d2: f64 = (0..3).map(|k| ((p[k] - c[k]) / radii[k]).powi(2)).sum();
                        let i = (z as usize * n + y as usize) * n + x as usize;
                        values[i] += amplitude * (-d2).exp() as f32;
                    }
                }
            }
        }
        values.iter_mut().for_each(|v| *v = v.max(0.0));
        TexturedVolume {
            origin_mm: [origin; 3],
            voxel_mm,
            dims: [n; 3],
            values,
        }
    }

    /// Trilinear echogenicity at `p` (0 outside).
    pub fn at(&self, p: &Point3<f64>) -> f64 {
        let g = [0, 1, 2].map(|k| (p[k] - self.origin_mm[k]) / self.voxel_mm);
        let f = g.map(f64::floor);
        if f.iter().zip(&self.dims).any(|(&v, &d)| v < 0.0 || v + 1.0 >= d as f64) {
            return 0.0;
        }
        let [nx, ny, _] = self.dims;
        let i = [f[0] as usize, f[1] as usize, f[2] as usize];
        let a = [g[0] - f[0], g[1] - f[1], g[2] - f[2]];
        let mut v = 0.0;
        for (dz, wz) in [(0, 1.0 - a[2]), (1, a[2])] {
            for (dy, wy) in [(0, 1.0 - a[1]), (1, a[1])] {
                for (dx, wx) in [(0, 1.0 - a[0]), (1, a[0])] {
                    let j = ((i[2] + dz) * ny + i[1] + dy) * nx + i[0] + dx;
                    v += wz * wy * wx * f64::from(self.values[j]);
                }
            }
        }
        v
    }
}

/// The scanner's image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SliceScanner {
    pub width_px: usize,
    pub height_px: usize,
    /// mm per pixel along a row (lateral) and down a column (axial).
    pub spacing_mm: [f64; 2],
}

/// Separable Gaussian blur of a row-major image, SDs in pixels.
fn blur(image: &mut [f64], w: usize, h: usize, sd_px: [f64; 2]) {
    let kernel = |sd: f64| -> Vec<f64> {
        let r = (3.0 * sd).ceil().max(1.0) as i64;
        let k: Vec<f64> = (-r..=r)
            .map(|i| (-(i as f64).powi(2) / (2.0 * sd * sd)).exp())
            .collect();
        let s: f64 = k.iter().sum();
        k.into_iter().map(|x| x / s).collect()
    };
    let (kx, ky) = (kernel(sd_px[0]), kernel(sd_px[1]));
    let (rx, ry) = ((kx.len() / 2) as i64, (ky.len() / 2) as i64);
    let mut tmp = vec![0.0; image.len()];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = kx
                .iter()
                .enumerate()
                .map(|(j, k)| k * image[y * w + (x as i64 + j as i64 - rx).clamp(0, w as i64 - 1) as usize])
                .sum();
        }
    }
    for y in 0..h {
        for x in 0..w {
            image[y * w + x] = ky
                .iter()
                .enumerate()
                .map(|(j, k)| k * tmp[(y as i64 + j as i64 - ry).clamp(0, h as i64 - 1) as usize * w + x])
                .sum();
        }
    }
}

/// One B-scan: the volume seen by the scanner placed by `reference_T_pixel`
/// (pixel (column, row, 0, 1) to Reference mm; its third column is the plane's
/// normal scaled as the pixels), speckle drawn from `rng`.
pub fn render_frame(
    volume: &TexturedVolume,
    scanner: &SliceScanner,
    reference_T_pixel: &Matrix4<f64>,
    rng: &mut Rng,
) -> Vec<u8> {
    let (w, h) = (scanner.width_px, scanner.height_px);
    let normal = reference_T_pixel.fixed_view::<3, 1>(0, 2).into_owned();
    let normal = normal / normal.norm().max(1e-12);
    let sd_e = ELEVATION_FWHM_MM / FWHM_PER_SD;
    let offsets = [(-sd_e, 0.25), (0.0, 0.5), (sd_e, 0.25)];
    let mut echo: Vec<f64> = (0..w * h)
        .map(|i| {
            let p = reference_T_pixel.transform_point(&Point3::new((i % w) as f64, (i / w) as f64, 0.0));
            offsets.iter().map(|(d, wt)| wt * volume.at(&(p + normal * *d))).sum()
        })
        .collect();
    let psf_px = [
        LATERAL_FWHM_MM / FWHM_PER_SD / scanner.spacing_mm[0],
        AXIAL_FWHM_MM / FWHM_PER_SD / scanner.spacing_mm[1],
    ];
    blur(&mut echo, w, h, psf_px);
    let mut re: Vec<f64> = (0..w * h).map(|_| rng.normal(0.0, 1.0)).collect();
    let mut im: Vec<f64> = (0..w * h).map(|_| rng.normal(0.0, 1.0)).collect();
    blur(&mut re, w, h, psf_px);
    blur(&mut im, w, h, psf_px);
    // The field's magnitude scaled to unit mean (Rayleigh: mean = σ √(π/2)).
    let var = re.iter().chain(&im).map(|v| v * v).sum::<f64>() / (2 * w * h) as f64;
    let scale = 1.0 / (var.sqrt() * (std::f64::consts::PI / 2.0).sqrt()).max(1e-12);
    (0..w * h)
        .map(|i| {
            let speckle = (re[i] * re[i] + im[i] * im[i]).sqrt() * scale;
            (echo[i] * speckle * 200.0).round().clamp(0.0, 255.0) as u8
        })
        .collect()
}

/// The image's pose (rigid, mm: x along a row, y down a column, z the normal)
/// for frame `i` of `n` of a sweep through the origin along `heading_deg`
/// (about the Reference z), `length_mm` long, rocking and turning as it goes.
pub fn crossing_pose(scanner: &SliceScanner, heading_deg: f64, length_mm: f64, i: usize, n: usize) -> Matrix4<f64> {
    let s = if n > 1 { i as f64 / (n - 1) as f64 } else { 0.5 };
    crossing_pose_at(scanner, heading_deg, length_mm, s)
}

/// [`crossing_pose`] at the fraction `s` of the sweep (0 its first frame, 1
/// its last; any other value continues the same motion).
pub fn crossing_pose_at(scanner: &SliceScanner, heading_deg: f64, length_mm: f64, s: f64) -> Matrix4<f64> {
    let phase = std::f64::consts::TAU * s;
    // Rocking across the plane (tilt about the image's rows), leaning in the
    // plane (about the normal), and twisting (about the image's columns).
    let rock = 15f64.to_radians() * (2.0 * phase).sin();
    let lean = 10f64.to_radians() * (1.5 * phase + 0.7).sin();
    let twist = 10f64.to_radians() * (phase + 1.9).sin();
    let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), heading_deg.to_radians());
    // At rest the image's row runs along the Reference x, its column down (−z),
    // its normal along +y: the sweep goes along the normal.
    let rest = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0));
    let wobble = Rotation3::from_axis_angle(&Vector3::x_axis(), rock)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), twist)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), lean);
    let r = heading * rest * wobble;
    let half = Vector3::new(
        scanner.width_px as f64 * scanner.spacing_mm[0] / 2.0,
        scanner.height_px as f64 * scanner.spacing_mm[1] / 2.0,
        0.0,
    );
    let centre = heading * Vector3::new(0.0, (s - 0.5) * length_mm, 0.0);
    let t = centre - r * half;
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(r.matrix());
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
    m
}
