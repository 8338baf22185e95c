//! 3D volumes on disk: MetaImage (`.mha`, with the header PLUS's
//! `VolumeReconstructor` writes, so 3D Slicer and PLUS read it as PLUS's own)
//! and NRRD (`.nrrd`, for tools that prefer it), and a MetaImage reader.
//!
//! Both are in the Reference frame with identity axes: MetaImage says
//! `AnatomicalOrientation = RAI` as PLUS does; the NRRD gives the same voxel
//! positions (`space origin`, `space directions`) in the `left-posterior-superior`
//! space Slicer assumes for MetaImage.

use std::path::{Path, PathBuf};

/// A volume's header facts.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeHeader {
    pub dims: [usize; 3],
    /// Centre of voxel (0, 0, 0), mm.
    pub origin_mm: [f64; 3],
    pub spacing_mm: [f64; 3],
    /// `MET_UCHAR` or `MET_FLOAT`.
    pub element_type: String,
}

/// A number as C++ streams print it by default (6 significant digits, no
/// trailing zeros), which is how PLUS writes `Offset` and `ElementSpacing`.
pub fn format_g6(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v.is_finite() { "0".into() } else { v.to_string() };
    }
    let exponent = v.abs().log10().floor() as i32;
    let rounded = format!("{:.*e}", 5, v);
    // The exponent after rounding (9.999996 rounds to 1.00000e1).
    let exponent = rounded
        .split('e')
        .nth(1)
        .and_then(|e| e.parse::<i32>().ok())
        .unwrap_or(exponent);
    if !(-4..6).contains(&exponent) {
        let (mantissa, _) = rounded.split_once('e').unwrap_or((&rounded, ""));
        let mantissa = trim_zeros(mantissa);
        return format!(
            "{mantissa}e{}{:02}",
            if exponent < 0 { '-' } else { '+' },
            exponent.abs()
        );
    }
    let decimals = (5 - exponent).max(0) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

fn triple(v: [f64; 3]) -> String {
    v.map(format_g6).join(" ")
}

/// A MetaImage file as PLUS writes a reconstructed volume (uncompressed).
pub fn metaimage_bytes(header: &VolumeHeader, data: &[u8]) -> Vec<u8> {
    let [w, h, d] = header.dims;
    let dim = format!("{w} {h}");
    let text = format!(
        "ObjectType = Image\nNDims = 3\nAnatomicalOrientation = RAI\nBinaryData = True\n\
         BinaryDataByteOrderMSB = False\nCenterOfRotation = 0 0 0\nCompressedData = False\n\
         DimSize = {dim}{d:>width$}\nElementNumberOfChannels = 1\nElementSpacing = {}\n\
         ElementType = {}\nKinds = domain domain{:>19}\nOffset = {}\n\
         TransformMatrix = 1 0 0 0 1 0 0 0 1\nUltrasoundImageOrientation = MFA\n\
         UltrasoundImageType = BRIGHTNESS\nSeq_Frame0000_ImageStatus = OK\nElementDataFile = LOCAL\n",
        triple(header.spacing_mm),
        header.element_type,
        "domain",
        triple(header.origin_mm),
        width = 30 - dim.len(),
    );
    let mut out = text.into_bytes();
    out.extend_from_slice(data);
    out
}

/// A NRRD file (raw, little-endian) of the same volume.
pub fn nrrd_bytes(header: &VolumeHeader, data: &[u8]) -> Vec<u8> {
    let kind = if header.element_type == "MET_FLOAT" {
        "float"
    } else {
        "uint8"
    };
    let [sx, sy, sz] = header.spacing_mm.map(format_g6);
    let text = format!(
        "NRRD0004\n# probecal reconstruction, Reference frame, mm\ntype: {kind}\ndimension: 3\n\
         space: left-posterior-superior\nsizes: {} {} {}\n\
         space directions: ({sx},0,0) (0,{sy},0) (0,0,{sz})\nkinds: domain domain domain\n\
         endian: little\nencoding: raw\nspace origin: ({})\n\n",
        header.dims[0],
        header.dims[1],
        header.dims[2],
        header.origin_mm.map(format_g6).join(","),
    );
    let mut out = text.into_bytes();
    out.extend_from_slice(data);
    out
}

/// Why a volume file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct VolumeReadError {
    pub path: PathBuf,
    pub message: String,
}

/// Most bytes of a volume file's header read before its data.
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

/// The voxels' bytes: what follows the header in `head`, then the file's
/// next bytes, no more than `expected` (compressed: what zlib may take for
/// them), inflated when `compressed`.
fn voxel_bytes(
    mut file: std::fs::File,
    mut data: Vec<u8>,
    expected: usize,
    compressed: bool,
    fail: impl Fn(String) -> VolumeReadError,
) -> Result<Vec<u8>, VolumeReadError> {
    use std::io::Read;
    // zlib never grows data by more than a few bytes per 16 KiB block.
    let most = if compressed {
        expected + expected / 1000 + 1024
    } else {
        expected
    };
    (&mut file)
        .take((most + 1).saturating_sub(data.len()) as u64)
        .read_to_end(&mut data)
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    if data.len() > most {
        return Err(fail(format!(
            "more data than the header declares ({expected} bytes of voxels{})",
            if compressed { ", compressed" } else { "" }
        )));
    }
    if !compressed {
        return Ok(data);
    }
    // Grown as the stream inflates, not reserved from the header's claim.
    let mut out = Vec::with_capacity(expected.min(data.len().saturating_mul(4)).min(1 << 26));
    flate2::read::ZlibDecoder::new(&data[..])
        .take(expected as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| fail(format!("compressed data is corrupt: {e}")))?;
    Ok(out)
}

/// Reads an uncompressed or zlib-compressed 3D MetaImage of 8-bit or float voxels:
/// its header and its voxels' bytes.
pub fn read_metaimage(path: &Path) -> Result<(VolumeHeader, Vec<u8>), VolumeReadError> {
    let fail = |message: String| VolumeReadError {
        path: path.to_path_buf(),
        message,
    };
    // The header first, from at most its first MiB (a device such as
    // /dev/zero says nothing of its size and never ends); the voxels then, no
    // more than the header declares.
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    let mut bytes = Vec::new();
    (&mut file)
        .take(MAX_HEADER_BYTES)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    let marker = b"ElementDataFile = LOCAL";
    let end = bytes.windows(marker.len()).position(|w| w == marker).ok_or_else(|| {
        fail(format!(
            "no `ElementDataFile = LOCAL` line in its first {} KiB",
            MAX_HEADER_BYTES >> 10
        ))
    })?;
    let data_start = bytes[end..]
        .iter()
        .position(|&b| b == b'\n')
        .map(|p| end + p + 1)
        .unwrap_or(bytes.len());
    let text = String::from_utf8_lossy(&bytes[..end]);
    let field = |key: &str| {
        text.lines().find_map(|l| {
            l.split_once('=')
                .filter(|(k, _)| k.trim() == key)
                .map(|(_, v)| v.trim().to_string())
        })
    };
    let numbers = |key: &str| -> Result<Vec<f64>, VolumeReadError> {
        let v = field(key).ok_or_else(|| fail(format!("header field `{key}` is missing")))?;
        v.split_whitespace()
            .map(|s| {
                s.parse::<f64>()
                    .map_err(|_| fail(format!("`{key} = {v}`: not numbers")))
            })
            .collect()
    };
    let dims = numbers("DimSize")?;
    let spacing = numbers("ElementSpacing")?;
    let origin = numbers("Offset").unwrap_or(vec![0.0; 3]);
    if dims.len() != 3 || spacing.len() != 3 || origin.len() != 3 || dims.iter().any(|d| *d < 1.0 || d.fract() != 0.0) {
        return Err(fail("expected a 3D volume (3 sizes, spacings, offsets)".into()));
    }
    let element_type = field("ElementType").unwrap_or_default();
    let sample = match element_type.as_str() {
        "MET_UCHAR" => 1,
        "MET_FLOAT" => 4,
        other => {
            return Err(fail(format!(
                "`ElementType = {other}`: only MET_UCHAR and MET_FLOAT are read"
            )))
        }
    };
    let count = dims
        .iter()
        .map(|d| *d as usize)
        .try_fold(sample, |a: usize, d| a.checked_mul(d));
    let expected = count
        .filter(|&n| n <= 1usize << 33)
        .ok_or_else(|| fail("`DimSize` is implausibly large".into()))?;
    let compressed = field("CompressedData").is_some_and(|v| v.eq_ignore_ascii_case("true"));
    let data = voxel_bytes(file, bytes[data_start..].to_vec(), expected, compressed, fail)?;
    if data.len() != expected {
        return Err(fail(format!("{} bytes of voxels, {expected} expected", data.len())));
    }
    Ok((
        VolumeHeader {
            dims: [dims[0] as usize, dims[1] as usize, dims[2] as usize],
            origin_mm: [origin[0], origin[1], origin[2]],
            spacing_mm: [spacing[0], spacing[1], spacing[2]],
            element_type,
        },
        data,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_print_as_cpp_streams_print_them() {
        for (v, want) in [
            (-74.52170038839084, "-74.5217"),
            (165.57342384663468, "165.573"),
            (29.071965406174055, "29.072"),
            (0.5, "0.5"),
            (30.53844319695025, "30.5384"),
            (1234567.0, "1.23457e+06"),
            (0.0000123, "1.23e-05"),
            (100.0, "100"),
        ] {
            assert_eq!(format_g6(v), want, "{v}");
        }
    }

    #[test]
    fn a_written_volume_reads_back() {
        let header = VolumeHeader {
            dims: [147, 106, 105],
            origin_mm: [-74.5217, 165.573, 29.072],
            spacing_mm: [0.5; 3],
            element_type: "MET_UCHAR".into(),
        };
        let data: Vec<u8> = (0..147 * 106 * 105).map(|i| (i % 7) as u8).collect();
        let bytes = metaimage_bytes(&header, &data);
        let text = String::from_utf8_lossy(&bytes[..600]);
        assert!(text.contains("DimSize = 147 106                    105\n"), "{text}");
        assert!(text.contains("Kinds = domain domain             domain\n"), "{text}");
        let dir = std::env::temp_dir().join(format!("probecal-volume-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("v.mha");
        std::fs::write(&path, &bytes).unwrap();
        let (read, voxels) = read_metaimage(&path).unwrap();
        assert_eq!((read, voxels), (header, data));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
