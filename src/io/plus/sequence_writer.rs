//! A sequence built frame by frame (frames received over a network) and
//! written as a PLUS sequence file: uncompressed 8-bit MF images, each frame's
//! fields (`Timestamp`, `<Name>Transform`, `<Name>TransformStatus`, …) as
//! `Seq_FrameNNNN_` header lines, in the layout PLUS writes and reads.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use super::orientation::Orientation;
use super::sequence::{Field, Sequence, SequenceFrame};

/// Why a frame could not be appended to a sequence.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PushFrameError {
    #[error("frames are appended to 8-bit sequences only")]
    NotEightBit,
    #[error("a frame of {pixels} pixels, the sequence's frames are {width}x{height}")]
    Size { pixels: usize, width: usize, height: usize },
    #[error("field `{key} = {value}` does not fit one header line")]
    Field { key: String, value: String },
}

impl Sequence {
    /// A sequence of no frames of `width` x `height` 8-bit MF images.
    pub fn empty(path: &Path, width: usize, height: usize) -> Sequence {
        Sequence {
            path: path.to_path_buf(),
            width,
            height,
            orientation: Orientation::Mf,
            header: BTreeMap::new(),
            frames: Vec::new(),
            pixels: Vec::new(),
            float_pixels: Vec::new(),
        }
    }

    /// Appends a frame of MF pixels and its fields (keys without the
    /// `Seq_FrameNNNN_` prefix; values one line of text each).
    pub fn push_frame(&mut self, fields: BTreeMap<String, String>, pixels: &[u8]) -> Result<(), PushFrameError> {
        if !self.float_pixels.is_empty() {
            return Err(PushFrameError::NotEightBit);
        }
        if pixels.len() != self.width * self.height {
            return Err(PushFrameError::Size {
                pixels: pixels.len(),
                width: self.width,
                height: self.height,
            });
        }
        if let Some((k, v)) = fields
            .iter()
            .find(|(k, v)| k.contains(['=', '\n', '\r']) || v.contains(['\n', '\r']))
        {
            return Err(PushFrameError::Field {
                key: k.clone(),
                value: v.clone(),
            });
        }
        self.frames.push(SequenceFrame {
            index: self.frames.len(),
            fields: fields
                .into_iter()
                .map(|(k, value)| (k, Field { value, line: 0 }))
                .collect(),
        });
        self.pixels.extend_from_slice(pixels);
        Ok(())
    }

    /// The sequence as a PLUS sequence file (`.igs.mha`), uncompressed, its
    /// images in MF orientation (as they are held).
    pub fn to_file_bytes(&self) -> Vec<u8> {
        let mut text = String::new();
        let _ = write!(
            text,
            "ObjectType = Image\nNDims = 3\nAnatomicalOrientation = RAI\nBinaryData = True\n\
             BinaryDataByteOrderMSB = False\nCenterOfRotation = 0 0 0\nCompressedData = False\n\
             DimSize = {} {} {}\nKinds = domain domain list\nElementSpacing = 1 1 1\n\
             ElementType = MET_UCHAR\nOffset = 0 0 0\nTransformMatrix = 1 0 0 0 1 0 0 0 1\n\
             UltrasoundImageOrientation = MF\nUltrasoundImageType = BRIGHTNESS\n",
            self.width,
            self.height,
            self.frames.len()
        );
        for frame in &self.frames {
            for (key, field) in &frame.fields {
                let _ = writeln!(text, "Seq_Frame{:04}_{key} = {}", frame.index, field.value);
            }
        }
        text.push_str("ElementDataFile = LOCAL\n");
        let mut bytes = text.into_bytes();
        let size = self.width * self.height;
        for frame in &self.frames {
            bytes.extend_from_slice(&self.pixels[frame.index * size..(frame.index + 1) * size]);
        }
        bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_built_sequence_reads_back_the_same() {
        let mut s = Sequence::empty(Path::new("received.igs.mha"), 3, 2);
        for i in 0..3u8 {
            let fields = BTreeMap::from([
                ("Timestamp".to_string(), format!("{}.25", i)),
                (
                    "ProbeToTrackerTransform".to_string(),
                    "1 0 0 10 0 1 0 20 0 0 1 30 0 0 0 1".to_string(),
                ),
                ("ProbeToTrackerTransformStatus".to_string(), "OK".to_string()),
            ]);
            s.push_frame(fields, &[i, 1, 2, 3, 4, 5 + i]).unwrap();
        }
        assert!(s
            .push_frame(BTreeMap::new(), &[0; 5])
            .unwrap_err()
            .to_string()
            .contains("3x2"));
        let bad = BTreeMap::from([("A".to_string(), "x\ny".to_string())]);
        assert!(s.push_frame(bad, &[0; 6]).is_err());
        let back = Sequence::parse(Path::new("received.igs.mha"), &s.to_file_bytes()).unwrap();
        assert_eq!(back.frames.len(), 3);
        assert_eq!(back.pixels(2), s.pixels(2));
        assert_eq!(back.frame_field(1, "Timestamp"), Some("1.25"));
        let t = back.transform(2, "ProbeToTracker").unwrap();
        assert_eq!(t.translation.vector.z, 30.0);
    }
}
