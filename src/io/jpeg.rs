//! JPEG files through libjpeg-turbo's TurboJPEG interface: the library OpenCV
//! decodes and encodes JPEG with on Debian, called with OpenCV's settings, so
//! that the pixels read and the bytes written are OpenCV's
//! (`tests/image_codecs.rs` holds them equal).
//!
//! Reading: grey output (libjpeg's own colour conversion, as OpenCV asks for it
//! with `IMREAD_GRAYSCALE`), the accurate integer inverse DCT. A warning from
//! the decoder (a truncated or damaged file) is an error here: such a file is
//! not read, rather than read with its missing part filled in.
//! Writing: the accurate DCT, 4:2:0 chroma for colour, baseline.

use super::codec::CodecError;
use std::ffi::{c_char, c_int, c_uchar, c_ulong, c_void, CStr};

const FORMAT: &str = "JPEG";

#[link(name = "turbojpeg")]
extern "C" {
    fn tjInitDecompress() -> *mut c_void;
    fn tjInitCompress() -> *mut c_void;
    fn tjDestroy(handle: *mut c_void) -> c_int;
    fn tjGetErrorStr2(handle: *mut c_void) -> *mut c_char;
    fn tjDecompressHeader3(
        handle: *mut c_void,
        jpeg: *const c_uchar,
        size: c_ulong,
        width: *mut c_int,
        height: *mut c_int,
        subsampling: *mut c_int,
        colorspace: *mut c_int,
    ) -> c_int;
    fn tjDecompress2(
        handle: *mut c_void,
        jpeg: *const c_uchar,
        size: c_ulong,
        dst: *mut c_uchar,
        width: c_int,
        pitch: c_int,
        height: c_int,
        pixel_format: c_int,
        flags: c_int,
    ) -> c_int;
    fn tjCompress2(
        handle: *mut c_void,
        src: *const c_uchar,
        width: c_int,
        pitch: c_int,
        height: c_int,
        pixel_format: c_int,
        jpeg: *mut *mut c_uchar,
        size: *mut c_ulong,
        subsampling: c_int,
        quality: c_int,
        flags: c_int,
    ) -> c_int;
    fn tjFree(buffer: *mut c_uchar);
}

const TJPF_BGR: c_int = 1;
const TJPF_GRAY: c_int = 6;
const TJSAMP_420: c_int = 2;
const TJSAMP_GRAY: c_int = 3;
const TJCS_CMYK: c_int = 3;
const TJCS_YCCK: c_int = 4;
const TJFLAG_ACCURATEDCT: c_int = 4096;

/// A TurboJPEG instance, destroyed when dropped.
struct Handle(*mut c_void);

impl Handle {
    fn new(compress: bool) -> Result<Handle, CodecError> {
        // SAFETY: the init functions take no arguments and return null on failure.
        let raw = unsafe {
            if compress {
                tjInitCompress()
            } else {
                tjInitDecompress()
            }
        };
        if raw.is_null() {
            return Err(CodecError::Start {
                library: "libjpeg-turbo",
            });
        }
        Ok(Handle(raw))
    }

    /// The last failure of this instance, read as a damaged file.
    fn damaged(&self) -> CodecError {
        CodecError::Damaged {
            format: FORMAT,
            detail: self.message(),
        }
    }

    /// The library's message for the last failure of this instance.
    fn message(&self) -> String {
        // SAFETY: the handle is live; the string is owned by the library and
        // copied before the next call.
        let text = unsafe { tjGetErrorStr2(self.0) };
        if text.is_null() {
            return "unknown libjpeg-turbo error".into();
        }
        unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned()
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: the handle came from an init function and is destroyed once.
        unsafe {
            tjDestroy(self.0);
        }
    }
}

/// Width and height from a JPEG's header, without decoding it.
fn header(handle: &Handle, bytes: &[u8]) -> Result<(usize, usize, c_int), CodecError> {
    let (mut width, mut height, mut subsampling, mut colorspace) = (0, 0, 0, 0);
    // SAFETY: the buffer and its length are a live slice; the outputs are locals.
    let status = unsafe {
        tjDecompressHeader3(
            handle.0,
            bytes.as_ptr(),
            bytes.len() as c_ulong,
            &mut width,
            &mut height,
            &mut subsampling,
            &mut colorspace,
        )
    };
    if status != 0 || width <= 0 || height <= 0 {
        return Err(handle.damaged());
    }
    Ok((width as usize, height as usize, colorspace))
}

/// Decodes a JPEG to (width, height, grey bytes, row-major).
pub fn decode_gray(bytes: &[u8]) -> Result<(usize, usize, Vec<u8>), CodecError> {
    let handle = Handle::new(false)?;
    let (width, height, colorspace) = header(&handle, bytes)?;
    if colorspace == TJCS_CMYK || colorspace == TJCS_YCCK {
        return Err(CodecError::Unsupported(
            "a CMYK JPEG is not read: save it as RGB or grey".into(),
        ));
    }
    let mut grey = vec![0u8; width * height];
    // SAFETY: `grey` holds width x height bytes, the pitch is the width, and the
    // size is the one the header gives.
    let status = unsafe {
        tjDecompress2(
            handle.0,
            bytes.as_ptr(),
            bytes.len() as c_ulong,
            grey.as_mut_ptr(),
            width as c_int,
            width as c_int,
            height as c_int,
            TJPF_GRAY,
            TJFLAG_ACCURATEDCT,
        )
    };
    if status != 0 {
        return Err(handle.damaged());
    }
    Ok((width, height, grey))
}

/// JPEG bytes of 8-bit grey (`channels` 1) or BGR (`channels` 3) pixels,
/// row-major, at `quality` (1–100).
pub fn encode(pixels: &[u8], width: usize, height: usize, channels: usize, quality: u8) -> Result<Vec<u8>, CodecError> {
    let (format, subsampling) = match channels {
        1 => (TJPF_GRAY, TJSAMP_GRAY),
        3 => (TJPF_BGR, TJSAMP_420),
        _ => {
            return Err(CodecError::Channels {
                format: FORMAT,
                channels,
            })
        }
    };
    let shape = CodecError::Shape {
        bytes: pixels.len(),
        width,
        height,
        channels,
    };
    if pixels.len() != width * height * channels || width == 0 || height == 0 {
        return Err(shape);
    }
    let side = |n: usize| c_int::try_from(n).map_err(|_| shape.clone());
    let handle = Handle::new(true)?;
    let mut out: *mut c_uchar = std::ptr::null_mut();
    let mut size: c_ulong = 0;
    // SAFETY: the source holds height rows of width x channels bytes (checked
    // above); the library allocates `out`, freed below with `tjFree`.
    let status = unsafe {
        tjCompress2(
            handle.0,
            pixels.as_ptr(),
            side(width)?,
            side(width * channels)?,
            side(height)?,
            format,
            &mut out,
            &mut size,
            subsampling,
            c_int::from(quality.clamp(1, 100)),
            TJFLAG_ACCURATEDCT,
        )
    };
    let result = if status != 0 || out.is_null() {
        Err(CodecError::Encode {
            format: FORMAT,
            detail: handle.message(),
        })
    } else {
        // SAFETY: the library wrote `size` bytes at `out`.
        Ok(unsafe { std::slice::from_raw_parts(out, size as usize) }.to_vec())
    };
    if !out.is_null() {
        // SAFETY: `out` was allocated by the library and is freed once.
        unsafe { tjFree(out) };
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grey_jpeg_comes_back_close_and_a_cut_one_is_refused() {
        let (w, h) = (64, 48);
        let grey: Vec<u8> = (0..w * h).map(|i| ((i % w) * 4) as u8).collect();
        let bytes = encode(&grey, w, h, 1, 95).unwrap();
        assert_eq!(&bytes[..2], &[0xFF, 0xD8]);
        let (bw, bh, back) = decode_gray(&bytes).unwrap();
        assert_eq!((bw, bh), (w, h));
        let worst = back.iter().zip(&grey).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
        assert!(worst < 10, "off by {worst}");
        assert!(decode_gray(&bytes[..bytes.len() / 2]).is_err(), "a truncated JPEG");
        assert!(decode_gray(b"\xFF\xD8 not a jpeg").is_err());
        assert!(encode(&grey, w, h, 2, 80).is_err());
        assert!(encode(&grey[1..], w, h, 1, 80).is_err());
    }

    #[test]
    fn colour_is_read_as_its_luma() {
        let (w, h) = (16, 16);
        let bgr: Vec<u8> = [40u8, 120, 200].repeat(w * h);
        let (_, _, grey) = decode_gray(&encode(&bgr, w, h, 3, 100).unwrap()).unwrap();
        // Y = 0.299 R + 0.587 G + 0.114 B = 135.0.
        assert!(grey.iter().all(|&v| v.abs_diff(135) <= 1), "{:?}", &grey[..4]);
    }
}
