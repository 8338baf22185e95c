//! The sweeps overlaid in planes of the grid, before and after the correction,
//! as PNG pictures embedded in `selfcal`'s page: the first sweep in magenta,
//! the others in green, so that where they agree the picture is grey and where
//! one is displaced from the other its edges show in colour.

use crate::estimate::selfcal::overlay::{Cut, OverlaySlice, AXES};
use crate::report::error::OutputError;
use crate::report::page::gallery::data_uri_of;

/// The page shows a picture at least this wide, px (small grids are enlarged).
const MIN_SHOWN_PX: usize = 240;

/// A layer's grey window: its values' 1st and 99th percentiles over both cuts
/// of a plane, so that before and after are drawn alike.
fn window(slice: &OverlaySlice, layer: usize) -> (f32, f32) {
    let mut values: Vec<f32> = [&slice.before, &slice.after]
        .iter()
        .flat_map(|c| c.layers[layer].iter().flatten().copied())
        .filter(|v| v.is_finite())
        .collect();
    if values.is_empty() {
        return (0.0, 1.0);
    }
    values.sort_by(f32::total_cmp);
    let at = |f: f64| values[((values.len() - 1) as f64 * f).round() as usize];
    let (low, high) = (at(0.01), at(0.99));
    (low, if high > low { high } else { low + 1.0 })
}

/// One cut as RGB pixels: red and blue the first layer, green the second, 0
/// where a layer does not cover.
fn rgb(cut: &Cut, windows: [(f32, f32); 2]) -> Vec<u8> {
    let level = |v: Option<f32>, (low, high): (f32, f32)| {
        v.map_or(0, |v| {
            (((v - low) / (high - low)) * 255.0).round().clamp(0.0, 255.0) as u8
        })
    };
    cut.layers[0]
        .iter()
        .zip(&cut.layers[1])
        .flat_map(|(a, b)| {
            let (a, b) = (level(*a, windows[0]), level(*b, windows[1]));
            [a, b, a]
        })
        .collect()
}

fn png_rgb(pixels: &[u8], size: [usize; 2]) -> Result<Vec<u8>, OutputError> {
    crate::io::png_codec::encode(pixels, size[0], size[1], 3).map_err(|e| OutputError::Figure(format!("overlay: {e}")))
}

fn correlation_words(cut: &Cut) -> String {
    match cut.correlation {
        Some(c) => format!("correlation {c:.3} over {} pixels", cut.pixels_compared),
        None => format!("{} common pixels, too few to correlate", cut.pixels_compared),
    }
}

/// Each plane's pictures (as data URIs) and words for the page's template.
pub fn figures(overlays: &[OverlaySlice]) -> Result<Vec<serde_json::Value>, OutputError> {
    overlays
        .iter()
        .filter(|s| s.size[0] > 0 && s.size[1] > 0)
        .map(|s| {
            let windows = [window(s, 0), window(s, 1)];
            let picture = |c: &Cut| -> Result<String, OutputError> {
                Ok(data_uri_of("image/png", &png_rgb(&rgb(c, windows), s.size)?))
            };
            let scale = MIN_SHOWN_PX.div_ceil(s.size[0]).max(1);
            Ok(serde_json::json!({
                "plane": format!("{} = {:.1} mm", AXES[s.normal], s.position_mm),
                "axes": format!("{} across, {} down", AXES[s.across], AXES[s.down]),
                "extent": format!("{:.0} × {:.0} mm", s.size[0] as f64 * s.voxel_mm, s.size[1] as f64 * s.voxel_mm),
                "width": s.size[0] * scale,
                "height": s.size[1] * scale,
                "before": picture(&s.before)?,
                "after": picture(&s.after)?,
                "before_words": correlation_words(&s.before),
                "after_words": correlation_words(&s.after),
            }))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agreeing_layers_are_grey_and_a_missing_one_leaves_its_colour_out() {
        let cut = Cut {
            layers: [
                vec![Some(0.0), Some(10.0), None],
                vec![Some(0.0), Some(10.0), Some(10.0)],
            ],
            correlation: None,
            pixels_compared: 2,
        };
        let px = rgb(&cut, [(0.0, 10.0), (0.0, 10.0)]);
        assert_eq!(px, vec![0, 0, 0, 255, 255, 255, 0, 255, 0]);
    }
}
