//! The PLUS sequence-file reader on arbitrary bytes: errors, never a panic; and
//! every frame's transform lookup on what it accepts.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(sequence) = probecal::io::plus::sequence::Sequence::parse(std::path::Path::new("seq.mha"), data) {
        for i in 0..sequence.frames.len() {
            let _ = sequence.transform(i, "ProbeToTracker");
            let _ = sequence.pixels(i).len();
        }
    }
});
