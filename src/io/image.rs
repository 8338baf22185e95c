//! 8-bit grey images on disk and their exchange with OpenCV.

use crate::core::limits::{MAX_IMAGE_FILE_BYTES, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX};
use std::path::{Path, PathBuf};

use opencv::core::{Mat, Vector, CV_8UC1};
use opencv::imgcodecs;
use opencv::prelude::*;

/// Why an image could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: image file does not exist")]
    Missing { path: PathBuf },
    #[error("{path}: image file is empty (0 bytes)")]
    Empty { path: PathBuf },
    #[error("{path}: not a decodable image (truncated, or not a PNG, JPEG, BMP or TIFF whose header gives its size)")]
    Undecodable { path: PathBuf },
    #[error("{path}: image is {got_w}x{got_h} px, expected {want_w}x{want_h}")]
    WrongSize {
        path: PathBuf,
        got_w: i32,
        got_h: i32,
        want_w: u32,
        want_h: u32,
    },
    #[error("{path}: image is {width}x{height} px, more than the {limit} pixels probecal decodes")]
    TooLarge {
        path: PathBuf,
        width: u64,
        height: u64,
        limit: u64,
    },
    #[error("{path}: the file is {bytes} bytes, more than the {limit} an image file may be")]
    FileTooLarge { path: PathBuf, bytes: u64, limit: u64 },
    #[error("{path}: cannot write image: {message}")]
    Write { path: PathBuf, message: String },
    #[error("opencv: {0}")]
    OpenCv(String),
}

impl From<opencv::Error> for ImageError {
    fn from(e: opencv::Error) -> ImageError {
        ImageError::OpenCv(e.to_string())
    }
}

/// A grey image, row-major, one byte per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Gray8 {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl Gray8 {
    /// Quantises floating-point grey levels (0..255) to bytes, rounding and clamping.
    pub fn from_levels(width: usize, height: usize, levels: &[f32]) -> Gray8 {
        let data = levels.iter().map(|v| v.round().clamp(0.0, 255.0) as u8).collect();
        Gray8 { width, height, data }
    }

    /// A copy as an OpenCV `CV_8UC1` matrix.
    pub fn to_mat(&self) -> Result<Mat, ImageError> {
        let mat = Mat::new_rows_cols_with_data(self.height as i32, self.width as i32, &self.data)?;
        Ok(mat.try_clone()?)
    }

    /// Writes a PNG atomically (temporary file, then rename).
    pub fn write_png(&self, path: &Path) -> Result<(), ImageError> {
        self.write_encoded(path, ".png", &Vector::new())
    }

    /// Writes a JPEG of the given quality (1..=100) atomically.
    pub fn write_jpeg(&self, path: &Path, quality: u8) -> Result<(), ImageError> {
        let params = Vector::<i32>::from_slice(&[imgcodecs::IMWRITE_JPEG_QUALITY, quality.clamp(1, 100) as i32]);
        self.write_encoded(path, ".jpg", &params)
    }

    fn write_encoded(&self, path: &Path, extension: &str, params: &Vector<i32>) -> Result<(), ImageError> {
        let mat = self.to_mat()?;
        let mut buffer = Vector::<u8>::new();
        imgcodecs::imencode(extension, &mat, &mut buffer, params)?;
        crate::io::fs::write_atomic(path, buffer.as_slice()).map_err(|e| ImageError::Write {
            path: path.to_path_buf(),
            message: e.message,
        })
    }
}

/// PNG bytes of a colour image given as BGR bytes, row-major.
pub fn encode_png_bgr(bgr: &[u8], width: usize, height: usize) -> Result<Vec<u8>, ImageError> {
    let flat = Mat::new_rows_cols_with_data(height as i32, width as i32 * 3, bgr)?;
    let mat = flat.reshape(3, height as i32)?;
    let mut buffer = Vector::<u8>::new();
    imgcodecs::imencode(".png", &mat, &mut buffer, &Vector::new())?;
    Ok(buffer.to_vec())
}

/// Width and height from a PNG's, a JPEG's, a BMP's or a TIFF's header, read
/// before decoding; `None` for other formats or a header that cannot be read
/// (such a file is not decoded).
pub fn header_size(bytes: &[u8]) -> Option<(u64, u64)> {
    let be16 = |i: usize| Some(u16::from_be_bytes([*bytes.get(i)?, *bytes.get(i + 1)?]) as u64);
    let be32 = |i: usize| Some(u32::from_be_bytes(bytes.get(i..i + 4)?.try_into().ok()?) as u64);
    if bytes.starts_with(b"BM") {
        let le32 = |i: usize| Some(i32::from_le_bytes(bytes.get(i..i + 4)?.try_into().ok()?));
        return Some((le32(18)?.unsigned_abs() as u64, le32(22)?.unsigned_abs() as u64));
    }
    if bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*") {
        return tiff_size(bytes);
    }
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") && bytes.get(12..16) == Some(b"IHDR") {
        return Some((be32(16)?, be32(20)?));
    }
    if bytes.starts_with(&[0xFF, 0xD8]) {
        // Segments up to the first start-of-frame marker (SOF0..SOF15 but DHT, JPG, DAC).
        let mut i = 2;
        while i + 4 <= bytes.len() {
            if bytes[i] != 0xFF {
                return None;
            }
            let marker = bytes[i + 1];
            if marker == 0xFF {
                i += 1; // a fill byte before the marker
                continue;
            }
            if (0xC0..=0xCF).contains(&marker) && ![0xC4, 0xC8, 0xCC].contains(&marker) {
                return Some((be16(i + 7)?, be16(i + 5)?));
            }
            i += 2 + be16(i + 2)? as usize;
        }
    }
    None
}

/// Width and height from the first image directory of a TIFF (tags 256 and
/// 257, 16 or 32 bits).
fn tiff_size(bytes: &[u8]) -> Option<(u64, u64)> {
    let little = bytes.starts_with(b"II");
    let u16_at = |i: usize| {
        let b: [u8; 2] = bytes.get(i..i + 2)?.try_into().ok()?;
        Some(if little {
            u16::from_le_bytes(b)
        } else {
            u16::from_be_bytes(b)
        } as u64)
    };
    let u32_at = |i: usize| {
        let b: [u8; 4] = bytes.get(i..i + 4)?.try_into().ok()?;
        Some(if little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        } as u64)
    };
    let directory = usize::try_from(u32_at(4)?).ok()?;
    let entries = u16_at(directory)? as usize;
    let (mut width, mut height) = (None, None);
    for k in 0..entries {
        let entry = directory + 2 + 12 * k;
        let value = match u16_at(entry + 2)? {
            3 => u16_at(entry + 8)?,
            4 => u32_at(entry + 8)?,
            _ => continue,
        };
        match u16_at(entry)? {
            256 => width = Some(value),
            257 => height = Some(value),
            _ => {}
        }
    }
    Some((width?, height?))
}

/// Whether a PNG or JPEG file has been written to its end: PNG's `IEND` chunk,
/// JPEG's end-of-image marker. Other files, and files that cannot be read, are
/// not complete.
pub fn file_complete(path: &Path) -> bool {
    use std::io::{Read, Seek, SeekFrom};
    const PNG_END: [u8; 12] = [0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    let mut head = [0u8; 8];
    let mut tail = [0u8; 12];
    let read = file.read_exact(&mut head).is_ok()
        && file.seek(SeekFrom::End(-12)).is_ok()
        && file.read_exact(&mut tail).is_ok();
    read && ((head == *b"\x89PNG\r\n\x1a\n" && tail == PNG_END)
        || (head[..2] == [0xFF, 0xD8] && tail[10..] == [0xFF, 0xD9]))
}

/// Reads an image file as 8-bit grey, saying exactly what is wrong with a bad one.
pub fn read_gray(path: &Path) -> Result<Mat, ImageError> {
    let meta = std::fs::metadata(path).map_err(|_| ImageError::Missing {
        path: path.to_path_buf(),
    })?;
    if meta.len() == 0 {
        return Err(ImageError::Empty {
            path: path.to_path_buf(),
        });
    }
    if meta.len() > MAX_IMAGE_FILE_BYTES {
        return Err(ImageError::FileTooLarge {
            path: path.to_path_buf(),
            bytes: meta.len(),
            limit: MAX_IMAGE_FILE_BYTES,
        });
    }
    let bytes = std::fs::read(path).map_err(|_| ImageError::Missing {
        path: path.to_path_buf(),
    })?;
    // Only an image whose size its header gives is decoded: the size is
    // checked before OpenCV allocates for it (a small file can claim gigapixels).
    let Some((width, height)) = header_size(&bytes) else {
        return Err(ImageError::Undecodable {
            path: path.to_path_buf(),
        });
    };
    if width * height > MAX_IMAGE_PIXELS || width.max(height) > MAX_IMAGE_SIDE_PX {
        return Err(ImageError::TooLarge {
            path: path.to_path_buf(),
            width,
            height,
            limit: MAX_IMAGE_PIXELS,
        });
    }
    if let Some(mat) = decode_gray8_png(&bytes) {
        return Ok(mat);
    }
    let buffer = Vector::<u8>::from_slice(&bytes);
    let mat = imgcodecs::imdecode(&buffer, imgcodecs::IMREAD_GRAYSCALE).map_err(|_| ImageError::Undecodable {
        path: path.to_path_buf(),
    })?;
    if mat.empty() || mat.typ() != CV_8UC1 {
        return Err(ImageError::Undecodable {
            path: path.to_path_buf(),
        });
    }
    Ok(mat)
}

/// An 8-bit grey, non-interlaced PNG decoded straight into a `Mat` by the `png`
/// crate (three to four times faster than OpenCV's libpng here; the same
/// pixels). Any other PNG, a JPEG, or a file this decoder refuses gives `None`,
/// and OpenCV decodes it (or says it cannot).
fn decode_gray8_png(bytes: &[u8]) -> Option<Mat> {
    if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return None;
    }
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().ok()?;
    let info = reader.info();
    let plain = info.color_type == png::ColorType::Grayscale
        && info.bit_depth == png::BitDepth::Eight
        && !info.interlaced
        && info.trns.is_none();
    let (width, height) = (i32::try_from(info.width).ok()?, i32::try_from(info.height).ok()?);
    if !plain || reader.output_buffer_size()? != info.width as usize * info.height as usize {
        return None;
    }
    let mut mat = Mat::new_rows_cols_with_default(height, width, CV_8UC1, opencv::core::Scalar::all(0.0)).ok()?;
    let data = mat.data_bytes_mut().ok()?;
    reader.next_frame(data).ok()?;
    Some(mat)
}

/// Reads a grey image and checks its size.
pub fn read_gray_sized(path: &Path, size: [u32; 2]) -> Result<Mat, ImageError> {
    let mat = read_gray(path)?;
    if mat.cols() != size[0] as i32 || mat.rows() != size[1] as i32 {
        return Err(ImageError::WrongSize {
            path: path.to_path_buf(),
            got_w: mat.cols(),
            got_h: mat.rows(),
            want_w: size[0],
            want_h: size[1],
        });
    }
    Ok(mat)
}

/// The bytes of a continuous `CV_8UC1` matrix as a [`Gray8`].
pub fn mat_to_gray8(mat: &Mat) -> Result<Gray8, ImageError> {
    let owned;
    let m = if mat.is_continuous() {
        mat
    } else {
        owned = mat.try_clone()?;
        &owned
    };
    Ok(Gray8 {
        width: m.cols() as usize,
        height: m.rows() as usize,
        data: m.data_bytes()?.to_vec(),
    })
}

/// Gaussian blur of floating-point levels (OpenCV, border replicated).
pub fn gaussian_blur_f32(
    width: usize,
    height: usize,
    levels: &mut [f32],
    sigma_x: f64,
    sigma_y: f64,
) -> Result<(), ImageError> {
    if sigma_x <= 0.0 && sigma_y <= 0.0 {
        return Ok(());
    }
    let mut dst = Mat::default();
    {
        // OpenCV reads the levels in place (no copy) and writes the blur beside them.
        let src = Mat::new_rows_cols_with_data(height as i32, width as i32, &*levels)?;
        opencv::imgproc::gaussian_blur(
            &src,
            &mut dst,
            opencv::core::Size::new(0, 0),
            sigma_x.max(0.01),
            sigma_y.max(0.01),
            opencv::core::BORDER_REPLICATE,
        )?;
    }
    levels.copy_from_slice(dst.data_typed::<f32>()?);
    Ok(())
}

#[cfg(test)]
mod header_tests {
    use super::*;

    #[test]
    fn image_headers_give_the_size_before_decoding() {
        let mat = Mat::new_rows_cols_with_default(30, 40, CV_8UC1, opencv::core::Scalar::all(9.0)).unwrap();
        for ext in [".png", ".jpg", ".bmp", ".tif"] {
            let mut buffer = Vector::<u8>::new();
            imgcodecs::imencode(ext, &mat, &mut buffer, &Vector::new()).unwrap();
            assert_eq!(header_size(buffer.as_slice()), Some((40, 30)), "{ext}");
        }
        assert_eq!(header_size(b"GIF89a"), None);
        assert_eq!(header_size(&[0xFF, 0xD8, 0xFF]), None, "a cut-off header is not read");
    }

    #[test]
    fn jpeg_photos_are_written_at_their_quality_and_read_back() {
        let dir = std::env::temp_dir().join(format!("probecal-jpeg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let levels: Vec<f32> = (0..64 * 48).map(|i| ((i % 64) * 4) as f32).collect();
        let image = Gray8::from_levels(64, 48, &levels);
        let sizes: Vec<u64> = [95u8, 30]
            .iter()
            .map(|&q| {
                let path = dir.join(format!("q{q}.jpg"));
                image.write_jpeg(&path, q).unwrap();
                let bytes = std::fs::read(&path).unwrap();
                assert_eq!(&bytes[..2], &[0xFF, 0xD8], "a JPEG");
                let back = mat_to_gray8(&read_gray(&path).unwrap()).unwrap();
                let worst = back
                    .data
                    .iter()
                    .zip(&image.data)
                    .map(|(a, b)| a.abs_diff(*b))
                    .max()
                    .unwrap();
                assert!(worst < 40, "quality {q}: off by {worst} grey levels");
                bytes.len() as u64
            })
            .collect();
        assert!(sizes[0] > sizes[1], "a lower quality compresses more: {sizes:?}");
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .filter(|n| n.ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn grey_pngs_decode_to_opencvs_pixels_and_others_are_left_to_opencv() {
        // A grey ramp with noise, encoded by OpenCV at two compression levels.
        let mut rng = crate::core::rng::Rng::new(7);
        let levels: Vec<f32> = (0..97 * 61)
            .map(|i| ((i % 97) as f32 * 2.5 + rng.uniform(0.0, 30.0) as f32).min(255.0))
            .collect();
        let mat = Gray8::from_levels(97, 61, &levels).to_mat().unwrap();
        for level in [1, 9] {
            let mut bytes = Vector::<u8>::new();
            let params = Vector::from_slice(&[imgcodecs::IMWRITE_PNG_COMPRESSION, level]);
            imgcodecs::imencode(".png", &mat, &mut bytes, &params).unwrap();
            let fast = decode_gray8_png(bytes.as_slice()).expect("a plain grey PNG takes the fast path");
            let opencv = imgcodecs::imdecode(&bytes, imgcodecs::IMREAD_GRAYSCALE).unwrap();
            assert_eq!(
                mat_to_gray8(&fast).unwrap(),
                mat_to_gray8(&opencv).unwrap(),
                "level {level}"
            );
        }
        // Colour and 16-bit PNGs, a JPEG and a cut-off PNG go to OpenCV.
        let mut colour = Mat::default();
        opencv::imgproc::cvt_color_def(&mat, &mut colour, opencv::imgproc::COLOR_GRAY2BGR).unwrap();
        let mut wide = Mat::default();
        mat.convert_to_def(&mut wide, opencv::core::CV_16U).unwrap();
        for (ext, image) in [(".png", &colour), (".png", &wide), (".jpg", &mat)] {
            let mut bytes = Vector::<u8>::new();
            imgcodecs::imencode(ext, image, &mut bytes, &Vector::new()).unwrap();
            assert!(decode_gray8_png(bytes.as_slice()).is_none(), "{ext} {}", image.typ());
        }
        let mut bytes = Vector::<u8>::new();
        imgcodecs::imencode(".png", &mat, &mut bytes, &Vector::new()).unwrap();
        assert!(decode_gray8_png(&bytes.as_slice()[..bytes.len() / 2]).is_none());
    }

    #[test]
    fn a_file_is_complete_once_its_end_marker_is_written() {
        let dir = std::env::temp_dir().join(format!("probecal-complete-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mat = Mat::new_rows_cols_with_default(20, 30, CV_8UC1, opencv::core::Scalar::all(90.0)).unwrap();
        for ext in [".png", ".jpg"] {
            let mut bytes = Vector::<u8>::new();
            imgcodecs::imencode(ext, &mat, &mut bytes, &Vector::new()).unwrap();
            let path = dir.join(format!("frame{ext}"));
            std::fs::write(&path, &bytes.as_slice()[..bytes.len() - 20]).unwrap();
            assert!(!file_complete(&path), "{ext}: cut short");
            std::fs::write(&path, bytes.as_slice()).unwrap();
            assert!(file_complete(&path), "{ext}: whole");
        }
        std::fs::write(dir.join("empty.png"), b"").unwrap();
        assert!(!file_complete(&dir.join("empty.png")));
        assert!(!file_complete(&dir.join("absent.png")));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
