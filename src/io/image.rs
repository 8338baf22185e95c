//! 8-bit grey images on disk and their exchange with OpenCV.

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
    #[error("{path}: not a decodable image (truncated or not PNG/JPEG)")]
    Undecodable { path: PathBuf },
    #[error("{path}: image is {got_w}x{got_h} px, expected {want_w}x{want_h}")]
    WrongSize {
        path: PathBuf,
        got_w: i32,
        got_h: i32,
        want_w: u32,
        want_h: u32,
    },
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
        let mat = self.to_mat()?;
        let tmp = path.with_extension("png.tmp");
        let write_err = |message: String| ImageError::Write {
            path: path.to_path_buf(),
            message,
        };
        let mut buffer = Vector::<u8>::new();
        imgcodecs::imencode(".png", &mat, &mut buffer, &Vector::new())?;
        std::fs::write(&tmp, buffer.as_slice()).map_err(|e| write_err(e.to_string()))?;
        std::fs::rename(&tmp, path).map_err(|e| write_err(e.to_string()))?;
        Ok(())
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
    let bytes = std::fs::read(path).map_err(|_| ImageError::Missing {
        path: path.to_path_buf(),
    })?;
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
    let src = Mat::new_rows_cols_with_data(height as i32, width as i32, levels)?.try_clone()?;
    let mut dst = Mat::default();
    opencv::imgproc::gaussian_blur(
        &src,
        &mut dst,
        opencv::core::Size::new(0, 0),
        sigma_x.max(0.01),
        sigma_y.max(0.01),
        opencv::core::BORDER_REPLICATE,
    )?;
    levels.copy_from_slice(dst.data_typed::<f32>()?);
    Ok(())
}
