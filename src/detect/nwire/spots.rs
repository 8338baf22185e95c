//! The bright spots of a B-scan that may be wire dots: each frame's threshold on
//! the cleaned image (`super::morphology`), connected regions, their cores'
//! centres.

use super::settings::Segmentation;

/// A bright region that may be a wire dot: its intensity-weighted centre and strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DotCandidate {
    pub centre_px: [f64; 2],
    pub pixels: usize,
    /// Sum of the spot's grey levels (the opened image's, or the original's with
    /// `original_intensity_score`).
    pub weight: f64,
}

/// Bright spots in the clip rectangle, strongest first. Spots are the connected
/// regions (8-neighbours) of `cleaned` (the image after
/// [`super::morphology::clean`]) at or above the frame's threshold; their centres
/// are weighted by `cleaned` over their cores, their strength is the sum of
/// `cleaned` over them, or of `original` with `original_intensity_score`.
pub fn find_spots(
    cleaned: &[u8],
    original: &[u8],
    width: usize,
    height: usize,
    clip: [usize; 4],
    settings: &Segmentation,
) -> Vec<DotCandidate> {
    let [u0, v0, w, h] = clip;
    let (u1, v1) = ((u0 + w).min(width), (v0 + h).min(height));
    let pixels = cleaned;
    let t = settings.threshold_for(cleaned, width, height, clip);
    let mut seen = vec![false; width * height];
    let mut spots = Vec::new();
    let mut stack = Vec::new();
    for v in v0..v1 {
        for u in u0..u1 {
            let i = v * width + u;
            if seen[i] || pixels[i] < t {
                continue;
            }
            seen[i] = true;
            stack.push(i);
            let mut members = Vec::new();
            while let Some(j) = stack.pop() {
                members.push(j);
                let (ju, jv) = (j % width, j / width);
                for dv in -1i64..=1 {
                    for du in -1i64..=1 {
                        let (nu, nv) = (ju as i64 + du, jv as i64 + dv);
                        if nu < u0 as i64 || nv < v0 as i64 || nu >= u1 as i64 || nv >= v1 as i64 {
                            continue;
                        }
                        let k = nv as usize * width + nu as usize;
                        if !seen[k] && pixels[k] >= t {
                            seen[k] = true;
                            stack.push(k);
                        }
                    }
                }
            }
            if members.len() < settings.min_dot_px {
                continue;
            }
            let scored = if settings.original_intensity_score {
                original
            } else {
                cleaned
            };
            let weight: f64 = members.iter().map(|&j| f64::from(scored[j])).sum();
            // The centre from the dot's core: grey levels above a fraction of its peak.
            let centre = |grey: &[u8]| {
                let peak = members.iter().map(|&j| grey[j]).max().unwrap_or(t);
                let level = (f64::from(peak) * settings.core_fraction).max(f64::from(t));
                let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
                for &j in &members {
                    let w = f64::from(grey[j]) - level;
                    if w > 0.0 {
                        sw += w;
                        su += w * (j % width) as f64;
                        sv += w * (j / width) as f64;
                    }
                }
                (sw, su, sv)
            };
            let (sw, su, sv) = centre(cleaned);
            // A flat spot (no grey level above its core level): its pixels' mean.
            let centre_px = if sw > 0.0 {
                [su / sw, sv / sw]
            } else {
                let n = members.len() as f64;
                [
                    members.iter().map(|&j| (j % width) as f64).sum::<f64>() / n,
                    members.iter().map(|&j| (j / width) as f64).sum::<f64>() / n,
                ]
            };
            spots.push(DotCandidate {
                centre_px,
                pixels: members.len(),
                weight,
            });
        }
    }
    spots.sort_by(|a, b| {
        b.weight
            .total_cmp(&a.weight)
            .then(a.centre_px[0].total_cmp(&b.centre_px[0]))
    });
    spots.truncate(settings.max_candidates);
    spots
}
