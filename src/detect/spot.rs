//! Stage 3 for the point and wire phantoms: compact echoes (a pin head, the dots
//! of wires) in a B-scan, and where the object's centre is behind each.
//!
//! 1. The fan's two straight sides are fitted from the image's own mask (outside
//!    the fan the image is 0); they meet at the fan's apex, from which every beam
//!    leaves. A linear probe (parallel sides) gives beams straight down.
//! 2. The image is smoothed (0.25 mm) and thresholded at the median plus 45 % of
//!    the span to the 99.7th percentile, inside the fan and below the near field.
//! 3. Connected echoes wider across the beam than an object can be are surfaces
//!    (the block, the container, the box floor) and are dropped.
//! 4. Echoes behind one another along a beam, within a few millimetres, are one
//!    object: a pin head's comet tail, the ringing of a wire thicker than the
//!    wavelength. The first one is the object's front surface.
//! 5. The front echo's position is the weighted centroid of its first lobe; the
//!    object's centre is one radius further along the beam.

use super::fan::{FAN_EDGE_MM, NEAR_FIELD_MM};
use crate::core::stats::median_and_quantile_nearest;
use opencv::core::Mat;

use crate::io::image::{gaussian_blur_f32, mat_to_gray8, ImageError};

/// What the detector needs to know.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpotSettings {
    pub spacing_mm_per_px: [f64; 2],
    /// Radius of the echoing object (pin head, wire), mm.
    pub object_radius_mm: f64,
}

/// One compact object.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Spot {
    /// The object's centre (front echo plus one radius along the beam), px.
    pub centre_px: [f64; 2],
    /// The front echo, px.
    pub echo_px: [f64; 2],
    /// Summed grey level above the threshold of the front echo.
    pub strength: f64,
    /// Width of the front echo across the beam, mm.
    pub width_mm: f64,
    /// Echoes of this object along its beam (1 + tail or ringing echoes).
    pub echoes: usize,
    /// Length along the beam from the front echo to the end of its last echo, mm.
    pub length_mm: f64,
}

/// What a B-scan holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Spots {
    /// Strongest first.
    pub spots: Vec<Spot>,
    /// The fan's apex, px (`None`: a linear probe, beams straight down).
    pub apex_px: Option<[f64; 2]>,
    /// Echoes dropped as surfaces.
    pub surfaces: usize,
}

/// An echo wider than two touching objects plus this is a surface.
const SURFACE_EXTRA_WIDTH_MM: f64 = 3.0;
/// Across-beam profile bins for splitting two touching objects, mm.
const SPLIT_BIN_MM: f64 = 0.2;
/// Echoes of one object lie within this distance across the beam...
const SAME_BEAM_MM: f64 = 1.5;
/// ...and this far behind its front echo.
const TAIL_LENGTH_MM: f64 = 8.0;
/// Axial extent of the front echo's first lobe.
const FRONT_LOBE_MM: f64 = 1.0;

/// Least-squares line `x = a + b y` through points, refitted without points more
/// than 1.5 px off.
fn fit_side(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let fit = |pts: &[(f64, f64)]| -> Option<(f64, f64)> {
        let n = pts.len() as f64;
        if pts.len() < 10 {
            return None;
        }
        let (my, mx) = (
            pts.iter().map(|p| p.1).sum::<f64>() / n,
            pts.iter().map(|p| p.0).sum::<f64>() / n,
        );
        let syy: f64 = pts.iter().map(|p| (p.1 - my).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.1 - my) * (p.0 - mx)).sum();
        (syy > 0.0).then(|| {
            let b = sxy / syy;
            (mx - b * my, b)
        })
    };
    let (a, b) = fit(points)?;
    let kept: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| (p.0 - (a + b * p.1)).abs() < 1.5)
        .copied()
        .collect();
    fit(&kept)
}

/// The apex of the fan from the image's mask (px), if its sides converge above the image.
pub fn fan_apex(mask: &[bool], width: usize, height: usize) -> Option<[f64; 2]> {
    let (mut left, mut right) = (Vec::new(), Vec::new());
    // The middle of the image height: below the top edge, above the bottom arc.
    for y in height / 10..height * 7 / 10 {
        let row = &mask[y * width..(y + 1) * width];
        let (Some(l), Some(r)) = (row.iter().position(|m| *m), row.iter().rposition(|m| *m)) else {
            continue;
        };
        if l > 0 && r + 1 < width {
            left.push((l as f64 - 0.5, y as f64));
            right.push((r as f64 + 0.5, y as f64));
        }
    }
    let (a1, b1) = fit_side(&left)?;
    let (a2, b2) = fit_side(&right)?;
    // The sides must open downwards and meet above the image.
    if (b1 - b2).abs() < 1e-3 {
        return None;
    }
    let y = (a2 - a1) / (b1 - b2);
    (y < 0.0 && b1 < 0.0 && b2 > 0.0).then_some([a1 + b1 * y, y])
}

struct Component {
    pixels: Vec<usize>,
}

/// Across-beam intervals `[from, to)` of the objects in one echo: one, or two
/// when the weighted across-beam profile has two peaks at least an object's
/// diameter apart with a dip below 60 % of the smaller one between them.
fn split_across(
    coords: &[(f64, f64, f64)],
    reference_angle: f64,
    across: &dyn Fn(f64, f64, f64) -> f64,
    radius_mm: f64,
) -> Vec<(f64, f64)> {
    let offsets: Vec<(f64, f64)> = coords
        .iter()
        .map(|p| (across(p.0, p.1, reference_angle), p.2))
        .collect();
    let lo = offsets.iter().map(|o| o.0).fold(f64::MAX, f64::min);
    let hi = offsets.iter().map(|o| o.0).fold(f64::MIN, f64::max);
    let whole = vec![(f64::MIN, f64::MAX)];
    let bins = ((hi - lo) / SPLIT_BIN_MM).ceil() as usize + 1;
    if hi - lo < 2.0 * radius_mm * 1.5 || bins < 5 {
        return whole;
    }
    let mut profile = vec![0.0; bins];
    for (a, weight) in &offsets {
        profile[((a - lo) / SPLIT_BIN_MM) as usize] += weight;
    }
    // Smooth over three bins.
    let smooth: Vec<f64> = (0..bins)
        .map(|i| (profile[i.saturating_sub(1)] + profile[i] + profile[(i + 1).min(bins - 1)]) / 3.0)
        .collect();
    let peaks: Vec<usize> = (1..bins - 1)
        .filter(|&i| smooth[i] >= smooth[i - 1] && smooth[i] > smooth[i + 1])
        .collect();
    let min_gap = (2.0 * radius_mm / SPLIT_BIN_MM).ceil() as usize;
    for (k, &a) in peaks.iter().enumerate() {
        for &b in &peaks[k + 1..] {
            if b - a < min_gap {
                continue;
            }
            let (dip_at, dip) = (a..=b)
                .map(|i| (i, smooth[i]))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .unwrap_or((a, smooth[a]));
            if dip < 0.6 * smooth[a].min(smooth[b]) {
                let cut = lo + dip_at as f64 * SPLIT_BIN_MM;
                return vec![(f64::MIN, cut), (cut, f64::MAX)];
            }
        }
    }
    whole
}

/// Connected pixels (8-neighbourhood) where `above` holds.
fn components(w: usize, h: usize, above: &dyn Fn(usize) -> bool) -> Vec<Component> {
    let mut seen = vec![false; w * h];
    let mut components = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if seen[start] || !above(start) {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut pixels = Vec::new();
        while let Some(i) = stack.pop() {
            pixels.push(i);
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if !seen[j] && above(j) {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        components.push(Component { pixels });
    }
    components
}

/// Beam coordinates (mm): distance from the apex and angle across the beam (a
/// linear array without an apex: depth and lateral position).
struct BeamFrame {
    apex_mm: Option<[f64; 2]>,
    spacing_mm_per_px: [f64; 2],
}

impl BeamFrame {
    fn beam(&self, x: f64, y: f64) -> (f64, f64) {
        let [sx, sy] = self.spacing_mm_per_px;
        let (u, v) = (x * sx, y * sy);
        match self.apex_mm {
            Some([ax, ay]) => {
                let (dx, dy) = (u - ax, v - ay);
                ((dx * dx + dy * dy).sqrt(), dx.atan2(dy))
            }
            None => (v, u),
        }
    }

    /// The offset across the beam from `reference_angle` at range `r`, mm.
    fn across(&self, r: f64, angle: f64, reference_angle: f64) -> f64 {
        match self.apex_mm {
            Some(_) => (angle - reference_angle) * r,
            None => angle - reference_angle,
        }
    }
}

/// One echo of a component: its front and back range, angle, width, the
/// centroid of its first lobe and its strength.
struct Echo {
    r_front: f64,
    r_back: f64,
    angle: f64,
    width_mm: f64,
    echo_px: [f64; 2],
    strength: f64,
}

/// The echo of the pixels of `c` whose offset across the beam lies in `part`.
fn part_echo(
    c: &Component,
    coords: &[(f64, f64, f64)],
    part: (f64, f64),
    mean_angle: f64,
    frame: &BeamFrame,
    w: usize,
) -> Option<Echo> {
    let across = |r: f64, angle: f64, reference_angle: f64| frame.across(r, angle, reference_angle);
    let members: Vec<(usize, &(f64, f64, f64))> = c
        .pixels
        .iter()
        .zip(coords)
        .filter(|(_, p)| {
            let a = across(p.0, p.1, mean_angle);
            a >= part.0 && a < part.1
        })
        .map(|(i, p)| (*i, p))
        .collect();
    if members.is_empty() {
        return None;
    }
    let total: f64 = members.iter().map(|(_, p)| p.2).sum();
    let angle = members.iter().map(|(_, p)| p.1 * p.2).sum::<f64>() / total;
    let r_front = members.iter().map(|(_, p)| p.0).fold(f64::MAX, f64::min);
    let r_back = members.iter().map(|(_, p)| p.0).fold(f64::MIN, f64::max);
    // The first lobe: the front echo, before any tail or ringing echo.
    let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
    for (i, p) in &members {
        if p.0 <= r_front + FRONT_LOBE_MM {
            sw += p.2;
            su += p.2 * (i % w) as f64;
            sv += p.2 * (i / w) as f64;
        }
    }
    let (lo, hi) = members.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (_, p)| {
        let a = across(p.0, p.1, angle);
        (lo.min(a), hi.max(a))
    });
    Some(Echo {
        r_front,
        r_back,
        angle,
        width_mm: hi - lo,
        echo_px: [su / sw, sv / sw],
        strength: total,
    })
}

/// Echoes behind one another along a beam grouped: the first is the object's
/// front (its centre one radius behind the echo).
fn grouped(mut echoes: Vec<Echo>, frame: &BeamFrame, object_radius_mm: f64) -> Vec<(Spot, f64, f64)> {
    let [sx, sy] = frame.spacing_mm_per_px;
    echoes.sort_by(|a, b| a.r_front.total_cmp(&b.r_front));
    let mut spots: Vec<(Spot, f64, f64)> = Vec::new();
    for e in echoes {
        let behind = spots.iter_mut().find(|(_, r, angle)| {
            frame.across(e.r_front, e.angle, *angle).abs() < SAME_BEAM_MM
                && e.r_front > *r
                && e.r_front - *r < TAIL_LENGTH_MM
        });
        if let Some((spot, r, _)) = behind {
            spot.echoes += 1;
            spot.length_mm = spot.length_mm.max(e.r_back - *r);
            continue;
        }
        let (r_echo, angle) = frame.beam(e.echo_px[0], e.echo_px[1]);
        let centre_mm = match frame.apex_mm {
            Some([ax, ay]) => {
                let r = r_echo + object_radius_mm;
                [ax + r * angle.sin(), ay + r * angle.cos()]
            }
            None => [e.echo_px[0] * sx, e.echo_px[1] * sy + object_radius_mm],
        };
        spots.push((
            Spot {
                centre_px: [centre_mm[0] / sx, centre_mm[1] / sy],
                echo_px: e.echo_px,
                strength: e.strength,
                width_mm: e.width_mm,
                echoes: 1,
                length_mm: e.r_back - e.r_front,
            },
            e.r_front,
            e.angle,
        ));
    }
    spots
}

/// Detects compact objects in a B-scan.
pub fn detect(image: &Mat, settings: &SpotSettings) -> Result<Spots, ImageError> {
    let gray = mat_to_gray8(image)?;
    let (w, h) = (gray.width, gray.height);
    let [sx, sy] = settings.spacing_mm_per_px;
    let mask: Vec<bool> = gray.data.iter().map(|v| *v > 0).collect();
    let apex_px = fan_apex(&mask, w, h);
    let edge_x = (FAN_EDGE_MM / sx).ceil() as usize;
    let edge_y = (FAN_EDGE_MM / sy).ceil() as usize;
    let near_rows = (NEAR_FIELD_MM / sy).ceil() as usize;
    let top = super::fan::first_rows(w, h, |i| mask[i]);
    let interior = super::fan::eroded(w, h, &mask, [edge_x, edge_y]);
    let usable = |x: usize, y: usize| interior[y * w + x] && top[x].is_some_and(|t| y >= t + near_rows);
    let mut smooth: Vec<f32> = gray.data.iter().map(|v| *v as f32).collect();
    gaussian_blur_f32(w, h, &mut smooth, 0.25 / sx, 0.25 / sy)?;
    let mut values: Vec<f32> = (0..w * h)
        .filter(|&i| usable(i % w, i / w))
        .map(|i| smooth[i])
        .collect();
    if values.is_empty() {
        return Ok(Spots {
            spots: Vec::new(),
            apex_px,
            surfaces: 0,
        });
    }
    let (median, high) = median_and_quantile_nearest(&mut values, 0.997);
    let threshold = median + 0.45 * (high - median).max(10.0);
    let above = |i: usize| smooth[i] >= threshold && usable(i % w, i / w);

    let components = components(w, h, &above);

    let frame = BeamFrame {
        apex_mm: apex_px.map(|a| [a[0] * sx, a[1] * sy]),
        spacing_mm_per_px: [sx, sy],
    };
    let beam = |x: f64, y: f64| frame.beam(x, y);
    let across = |r: f64, angle: f64, reference_angle: f64| frame.across(r, angle, reference_angle);
    let max_width = 4.0 * settings.object_radius_mm + SURFACE_EXTRA_WIDTH_MM;
    let mut surfaces = 0;
    let mut echoes: Vec<Echo> = Vec::new();
    for c in &components {
        if c.pixels.len() < 4 {
            continue;
        }
        let coords: Vec<(f64, f64, f64)> = c
            .pixels
            .iter()
            .map(|&i| {
                let (r, a) = beam((i % w) as f64, (i / w) as f64);
                (r, a, (smooth[i] - threshold) as f64 + 1.0)
            })
            .collect();
        let total: f64 = coords.iter().map(|p| p.2).sum();
        let mean_angle = coords.iter().map(|p| p.1 * p.2).sum::<f64>() / total;
        let (lo, hi) = coords.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            let a = across(p.0, p.1, mean_angle);
            (lo.min(a), hi.max(a))
        });
        let width_mm = hi - lo;
        if width_mm > max_width {
            surfaces += 1;
            continue;
        }
        // Two objects side by side (wires near their crossing) make one echo with
        // two peaks across the beam: split it at the dip between them.
        let parts = split_across(&coords, mean_angle, &across, settings.object_radius_mm);
        for part in parts {
            echoes.extend(part_echo(c, &coords, part, mean_angle, &frame, w));
        }
    }
    let spots = grouped(echoes, &frame, settings.object_radius_mm);
    let mut spots: Vec<Spot> = spots.into_iter().map(|(s, _, _)| s).collect();
    spots.sort_by(|a, b| {
        b.strength
            .total_cmp(&a.strength)
            .then(a.centre_px[0].total_cmp(&b.centre_px[0]))
    });
    Ok(Spots {
        spots,
        apex_px,
        surfaces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn apex_of_a_drawn_fan() {
        // A fan with its apex at (100, -50) px, 30° half angle.
        let (w, h) = (201, 150);
        let mask: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 - 100.0, (i / w) as f64 + 50.0);
                x.atan2(y).abs() < 30f64.to_radians() && (x * x + y * y).sqrt() < 190.0
            })
            .collect();
        let apex = fan_apex(&mask, w, h).unwrap();
        assert!(
            (apex[0] - 100.0).abs() < 0.5 && (apex[1] + 50.0).abs() < 1.5,
            "{apex:?}"
        );
        // Parallel sides (a linear probe): no apex.
        let linear: Vec<bool> = (0..w * h).map(|i| (20..180).contains(&(i % w))).collect();
        assert_eq!(fan_apex(&linear, w, h), None);
    }
}
