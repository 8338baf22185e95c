//! A sequence's compressed 8-bit frames, decoded one frame at a time
//! (`Sequence::read_any_deferred` in `sequence.rs`): a reconstruction pastes
//! each frame while the next ones are still being inflated.

use std::path::PathBuf;

use flate2::{Decompress, FlushDecompress, Status};

use super::orientation::Orientation;
use super::sequence_types::SequenceError;

/// The compressed pixels of a sequence read without them.
#[derive(Debug)]
pub struct Deferred {
    pub(super) path: PathBuf,
    /// The whole file.
    pub(super) bytes: Vec<u8>,
    /// Where the compressed pixels start in `bytes`.
    pub(super) data_start: usize,
    /// Bytes of pixels, all frames.
    pub(super) expected: usize,
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) orientation: Orientation,
}

impl Deferred {
    /// Bytes of pixels the frames decode to (`out`'s length for [`Deferred::decode`]).
    pub fn expected(&self) -> usize {
        self.expected
    }

    /// Bytes held once the frames are decoded: the file's and the pixels'.
    pub fn held_bytes(&self) -> usize {
        self.bytes.len() + self.expected
    }

    /// Decodes the frames into `out` (all frames' pixels, frame after frame),
    /// flipped to MF as `Sequence::read_any` holds them, and hands each frame
    /// to `arrived` as soon as it is whole. A damaged, short or long stream is
    /// refused with the error the whole read gives it.
    pub fn decode<'a>(&self, out: &'a mut [u8], mut arrived: impl FnMut(&'a [u8])) -> Result<(), SequenceError> {
        let frame = self.width * self.height;
        if out.len() != self.expected || frame == 0 {
            return Err(self.refusal());
        }
        let mut stream = Decompress::new(true);
        let mut input = &self.bytes[self.data_start..];
        for pixels in out.chunks_exact_mut(frame) {
            let mut filled = 0;
            while filled < pixels.len() {
                let (read, written) = (stream.total_in(), stream.total_out());
                let status = stream
                    .decompress(input, &mut pixels[filled..], FlushDecompress::None)
                    .map_err(|_| self.refusal())?;
                let read = (stream.total_in() - read) as usize;
                let written = (stream.total_out() - written) as usize;
                input = &input[read..];
                filled += written;
                let stalled = read == 0 && written == 0;
                if filled < pixels.len() && (status == Status::StreamEnd || stalled) {
                    return Err(self.refusal());
                }
            }
            self.orientation.flip_to_mf(pixels, self.width, self.height);
            arrived(pixels);
        }
        // Nothing may follow the last frame's pixels.
        let mut more = [0u8; 1];
        let written = stream.total_out();
        let status = stream.decompress(input, &mut more, FlushDecompress::Finish);
        if status.is_err() || stream.total_out() > written {
            return Err(self.refusal());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;
    use std::path::Path;

    use crate::io::plus::sequence::Sequence;

    /// A compressed MN sequence of `frames` 5x4 frames whose data holds
    /// `pixel_frames` frames' pixels, then `cut` bytes cut off its end.
    fn file(frames: usize, pixel_frames: usize, cut: usize) -> Vec<u8> {
        let pixels: Vec<u8> = (0..pixel_frames * 20).map(|i| (i * 7 % 251) as u8).collect();
        let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        encoder.write_all(&pixels).expect("in memory");
        let mut data = encoder.finish().expect("in memory");
        data.truncate(data.len() - cut);
        let mut text = format!(
            "ObjectType = Image\nNDims = 3\nCompressedData = True\nCompressedDataSize = {}\nDimSize = 5 4 {frames}\n\
             ElementType = MET_UCHAR\nUltrasoundImageOrientation = MN\n",
            data.len()
        );
        for k in 0..frames {
            text += &format!("Seq_Frame{k:04}_ImageStatus = OK\n");
        }
        text += "ElementDataFile = LOCAL\n";
        [text.as_bytes(), &data].concat()
    }

    fn saved(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let path = std::env::temp_dir().join(format!("probecal-deferred-{}-{name}.mha", std::process::id()));
        std::fs::write(&path, bytes).expect("temp file");
        path
    }

    #[test]
    fn frames_decode_one_by_one_to_the_whole_reads_pixels() {
        let path = saved("good", &file(3, 3, 0));
        let whole = Sequence::read_any(&path).expect("a good file");
        let (sequence, deferred) = Sequence::read_any_deferred(&path).expect("a good file");
        let deferred = deferred.expect("compressed 8-bit frames are deferred");
        assert!(sequence.pixels(0).is_empty());
        assert_eq!(sequence.frames, whole.frames);
        let mut out = vec![0u8; deferred.expected()];
        let mut arrived = Vec::new();
        deferred
            .decode(&mut out, |frame| arrived.push(frame.to_vec()))
            .expect("decodes");
        assert_eq!(arrived.len(), 3);
        for (k, frame) in arrived.iter().enumerate() {
            assert_eq!(
                frame.as_slice(),
                whole.pixels(k),
                "frame {k}, flipped to MF as the whole read flips it"
            );
        }
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_damaged_stream_is_refused_as_the_whole_read_refuses_it() {
        let mut corrupt = file(3, 3, 0);
        let n = corrupt.len();
        corrupt[n - 30] ^= 0xFF;
        for (name, bytes) in [
            ("short", file(3, 2, 0)),
            ("long", file(3, 4, 0)),
            ("cut", file(3, 3, 9)),
            ("corrupt", corrupt),
        ] {
            let path = saved(name, &bytes);
            let whole = Sequence::read_any(&path).expect_err(name);
            if let Some(deferred) = Sequence::read_any_deferred(&path).expect(name).1 {
                let mut out = vec![0u8; deferred.expected()];
                let mut frames = 0;
                let error = deferred.decode(&mut out, |_| frames += 1).expect_err(name);
                assert_eq!(error, whole, "{name}");
                assert!(frames < 3 || name == "long", "{name}: {frames} frames handed over");
            }
            let _ = std::fs::remove_file(path);
        }
        let plain = String::from_utf8_lossy(&file(1, 0, 0)).replace("CompressedData = True", "CompressedData = False");
        let path = saved("plain", plain.as_bytes());
        assert!(Sequence::read_any_deferred(Path::new(&path))
            .map(|(_, d)| d.is_none())
            .unwrap_or(true));
        let _ = std::fs::remove_file(path);
    }
}
