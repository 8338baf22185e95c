//! The types a PLUS sequence file's readers share: the error that names the
//! file and line, one header field, and how a value is quoted in a message
//! (kept apart from the reader, `sequence.rs`, so that the header and the deferred
//! decoder name them without importing the reader).

use std::path::PathBuf;

/// Why a sequence file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct SequenceError {
    pub path: PathBuf,
    /// 1-based header line, where the problem has one.
    pub line: Option<usize>,
    pub message: String,
}

/// One header value and the line it was on.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub value: String,
    pub line: usize,
}

pub(super) fn clip(text: &str) -> String {
    let mut s: String = text.chars().take(60).collect();
    if s.len() < text.len() {
        s.push('…');
    }
    s
}

/// Most bytes of samples a sequence may hold, all frames together (4 GiB): a
/// corrupt or hostile header is refused before anything is allocated for it.
pub const MAX_SAMPLE_BYTES: usize = 1 << 32;

/// Most pixels of one frame (8192 x 8192): far beyond any B-scan.
pub const MAX_FRAME_PIXELS: usize = 1 << 26;
