//! Why an image codec (the PNG and the JPEG one) could not read or
//! write pixels; the image reader wraps it with the file's path.

/// A codec's refusal, in words a user can act on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CodecError {
    /// The decoder refused the bytes (truncated, a bad checksum, not the format).
    #[error("a damaged or truncated {format} ({detail})")]
    Damaged { format: &'static str, detail: String },
    /// A kind of file probecal does not convert as OpenCV would.
    #[error("{0}")]
    Unsupported(String),
    /// The library itself could not start.
    #[error("{library} could not start")]
    Start { library: &'static str },
    /// Pixels handed to an encoder in a layout it does not write.
    #[error("{channels} channels: a {format} is written from 1 or 3")]
    Channels { format: &'static str, channels: usize },
    /// A pixel buffer whose length is not its width x height x channels.
    #[error("{bytes} bytes for {width}x{height} px of {channels} channels")]
    Shape {
        bytes: usize,
        width: usize,
        height: usize,
        channels: usize,
    },
    /// The encoder failed while writing.
    #[error("{format} encoder: {detail}")]
    Encode { format: &'static str, detail: String },
}
