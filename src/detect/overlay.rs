//! A screen grab's overlay found from the recording itself. A B-scan grabbed
//! from a scanner's video output carries text, rulers, depth and focus markers
//! drawn over and around the image; the dots of a depth scale look like wire
//! dots to the segmentation. They are the part of the picture that does not
//! move: while the probe sweeps, an echo moves across the image, and a pixel of
//! the overlay is bright in every frame. So the overlay is every pixel that is
//! at least as bright as the segmentation's threshold in every frame, grown by
//! the dot-opening radius; the segmentation then sees those pixels as black.
//!
//! It is used when no clip rectangle is given (a device set without
//! `ClipRectangleOrigin`/`Size`, a manifest without `clip_rectangle_px`), and
//! needs a sweep: at least [`MIN_FRAMES`] frames.

/// Frames needed before "bright in every frame" says "drawn, not imaged".
pub const MIN_FRAMES: usize = 10;

/// Pixels that are bright in every frame of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Overlay {
    pub width: usize,
    pub height: usize,
    /// Row-major, `true` for an overlay pixel (after growing).
    pub mask: Vec<bool>,
    /// Grey level a pixel had to reach in every frame.
    pub threshold_grey: u8,
    /// Frames it was found from.
    pub frames: usize,
}

impl Overlay {
    /// The overlay of `frames` (each `width × height` grey pixels, row-major):
    /// the pixels at least `threshold_grey` bright in every frame, or, without
    /// it, `threshold_percent` % of a frame's brightest pixel (the median over
    /// frames of each frame's brightest); grown by `grow_px`. `None` for fewer
    /// than [`MIN_FRAMES`] frames or frames of another size.
    pub fn find<'a>(
        frames: impl Iterator<Item = &'a [u8]>,
        [width, height]: [usize; 2],
        threshold_grey: Option<u8>,
        threshold_percent: f64,
        grow_px: usize,
    ) -> Option<Overlay> {
        let mut lowest: Vec<u8> = Vec::new();
        let mut brightest: Vec<u8> = Vec::new();
        for pixels in frames {
            if pixels.len() != width * height {
                return None;
            }
            brightest.push(pixels.iter().copied().max().unwrap_or(0));
            if lowest.is_empty() {
                lowest = pixels.to_vec();
            } else {
                lowest.iter_mut().zip(pixels).for_each(|(low, &p)| *low = (*low).min(p));
            }
        }
        if brightest.len() < MIN_FRAMES {
            return None;
        }
        let frames = brightest.len();
        brightest.sort_unstable();
        let median = brightest[frames / 2] as f64;
        let threshold_grey =
            threshold_grey.unwrap_or_else(|| (median * threshold_percent / 100.0).round().clamp(1.0, 255.0) as u8);
        let seeds: Vec<bool> = lowest.iter().map(|&p| p >= threshold_grey).collect();
        Some(Overlay {
            width,
            height,
            mask: grow(&seeds, width, height, grow_px),
            threshold_grey,
            frames,
        })
    }

    /// Overlay pixels.
    pub fn pixels(&self) -> usize {
        self.mask.iter().filter(|&&m| m).count()
    }

    /// `pixels` (one frame) with the overlay blacked out.
    pub fn remove(&self, pixels: &[u8]) -> Vec<u8> {
        pixels
            .iter()
            .zip(&self.mask)
            .map(|(&p, &overlay)| if overlay { 0 } else { p })
            .collect()
    }
}

/// `mask` grown by `by` pixels (a square neighbourhood).
fn grow(mask: &[bool], width: usize, height: usize, by: usize) -> Vec<bool> {
    // Rows first, then columns: the square's two passes.
    let mut rows = vec![false; mask.len()];
    for y in 0..height {
        let row = &mask[y * width..(y + 1) * width];
        for x in 0..width {
            let (a, b) = (x.saturating_sub(by), (x + by).min(width - 1));
            rows[y * width + x] = row[a..=b].iter().any(|&m| m);
        }
    }
    let mut out = vec![false; mask.len()];
    for x in 0..width {
        for y in 0..height {
            let (a, b) = (y.saturating_sub(by), (y + by).min(height - 1));
            out[y * width + x] = (a..=b).any(|k| rows[k * width + x]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep of `n` frames, 40 × 30: a label drawn at (2..6, 2) in every frame,
    /// and an echo dot moving one pixel to the right per frame along row 20.
    fn sweep(n: usize) -> Vec<Vec<u8>> {
        (0..n)
            .map(|k| {
                let mut frame = vec![3u8; 40 * 30];
                for x in 2..6 {
                    frame[2 * 40 + x] = 250;
                }
                frame[20 * 40 + 5 + k] = 200;
                frame
            })
            .collect()
    }

    #[test]
    fn the_drawn_label_is_overlay_and_the_moving_echo_is_not() {
        let frames = sweep(12);
        let overlay = Overlay::find(frames.iter().map(Vec::as_slice), [40, 30], None, 10.0, 1).unwrap();
        assert_eq!(overlay.threshold_grey, 25);
        assert_eq!(overlay.frames, 12);
        // The label (4 × 1) grown by one pixel: 6 × 3.
        assert_eq!(overlay.pixels(), 18);
        assert!(overlay.mask[2 * 40 + 2] && overlay.mask[40 + 1] && overlay.mask[3 * 40 + 6]);
        assert!(!overlay.mask[2 * 40 + 7]);
        let cleaned = overlay.remove(&frames[4]);
        assert_eq!(cleaned[2 * 40 + 3], 0);
        assert_eq!(cleaned[20 * 40 + 9], 200, "the echo is kept");
        assert_eq!(cleaned[10 * 40 + 10], 3, "the background is kept");
    }

    #[test]
    fn too_few_frames_or_a_frame_of_another_size_finds_nothing() {
        let frames = sweep(MIN_FRAMES - 1);
        assert!(Overlay::find(frames.iter().map(Vec::as_slice), [40, 30], None, 10.0, 1).is_none());
        let mut frames = sweep(MIN_FRAMES);
        frames[3].pop();
        assert!(Overlay::find(frames.iter().map(Vec::as_slice), [40, 30], None, 10.0, 1).is_none());
    }
}
