//! 8-bit grey images on disk and their exchange with OpenCV. PNG and JPEG files
//! are read and written by [`super::png_codec`] and [`super::jpeg`], with the
//! pixels OpenCV's `imread` gives; OpenCV's own codec module is not linked (its
//! 140 libraries took longer to load than most commands take to run).

use super::codec::CodecError;
use crate::core::limits::{MAX_IMAGE_FILE_BYTES, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX};
use std::path::{Path, PathBuf};

use opencv::core::Mat;
use opencv::prelude::*;

/// Why an image could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: image file does not exist")]
    Missing { path: PathBuf },
    #[error("{path}: image file is empty (0 bytes)")]
    Empty { path: PathBuf },
    #[error("{path}: not a decodable image (truncated, or not a PNG or JPEG whose header gives its size)")]
    Undecodable { path: PathBuf },
    #[error("{path}: {reason}")]
    Unreadable { path: PathBuf, reason: String },
    #[error("{path}: a {format} file; probecal reads PNG and JPEG images (convert it, e.g. to PNG)")]
    Unsupported { path: PathBuf, format: &'static str },
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
        let bytes = super::png_codec::encode(&self.data, self.width, self.height, 1);
        write_encoded(path, bytes)
    }

    /// Writes a JPEG of the given quality (1..=100) atomically.
    pub fn write_jpeg(&self, path: &Path, quality: u8) -> Result<(), ImageError> {
        write_encoded(
            path,
            super::jpeg::encode(&self.data, self.width, self.height, 1, quality),
        )
    }
}

fn write_encoded(path: &Path, bytes: Result<Vec<u8>, CodecError>) -> Result<(), ImageError> {
    let write = |message: String| ImageError::Write {
        path: path.to_path_buf(),
        message,
    };
    let bytes = bytes.map_err(|e| write(e.to_string()))?;
    crate::io::fs::write_atomic(path, &bytes).map_err(|e| write(e.message))
}

/// PNG bytes of a colour image given as BGR bytes, row-major.
pub fn encode_png_bgr(bgr: &[u8], width: usize, height: usize) -> Result<Vec<u8>, ImageError> {
    let rgb: Vec<u8> = bgr.chunks_exact(3).flat_map(|p| [p[2], p[1], p[0]]).collect();
    super::png_codec::encode(&rgb, width, height, 3).map_err(|e| ImageError::OpenCv(e.to_string()))
}

/// JPEG bytes of an 8-bit grey or BGR matrix, with the settings of OpenCV's
/// `imencode(".jpg")` (the same bytes).
pub fn mat_to_jpeg(mat: &Mat, quality: u8) -> Result<Vec<u8>, opencv::Error> {
    with_continuous(mat, |m| {
        let fail = |message: String| opencv::Error::new(opencv::core::StsError, message);
        if m.depth() != opencv::core::CV_8U {
            return Err(fail(format!(
                "a JPEG is written from 8-bit pixels, not type {}",
                m.typ()
            )));
        }
        let (width, height, channels) = (m.cols() as usize, m.rows() as usize, m.channels() as usize);
        super::jpeg::encode(m.data_bytes()?, width, height, channels, quality).map_err(|e| fail(e.to_string()))
    })
}

/// `f` of the matrix, or of a continuous copy of it if it is not.
fn with_continuous<R>(mat: &Mat, f: impl FnOnce(&Mat) -> Result<R, opencv::Error>) -> Result<R, opencv::Error> {
    if mat.is_continuous() {
        f(mat)
    } else {
        f(&mat.try_clone()?)
    }
}

/// The format of a file probecal does not read, from its first bytes.
fn unsupported_format(bytes: &[u8]) -> Option<&'static str> {
    [
        (&b"BM"[..], "BMP"),
        (b"II*\0", "TIFF"),
        (b"MM\0*", "TIFF"),
        (b"GIF8", "GIF"),
        (b"RIFF", "WebP"),
        (b"\0\0\0\x0cjP", "JPEG 2000"),
    ]
    .iter()
    .find(|(magic, _)| bytes.starts_with(magic))
    .map(|(_, name)| *name)
}

/// Width and height from a PNG's or a JPEG's header, read before decoding;
/// `None` for other formats or a header that cannot be read (such a file is not
/// decoded).
pub fn header_size(bytes: &[u8]) -> Option<(u64, u64)> {
    let be16 = |i: usize| Some(u16::from_be_bytes([*bytes.get(i)?, *bytes.get(i + 1)?]) as u64);
    let be32 = |i: usize| Some(u32::from_be_bytes(bytes.get(i..i + 4)?.try_into().ok()?) as u64);
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
    let bytes = crate::io::fs::read_capped(path, MAX_IMAGE_FILE_BYTES).map_err(|_| ImageError::Missing {
        path: path.to_path_buf(),
    })?;
    if let Some(format) = unsupported_format(&bytes) {
        return Err(ImageError::Unsupported {
            path: path.to_path_buf(),
            format,
        });
    }
    // Only an image whose size its header gives is decoded: the size is
    // checked before the decoder allocates for it (a small file can claim gigapixels).
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
    let decoded = if bytes.starts_with(b"\x89PNG") {
        super::png_codec::decode_gray(&bytes)
    } else {
        super::jpeg::decode_gray(&bytes)
    };
    let (w, h, grey) = decoded.map_err(|e| ImageError::Unreadable {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    if (w as u64, h as u64) != (width, height) {
        return Err(ImageError::Undecodable {
            path: path.to_path_buf(),
        });
    }
    Gray8 {
        width: w,
        height: h,
        data: grey,
    }
    .to_mat()
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
    Ok(with_continuous(mat, |m| {
        Ok(Gray8 {
            width: m.cols() as usize,
            height: m.rows() as usize,
            data: m.data_bytes()?.to_vec(),
        })
    })?)
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

    /// A 40x30 grey image encoded as `ext` (".png" or ".jpg").
    fn encoded(ext: &str, level: u8) -> Vec<u8> {
        let grey = vec![level; 40 * 30];
        match ext {
            ".png" => crate::io::png_codec::encode(&grey, 40, 30, 1).unwrap(),
            _ => crate::io::jpeg::encode(&grey, 40, 30, 1, 90).unwrap(),
        }
    }

    #[test]
    fn image_headers_give_the_size_before_decoding() {
        for ext in [".png", ".jpg"] {
            assert_eq!(header_size(&encoded(ext, 9)), Some((40, 30)), "{ext}");
        }
        assert_eq!(header_size(b"GIF89a"), None);
        assert_eq!(header_size(&[0xFF, 0xD8, 0xFF]), None, "a cut-off header is not read");
    }

    #[test]
    fn other_formats_are_named_and_refused() {
        let dir = std::env::temp_dir().join(format!("probecal-formats-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes, format) in [
            ("a.bmp", &b"BM\x36\x10\0\0\0\0"[..], "BMP"),
            ("a.tif", b"II*\0\x08\0\0\0", "TIFF"),
            ("b.tif", b"MM\0*\0\0\0\x08", "TIFF"),
            ("a.gif", b"GIF89a\x01\0", "GIF"),
        ] {
            let path = dir.join(name);
            std::fs::write(&path, bytes).unwrap();
            let err = read_gray(&path).unwrap_err();
            assert_eq!(err, ImageError::Unsupported { path, format }, "{name}");
            assert!(err.to_string().contains("reads PNG and JPEG"), "{err}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
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
    fn a_file_is_complete_once_its_end_marker_is_written() {
        let dir = std::env::temp_dir().join(format!("probecal-complete-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for ext in [".png", ".jpg"] {
            let bytes = encoded(ext, 90);
            let path = dir.join(format!("frame{ext}"));
            std::fs::write(&path, &bytes[..bytes.len() - 20]).unwrap();
            assert!(!file_complete(&path), "{ext}: cut short");
            assert!(read_gray(&path).is_err(), "{ext}: a cut-off file is not read");
            std::fs::write(&path, &bytes).unwrap();
            assert_eq!(
                mat_to_gray8(&read_gray(&path).unwrap()).unwrap().data,
                vec![90; 1200],
                "{ext}"
            );
            assert!(file_complete(&path), "{ext}: whole");
        }
        std::fs::write(dir.join("empty.png"), b"").unwrap();
        assert!(!file_complete(&dir.join("empty.png")));
        assert!(!file_complete(&dir.join("absent.png")));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
