//! The manifest parser and validator on arbitrary text: errors, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Err(errors) = probecal::manifest::Manifest::from_text(std::path::Path::new("fuzz.yaml"), text) {
            // Every error must render, and name the file.
            assert!(errors.to_string().starts_with("fuzz.yaml"));
        }
    }
});
