//! OpenIGTLink messages: the 58-byte header (protocol versions 1 and 2), the
//! CRC-64 of the body, and the bodies probecal reads (IMAGE, TRANSFORM, STRING,
//! STATUS) and writes (TRANSFORM, IMAGE, STRING, STATUS).
//!
//! All numbers are big-endian. A version-2 body starts with a 12-byte extended
//! header and ends with the metadata it announces; the content between is laid
//! out as in version 1. The header's timestamp is seconds since 1970 in its
//! high 32 bits and a fraction of a second in units of 2^-32 in its low 32 bits.

use super::IgtlError;
use nalgebra::Matrix4;

/// Bytes of a message header.
pub const HEADER_BYTES: usize = 58;
/// Bytes of a version-2 extended header.
const EXTENDED_HEADER_BYTES: usize = 12;
/// Bytes of an IMAGE content's own header.
const IMAGE_HEADER_BYTES: usize = 72;
/// Bytes of a TRANSFORM content: 12 float32.
const TRANSFORM_BYTES: usize = 48;

/// CRC-64 as OpenIGTLink computes it (ECMA-182 polynomial, not reflected, zero
/// start, no final xor).
pub fn crc64(bytes: &[u8]) -> u64 {
    const POLY: u64 = 0x42F0_E1EB_A9EA_3693;
    static TABLE: std::sync::OnceLock<[u64; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let mut c = (i as u64) << 56;
            for _ in 0..8 {
                c = if c & (1 << 63) != 0 { (c << 1) ^ POLY } else { c << 1 };
            }
            c
        })
    });
    bytes
        .iter()
        .fold(0u64, |crc, &b| table[((crc >> 56) as u8 ^ b) as usize] ^ (crc << 8))
}

/// A message header, decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    pub version: u16,
    /// Message type, e.g. `IMAGE`.
    pub kind: String,
    pub device: String,
    /// Seconds since 1970 (the header's 32.32 fixed-point value).
    pub timestamp_s: f64,
    pub body_bytes: u64,
    pub crc: u64,
}

/// A fixed-width, NUL-padded name field as text.
fn name_field(bytes: &[u8]) -> String {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes(b[at..at + 4].try_into().unwrap_or_default())
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_be_bytes(b[at..at + 8].try_into().unwrap_or_default())
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_be_bytes(b[at..at + 4].try_into().unwrap_or_default())
}

/// The 64-bit header timestamp as seconds.
pub fn timestamp_from_bits(bits: u64) -> f64 {
    (bits >> 32) as f64 + (bits & 0xFFFF_FFFF) as f64 / 4_294_967_296.0
}

/// Seconds as the 64-bit header timestamp (0 for a time before 1970 or past 2106).
pub fn timestamp_to_bits(seconds: f64) -> u64 {
    if !(seconds.is_finite() && (0.0..4_294_967_296.0).contains(&seconds)) {
        return 0;
    }
    let whole = seconds.floor();
    let fraction = (((seconds - whole) * 4_294_967_296.0).round() as u64).min(0xFFFF_FFFF);
    ((whole as u64) << 32) | fraction
}

impl Header {
    /// Decodes a header; the version must be one probecal reads.
    pub fn parse(bytes: &[u8; HEADER_BYTES]) -> Result<Header, IgtlError> {
        let version = u16_at(bytes, 0);
        if !(1..=3).contains(&version) {
            return Err(IgtlError::Unframed(format!(
                "header version {version}: OpenIGTLink headers are versions 1, 2 and 3"
            )));
        }
        Ok(Header {
            version,
            kind: name_field(&bytes[2..14]),
            device: name_field(&bytes[14..34]),
            timestamp_s: timestamp_from_bits(u64_at(bytes, 34)),
            body_bytes: u64_at(bytes, 42),
            crc: u64_at(bytes, 50),
        })
    }
}

/// An IMAGE message's pixels and geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Columns, rows and slices.
    pub size: [usize; 3],
    /// OpenIGTLink scalar type (3: uint8).
    pub scalar_type: u8,
    pub components: u8,
    /// Pixel spacing along the columns and rows, mm (the lengths of the matrix's axes).
    pub spacing_mm: [f64; 3],
    pub pixels: Vec<u8>,
}

/// A decoded message body.
#[derive(Debug, Clone, PartialEq)]
pub enum Body {
    Image(Image),
    /// The 4x4 matrix (its last row 0 0 0 1).
    Transform(Matrix4<f64>),
    String(String),
    Status {
        code: u16,
        name: String,
        message: String,
    },
    /// A type probecal does not read (e.g. `POSITION`, `GET_IMAGE`): its name.
    Other(String),
}

/// Bytes per sample of an OpenIGTLink scalar type.
fn scalar_bytes(kind: u8) -> Option<usize> {
    match kind {
        2 | 3 => Some(1),
        4 | 5 => Some(2),
        6 | 7 | 10 => Some(4),
        11 => Some(8),
        _ => None,
    }
}

/// The content of a body (without a version-2 extended header and metadata).
fn content<'a>(header: &Header, body: &'a [u8]) -> Result<&'a [u8], IgtlError> {
    if header.version < 2 {
        return Ok(body);
    }
    if body.len() < EXTENDED_HEADER_BYTES {
        return Err(IgtlError::Malformed(format!(
            "version-{} body of {} bytes is shorter than its {EXTENDED_HEADER_BYTES}-byte extended header",
            header.version,
            body.len()
        )));
    }
    let extended = u16_at(body, 0) as usize;
    let metadata_header = u16_at(body, 2) as usize;
    let metadata = u32_at(body, 4) as usize;
    let tail = metadata_header.saturating_add(metadata);
    if extended < EXTENDED_HEADER_BYTES || extended.saturating_add(tail) > body.len() {
        return Err(IgtlError::Malformed(format!(
            "extended header of {extended} bytes and metadata of {tail} bytes do not fit a body of {} bytes",
            body.len()
        )));
    }
    Ok(&body[extended..body.len() - tail])
}

/// Decodes a body whose CRC has been checked.
pub fn decode(header: &Header, body: &[u8]) -> Result<Body, IgtlError> {
    let c = content(header, body)?;
    let need = |n: usize, what: &str| {
        if c.len() < n {
            Err(IgtlError::Malformed(format!(
                "{what} needs {n} bytes, the body has {}",
                c.len()
            )))
        } else {
            Ok(())
        }
    };
    match header.kind.as_str() {
        "TRANSFORM" => {
            need(TRANSFORM_BYTES, "a TRANSFORM")?;
            let v: [f64; 12] = std::array::from_fn(|i| f32_at(c, 4 * i) as f64);
            if v.iter().any(|x| !x.is_finite()) {
                return Err(IgtlError::Malformed("a TRANSFORM with a non-finite entry".into()));
            }
            // Columns first: the three axes, then the translation.
            Ok(Body::Transform(Matrix4::new(
                v[0], v[3], v[6], v[9], v[1], v[4], v[7], v[10], v[2], v[5], v[8], v[11], 0.0, 0.0, 0.0, 1.0,
            )))
        }
        "STRING" => {
            need(4, "a STRING")?;
            let length = u16_at(c, 2) as usize;
            need(4 + length, "a STRING of its stated length")?;
            Ok(Body::String(String::from_utf8_lossy(&c[4..4 + length]).into_owned()))
        }
        "STATUS" => {
            need(30, "a STATUS")?;
            Ok(Body::Status {
                code: u16_at(c, 0),
                name: name_field(&c[10..30]),
                message: name_field(&c[30..]),
            })
        }
        "IMAGE" => decode_image(c),
        other => Ok(Body::Other(other.to_string())),
    }
}

fn decode_image(c: &[u8]) -> Result<Body, IgtlError> {
    if c.len() < IMAGE_HEADER_BYTES {
        return Err(IgtlError::Malformed(format!(
            "an IMAGE needs its {IMAGE_HEADER_BYTES}-byte image header, the body has {}",
            c.len()
        )));
    }
    let components = c[2];
    let scalar_type = c[3];
    let size = [u16_at(c, 6) as usize, u16_at(c, 8) as usize, u16_at(c, 10) as usize];
    let axis = |k: usize| {
        let v: [f64; 3] = std::array::from_fn(|i| f32_at(c, 12 + 12 * k + 4 * i) as f64);
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    };
    let spacing_mm = [axis(0), axis(1), axis(2)];
    let offset = [u16_at(c, 60) as usize, u16_at(c, 62) as usize, u16_at(c, 64) as usize];
    let sub = [u16_at(c, 66) as usize, u16_at(c, 68) as usize, u16_at(c, 70) as usize];
    let sample = scalar_bytes(scalar_type)
        .ok_or_else(|| IgtlError::Malformed(format!("an IMAGE of unknown scalar type {scalar_type}")))?;
    if components == 0 {
        return Err(IgtlError::Malformed("an IMAGE of 0 components".into()));
    }
    if offset != [0, 0, 0] || sub != size {
        return Err(IgtlError::Malformed(format!(
            "an IMAGE sub-volume ({}x{}x{} at {},{},{}) of a {}x{}x{} image: only whole images are read",
            sub[0], sub[1], sub[2], offset[0], offset[1], offset[2], size[0], size[1], size[2]
        )));
    }
    let expected = size[0] * size[1] * size[2] * components as usize * sample;
    let pixels = &c[IMAGE_HEADER_BYTES..];
    if pixels.len() != expected {
        return Err(IgtlError::Malformed(format!(
            "an IMAGE of {}x{}x{} with {components} component(s) of {sample} byte(s) needs {expected} bytes of pixels, the body holds {}",
            size[0],
            size[1],
            size[2],
            pixels.len()
        )));
    }
    Ok(Body::Image(Image {
        size,
        scalar_type,
        components,
        spacing_mm,
        pixels: pixels.to_vec(),
    }))
}

/// A version-1 message: header then `body`.
pub fn encode(kind: &str, device: &str, timestamp_s: f64, body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_BYTES + body.len());
    out.extend_from_slice(&1u16.to_be_bytes());
    let mut field = |text: &str, width: usize| {
        let mut bytes = text.as_bytes()[..text.len().min(width)].to_vec();
        bytes.resize(width, 0);
        out.extend_from_slice(&bytes);
    };
    field(kind, 12);
    field(device, 20);
    out.extend_from_slice(&timestamp_to_bits(timestamp_s).to_be_bytes());
    out.extend_from_slice(&(body.len() as u64).to_be_bytes());
    out.extend_from_slice(&crc64(body).to_be_bytes());
    out.extend_from_slice(body);
    out
}

/// A TRANSFORM body of a 4x4 matrix (its last row is not sent).
pub fn transform_body(m: &Matrix4<f64>) -> Vec<u8> {
    let order = [
        (0, 0),
        (1, 0),
        (2, 0),
        (0, 1),
        (1, 1),
        (2, 1),
        (0, 2),
        (1, 2),
        (2, 2),
        (0, 3),
        (1, 3),
        (2, 3),
    ];
    order
        .iter()
        .flat_map(|&(r, c)| (m[(r, c)] as f32).to_be_bytes())
        .collect()
}

/// A STRING body (UTF-8, MIBenum 106).
pub fn string_body(text: &str) -> Vec<u8> {
    let bytes = &text.as_bytes()[..text.len().min(u16::MAX as usize)];
    let mut out = Vec::with_capacity(4 + bytes.len());
    out.extend_from_slice(&106u16.to_be_bytes());
    out.extend_from_slice(&(bytes.len() as u16).to_be_bytes());
    out.extend_from_slice(bytes);
    out
}

/// An IMAGE body of 8-bit pixels, columns × rows × slices, with the spacing on
/// the axes and the image's first voxel at `origin_mm` (the matrix OpenIGTLink
/// sends holds the centre; the voxel grid is axis-aligned).
pub fn image_body(size: [usize; 3], spacing_mm: [f64; 3], origin_mm: [f64; 3], pixels: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(IMAGE_HEADER_BYTES + pixels.len());
    out.extend_from_slice(&1u16.to_be_bytes());
    out.extend_from_slice(&[1, 3, 2, 2]);
    for s in size {
        out.extend_from_slice(&(s.min(u16::MAX as usize) as u16).to_be_bytes());
    }
    for (k, &s) in spacing_mm.iter().enumerate() {
        for i in 0..3 {
            out.extend_from_slice(&(if i == k { s as f32 } else { 0.0 }).to_be_bytes());
        }
    }
    for k in 0..3 {
        let centre = origin_mm[k] + spacing_mm[k] * (size[k] as f64 - 1.0) / 2.0;
        out.extend_from_slice(&(centre as f32).to_be_bytes());
    }
    out.extend_from_slice(&[0; 6]);
    for s in size {
        out.extend_from_slice(&(s.min(u16::MAX as usize) as u16).to_be_bytes());
    }
    out.extend_from_slice(pixels);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_is_ecma_182_check_value() {
        // CRC-64/ECMA-182's published check value for "123456789".
        assert_eq!(crc64(b"123456789"), 0x6C40_DF5F_0B49_7347);
    }

    #[test]
    fn timestamp_bits_round_trip() {
        let t = 1_796_400_000.123_456_7;
        assert!((timestamp_from_bits(timestamp_to_bits(t)) - t).abs() < 1e-6);
        assert_eq!(timestamp_to_bits(f64::NAN), 0);
        assert_eq!(timestamp_to_bits(-1.0), 0);
    }

    #[test]
    fn transform_round_trips_at_float_precision() {
        let m = Matrix4::new(
            0.214041, -0.922145, 0.322235, 284.342, -0.358213, 0.232802, 0.90415, -37.5047, -0.908774, -0.308954,
            -0.280495, -13.1385, 0.0, 0.0, 0.0, 1.0,
        );
        let bytes = encode("TRANSFORM", "ProbeToTracker", 12.5, &transform_body(&m));
        let header = Header::parse(bytes[..HEADER_BYTES].try_into().unwrap()).unwrap();
        assert_eq!(header.device, "ProbeToTracker");
        assert_eq!(header.crc, crc64(&bytes[HEADER_BYTES..]));
        let Body::Transform(back) = decode(&header, &bytes[HEADER_BYTES..]).unwrap() else {
            panic!("not a transform")
        };
        assert!((back - m).abs().max() < 1e-4);
    }

    #[test]
    fn short_and_inconsistent_bodies_are_refused_with_their_sizes() {
        let header = |kind: &str, version: u16| Header {
            version,
            kind: kind.into(),
            device: "d".into(),
            timestamp_s: 0.0,
            body_bytes: 0,
            crc: 0,
        };
        let e = decode(&header("TRANSFORM", 1), &[0; 40]).unwrap_err().to_string();
        assert!(e.contains("48 bytes") && e.contains("40"), "{e}");
        let mut image = image_body([4, 3, 1], [1.0; 3], [0.0; 3], &[7; 12]);
        image.pop();
        let e = decode(&header("IMAGE", 1), &image).unwrap_err().to_string();
        assert!(e.contains("needs 12 bytes") && e.contains("holds 11"), "{e}");
        let e = decode(&header("IMAGE", 2), &[0, 200, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("extended header of 200 bytes"), "{e}");
        assert_eq!(
            decode(&header("POSITION", 1), &[]).unwrap(),
            Body::Other("POSITION".into())
        );
    }

    #[test]
    fn version_two_content_sits_between_extended_header_and_metadata() {
        let text = string_body("SequenceEnd");
        let mut body = vec![0, 12, 0, 2, 0, 0, 0, 5, 0, 0, 0, 1];
        body.extend_from_slice(&text);
        body.extend_from_slice(&[0, 0, 1, 2, 3, 4, 5]);
        let h = Header {
            version: 2,
            kind: "STRING".into(),
            device: "SequenceEnd".into(),
            timestamp_s: 0.0,
            body_bytes: body.len() as u64,
            crc: crc64(&body),
        };
        assert_eq!(decode(&h, &body).unwrap(), Body::String("SequenceEnd".into()));
    }
}
