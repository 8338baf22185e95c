//! The dataset frame-list parser on arbitrary text: errors, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = probecal::io::dataset::parse_frame_list(std::path::Path::new("dataset"), text);
    }
});
