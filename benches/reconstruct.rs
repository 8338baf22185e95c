//! Volume reconstruction speed (`cargo bench --bench reconstruct`), on PLUS's
//! spine-phantom sweep (`../shared/data/plus-volume-reconstruction`, 21 frames
//! of 820x616) with its nearest-neighbour + MEAN + hole-filling device set:
//!
//! - `frames_per_second/paste+holes`: the distribution and hole filling alone,
//!   frames inserted per second (throughput);
//! - `end_to_end/probecal`: `probecal reconstruct` as a process, from its start
//!   to the written volume (reading, pictures and report included);
//! - `end_to_end/numpy_nn`: `benches/numpy_nn_reference.py`, a plain numpy
//!   nearest-neighbour reconstruction of the same sweep (no clipping, no hole
//!   filling), also as a process from start to written volume.
//!
//! Both end-to-end figures come from the same run on the same machine; their
//! ratio is the speed claim in `docs/reconstruction.md`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use probecal::pipeline::reconstruct::{run, ReconstructInputs};

// The command's allocator, so that the in-process figure is the command's.
#[global_allocator]
static ALLOCATOR: probecal::core::large_pages::LargePages = probecal::core::large_pages::LargePages;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/plus-volume-reconstruction")
}

fn reconstruct(c: &mut Criterion) {
    let data = data();
    let sequence = data.join("SpinePhantomFreehand.igs.mha");
    let config = data.join("PlusDeviceSet_VolumeReconstructionOnly_SpinePhantom_NN_MEAN.xml");
    if !sequence.exists() {
        eprintln!("skipped: {} is not there", sequence.display());
        return;
    }
    let inputs = ReconstructInputs {
        sequence: sequence.clone(),
        config: config.clone(),
        threads: None,
        wires: None,
        image_to_probe: None,
        tracker_lag_s: None,
    };
    let first = run(&inputs).expect("the sweep reconstructs");
    let mut group = c.benchmark_group("frames_per_second");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10))
        .throughput(Throughput::Elements(first.frames_used.len() as u64));
    group.bench_function("read+paste+holes", |b| b.iter(|| run(&inputs).expect("reconstructs")));
    group.finish();

    let out = std::env::temp_dir().join(format!("probecal-bench-reconstruct-{}", std::process::id()));
    let numpy_out = out.with_extension("numpy.mha");
    let image_to_probe = "-0.00157821 0.0785919 -0.00803285 15.3978 -0.0839128 0.00372697 0.0153803 49.5705 \
                          0.0159024 0.00714276 0.0803604 -8.63446 0 0 0 1";
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/numpy_nn_reference.py");
    // Debian's python3-numpy lives with the system interpreter.
    let python = if Path::new("/usr/bin/python3").exists() {
        "/usr/bin/python3"
    } else {
        "python3"
    };
    let mut group = c.benchmark_group("end_to_end");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    group.bench_function("probecal", |b| {
        b.iter(|| {
            let status = Command::new(env!("CARGO_BIN_EXE_probecal"))
                .arg("reconstruct")
                .arg(&sequence)
                .arg("--config")
                .arg(&config)
                .arg("--out")
                .arg(&out)
                .stdout(std::process::Stdio::null())
                .status()
                .expect("probecal starts");
            assert!(status.success());
        })
    });
    group.bench_function("numpy_nn", |b| {
        b.iter(|| {
            let status = Command::new(python)
                .arg(&script)
                .arg(&sequence)
                .arg(image_to_probe)
                .arg("0.5")
                .arg(&numpy_out)
                .status()
                .expect("python3 with numpy starts (Debian: python3-numpy)");
            assert!(status.success());
        })
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_file(&numpy_out);
}

criterion_group!(benches, reconstruct);
criterion_main!(benches);
