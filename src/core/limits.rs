//! The sizes probecal accepts, each enforced where the input enters (manifest
//! checks, frame lists, images before decoding, the command line): past them a
//! clear error, never an allocation that aborts or a loop that does not end.

/// Frame numbers are 64-bit from the frame list to the tables (`usize` here,
/// `u64` in `frames.csv`/`.parquet`): a platform with a narrower `usize` does not build.
const _: () = assert!(usize::BITS >= 64, "probecal carries 64-bit frame numbers in usize");

/// Frames of a dataset (a frame list's rows, a rendered dataset's frames).
pub const MAX_FRAMES: usize = 100_000;
/// Camera calibration views.
pub const MAX_CALIBRATION_VIEWS: usize = 500;
/// Inner corners of a checkerboard, per side.
pub const MAX_BOARD_CORNERS: u32 = 100;
/// ArUco markers of a board, per side.
pub const MAX_BOARD_MARKERS: u32 = 50;
/// Pixels of one image, checked from its header before it is decoded (a small
/// PNG can decode to gigabytes): 100 megapixels.
pub const MAX_IMAGE_PIXELS: u64 = 100_000_000;
/// Side of one image, px.
pub const MAX_IMAGE_SIDE_PX: u64 = 30_000;
/// Bytes of one image file, read whole before it is decoded: the largest
/// image at 16 bits in four channels, rounded up (1 GiB).
pub const MAX_IMAGE_FILE_BYTES: u64 = 1 << 30;
/// Bytes of a JSON, CSV or text file read whole (a summary, a study, a frame
/// list of 100 000 frames is about 20 MB, a tracker's poses): 64 MiB.
pub const MAX_TEXT_FILE_BYTES: u64 = 64 << 20;
/// Worker threads.
pub const MAX_THREADS: usize = 256;
/// Nesting of a manifest's YAML (mappings and sequences inside each other).
pub const MAX_YAML_DEPTH: usize = 32;
/// Seeds of one study.
pub const MAX_SEEDS: u64 = 10_000;
/// Folds of a cross-validation.
pub const MAX_FOLDS: usize = 20;
/// Spheres of a `spheres` phantom (each B-scan is searched for this many arcs).
pub const MAX_SPHERES: usize = 8;
