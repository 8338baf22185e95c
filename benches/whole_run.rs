//! The user's run as a criterion benchmark (`cargo bench --bench whole_run`):
//! `probecal run experiments/hemisphere_checkerboard.yaml --force --quiet` from
//! the cached rendered dataset, outputs included (report, tables, gallery,
//! hashing), through the same `run_all` and report writer the command line
//! uses. The dataset is rendered first if it is not cached. Per-stage figures
//! are `cargo bench --bench stages`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use probecal::pipeline::experiment::{load_all, run_all, RunOptions};
use probecal::report::writer::ReportWriter;

fn whole_run(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = root.join("experiments/hemisphere_checkerboard.yaml");
    let experiments = load_all(&[manifest]).expect("the default experiment loads");
    let out: PathBuf = std::env::temp_dir().join("probecal-bench-whole-run");
    let datasets = root.join("datasets");
    let options = RunOptions {
        out: &out,
        datasets: &datasets,
        force: true,
    };
    probecal::core::progress::set_quiet(true);
    // Once to render the dataset if needed and to count the frames.
    let first = run_all(&experiments, &options, &mut ReportWriter::new(true), &mut |_| {});
    assert_eq!(first.code, 0, "the default run failed");
    let frames: u64 = first.runs.iter().map(|(_, r)| r.frames.len() as u64).sum();
    let mut group = c.benchmark_group("whole_run");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(30))
        .throughput(Throughput::Elements(frames));
    group.bench_function("hemisphere_checkerboard", |b| {
        b.iter(|| {
            let outcome = run_all(&experiments, &options, &mut ReportWriter::new(true), &mut |_| {});
            assert_eq!(outcome.code, 0);
        })
    });
    group.finish();
}

criterion_group!(benches, whole_run);
criterion_main!(benches);
