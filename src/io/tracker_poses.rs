//! Stage 2 without a camera: per-frame poses from a tracker, as a plain CSV of
//! 4x4 matrices.
//!
//! ```text
//! frame,transform,m00,m01,m02,m03,m10,m11,m12,m13,m20,m21,m22,m23,m30,m31,m32,m33
//! 0,ProbeToTracker,0.99,...,1
//! 0,ReferenceToTracker,1,...,1
//! ```
//!
//! One row per frame and transform, the matrix row-major, translations in
//! millimetres. `ProbeToTracker` is `tracker_T_marker` (the marker on the probe in
//! the tracker's frame), `ReferenceToTracker` is `tracker_T_phantom` (the phantom's
//! reference marker, whose frame the phantom's geometry is given in); the names are
//! the manifest's. The tracker takes the camera's place: both poses of a frame must
//! be in the same tracker frame.

use super::csv;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Rotation3, Vector3};

use crate::core::geometry::{rigid_from_parts, to_rows, Rigid};

/// The header every tracker-pose CSV starts with.
pub const HEADER: &str = "frame,transform,m00,m01,m02,m03,m10,m11,m12,m13,m20,m21,m22,m23,m30,m31,m32,m33";

/// Largest |RᵀR − I| accepted: trackers write 6 or so decimals. The rotation is
/// made exactly orthonormal after the check.
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-4;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrackerPosesError {
    #[error("{path}: cannot read the tracker poses: {message}")]
    Unreadable { path: PathBuf, message: String },
    #[error("{path}:1: the header must be `{HEADER}`, found `{found}`")]
    Header { path: PathBuf, found: String },
    #[error("{path}:{line}: {message}")]
    Line {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{path}: holds no poses")]
    Empty { path: PathBuf },
}

/// Every pose of a tracker-pose file.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerPoses {
    pub path: PathBuf,
    /// frame → transform name → the transform (`tracker_T_<marker>`).
    pub poses: BTreeMap<usize, BTreeMap<String, Rigid>>,
}

/// One frame's two poses, in the tracker's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackedFrame {
    pub tracker_T_marker: Rigid,
    pub tracker_T_phantom: Rigid,
}

impl TrackerPoses {
    pub fn read(path: &Path) -> Result<TrackerPoses, TrackerPosesError> {
        let text = crate::io::fs::read_text_capped(path, crate::core::limits::MAX_TEXT_FILE_BYTES).map_err(|e| {
            TrackerPosesError::Unreadable {
                path: path.to_path_buf(),
                message: e.to_string(),
            }
        })?;
        TrackerPoses::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<TrackerPoses, TrackerPosesError> {
        let (header, records) = csv::split(text);
        if header.replace(' ', "") != HEADER {
            return Err(TrackerPosesError::Header {
                path: path.to_path_buf(),
                found: header.to_string(),
            });
        }
        let mut poses: BTreeMap<usize, BTreeMap<String, Rigid>> = BTreeMap::new();
        for csv::Record { line, fields } in records {
            let fail = |message: String| TrackerPosesError::Line {
                path: path.to_path_buf(),
                line,
                message,
            };
            if fields.len() != 18 {
                return Err(fail(format!(
                    "expected 18 comma-separated fields (frame, transform, 16 matrix entries), found {}",
                    fields.len()
                )));
            }
            let frame = csv::frame_number(fields[0]).map_err(|e| fail(e.to_string()))?;
            let name = fields[1];
            if name.is_empty() {
                return Err(fail("the transform name is empty".into()));
            }
            let mut m = [[0.0; 4]; 4];
            for (k, field) in fields[2..].iter().enumerate() {
                let (r, c) = (k / 4, k % 4);
                let value: f64 = field
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| fail(format!("m{r}{c} = `{field}` is not a finite number")))?;
                m[r][c] = value;
            }
            let pose = rigid_from_tracker_rows(&m).map_err(|e| fail(format!("{name} of frame {frame}: {e}")))?;
            let entry = poses.entry(frame).or_default();
            if entry.insert(name.to_string(), pose).is_some() {
                return Err(fail(format!("{name} of frame {frame} is given twice")));
            }
        }
        if poses.is_empty() {
            return Err(TrackerPosesError::Empty {
                path: path.to_path_buf(),
            });
        }
        Ok(TrackerPoses {
            path: path.to_path_buf(),
            poses,
        })
    }

    /// A frame's probe and reference poses, or why the frame has none.
    pub fn frame(&self, frame: usize, probe: &str, reference: &str) -> Result<TrackedFrame, MissingPose> {
        let file = self
            .path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let poses = self.poses.get(&frame);
        let get = |name: &str| {
            poses.and_then(|p| p.get(name)).copied().ok_or_else(|| MissingPose {
                file: file.clone(),
                transform: name.to_string(),
                frame,
            })
        };
        Ok(TrackedFrame {
            tracker_T_marker: get(probe)?,
            tracker_T_phantom: get(reference)?,
        })
    }
}

/// A frame without one of the poses it needs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file} has no {transform} for frame {frame}")]
pub struct MissingPose {
    pub file: String,
    pub transform: String,
    pub frame: usize,
}

/// Why a 4x4 matrix is not a rigid transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RigidityError {
    #[error("the matrix has a non-finite entry")]
    NonFinite,
    #[error("the last row must be 0 0 0 1, found {} {} {} {}", .0[0], .0[1], .0[2], .0[3])]
    LastRow([f64; 4]),
    #[error("the rotation part is not orthonormal (|RᵀR − I| = {off:.1e}, tolerance {tolerance:.0e}); is the matrix scaled or sheared?")]
    NotOrthonormal { off: f64, tolerance: f64 },
    #[error("the rotation part is a reflection (det R < 0)")]
    Reflection,
}

/// A tracker's 4x4 matrix as a rigid transform: see [`check_near_rigid`]; the
/// rotation is then made exactly orthonormal.
fn rigid_from_tracker_rows(m: &[[f64; 4]; 4]) -> Result<Rigid, RigidityError> {
    check_near_rigid(m, ORTHONORMAL_TOLERANCE)?;
    let r = Matrix3::from_fn(|i, j| m[i][j]);
    let rotation = Rotation3::from_matrix_eps(&r, 1e-12, 100, Rotation3::identity());
    Ok(rigid_from_parts(
        rotation.matrix(),
        &Vector3::new(m[0][3], m[1][3], m[2][3]),
    ))
}

/// Whether a 4x4 matrix written with a few decimals is a rigid transform: last row
/// `[0 0 0 1]`, rotation orthonormal within `tolerance` and not a reflection.
pub fn check_near_rigid(m: &[[f64; 4]; 4], tolerance: f64) -> Result<(), RigidityError> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(RigidityError::NonFinite);
    }
    let last = m[3];
    if last[0].abs() > 1e-9 || last[1].abs() > 1e-9 || last[2].abs() > 1e-9 || (last[3] - 1.0).abs() > 1e-9 {
        return Err(RigidityError::LastRow(last));
    }
    let r = Matrix3::from_fn(|i, j| m[i][j]);
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    if off > tolerance {
        return Err(RigidityError::NotOrthonormal { off, tolerance });
    }
    if r.determinant() < 0.0 {
        return Err(RigidityError::Reflection);
    }
    Ok(())
}

/// Writes poses as a tracker-pose CSV, full precision.
pub fn write(path: &Path, rows: &[(usize, &str, Rigid)]) -> std::io::Result<()> {
    let mut text = String::from(HEADER);
    text.push('\n');
    for (frame, name, pose) in rows {
        text.push_str(&format!("{frame},{name}"));
        for v in to_rows(pose).iter().flatten() {
            text.push_str(&format!(",{v}"));
        }
        text.push('\n');
    }
    std::fs::write(path, text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;

    fn row(frame: usize, name: &str, m: [[f64; 4]; 4]) -> String {
        let values: Vec<String> = m.iter().flatten().map(|v| v.to_string()).collect();
        format!("{frame},{name},{}\n", values.join(","))
    }

    #[test]
    fn round_trip_and_frame_lookup() {
        let dir = std::env::temp_dir().join(format!("probecal-tracker-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("poses.csv");
        let a = rigid_from_axis_angle(Vector3::new(0.1, -0.2, 0.3), Vector3::new(10.0, 20.0, 300.0));
        let b = rigid_from_axis_angle(Vector3::new(-0.4, 0.0, 0.1), Vector3::new(-50.0, 2.0, 400.0));
        write(&path, &[(3, "ProbeToTracker", a), (3, "ReferenceToTracker", b)]).unwrap();
        let read = TrackerPoses::read(&path).unwrap();
        let f = read.frame(3, "ProbeToTracker", "ReferenceToTracker").unwrap();
        assert!((f.tracker_T_marker.to_homogeneous() - a.to_homogeneous()).abs().max() < 1e-9);
        assert!((f.tracker_T_phantom.to_homogeneous() - b.to_homogeneous()).abs().max() < 1e-9);
        let missing = read.frame(4, "ProbeToTracker", "ReferenceToTracker").unwrap_err();
        assert_eq!(
            missing,
            MissingPose {
                file: "poses.csv".into(),
                transform: "ProbeToTracker".into(),
                frame: 4
            }
        );
        assert_eq!(missing.to_string(), "poses.csv has no ProbeToTracker for frame 4");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn six_decimals_are_accepted_and_made_orthonormal() {
        let a = rigid_from_axis_angle(Vector3::new(0.3, 0.2, -0.1), Vector3::new(1.0, 2.0, 3.0));
        let mut m = to_rows(&a);
        for v in m.iter_mut().flatten() {
            *v = (*v * 1e6).round() / 1e6;
        }
        let text = format!("{HEADER}\n{}", row(0, "P", m));
        let poses = TrackerPoses::parse(Path::new("t.csv"), &text).unwrap();
        let r = poses.poses[&0]["P"].rotation.to_rotation_matrix();
        assert!((r.matrix().transpose() * r.matrix() - Matrix3::identity()).abs().max() < 1e-12);
        assert!(poses.poses[&0]["P"].rotation.angle_to(&a.rotation) < 1e-5);
    }

    #[test]
    fn bad_rows_name_the_line_and_the_problem() {
        let id = to_rows(&Rigid::identity());
        let mut scaled = id;
        scaled[0][0] = 2.0;
        let mut mirrored = id;
        mirrored[2][2] = -1.0;
        let mut projective = id;
        projective[3][0] = 0.5;
        let cases: Vec<(String, &str)> = vec![
            ("frame,matrix\n".into(), "t.csv:1: the header must be"),
            (format!("{HEADER}\n0,P,1,2\n"), "t.csv:2: expected 18"),
            (
                format!("{HEADER}\n{}", row(0, "P", scaled)),
                "t.csv:2: P of frame 0: the rotation part is not orthonormal",
            ),
            (format!("{HEADER}\n{}", row(0, "P", mirrored)), "reflection"),
            (
                format!("{HEADER}\n{}", row(0, "P", projective)),
                "last row must be 0 0 0 1",
            ),
            (
                format!("{HEADER}\n{}", row(0, "P", id).replace(",1,0,0,0", ",nan,0,0,0")),
                "m00 = `nan` is not a finite number",
            ),
            (
                format!("{HEADER}\n{}{}", row(0, "P", id), row(0, "P", id)),
                "t.csv:3: P of frame 0 is given twice",
            ),
            (
                format!("{HEADER}\n{}", row(0, "P", id).replacen('0', "x", 1)),
                "frame `x` is not a whole number",
            ),
            (format!("{HEADER}\n\n"), "holds no poses"),
        ];
        for (text, want) in cases {
            let err = TrackerPoses::parse(Path::new("t.csv"), &text).unwrap_err().to_string();
            assert!(err.contains(want), "expected `{want}` in `{err}`");
        }
    }
}
