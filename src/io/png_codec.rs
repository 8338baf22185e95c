//! PNG files as 8-bit grey, with the pixels OpenCV's `imread(IMREAD_GRAYSCALE)`
//! gives (the reference the project's detections were built and tested on), and
//! PNG writing.
//!
//! OpenCV reads a PNG through libpng with these transformations, reproduced here:
//! palette to RGB; grey of 1, 2 or 4 bits to 8; alpha (and `tRNS`) dropped, not
//! composited; RGB to grey with libpng's `png_set_rgb_to_gray(1, 0.299, 0.587)`,
//! that is the weights 9797, 19234 and 9737 in 1/32768; 16 bits to 8 by keeping
//! the high byte, after the grey conversion. A colour file whose `gAMA` or `sRGB`
//! chunk gives a gamma other than 1 is converted in linear light, through
//! libpng's 8-bit gamma tables. `tests/image_codecs.rs` compares every case with
//! OpenCV's own decoding.

use std::io::Cursor;

/// libpng's grey weights for OpenCV's 0.299 and 0.587, in 1/32768.
const RED: u32 = 9797;
const GREEN: u32 = 19234;
const BLUE: u32 = 32768 - RED - GREEN;

use super::codec::CodecError;

const FORMAT: &str = "PNG";

/// Decodes a PNG to (width, height, grey bytes, row-major).
pub fn decode_gray(bytes: &[u8]) -> Result<(usize, usize, Vec<u8>), CodecError> {
    let corrupt = |e: png::DecodingError| CodecError::Damaged {
        format: FORMAT,
        detail: e.to_string(),
    };
    let mut decoder = png::Decoder::new(Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(corrupt)?;
    let info = reader.info();
    let (width, height) = (info.width as usize, info.height as usize);
    let colour = matches!(
        info.color_type,
        png::ColorType::Rgb | png::ColorType::Rgba | png::ColorType::Indexed
    );
    let gamma = if info.srgb.is_some() {
        Some(SRGB_GAMMA)
    } else {
        info.gama_chunk.map(|g| g.into_scaled())
    }
    .filter(|&g| significant(g));
    let (out_type, depth) = reader.output_color_type();
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| CodecError::Unsupported(format!("{width}x{height} px does not fit in memory")))?;
    let mut buffer = vec![0u8; size];
    let frame = reader.next_frame(&mut buffer).map_err(corrupt)?;
    let channels = out_type.samples();
    let wide = depth == png::BitDepth::Sixteen;
    if wide && colour && gamma.is_some() {
        return Err(CodecError::Unsupported(
            "a 16-bit colour PNG with a gamma chunk (gAMA or sRGB) is not converted to grey as OpenCV does; \
             save it as 8-bit or grey"
                .into(),
        ));
    }
    let line = frame.line_size;
    let tables = gamma.map(GammaTables::new);
    let mut grey = Vec::with_capacity(width * height);
    for row in buffer.chunks_exact(line).take(height) {
        for x in 0..width {
            let sample = |c: usize| -> u32 {
                if wide {
                    let at = (x * channels + c) * 2;
                    u32::from(row[at]) << 8 | u32::from(row[at + 1])
                } else {
                    u32::from(row[x * channels + c])
                }
            };
            let value = if channels >= 3 {
                let (r, g, b) = (sample(0), sample(1), sample(2));
                match (&tables, wide) {
                    _ if r == g && r == b => r,
                    (Some(t), false) => t.to_grey(r, g, b),
                    (None, false) => (RED * r + GREEN * g + BLUE * b) >> 15,
                    (_, true) => (RED * r + GREEN * g + BLUE * b + 16384) >> 15,
                }
            } else {
                sample(0)
            };
            grey.push(if wide { (value >> 8) as u8 } else { value as u8 });
        }
    }
    Ok((width, height, grey))
}

/// libpng's fixed-point gamma (1/100000) of an `sRGB` chunk.
const SRGB_GAMMA: u32 = 45455;

/// libpng's `png_gamma_significant`: further than 0.05 from 1.
fn significant(gamma: u32) -> bool {
    !(95_000..=105_000).contains(&gamma)
}

/// libpng's `png_reciprocal` of a fixed-point gamma.
fn reciprocal(gamma: u32) -> u32 {
    (1e10 / f64::from(gamma) + 0.5).floor() as u32
}

/// libpng's 8-bit tables into and out of linear light for a file gamma.
struct GammaTables {
    to_linear: [u8; 256],
    from_linear: [u8; 256],
}

impl GammaTables {
    fn new(file_gamma: u32) -> GammaTables {
        // With no screen gamma set, libpng takes the file's reciprocal as the
        // screen's: into linear light by 1/gamma, back by 1/screen.
        let screen = reciprocal(file_gamma);
        GammaTables {
            to_linear: table(reciprocal(file_gamma)),
            from_linear: table(reciprocal(screen)),
        }
    }

    fn to_grey(&self, r: u32, g: u32, b: u32) -> u32 {
        let [r, g, b] = [r, g, b].map(|v| u32::from(self.to_linear[v as usize]));
        u32::from(self.from_linear[((RED * r + GREEN * g + BLUE * b + 16384) >> 15) as usize])
    }
}

/// libpng's `png_build_8bit_table`: `255·(i/255)^(gamma/100000)`, rounded.
fn table(gamma: u32) -> [u8; 256] {
    let mut out = [0u8; 256];
    for (i, slot) in out.iter_mut().enumerate() {
        *slot = if significant(gamma) && i > 0 && i < 255 {
            (255.0 * (i as f64 / 255.0).powf(f64::from(gamma) * 1e-5) + 0.5).floor() as u8
        } else {
            i as u8
        };
    }
    out
}

/// PNG bytes of 8-bit grey (`channels` 1) or RGB (`channels` 3) pixels, row-major.
pub fn encode(pixels: &[u8], width: usize, height: usize, channels: usize) -> Result<Vec<u8>, CodecError> {
    let colour = match channels {
        1 => png::ColorType::Grayscale,
        3 => png::ColorType::Rgb,
        _ => {
            return Err(CodecError::Channels {
                format: FORMAT,
                channels,
            })
        }
    };
    let shape = CodecError::Shape {
        bytes: pixels.len(),
        width,
        height,
        channels,
    };
    if pixels.len() != width * height * channels {
        return Err(shape);
    }
    let (Ok(w), Ok(h)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(shape);
    };
    let encode_error = |e: png::EncodingError| CodecError::Encode {
        format: FORMAT,
        detail: e.to_string(),
    };
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, w, h);
    encoder.set_color(colour);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().map_err(encode_error)?;
    writer.write_image_data(pixels).map_err(encode_error)?;
    writer.finish().map_err(encode_error)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_and_colour_pngs_come_back_as_their_grey() {
        let (w, h) = (5, 3);
        let grey: Vec<u8> = (0..15).map(|i| (i * 17) as u8).collect();
        let back = decode_gray(&encode(&grey, w, h, 1).unwrap()).unwrap();
        assert_eq!(back, (w, h, grey.clone()));
        // Equal channels stay as they are; others take libpng's weights, truncated.
        let rgb: Vec<u8> = grey.iter().flat_map(|&v| [v, v, v]).collect();
        assert_eq!(decode_gray(&encode(&rgb, w, h, 3).unwrap()).unwrap().2, grey);
        let red = [200u8, 10, 30].repeat(15);
        let want = ((RED * 200 + GREEN * 10 + BLUE * 30) >> 15) as u8;
        assert_eq!(decode_gray(&encode(&red, w, h, 3).unwrap()).unwrap().2, vec![want; 15]);
        assert!(encode(&grey, w, h, 2).is_err());
        assert!(encode(&grey[1..], w, h, 1).is_err());
    }

    #[test]
    fn a_cut_off_png_is_corrupt() {
        let bytes = encode(&[7u8; 64 * 64], 64, 64, 1).unwrap();
        assert!(matches!(
            decode_gray(&bytes[..bytes.len() / 2]),
            Err(CodecError::Damaged { .. })
        ));
    }

    #[test]
    fn gamma_tables_are_libpngs() {
        assert!(!significant(100_000) && !significant(96_000) && significant(45_455));
        assert_eq!(reciprocal(45_455), 219_998);
        assert_eq!(reciprocal(219_998), 45_455);
        let t = GammaTables::new(45_455);
        assert_eq!((t.to_linear[0], t.to_linear[255]), (0, 255));
        // 255·(128/255)^2.19998 = 55.6 and 255·(56/255)^0.45455 = 128.0.
        assert_eq!(t.to_linear[128], 56);
        assert_eq!(t.from_linear[56], 128);
    }
}
