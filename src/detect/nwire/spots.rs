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

/// How far inside the processed region a spot's centre must lie, px: PLUS
/// accepts a dot only at least this far from the region's first row and column
/// and more than this far from its end (`AcceptDot`), whatever the pixel size.
pub const DOT_MARGIN_PX: f64 = 8.0;

/// Bright spots in `region_px` (`[u0, v0, u1, v1)`, the region
/// [`super::morphology::clean`] processed), strongest first, at most
/// `max_candidates`. Spots are the connected regions (8-neighbours) of `cleaned`
/// at or above the frame's threshold whose grey-weighted centre lies
/// [`DOT_MARGIN_PX`] inside the region, as PLUS accepts them; their centres are
/// weighted by `cleaned` over their cores, their strength is the sum of
/// `cleaned` over them, or of `original` with `original_intensity_score`.
pub fn find_spots(
    cleaned: &[u8],
    original: &[u8],
    width: usize,
    height: usize,
    region_px: [usize; 4],
    settings: &Segmentation,
) -> Vec<DotCandidate> {
    let (u1, v1) = (region_px[2].min(width), region_px[3].min(height));
    let (u0, v0) = (region_px[0].min(u1), region_px[1].min(v1));
    let pixels = cleaned;
    let t = settings.threshold_for(cleaned, width, height, [u0, v0, u1 - u0, v1 - v0]);
    let inside = |c: [f64; 2]| {
        let (lo, hi) = ([u0 as f64, v0 as f64], [u1 as f64, v1 as f64]);
        (0..2).all(|k| c[k] >= lo[k] + DOT_MARGIN_PX && c[k] < hi[k] - DOT_MARGIN_PX)
    };
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
            if members.len() < settings.min_dot_px || !inside(grey_weighted_centre(cleaned, &members, width)) {
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

/// The centre of `members` (pixel indices of a `width`-wide image) weighted by
/// their grey levels: PLUS's dot centre, by which it accepts a dot.
fn grey_weighted_centre(grey: &[u8], members: &[usize], width: usize) -> [f64; 2] {
    let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
    for &j in members {
        let w = f64::from(grey[j]);
        sw += w;
        su += w * (j % width) as f64;
        sv += w * (j / width) as f64;
    }
    [su / sw, sv / sw]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dot whose centre is within 8 px of the region's start, or not more
    /// than 8 px before its end, is not a candidate; one just inside is.
    #[test]
    fn spots_keep_plus_s_margin_inside_the_region() {
        let (w, h) = (100usize, 60usize);
        let region = [10, 10, 90, 50];
        let mut img = vec![0u8; w * h];
        // 3x3 dots centred at u = 17 (7 px in), 18 (8 px in), 50, 81 (9 px
        // before the end), 82 (8 px before it).
        for (u, v) in [(17usize, 30usize), (18, 20), (50, 30), (81, 40), (82, 25)] {
            for dv in 0..3 {
                for du in 0..3 {
                    img[(v - 1 + dv) * w + u - 1 + du] = 200;
                }
            }
        }
        let settings = Segmentation {
            min_dot_px: 4,
            ..Segmentation::default()
        };
        let mut us: Vec<f64> = find_spots(&img, &img, w, h, region, &settings)
            .iter()
            .map(|s| s.centre_px[0])
            .collect();
        us.sort_by(f64::total_cmp);
        assert_eq!(us, vec![18.0, 50.0, 81.0]);
    }
}
