//! The B-scan's clean-up before its dots are thresholded, as PLUS's
//! `PlusFidSegmentation::MorphologicalOperations` defines it:
//!
//! 1. bright lines longer than the bar are removed: for bars at 0°, 45°, 90° and
//!    135° in turn (each `2 b + 1` pixels, `b` = `MorphologicalOpeningBarSizeMm`
//!    over the approximate pixel size), the image's opening with the bar
//!    (a grey-level erosion, then a dilation) is subtracted from it, saturating
//!    at black (a white top-hat per direction);
//! 2. what is left is opened with a disk of radius `r`
//!    (`MorphologicalOpeningCircleRadiusMm`), the pixels within `r` of the centre
//!    (`x² + y² ≤ r²`).
//!
//! Every stage is computed inside the region of interest only (the clip
//! rectangle, pulled in so that a bar never leaves the image) and is black
//! outside it, so a bright structure outside the region never reaches a dot.

use opencv::core::{self, Mat, Point, Scalar, BORDER_CONSTANT, CV_8U};
use opencv::imgproc;
use opencv::prelude::*;

/// The processed image, and the region `[u0, v0, u1, v1)` it was computed in
/// (empty when the image is too small for the bar).
#[derive(Debug, Clone, PartialEq)]
pub struct Cleaned {
    pub pixels: Vec<u8>,
    pub region_px: [usize; 4],
}

/// The region PLUS processes: the clip rectangle `[u, v, width, height]` pulled in
/// to at least `bar_px + 1` from every edge of a `width` x `height` image
/// (`ValidateRegionOfInterest`); `[0; 4]` when the image is narrower than a bar.
pub fn region_of_interest(clip: [usize; 4], width: usize, height: usize, bar_px: usize) -> [usize; 4] {
    if width < 2 * bar_px + 1 || height < 2 * bar_px + 1 {
        return [0; 4];
    }
    let [u, v, w, h] = clip;
    let u0 = u.max(bar_px + 1).min(width - bar_px - 1);
    let v0 = v.max(bar_px + 1).min(height - bar_px - 1);
    let u1 = (u + w).max(u0).min(width - bar_px - 1);
    let v1 = (v + h).max(v0).min(height - bar_px - 1);
    [u0, v0, u1, v1]
}

/// The bars' structuring elements, `(2 b + 1)` square, one line of ones each: 0°
/// (along a row), 45° (up to the right), 90° (along a column), 135°.
fn bar_kernels(bar_px: usize) -> Result<Vec<Mat>, opencv::Error> {
    let n = 2 * bar_px + 1;
    let mut kernels = Vec::with_capacity(4);
    for direction in 0..4 {
        let mut kernel = Mat::new_rows_cols_with_default(n as i32, n as i32, CV_8U, Scalar::all(0.0))?;
        for k in 0..n {
            let (row, col) = match direction {
                0 => (bar_px, k),
                1 => (k, n - 1 - k),
                2 => (k, bar_px),
                _ => (k, k),
            };
            *kernel.at_2d_mut::<u8>(row as i32, col as i32)? = 1;
        }
        kernels.push(kernel);
    }
    Ok(kernels)
}

/// The disk of radius `r` px: the offsets with `x² + y² ≤ r²`.
fn disk_kernel(radius_px: usize) -> Result<Mat, opencv::Error> {
    let n = 2 * radius_px + 1;
    let r = radius_px as i64;
    let mut kernel = Mat::new_rows_cols_with_default(n as i32, n as i32, CV_8U, Scalar::all(0.0))?;
    for row in 0..n {
        for col in 0..n {
            let (y, x) = (row as i64 - r, col as i64 - r);
            if x * x + y * y <= r * r {
                *kernel.at_2d_mut::<u8>(row as i32, col as i32)? = 1;
            }
        }
    }
    Ok(kernel)
}

/// `image` black outside `region` `[u0, v0, u1, v1)`.
fn black_outside(image: &mut Mat, region: [usize; 4]) -> Result<(), opencv::Error> {
    let [u0, v0, u1, v1] = region;
    let (rows, cols) = (image.rows() as usize, image.cols() as usize);
    let bytes = image.data_bytes_mut()?;
    for v in 0..rows {
        let row = &mut bytes[v * cols..(v + 1) * cols];
        if v < v0 || v >= v1 {
            row.fill(0);
        } else {
            row[..u0.min(cols)].fill(0);
            row[u1.min(cols)..].fill(0);
        }
    }
    Ok(())
}

fn morph(src: &Mat, kernel: &Mat, erode: bool, region: [usize; 4]) -> Result<Mat, opencv::Error> {
    let mut out = Mat::default();
    let anchor = Point::new(-1, -1);
    let border = imgproc::morphology_default_border_value()?;
    if erode {
        imgproc::erode(src, &mut out, kernel, anchor, 1, BORDER_CONSTANT, border)?;
    } else {
        imgproc::dilate(src, &mut out, kernel, anchor, 1, BORDER_CONSTANT, border)?;
    }
    black_outside(&mut out, region)?;
    Ok(out)
}

/// PLUS's clean-up of one `width` x `height` grey image (the module's doc) in the
/// clip rectangle `[u, v, width, height]`; `bar_px` 0 removes no lines,
/// `radius_px` 0 opens with no disk.
pub fn clean(
    pixels: &[u8],
    width: usize,
    height: usize,
    clip: [usize; 4],
    bar_px: usize,
    radius_px: usize,
) -> Result<Cleaned, opencv::Error> {
    let region = region_of_interest(clip, width, height, bar_px.max(radius_px));
    let mut working = Mat::new_rows_cols_with_data(height as i32, width as i32, pixels)?.try_clone()?;
    if region[0] >= region[2] || region[1] >= region[3] {
        return Ok(Cleaned {
            pixels: vec![0; width * height],
            region_px: region,
        });
    }
    if bar_px > 0 {
        for kernel in bar_kernels(bar_px)? {
            let opened = morph(&morph(&working, &kernel, true, region)?, &kernel, false, region)?;
            let mut rest = Mat::default();
            core::subtract(&working, &opened, &mut rest, &core::no_array(), -1)?;
            working = rest;
        }
    }
    let mut out = working;
    if radius_px > 0 {
        let disk = disk_kernel(radius_px)?;
        out = morph(&morph(&out, &disk, true, region)?, &disk, false, region)?;
    } else {
        black_outside(&mut out, region)?;
    }
    Ok(Cleaned {
        pixels: out.data_bytes()?.to_vec(),
        region_px: region,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plain reference: each stage pixel by pixel, as the module's doc says.
    fn reference(pixels: &[u8], width: usize, height: usize, region: [usize; 4], bar: usize, r: usize) -> Vec<u8> {
        let [u0, v0, u1, v1] = region;
        let inside = |u: usize, v: usize| u >= u0 && u < u1 && v >= v0 && v < v1;
        let filter = |src: &[u8], offsets: &[(i64, i64)], erode: bool| {
            let mut out = vec![0u8; width * height];
            for v in v0..v1 {
                for u in u0..u1 {
                    let values = offsets
                        .iter()
                        .map(|(du, dv)| src[(v as i64 + dv) as usize * width + (u as i64 + du) as usize]);
                    out[v * width + u] = if erode {
                        values.min().unwrap()
                    } else {
                        values.max().unwrap()
                    };
                }
            }
            out
        };
        let b = bar as i64;
        let mut working = pixels.to_vec();
        if bar > 0 {
            for (su, sv) in [(1i64, 0i64), (1, -1), (0, 1), (1, 1)] {
                let offsets: Vec<(i64, i64)> = (-b..=b).map(|k| (k * su, k * sv)).collect();
                let opened = filter(&filter(&working, &offsets, true), &offsets, false);
                for i in 0..working.len() {
                    working[i] = working[i].saturating_sub(opened[i]);
                }
            }
        }
        let ri = r as i64;
        let disk: Vec<(i64, i64)> = (-ri..=ri)
            .flat_map(|y| (-ri..=ri).map(move |x| (x, y)))
            .filter(|(x, y)| x * x + y * y <= ri * ri)
            .collect();
        let out = filter(&filter(&working, &disk, true), &disk, false);
        (0..width * height)
            .map(|i| if inside(i % width, i / width) { out[i] } else { 0 })
            .collect()
    }

    #[test]
    fn removes_long_lines_keeps_dots_and_equals_the_plain_reference() {
        let (width, height) = (90usize, 70usize);
        let mut state = 12345u64;
        let mut image: Vec<u8> = (0..width * height)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 59) * 3) as u8
            })
            .collect();
        // A horizontal line 40 px long, a diagonal one, and a 5x5 dot.
        for u in 20..60 {
            image[30 * width + u] = 200;
        }
        for k in 0..30 {
            image[(55 - k) * width + 15 + k] = 180;
        }
        for v in 12..17 {
            for u in 60..65 {
                image[v * width + u] = 220;
            }
        }
        let clip = [5, 5, 80, 60];
        let cleaned = clean(&image, width, height, clip, 6, 1).unwrap();
        assert_eq!(cleaned.region_px, [7, 7, 83, 63]);
        let expected = reference(&image, width, height, cleaned.region_px, 6, 1);
        assert_eq!(cleaned.pixels, expected);
        assert!(cleaned.pixels[14 * width + 62] > 150, "the dot stays");
        assert_eq!(cleaned.pixels[30 * width + 40], 0, "the horizontal line goes");
        assert_eq!(cleaned.pixels[(55 - 15) * width + 30], 0, "the diagonal line goes");
        let no_bars = clean(&image, width, height, clip, 0, 1).unwrap();
        assert_eq!(
            no_bars.pixels,
            reference(&image, width, height, no_bars.region_px, 0, 1)
        );
        // An image narrower than a bar has no region and comes out black.
        let tiny = clean(&image[..10 * width], width, 10, clip, 6, 1).unwrap();
        assert!(tiny.pixels.iter().all(|&p| p == 0) && tiny.region_px == [0; 4]);
    }
}
