//! PLUS sequence files: MetaImage (`.mha`, `.igs.mha`) "tracked frame lists".
//!
//! An ASCII header of `Key = value` lines, then `ElementDataFile = LOCAL` and the
//! pixel data of all frames (uint8, row-major, frame after frame), zlib-compressed
//! when `CompressedData = True`. Per frame `i` the header holds fields
//! `Seq_Frame%04d_<Name>`, among them the tracker transforms (16 numbers, a 4x4
//! matrix row by row, mm) and their `...TransformStatus` (`OK` / `INVALID`).
//!
//! Everything that makes the file unreadable is an error naming the file, the line
//! and the key; a transform that is merely unusable in one frame (status not OK,
//! not a rigid matrix) is a [`FrameFault`] for that frame only.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use super::orientation::Orientation;
pub use super::sequence_deferred::Deferred;
use super::sequence_header::{
    big_endian, bytes_of_samples, check_element, check_ndims, compressed_flag, dimensions, orientation, pixel_bytes,
    read_bounded, read_header, samples_in_mf, Header, StoredSamples,
};
use super::sequence_types::clip;
pub use super::sequence_types::{Field, SequenceError};
pub use super::sequence_types::{MAX_FRAME_PIXELS, MAX_SAMPLE_BYTES};
use crate::core::geometry::{rigid_from_rows, Rigid};

/// Why one frame's transform cannot be used (the frame is rejected with it).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameFault {
    #[error("frame {frame}: field `{field}` is missing")]
    Missing { frame: usize, field: String },
    #[error("frame {frame}: `{field}` is {status}, not OK")]
    Status {
        frame: usize,
        field: String,
        status: String,
    },
    #[error("frame {frame}: `{field}` (line {line}) is not a rigid transform: {reason}")]
    NotRigid {
        frame: usize,
        field: String,
        line: usize,
        reason: String,
    },
}

/// One frame: its pixels and its own header fields (without the `Seq_FrameNNNN_` prefix).
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceFrame {
    pub index: usize,
    pub fields: BTreeMap<String, Field>,
}

/// A whole sequence file in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    pub path: PathBuf,
    pub width: usize,
    pub height: usize,
    /// How the file's images ran; the pixels are held flipped to MF, as PLUS
    /// segments and calibrates them.
    pub orientation: Orientation,
    /// Header fields that are not per-frame, in file order by key.
    pub header: BTreeMap<String, Field>,
    pub frames: Vec<SequenceFrame>,
    /// All frames' pixels, frame after frame (8-bit sequences).
    pub(super) pixels: Vec<u8>,
    /// All frames' samples of a `MET_FLOAT` sequence (read only by
    /// [`Sequence::read_any`]); empty otherwise.
    pub(super) float_pixels: Vec<f32>,
}

/// One frame's samples, whichever element type the file holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Samples<'a> {
    U8(&'a [u8]),
    F32(&'a [f32]),
}

/// The header's frames (their indices, ascending) are `DimSize`'s `count`,
/// numbered from 0 without a gap.
fn check_frame_count(
    indices: impl DoubleEndedIterator<Item = usize> + ExactSizeIterator,
    count: usize,
    dims: &Field,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<(), SequenceError> {
    let described = indices.len();
    let last = indices.last().map(|l| l + 1).unwrap_or(0);
    if described != count || last != count {
        return Err(fail(
            Some(dims.line),
            format!(
                "frame count mismatch: `DimSize` has {count} frames, the header describes {described} (indices up to {last})"
            ),
        ));
    }
    Ok(())
}

/// Whether a sequence's pixels may be decoded frame by frame: compressed 8-bit
/// samples, some of them, no more than zlib can expand `data_len` bytes to
/// (about 1032 times), and a `CompressedDataSize` (if any) that the file holds.
fn deferrable(compressed_u8: bool, expected: usize, data_len: usize, size: Option<&Field>) -> bool {
    compressed_u8
        && expected > 0
        && expected <= data_len.saturating_mul(1032)
        && size.is_none_or(|s| s.value.parse::<usize>().is_ok_and(|n| n <= data_len))
}

impl Sequence {
    /// Reads and checks a sequence file.
    pub fn read(path: &Path) -> Result<Sequence, SequenceError> {
        let bytes = read_bounded(path)?;
        Sequence::parse(path, &bytes)
    }

    /// Reads a sequence of 8-bit or 32-bit float images (volume reconstruction
    /// takes both; [`Sequence::samples`] gives either).
    pub fn read_any(path: &Path) -> Result<Sequence, SequenceError> {
        let bytes = read_bounded(path)?;
        Sequence::parse_with(path, &bytes, true)
    }

    /// Parses the bytes of a sequence file of 8-bit images; `path` is only used in messages.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Sequence, SequenceError> {
        Sequence::parse_with(path, bytes, false)
    }

    /// Parses the bytes of a sequence file, float images too where `allow_float`.
    pub fn parse_with(path: &Path, bytes: &[u8], allow_float: bool) -> Result<Sequence, SequenceError> {
        Sequence::parse_deferring(path, bytes, allow_float, false).map(|(sequence, _)| sequence)
    }

    /// Reads a sequence as [`Sequence::read_any`] does, except that the frames of
    /// a zlib-compressed 8-bit sequence are left compressed: the sequence comes
    /// without pixels, and [`Deferred::decode`] decodes them frame by frame, so
    /// that each can be used as soon as it is decoded. Any other sequence is read
    /// whole, as `read_any` reads it.
    pub fn read_any_deferred(path: &Path) -> Result<(Sequence, Option<Deferred>), SequenceError> {
        let bytes = read_bounded(path)?;
        let (sequence, data) = Sequence::parse_deferring(path, &bytes, true, true)?;
        let deferred = data.map(|(data_start, expected)| Deferred {
            path: path.to_path_buf(),
            bytes,
            data_start,
            expected,
            width: sequence.width,
            height: sequence.height,
            orientation: sequence.orientation,
        });
        Ok((sequence, deferred))
    }

    /// [`Sequence::parse_with`]; where `defer` and the sequence's pixels are
    /// zlib-compressed 8-bit samples of a plausible size, without them, and with
    /// where they start and how many bytes they decode to.
    fn parse_deferring(
        path: &Path,
        bytes: &[u8],
        allow_float: bool,
        defer: bool,
    ) -> Result<(Sequence, Option<(usize, usize)>), SequenceError> {
        let fail = |line: Option<usize>, message: String| SequenceError {
            path: path.to_path_buf(),
            line,
            message,
        };
        let Header {
            fields: header,
            per_frame,
            data_start,
        } = read_header(bytes, &fail)?;
        let get = |key: &str| {
            header
                .get(key)
                .ok_or_else(|| fail(None, format!("header field `{key}` is missing")))
        };
        let dims = get("DimSize")?;
        let (width, height, count) = dimensions(dims, &fail)?;
        check_ndims(header.get("NDims"), dims, &fail)?;
        let float = check_element(
            get("ElementType")?,
            header.get("ElementNumberOfChannels"),
            allow_float,
            &fail,
        )?;
        let sample_bytes = if float { 4 } else { 1 };
        let expected = bytes_of_samples(width, height, count, sample_bytes, dims, &fail)?;
        let compressed = compressed_flag(header.get("CompressedData"), &fail)?;
        check_frame_count(per_frame.keys().copied(), count, dims, &fail)?;
        let data = &bytes[data_start..];
        let assemble = |orientation, pixels, float_pixels| Sequence {
            path: path.to_path_buf(),
            width,
            height,
            orientation,
            header: header.clone(),
            frames: per_frame
                .into_iter()
                .map(|(index, fields)| SequenceFrame { index, fields })
                .collect(),
            pixels,
            float_pixels,
        };
        // Deferred only where nothing below can fail before the pixels are
        // decoded (decoding checks the rest, and a failure is reported as the
        // whole read reports it).
        if defer
            && deferrable(
                compressed && !float,
                expected,
                data.len(),
                header.get("CompressedDataSize"),
            )
        {
            if let Ok(orientation) = orientation(header.get("UltrasoundImageOrientation"), &fail) {
                return Ok((
                    assemble(orientation, Vec::new(), Vec::new()),
                    Some((data_start, expected)),
                ));
            }
        }
        let compressed_size = if compressed {
            Some(header.get("CompressedDataSize"))
        } else {
            None
        };
        let pixels = pixel_bytes(data, compressed_size, expected, &fail)?;
        if pixels.len() < expected {
            return Err(fail(
                None,
                format!(
                    "data truncated: {} bytes of pixels, {expected} expected for {count} frames of {width}x{height}",
                    pixels.len()
                ),
            ));
        }
        // A tracker-only sequence may carry bytes after its header that no image
        // owns (PLUS writes some); there are no pixels to read.
        let pixels = if expected == 0 { Vec::new() } else { pixels };
        if pixels.len() > expected {
            return Err(fail(
                Some(dims.line),
                format!("more pixel data than `DimSize` says ({count} frames of {width}x{height})"),
            ));
        }
        let orientation = orientation(header.get("UltrasoundImageOrientation"), &fail)?;
        let samples = StoredSamples::of(float, big_endian(&header));
        let (pixels, float_pixels) = samples_in_mf(pixels, samples, orientation, width, height, &fail)?;
        let sequence = assemble(orientation, pixels, float_pixels);
        Ok((sequence, None))
    }

    /// Frame `index`'s samples, 8-bit or float (row-major, `width * height`).
    pub fn samples(&self, index: usize) -> Samples<'_> {
        let size = self.width * self.height;
        if self.pixels.is_empty() && !self.float_pixels.is_empty() {
            Samples::F32(&self.float_pixels[index * size..(index + 1) * size])
        } else {
            Samples::U8(self.pixels(index))
        }
    }

    /// The pixels of frame `index` (row-major, `width * height` bytes); empty
    /// for a float sequence (read those with [`Sequence::samples`]).
    pub fn pixels(&self, index: usize) -> &[u8] {
        if self.pixels.is_empty() {
            return &[];
        }
        let size = self.width * self.height;
        &self.pixels[index * size..(index + 1) * size]
    }

    /// Frame `index`'s transform `<name>Transform` (e.g. `ProbeToTracker`), checked:
    /// its status must be OK and its matrix rigid.
    pub fn transform(&self, index: usize, name: &str) -> Result<Rigid, FrameFault> {
        let (mut rows, field, line) = self.rows(index, name)?;
        let not_rigid = |reason: String| FrameFault::NotRigid {
            frame: index,
            field: field.clone(),
            line,
            reason,
        };
        // Trackers write 6 significant digits: a rotation that is orthonormal to that
        // precision is snapped onto the nearest orthonormal matrix (a mirror stays a
        // mirror and is refused below) before the strict check.
        let rotation = nalgebra::Matrix3::from_fn(|r, c| rows[r][c]);
        let off = (rotation.transpose() * rotation - nalgebra::Matrix3::identity())
            .abs()
            .max();
        if off.is_finite() && off < 1e-4 {
            let svd = rotation.svd(true, true);
            if let (Some(u), Some(v_t)) = (svd.u, svd.v_t) {
                let fixed = u * v_t;
                for (r, row) in rows.iter_mut().take(3).enumerate() {
                    for (c, v) in row.iter_mut().take(3).enumerate() {
                        *v = fixed[(r, c)];
                    }
                }
            }
        }
        rigid_from_rows(&rows).map_err(|e| not_rigid(e.to_string()))
    }

    /// Frame `index`'s transform `<name>Transform` as its 4x4 matrix: status OK and
    /// 16 finite numbers, not checked for rigidity (where only a position is used,
    /// e.g. a tracker whose rotations are orthonormal to 3 digits only).
    pub fn matrix(&self, index: usize, name: &str) -> Result<nalgebra::Matrix4<f64>, FrameFault> {
        let (rows, field, line) = self.rows(index, name)?;
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err(FrameFault::NotRigid {
                frame: index,
                field,
                line,
                reason: "matrix has a non-finite entry".into(),
            });
        }
        Ok(nalgebra::Matrix4::from_fn(|r, c| rows[r][c]))
    }

    /// The 16 numbers of frame `index`'s `<name>Transform` (status OK), with the
    /// field's name and line.
    fn rows(&self, index: usize, name: &str) -> Result<([[f64; 4]; 4], String, usize), FrameFault> {
        let frame = &self.frames[index];
        let field = format!("{name}Transform");
        let status_field = format!("{field}Status");
        if let Some(status) = frame.fields.get(&status_field) {
            if status.value != "OK" {
                return Err(FrameFault::Status {
                    frame: index,
                    field: status_field,
                    status: status.value.clone(),
                });
            }
        }
        let value = frame.fields.get(&field).ok_or_else(|| FrameFault::Missing {
            frame: index,
            field: field.clone(),
        })?;
        let not_rigid = |reason: String| FrameFault::NotRigid {
            frame: index,
            field: field.clone(),
            line: value.line,
            reason,
        };
        let numbers: Vec<f64> = value
            .value
            .split_whitespace()
            .map(|s| s.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| not_rigid(format!("`{}` holds a non-number", clip(&value.value))))?;
        if numbers.len() != 16 {
            return Err(not_rigid(format!("{} numbers, a 4x4 matrix needs 16", numbers.len())));
        }
        let rows = std::array::from_fn(|r| std::array::from_fn(|c| numbers[r * 4 + c]));
        Ok((rows, field, value.line))
    }

    /// Frame `index`'s `Timestamp`, s, when it is a finite number.
    pub fn timestamp_s(&self, index: usize) -> Option<f64> {
        self.frame_field(index, "Timestamp")
            .and_then(|t| t.parse::<f64>().ok())
            .filter(|t| t.is_finite())
    }

    /// Whether the samples are 32-bit floats.
    pub fn is_float(&self) -> bool {
        !self.float_pixels.is_empty()
    }

    /// Bytes of samples held in memory (8-bit and float).
    pub fn held_bytes(&self) -> usize {
        self.pixels.len() + 4 * self.float_pixels.len()
    }

    /// A per-frame field as text (e.g. `Timestamp`).
    pub fn frame_field(&self, index: usize, name: &str) -> Option<&str> {
        self.frames[index].fields.get(name).map(|f| f.value.as_str())
    }

    /// The names of the transforms the first frame carries
    /// (`Seq_FrameNNNN_<name>Transform` → `<name>`), sorted.
    pub fn transform_names(&self) -> Vec<String> {
        let Some(first) = self.frames.first() else {
            return Vec::new();
        };
        first
            .fields
            .keys()
            .filter_map(|k| k.strip_suffix("Transform"))
            .filter(|n| !n.is_empty())
            .map(str::to_string)
            .collect()
    }
}

impl Deferred {
    /// The error reading the whole file gives: the decoding stops at the first
    /// fault, and the whole read names it as it always does.
    pub(super) fn refusal(&self) -> SequenceError {
        match Sequence::parse_with(&self.path, &self.bytes, true) {
            Err(e) => e,
            Ok(_) => SequenceError {
                path: self.path.clone(),
                line: None,
                message: "the compressed pixels could not be decoded frame by frame".into(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn file(frames: usize, status: &str, matrix: &str, compressed_len_cut: usize) -> Vec<u8> {
        let (w, h) = (4usize, 3usize);
        let pixels: Vec<u8> = (0..w * h * frames).map(|i| (i % 251) as u8).collect();
        let mut enc = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(&pixels).unwrap();
        let mut z = enc.finish().unwrap();
        z.truncate(z.len() - compressed_len_cut);
        let mut text = format!(
            "ObjectType = Image\nNDims = 3\nCompressedData = True\nCompressedDataSize = {}\nDimSize = {w} {h} {frames}\nElementType = MET_UCHAR\n",
            z.len()
        );
        for i in 0..frames {
            text += &format!("Seq_Frame{i:04}_ProbeToTrackerTransform = {matrix}\n");
            text += &format!("Seq_Frame{i:04}_ProbeToTrackerTransformStatus = {status}\n");
        }
        text += "ElementDataFile = LOCAL\n";
        let mut bytes = text.into_bytes();
        bytes.extend(z);
        bytes
    }

    const IDENTITY: &str = "1 0 0 5 0 1 0 6 0 0 1 7 0 0 0 1";

    #[test]
    fn reads_frames_and_transforms() {
        let s = Sequence::parse(Path::new("t.mha"), &file(2, "OK", IDENTITY, 0)).unwrap();
        assert_eq!((s.width, s.height, s.frames.len()), (4, 3, 2));
        assert_eq!(s.pixels(1)[0], 12);
        let t = s.transform(1, "ProbeToTracker").unwrap();
        assert_eq!(t.translation.vector.z, 7.0);
    }

    #[test]
    fn bad_status_and_matrices_are_frame_faults() {
        let s = Sequence::parse(Path::new("t.mha"), &file(1, "INVALID", IDENTITY, 0)).unwrap();
        let e = s.transform(0, "ProbeToTracker").unwrap_err();
        assert_eq!(
            e.to_string(),
            "frame 0: `ProbeToTrackerTransformStatus` is INVALID, not OK"
        );
        let s = Sequence::parse(Path::new("t.mha"), &file(1, "OK", "1 0 0 5 0 2 0 6 0 0 1 7 0 0 0 1", 0)).unwrap();
        let e = s.transform(0, "ProbeToTracker").unwrap_err().to_string();
        assert!(e.contains("line 7") && e.contains("not orthonormal"), "{e}");
        let s = Sequence::parse(
            Path::new("t.mha"),
            &file(1, "OK", "1 0 0 nan 0 1 0 6 0 0 1 7 0 0 0 1", 0),
        )
        .unwrap();
        let e = s.transform(0, "ProbeToTracker").unwrap_err().to_string();
        assert!(e.contains("non-finite"), "{e}");
        assert!(matches!(
            s.transform(0, "ReferenceToTracker"),
            Err(FrameFault::Missing { .. })
        ));
    }

    #[test]
    fn truncated_data_is_an_error() {
        let e = Sequence::parse(Path::new("t.mha"), &file(2, "OK", IDENTITY, 5)).unwrap_err();
        assert!(e.message.contains("truncated"), "{e}");
        let bytes = file(2, "OK", IDENTITY, 0);
        let cut = &bytes[..bytes.len() / 2];
        let e = Sequence::parse(Path::new("t.mha"), cut).unwrap_err();
        assert!(e.to_string().starts_with("t.mha"), "{e}");
    }

    /// A tracker-only sequence (`DimSize = 0 0 N`): poses, no images, and bytes
    /// after the header that no image owns; one zero side alone is refused.
    #[test]
    fn a_tracker_only_sequence_has_poses_and_no_pixels() {
        let text = "ObjectType = Image\nNDims = 3\nCompressedData = False\nDimSize = 0 0 2\nElementType = MET_UCHAR\n\
                    Seq_Frame0000_ProbeToTrackerTransform = 1 0 0 1 0 1 0 2 0 0 1 3 0 0 0 1\n\
                    Seq_Frame0000_Timestamp = 1.0\n\
                    Seq_Frame0001_ProbeToTrackerTransform = 1 0 0 4 0 1 0 5 0 0 1 6 0 0 0 1\n\
                    Seq_Frame0001_Timestamp = 1.1\n\
                    ElementDataFile = LOCAL\n";
        let bytes = [text.as_bytes(), &[7u8, 9]].concat();
        let seq = Sequence::parse(Path::new("tracker.mha"), &bytes).unwrap();
        assert_eq!((seq.width, seq.height, seq.frames.len()), (0, 0, 2));
        assert!(seq.pixels(1).is_empty());
        assert_eq!(seq.transform(1, "ProbeToTracker").unwrap().translation.vector.x, 4.0);
        let one_side = text.replace("DimSize = 0 0 2", "DimSize = 0 4 2");
        let e = Sequence::parse(Path::new("tracker.mha"), one_side.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("zero size"), "{e}");
    }
}
