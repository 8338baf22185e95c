//! A dataset folder: `frames.csv` (frame, camera_image, bscan_image; paths
//! relative to the folder), the images it names, and optionally
//! `camera_calibration/` with board views. Rendered and recorded datasets share it.
//! A dataset tracked without a camera may leave `camera_image` empty.

use super::csv;
use crate::core::limits::MAX_FRAMES;
use std::path::{Path, PathBuf};

/// Name of the frame list inside a dataset folder.
pub const FRAME_LIST: &str = "frames.csv";

/// The files of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFiles {
    pub frame: usize,
    /// `None` where the frame has no photo (poses from a tracker).
    pub camera_image: Option<PathBuf>,
    pub bscan_image: PathBuf,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DatasetError {
    #[error("{path}: cannot read the frame list: {message}")]
    Unreadable { path: PathBuf, message: String },
    #[error("{path}:1: the header must be `frame,camera_image,bscan_image`, found `{found}`")]
    Header { path: PathBuf, found: String },
    #[error("{path}:{line}: {message}")]
    Line {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{path}: lists no frames")]
    Empty { path: PathBuf },
}

/// Reads and checks a dataset's frame list (the images themselves are checked when read).
pub fn load_frame_list(folder: &Path) -> Result<Vec<FrameFiles>, DatasetError> {
    let path = folder.join(FRAME_LIST);
    let text = crate::io::fs::read_text_capped(&path, crate::core::limits::MAX_TEXT_FILE_BYTES).map_err(|e| {
        DatasetError::Unreadable {
            path: path.clone(),
            message: e.to_string(),
        }
    })?;
    parse_frame_list(folder, &text)
}

/// Parses frame-list text; paths are taken relative to `folder`.
pub fn parse_frame_list(folder: &Path, text: &str) -> Result<Vec<FrameFiles>, DatasetError> {
    let path = folder.join(FRAME_LIST);
    let (header, records) = csv::split(text);
    if header != "frame,camera_image,bscan_image" {
        return Err(DatasetError::Header {
            path,
            found: header.to_string(),
        });
    }
    let mut frames: Vec<FrameFiles> = Vec::new();
    for csv::Record { line, fields } in records {
        let fail = |message: String| DatasetError::Line {
            path: path.clone(),
            line,
            message,
        };
        if fields.len() != 3 {
            return Err(fail(format!(
                "expected 3 comma-separated fields, found {}",
                fields.len()
            )));
        }
        let frame = csv::frame_number(fields[0]).map_err(|e| fail(e.to_string()))?;
        if frames.len() >= MAX_FRAMES {
            return Err(fail(format!("more than {MAX_FRAMES} frames")));
        }
        if frames.iter().any(|f| f.frame == frame) {
            return Err(fail(format!("frame {frame} is listed twice")));
        }
        if fields[2].is_empty() {
            return Err(fail("bscan_image must be given".into()));
        }
        frames.push(FrameFiles {
            frame,
            camera_image: (!fields[1].is_empty()).then(|| folder.join(fields[1])),
            bscan_image: folder.join(fields[2]),
        });
    }
    if frames.is_empty() {
        return Err(DatasetError::Empty { path });
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_list(name: &str, text: &str) -> (PathBuf, Result<Vec<FrameFiles>, DatasetError>) {
        let dir = std::env::temp_dir().join(format!("probecal-list-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(FRAME_LIST), text).unwrap();
        let result = load_frame_list(&dir);
        (dir, result)
    }

    #[test]
    fn reads_good_list_and_names_the_line_of_a_bad_one() {
        let (dir, ok) = with_list(
            "good",
            "frame,camera_image,bscan_image\n0,c0.png,b0.png\n\n3,c3.png,b3.png\n",
        );
        let ok = ok.unwrap();
        assert_eq!(ok.len(), 2);
        assert_eq!(ok[1].frame, 3);
        assert_eq!(ok[1].bscan_image, dir.join("b3.png"));
        let (_, bad) = with_list(
            "bad",
            "frame,camera_image,bscan_image\n0,c0.png,b0.png\nx,c1.png,b1.png\n",
        );
        let msg = bad.unwrap_err().to_string();
        assert!(msg.ends_with(":3: frame `x` is not a whole number"), "{msg}");
        let (_, dup) = with_list("dup", "frame,camera_image,bscan_image\n0,a,b\n0,a,b\n");
        assert!(dup.unwrap_err().to_string().contains(":3: frame 0 is listed twice"));
        let (_, header) = with_list("header", "id,cam,us\n");
        assert!(matches!(header.unwrap_err(), DatasetError::Header { .. }));
        let (dir, no_photo) = with_list("nophoto", "frame,camera_image,bscan_image\n0,,b0.png\n");
        let no_photo = no_photo.unwrap();
        assert_eq!(no_photo[0].camera_image, None);
        assert_eq!(no_photo[0].bscan_image, dir.join("b0.png"));
        let (_, no_bscan) = with_list("nobscan", "frame,camera_image,bscan_image\n0,c0.png,\n");
        assert!(no_bscan
            .unwrap_err()
            .to_string()
            .contains(":2: bscan_image must be given"));
        let (_, empty) = with_list("empty", "frame,camera_image,bscan_image\n");
        assert!(matches!(empty.unwrap_err(), DatasetError::Empty { .. }));
    }
}
