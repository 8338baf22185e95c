//! The pinhole camera with OpenCV's distortion model, and its FileStorage files.
//!
//! Projection of a point `(X, Y, Z)` in the camera frame (mm): `x = X/Z, y = Y/Z`,
//! `r² = x² + y²`, radial `1 + k1 r² + k2 r⁴ + k3 r⁶`, tangential p1, p2, then
//! `u = fx x' + cx`, `v = fy y' + cy` (pixels, origin at the centre of the top-left pixel).

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Point3};
use opencv::core::{
    FileNodeTraitConst, FileStorage, FileStorageTrait, FileStorageTraitConst, Mat, MatTraitConst, CV_64F,
};
use opencv::prelude::*;

/// Camera intrinsics and the provenance of an estimate.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CameraIntrinsics {
    pub image_size_px: [u32; 2],
    /// `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub camera_matrix: [[f64; 3]; 3],
    /// k1, k2, p1, p2, k3 (missing trailing terms are zero).
    pub distortion: [f64; 5],
    /// RMS reprojection error of the calibration that produced these, px.
    pub rms_px: Option<f64>,
    /// Per-view RMS reprojection error, px.
    pub per_view_rms_px: Vec<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum IntrinsicsError {
    #[error("{path}: cannot open as OpenCV FileStorage (missing, or not YAML/XML)")]
    Open { path: PathBuf },
    #[error("{path}: {reason}")]
    Refused { path: PathBuf, reason: String },
    #[error("{path}: field `{field}` {problem}")]
    Field {
        path: PathBuf,
        field: &'static str,
        problem: String,
    },
    #[error("{path}: cannot write: {message}")]
    Write { path: PathBuf, message: String },
    #[error("opencv: {0}")]
    OpenCv(#[from] opencv::Error),
}

impl CameraIntrinsics {
    pub fn fx(&self) -> f64 {
        self.camera_matrix[0][0]
    }
    pub fn fy(&self) -> f64 {
        self.camera_matrix[1][1]
    }
    pub fn cx(&self) -> f64 {
        self.camera_matrix[0][2]
    }
    pub fn cy(&self) -> f64 {
        self.camera_matrix[1][2]
    }

    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| self.camera_matrix[r][c])
    }

    /// Applies the distortion model to normalised coordinates.
    pub fn distort_normalized(&self, x: f64, y: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        (xd, yd)
    }

    /// Pixel of a point in the camera frame (None behind the camera).
    pub fn project(&self, point_in_camera: &Point3<f64>) -> Option<[f64; 2]> {
        if point_in_camera.z <= 1e-9 {
            return None;
        }
        let (xd, yd) = self.distort_normalized(
            point_in_camera.x / point_in_camera.z,
            point_in_camera.y / point_in_camera.z,
        );
        Some([self.fx() * xd + self.cx(), self.fy() * yd + self.cy()])
    }

    /// Normalised undistorted coordinates of a pixel (fixed-point iteration, as OpenCV).
    pub fn undistort_pixel(&self, pixel: [f64; 2]) -> (f64, f64) {
        let xd = (pixel[0] - self.cx()) / self.fx();
        let yd = (pixel[1] - self.cy()) / self.fy();
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            x = (xd - dx) / radial;
            y = (yd - dy) / radial;
        }
        (x, y)
    }

    /// The camera matrix as an OpenCV `CV_64F` 3x3 matrix.
    pub fn camera_matrix_mat(&self) -> opencv::Result<Mat> {
        Mat::from_slice_2d(&self.camera_matrix)
    }

    /// The distortion coefficients as an OpenCV 1x5 `CV_64F` matrix.
    pub fn distortion_mat(&self) -> opencv::Result<Mat> {
        Mat::from_slice(&self.distortion)?.try_clone()
    }

    /// Reads an OpenCV FileStorage file (as written by OpenCV's calibration sample).
    pub fn load(path: &Path) -> Result<CameraIntrinsics, IntrinsicsError> {
        let open_err = || IntrinsicsError::Open {
            path: path.to_path_buf(),
        };
        if !path.is_file() {
            return Err(open_err());
        }
        if let Some(reason) = crate::io::storage::refusal(path) {
            return Err(IntrinsicsError::Refused {
                path: path.to_path_buf(),
                reason,
            });
        }
        let fs = FileStorage::new_def(
            path.to_string_lossy().as_ref(),
            opencv::core::FileStorage_Mode::READ as i32,
        )
        .map_err(|_| open_err())?;
        if !fs.is_opened()? {
            return Err(open_err());
        }
        let field_err = |field: &'static str, problem: &str| IntrinsicsError::Field {
            path: path.to_path_buf(),
            field,
            problem: problem.to_string(),
        };
        let read_mat = |field: &'static str| -> Result<Mat, IntrinsicsError> {
            let node = fs.get(field)?;
            if node.empty()? {
                return Err(field_err(field, "is missing"));
            }
            let mat = node.mat().map_err(|_| field_err(field, "is not an opencv-matrix"))?;
            let mut as_f64 = Mat::default();
            mat.convert_to_def(&mut as_f64, CV_64F)?;
            Ok(as_f64)
        };
        let k = read_mat("camera_matrix")?;
        if k.rows() != 3 || k.cols() != 3 {
            return Err(field_err(
                "camera_matrix",
                &format!("must be 3x3, is {}x{}", k.rows(), k.cols()),
            ));
        }
        let mut camera_matrix = [[0.0; 3]; 3];
        for (r, row) in camera_matrix.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = *k.at_2d::<f64>(r as i32, c as i32)?;
            }
        }
        if camera_matrix.iter().flatten().any(|v| !v.is_finite())
            || camera_matrix[0][0] <= 0.0
            || camera_matrix[1][1] <= 0.0
        {
            return Err(field_err(
                "camera_matrix",
                "must have finite entries and positive focal lengths",
            ));
        }
        let d = read_mat("distortion_coefficients")?;
        let values: Vec<f64> = d.data_typed::<f64>().map(|s| s.to_vec()).unwrap_or_default();
        if !matches!(values.len(), 4 | 5) || values.iter().any(|v| !v.is_finite()) {
            return Err(field_err(
                "distortion_coefficients",
                &format!("must hold 4 or 5 finite numbers, holds {}", values.len()),
            ));
        }
        let mut distortion = [0.0; 5];
        distortion[..values.len()].copy_from_slice(&values);
        let read_int = |field: &str| -> Option<i32> {
            fs.get(field)
                .ok()
                .filter(|n| !n.empty().unwrap_or(true))
                .and_then(|n| n.to_i32().ok())
        };
        // The frames are checked against this size: without it every frame would be refused.
        let size = |field: &'static str| match read_int(field) {
            Some(v) if v > 0 => Ok(v as u32),
            Some(v) => Err(field_err(
                field,
                &format!("must be a positive number of pixels, is {v}"),
            )),
            None => Err(field_err(field, "is missing")),
        };
        let width = size("image_width")?;
        let height = size("image_height")?;
        let rms_px = fs
            .get("avg_reprojection_error")
            .ok()
            .filter(|n| !n.empty().unwrap_or(true))
            .and_then(|n| n.real().ok());
        Ok(CameraIntrinsics {
            image_size_px: [width, height],
            camera_matrix,
            distortion,
            rms_px,
            per_view_rms_px: Vec::new(),
        })
    }

    /// Writes OpenCV FileStorage YAML with the keys of OpenCV's calibration sample.
    pub fn save(&self, path: &Path, board: Option<([u32; 2], f64)>) -> Result<(), IntrinsicsError> {
        self.save_with_views(path, board, &[])
    }

    /// Like [`CameraIntrinsics::save`], with each view's fate under `views`: its
    /// image, whether it was used, and how its board was found or why not.
    pub fn save_with_views(
        &self,
        path: &Path,
        board: Option<([u32; 2], f64)>,
        views: &[ViewFate],
    ) -> Result<(), IntrinsicsError> {
        let tmp = path.with_extension("tmp.yml");
        let write_err = |message: String| IntrinsicsError::Write {
            path: path.to_path_buf(),
            message,
        };
        {
            let mut fs = FileStorage::new_def(
                tmp.to_string_lossy().as_ref(),
                opencv::core::FileStorage_Mode::WRITE as i32,
            )
            .map_err(|e| write_err(e.to_string()))?;
            if !fs.is_opened()? {
                return Err(write_err("cannot create the file".into()));
            }
            fs.write_i32("nframes", self.per_view_rms_px.len() as i32)?;
            fs.write_i32("image_width", self.image_size_px[0] as i32)?;
            fs.write_i32("image_height", self.image_size_px[1] as i32)?;
            if let Some((corners, square)) = board {
                fs.write_i32("board_width", corners[0] as i32)?;
                fs.write_i32("board_height", corners[1] as i32)?;
                fs.write_f64("square_size", square)?;
            }
            fs.write_i32("flags", 0)?;
            fs.write_mat("camera_matrix", &self.camera_matrix_mat()?)?;
            let d = Mat::from_slice(&self.distortion)?.reshape(1, 5)?.try_clone()?;
            fs.write_mat("distortion_coefficients", &d)?;
            if let Some(rms) = self.rms_px {
                fs.write_f64("avg_reprojection_error", rms)?;
            }
            if !self.per_view_rms_px.is_empty() {
                let pv = Mat::from_slice(&self.per_view_rms_px)?
                    .reshape(1, self.per_view_rms_px.len() as i32)?
                    .try_clone()?;
                fs.write_mat("per_view_reprojection_errors", &pv)?;
            }
            if !views.is_empty() {
                fs.start_write_struct("views", opencv::core::FileNode_SEQ, "")?;
                for v in views {
                    fs.start_write_struct("", opencv::core::FileNode_MAP, "")?;
                    fs.write_str("image", &v.image)?;
                    fs.write_i32("used", i32::from(v.used))?;
                    fs.write_str("how", &v.how)?;
                    fs.end_write_struct()?;
                }
                fs.end_write_struct()?;
            }
            fs.release()?;
        }
        std::fs::rename(&tmp, path).map_err(|e| write_err(e.to_string()))?;
        Ok(())
    }
}

/// One calibration view's fate, as the intrinsics file records it.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewFate {
    pub image: String,
    pub used: bool,
    /// How its board was found (used), or why it was not used.
    pub how: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            image_size_px: [1920, 1080],
            camera_matrix: [[1400.0, 0.0, 966.5], [0.0, 1400.0, 536.0], [0.0, 0.0, 1.0]],
            distortion: [-0.12, 0.05, 0.001, -0.0005, 0.0],
            rms_px: None,
            per_view_rms_px: vec![],
        }
    }

    #[test]
    fn undistort_inverts_distort_across_the_image() {
        let cam = camera();
        for &(u, v) in &[(0.0, 0.0), (1919.0, 1079.0), (960.0, 540.0), (100.0, 900.0)] {
            let (x, y) = cam.undistort_pixel([u, v]);
            let p = cam.project(&Point3::new(x, y, 1.0)).unwrap();
            assert!((p[0] - u).abs() < 1e-6 && (p[1] - v).abs() < 1e-6, "({u},{v}) -> {p:?}");
        }
    }

    #[test]
    fn reads_opencv_sample_file_and_round_trips() {
        let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/opencv-chessboard/left_intrinsics.yml");
        let cam = CameraIntrinsics::load(&sample).expect("sample intrinsics");
        assert!((cam.fx() - 535.9157).abs() < 1e-3);
        assert!((cam.cy() - 235.5708).abs() < 1e-3);
        assert_eq!(cam.image_size_px, [640, 480]);
        let dir = std::env::temp_dir().join(format!("probecal-intrinsics-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("round.yml");
        cam.save(&out, Some(([9, 6], 25.0))).unwrap();
        let back = CameraIntrinsics::load(&out).unwrap();
        assert_eq!(back.camera_matrix, cam.camera_matrix);
        assert_eq!(back.distortion, cam.distortion);
        let missing = CameraIntrinsics::load(&dir.join("nope.yml")).unwrap_err();
        assert!(missing.to_string().contains("nope.yml"), "{missing}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
