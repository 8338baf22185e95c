//! The header and pixel-data parts of a PLUS sequence file (see `sequence.rs`):
//! `Key = value` lines, `DimSize`, the element type, compression, orientation.

use std::collections::BTreeMap;
use std::io::Read;

use super::orientation::Orientation;
use super::sequence_types::{clip, Field, SequenceError, MAX_FRAME_PIXELS, MAX_SAMPLE_BYTES};
use std::path::Path;

/// The header's fields (per-frame ones apart) and where the pixel data starts.
pub(super) struct Header {
    pub(super) fields: BTreeMap<String, Field>,
    pub(super) per_frame: BTreeMap<usize, BTreeMap<String, Field>>,
    pub(super) data_start: usize,
}

/// Longest header read, bytes: a PLUS header is about 1 KB a frame, and a
/// sequence holds at most `MAX_FRAMES` frames.
pub(super) const MAX_HEADER_BYTES: usize = 256 << 20;

/// Most header fields besides the frames' own (PLUS writes about twenty).
const MAX_HEADER_FIELDS: usize = 10_000;

/// Reads `Key = value` lines up to `ElementDataFile = LOCAL`.
pub(super) fn read_header(
    bytes: &[u8],
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<Header, SequenceError> {
    let mut header: BTreeMap<String, Field> = BTreeMap::new();
    let mut per_frame: BTreeMap<usize, BTreeMap<String, Field>> = BTreeMap::new();
    let mut offset = 0usize;
    let mut line_no = 0usize;
    while offset < bytes.len() {
        if offset > MAX_HEADER_BYTES || header.len() > MAX_HEADER_FIELDS {
            return Err(fail(
                Some(line_no),
                format!(
                    "the header goes on past {MAX_HEADER_BYTES} bytes or {MAX_HEADER_FIELDS} fields besides the frames' (data before `ElementDataFile`?)"
                ),
            ));
        }
        let end = bytes[offset..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|p| offset + p)
            .unwrap_or(bytes.len());
        line_no += 1;
        let raw = &bytes[offset..end];
        offset = (end + 1).min(bytes.len());
        let text = std::str::from_utf8(raw)
            .map_err(|_| {
                fail(
                    Some(line_no),
                    "header line is not text (data before `ElementDataFile`?)".into(),
                )
            })?
            .trim_end_matches('\r');
        if text.trim().is_empty() {
            continue;
        }
        let Some((key, value)) = text.split_once('=') else {
            return Err(fail(
                Some(line_no),
                format!("expected `Key = value`, got `{}`", clip(text)),
            ));
        };
        let key = key.trim().to_string();
        let value = value.trim().to_string();
        if key == "ElementDataFile" {
            if value != "LOCAL" {
                return Err(fail(
                    Some(line_no),
                    format!("`ElementDataFile = {value}`: only LOCAL (data in the same file) is supported"),
                ));
            }
            header.insert(key, Field { value, line: line_no });
            return Ok(Header {
                fields: header,
                per_frame,
                data_start: offset,
            });
        }
        let field = Field { value, line: line_no };
        if let Some(rest) = key.strip_prefix("Seq_Frame") {
            let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
            let name = rest[digits.len()..].strip_prefix('_');
            match (digits.parse::<usize>(), name) {
                (Ok(index), Some(name)) if !name.is_empty() => {
                    // `Seq_Frame0005_X` and `Seq_Frame00005_X` are one field.
                    if let Some(first) = per_frame.entry(index).or_default().insert(name.to_string(), field) {
                        return Err(twice(&format!("frame {index}'s `{name}`"), first.line, line_no, fail));
                    }
                }
                _ => return Err(fail(Some(line_no), format!("`{key}`: expected `Seq_FrameNNNN_<Name>`"))),
            }
        } else if let Some(first) = header.insert(key.clone(), field) {
            return Err(twice(&format!("`{key}`"), first.line, line_no, fail));
        }
    }
    Err(fail(
        Some(line_no),
        "no `ElementDataFile = LOCAL` line: the header never ends (file cut off?)".into(),
    ))
}

/// A header field given a second time: refused, since which one counts would
/// be a guess.
fn twice(
    what: &str,
    first: usize,
    again: usize,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> SequenceError {
    fail(
        Some(again),
        format!("{what} is given twice (lines {first} and {again}); a field may be given once"),
    )
}

/// `DimSize`: width, height and frames (`0 0 N` for a tracker-only sequence).
pub(super) fn dimensions(
    dims: &Field,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<(usize, usize, usize), SequenceError> {
    let numbers: Vec<usize> = dims
        .value
        .split_whitespace()
        .map(|s| s.parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            fail(
                Some(dims.line),
                format!("`DimSize = {}`: not whole numbers", dims.value),
            )
        })?;
    let (width, height, count) = match numbers.as_slice() {
        [w, h, n] => (*w, *h, *n),
        [w, h] => (*w, *h, 1),
        _ => {
            return Err(fail(
                Some(dims.line),
                format!("`DimSize = {}`: expected width height frames", dims.value),
            ))
        }
    };
    if (width == 0) != (height == 0) {
        return Err(fail(Some(dims.line), "`DimSize`: an image of zero size".into()));
    }
    Ok((width, height, count))
}

/// `CompressedData`: True or False (absent: False).
pub(super) fn compressed_flag(
    field: Option<&Field>,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<bool, SequenceError> {
    match field {
        None => Ok(false),
        Some(f) => match f.value.to_ascii_lowercase().as_str() {
            "true" => Ok(true),
            "false" => Ok(false),
            other => Err(fail(
                Some(f.line),
                format!("`CompressedData = {other}`: expected True or False"),
            )),
        },
    }
}

/// `UltrasoundImageOrientation` (MF where absent).
pub(super) fn orientation(
    field: Option<&Field>,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<Orientation, SequenceError> {
    match field {
        None => Ok(Orientation::default()),
        Some(f) => Orientation::parse(&f.value).ok_or_else(|| {
            fail(
                Some(f.line),
                format!(
                    "`UltrasoundImageOrientation = {}`: expected MF, MN, UF or UN (a third letter allowed)",
                    f.value
                ),
            )
        }),
    }
}

/// How a float sequence's samples are stored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum StoredSamples {
    U8,
    /// 32-bit floats, most significant byte first when `big_endian`.
    F32 {
        big_endian: bool,
    },
}

impl StoredSamples {
    pub(super) fn of(float: bool, big_endian: bool) -> StoredSamples {
        match float {
            true => StoredSamples::F32 { big_endian },
            false => StoredSamples::U8,
        }
    }
}

/// The pixel bytes as 8-bit or float samples (the other vector empty), flipped
/// to MF; a float sample that is not a finite number is refused with its frame
/// and pixel (it would give non-finite voxels, silently).
pub(super) fn samples_in_mf(
    mut pixels: Vec<u8>,
    samples: StoredSamples,
    orientation: Orientation,
    width: usize,
    height: usize,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<(Vec<u8>, Vec<f32>), SequenceError> {
    let StoredSamples::F32 { big_endian } = samples else {
        orientation.flip_to_mf(&mut pixels, width, height);
        return Ok((pixels, Vec::new()));
    };
    let mut floats: Vec<f32> = pixels
        .chunks_exact(4)
        .map(|b| {
            let b = [b[0], b[1], b[2], b[3]];
            if big_endian {
                f32::from_be_bytes(b)
            } else {
                f32::from_le_bytes(b)
            }
        })
        .collect();
    if let Some(at) = floats.iter().position(|v| !v.is_finite()) {
        let frame_px = (width * height).max(1);
        let (frame, within) = (at / frame_px, at % frame_px);
        return Err(fail(
            None,
            format!(
                "frame {frame}: the sample at column {}, row {} of the file's image is {}, not a finite number",
                within % width.max(1),
                within / width.max(1),
                floats[at]
            ),
        ));
    }
    orientation.flip_to_mf(&mut floats, width, height);
    Ok((Vec::new(), floats))
}

/// The byte order of a sequence's samples: `BinaryDataByteOrderMSB` (or
/// `ElementByteOrderMSB`) `True` is big-endian; it matters for floats only.
pub(super) fn big_endian(header: &std::collections::BTreeMap<String, Field>) -> bool {
    ["BinaryDataByteOrderMSB", "ElementByteOrderMSB"]
        .iter()
        .any(|k| header.get(*k).is_some_and(|f| f.value.eq_ignore_ascii_case("true")))
}

/// 8-bit grey pixels, and 32-bit float ones where `allow_float`; true for float.
pub(super) fn check_element(
    element: &Field,
    channels: Option<&Field>,
    allow_float: bool,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<bool, SequenceError> {
    let float = match element.value.as_str() {
        "MET_UCHAR" => false,
        "MET_FLOAT" if allow_float => true,
        other => {
            let supported = if allow_float {
                "MET_UCHAR (8-bit) and MET_FLOAT (32-bit) are"
            } else {
                "MET_UCHAR (8-bit B-scans) is"
            };
            return Err(fail(
                Some(element.line),
                format!("`ElementType = {other}`: only {supported} supported"),
            ));
        }
    };
    match channels {
        Some(channels) if channels.value != "1" => Err(fail(
            Some(channels.line),
            format!(
                "`ElementNumberOfChannels = {}`: only grey (1) is supported",
                channels.value
            ),
        )),
        _ => Ok(float),
    }
}

/// The pixel bytes after the header: as they are, or inflated (`compressed_size`
/// is `Some` for compressed data, holding `CompressedDataSize` when given), at
/// most one byte past `expected`.
pub(super) fn pixel_bytes(
    data: &[u8],
    compressed_size: Option<Option<&Field>>,
    expected: usize,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<Vec<u8>, SequenceError> {
    let Some(size) = compressed_size else {
        return Ok(data.to_vec());
    };
    if let Some(size) = size {
        let declared: usize = size.value.parse().map_err(|_| {
            fail(
                Some(size.line),
                format!("`CompressedDataSize = {}`: not a whole number", size.value),
            )
        })?;
        if declared > data.len() {
            return Err(fail(
                Some(size.line),
                format!(
                    "data truncated: `CompressedDataSize` says {declared} bytes, the file has {} after the header",
                    data.len()
                ),
            ));
        }
    }
    // zlib expands at most about 1032 times: a short file that claims a large
    // image gets no large allocation before its bytes are decoded.
    let mut out = Vec::with_capacity(expected.min(data.len().saturating_mul(1032)));
    let mut decoder = flate2::read::ZlibDecoder::new(data).take(expected as u64 + 1);
    decoder.read_to_end(&mut out).map_err(|e| {
        fail(
            None,
            format!(
                "compressed data is corrupt or truncated after {} of {expected} bytes: {e}",
                out.len()
            ),
        )
    })?;
    Ok(out)
}

/// `NDims`, where given, must count `DimSize`'s sizes: a header that says two
/// things about its shape is refused.
pub(super) fn check_ndims(
    ndims: Option<&Field>,
    dims: &Field,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<(), SequenceError> {
    let Some(n) = ndims else { return Ok(()) };
    let given = dims.value.split_whitespace().count();
    if n.value.parse::<usize>().ok() == Some(given) {
        return Ok(());
    }
    Err(fail(
        Some(n.line),
        format!(
            "`NDims = {}` contradicts `DimSize = {}` (line {}), which has {given} sizes",
            n.value, dims.value, dims.line
        ),
    ))
}

/// A sequence file's bytes, read as far as its header lets them go: the header
/// first (up to its `ElementDataFile = LOCAL` line, within the header's limit),
/// then no more data than its `DimSize` and compression allow, plus one byte to
/// tell a file with more. A file whose metadata claims more than any sequence
/// probecal takes is refused unread; a device that never ends (`/dev/zero`) is
/// read no further than its header's limit.
pub(super) fn read_bounded(path: &Path) -> Result<Vec<u8>, SequenceError> {
    use std::io::Read;
    let fail = |message: String| SequenceError {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    let limit = (MAX_SAMPLE_BYTES + (64 << 20)) as u64;
    let mut file = std::fs::File::open(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    let size = file.metadata().map_err(|e| fail(format!("cannot read: {e}")))?.len();
    if size > limit {
        return Err(fail(format!(
            "{size} bytes: larger than any sequence probecal reads ({limit} bytes)"
        )));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    let marker = b"ElementDataFile";
    let header_end = loop {
        let searched = bytes.len().saturating_sub(marker.len() + 64);
        let before = bytes.len();
        (&mut file)
            .take(1 << 20)
            .read_to_end(&mut bytes)
            .map_err(|e| fail(format!("cannot read: {e}")))?;
        let found = bytes[searched..]
            .windows(marker.len())
            .position(|w| w == marker)
            .and_then(|at| {
                bytes[searched + at..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map(|nl| searched + at + nl + 1)
            });
        match found {
            Some(end) => break end,
            // The whole file, as much as a header may be, or bytes no header
            // holds (a NUL): the parser says what is wrong.
            None if bytes.len() == before || bytes.len() > MAX_HEADER_BYTES || bytes[before..].contains(&0) => {
                return Ok(bytes)
            }
            None => {}
        }
    };
    let most = header_end.saturating_add(data_bound(path, &bytes[..header_end])?);
    if bytes.len() <= most {
        (&mut file)
            .take((most + 1 - bytes.len()) as u64)
            .read_to_end(&mut bytes)
            .map_err(|e| fail(format!("cannot read: {e}")))?;
    }
    Ok(bytes)
}

/// The most data bytes a header allows after it: its samples, or their zlib
/// stream (at most a thousandth larger, or its `CompressedDataSize`); for a
/// tracker-only sequence, 64 MiB of bytes no image owns (PLUS writes some).
fn data_bound(path: &Path, header: &[u8]) -> Result<usize, SequenceError> {
    let fail = |line: Option<usize>, message: String| SequenceError {
        path: path.to_path_buf(),
        line,
        message,
    };
    let Header { fields, .. } = read_header(header, &fail)?;
    let Some(dims) = fields.get("DimSize") else {
        return Ok(0);
    };
    let (width, height, count) = dimensions(dims, &fail)?;
    let float = fields.get("ElementType").is_some_and(|e| e.value == "MET_FLOAT");
    let expected = bytes_of_samples(width, height, count, if float { 4 } else { 1 }, dims, &fail)?;
    if expected == 0 {
        return Ok(64 << 20);
    }
    if !compressed_flag(fields.get("CompressedData"), &fail)? {
        return Ok(expected);
    }
    let declared = fields
        .get("CompressedDataSize")
        .and_then(|f| f.value.trim().parse::<usize>().ok())
        .unwrap_or(0)
        .min(MAX_SAMPLE_BYTES);
    Ok(declared.max(expected + expected / 1000 + 1024))
}

/// Bytes of samples `count` frames of `width` x `height` take, refused (naming
/// `dims`'s line) beyond [`MAX_FRAME_PIXELS`] a frame or [`MAX_SAMPLE_BYTES`] in all.
pub(super) fn bytes_of_samples(
    width: usize,
    height: usize,
    count: usize,
    sample_bytes: usize,
    dims: &Field,
    fail: &dyn Fn(Option<usize>, String) -> SequenceError,
) -> Result<usize, SequenceError> {
    let frame_pixels = width.checked_mul(height).filter(|&p| p <= MAX_FRAME_PIXELS);
    frame_pixels
        .and_then(|p| p.checked_mul(count))
        .and_then(|p| p.checked_mul(sample_bytes))
        .filter(|&b| b <= MAX_SAMPLE_BYTES)
        .ok_or_else(|| {
        fail(
            Some(dims.line),
            format!(
            "`DimSize = {}` is implausibly large: at most {MAX_FRAME_PIXELS} pixels a frame and {} GiB of samples in all",
            dims.value,
            MAX_SAMPLE_BYTES >> 30
            ),
        )
        })
}
