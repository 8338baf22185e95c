//! The bright spots of a B-scan that may be wire dots: a morphological
//! opening, each frame's threshold, connected regions, their cores' centres.

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

/// Grey-level morphological opening with a disk (erosion, then dilation): removes
/// bright structures thinner than the disk (speckle, the streaks of comet tails)
/// and keeps the dots' shape.
pub fn open_image(pixels: &[u8], width: usize, height: usize, radius_px: u32) -> Result<Vec<u8>, opencv::Error> {
    use opencv::core::{Mat, Point, Size, BORDER_CONSTANT};
    use opencv::imgproc;
    use opencv::prelude::*;
    let src = Mat::new_rows_cols_with_data(height as i32, width as i32, pixels)?;
    let d = 2 * radius_px as i32 + 1;
    let kernel = imgproc::get_structuring_element(imgproc::MORPH_ELLIPSE, Size::new(d, d), Point::new(-1, -1))?;
    let mut out = Mat::default();
    imgproc::morphology_ex(
        &src,
        &mut out,
        imgproc::MORPH_OPEN,
        &kernel,
        Point::new(-1, -1),
        1,
        BORDER_CONSTANT,
        imgproc::morphology_default_border_value()?,
    )?;
    Ok(out.data_bytes()?.to_vec())
}

/// Bright spots in the clip rectangle, strongest first. Spots are the connected
/// regions above the threshold in `pixels`; their centres are weighted by
/// `centre_pixels` (e.g. the opened image), falling back to `pixels` where that
/// leaves nothing.
pub fn find_spots(
    pixels: &[u8],
    centre_pixels: &[u8],
    width: usize,
    height: usize,
    clip: [usize; 4],
    settings: &Segmentation,
) -> Vec<DotCandidate> {
    let [u0, v0, w, h] = clip;
    let (u1, v1) = ((u0 + w).min(width), (v0 + h).min(height));
    let t = settings.threshold_for(centre_pixels, width, height, clip);
    let mut seen = vec![false; width * height];
    let mut spots = Vec::new();
    let mut stack = Vec::new();
    for v in v0..v1 {
        for u in u0..u1 {
            let i = v * width + u;
            if seen[i] || pixels[i] <= t {
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
                        if !seen[k] && pixels[k] > t {
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
                pixels
            } else {
                centre_pixels
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
            let (mut sw, mut su, mut sv) = centre(centre_pixels);
            if sw <= 0.0 {
                (sw, su, sv) = centre(pixels);
            }
            if sw > 0.0 {
                spots.push(DotCandidate {
                    centre_px: [su / sw, sv / sw],
                    pixels: members.len(),
                    weight,
                });
            }
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
