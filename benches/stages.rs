//! Benchmarks of each stage on a fixed dataset (`cargo bench --bench stages`).
//!
//! The dataset is the default experiment's (experiments/hemisphere_checkerboard.yaml,
//! seed 3, 50 frames), rendered into `datasets/` if it is not there yet. Each
//! figure is the median of repeated runs; the full run also reports frames per
//! second end to end and the process's peak memory.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use nalgebra::{Point3, Vector3};
use probecal::detect::board_pose::RigBoards;
use probecal::manifest::{DatasetSource, Manifest};

fn median_s(repeats: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..repeats)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = Manifest::load(&root.join("experiments/hemisphere_checkerboard.yaml")).expect("default experiment");
    let dataset = &manifest.datasets[0];
    let DatasetSource::Render(spec) = &dataset.source else {
        panic!("the default experiment renders")
    };
    let datasets = root.join("datasets");
    let folder = probecal::synth::dataset_folder(&datasets, &manifest.experiment, &dataset.name);
    let t = Instant::now();
    let outcome =
        probecal::synth::ensure_rendered(&probecal::pipeline::settings::lab(&manifest), spec, &folder).expect("render");
    println!(
        "dataset: {:?} in {:.1} s ({})",
        outcome,
        t.elapsed().as_secs_f64(),
        folder.display()
    );

    let cal = probecal::detect::camera_calibration::calibrate_folder(&folder.join("camera_calibration"), [9, 6], 30.0)
        .unwrap();
    let camera = cal.intrinsics.clone();
    let rig = RigBoards::from_rig(&manifest.rig).unwrap();
    let photo = probecal::io::image::read_gray(&folder.join("frames/camera_001.png")).unwrap();
    let bscan = probecal::io::image::read_gray(&folder.join("frames/bscan_001.png")).unwrap();

    let pose = median_s(15, || {
        black_box(
            probecal::detect::rig_pose::estimate(&photo, &camera, &rig)
                .unwrap()
                .unwrap(),
        );
    });
    println!("camera pose (both boards) per image: {:.1} ms", pose * 1e3);
    let decode = median_s(15, || {
        black_box(probecal::io::image::read_gray(&folder.join("frames/camera_001.png")).unwrap());
    });
    println!("decode one camera PNG (1920x1080): {:.1} ms", decode * 1e3);
    let settings = probecal::detect::arc::ArcSettings {
        spacing_mm_per_px: [0.2, 0.2],
        radius_mm: [8.25, 17.25],
        min_span_deg: 40.0,
        max_rms_px: 2.5,
        min_points: 25,
        fixed_radius_mm: Some(15.0),
        peak: probecal::detect::ridge::RidgePeak::Column,
    };
    let arc = median_s(15, || {
        black_box(probecal::detect::arc::detect(&bscan, &settings).unwrap().unwrap());
    });
    println!("B-scan arc detection per image: {:.1} ms", arc * 1e3);

    all_frames(&folder, &camera, &rig, &settings);

    let truth =
        probecal::core::geometry::rigid_from_axis_angle(Vector3::new(0.1, -0.2, 0.3), Vector3::new(10.0, 150.0, 25.0));
    for n in [10usize, 100, 10_000] {
        let mut rng = probecal::core::rng::Rng::new(n as u64);
        let source: Vec<Point3<f64>> = (0..n)
            .map(|_| Point3::new(rng.uniform(0.0, 160.0), rng.uniform(0.0, 120.0), 0.0))
            .collect();
        let target: Vec<Point3<f64>> = source
            .iter()
            .map(|p| truth * p + Vector3::new(rng.normal(0.0, 0.3), rng.normal(0.0, 0.3), rng.normal(0.0, 0.3)))
            .collect();
        let repeats = if n > 1000 { 101 } else { 1001 };
        let horn = median_s(repeats, || {
            black_box(
                probecal::estimate::horn::solve(&source, &target, probecal::estimate::horn::Variant::Rigid).unwrap(),
            );
        });
        println!("Horn, {n} pairs: {:.1} µs", horn * 1e6);
    }

    probecal::core::progress::set_quiet(true);
    let frames = {
        let list = probecal::io::dataset::load_frame_list(&folder).unwrap();
        list.len()
    };
    let full = median_s(5, || {
        black_box(probecal::pipeline::run::run_dataset(&manifest, dataset, &datasets, &mut |_| {}).unwrap());
    });
    println!(
        "full run from cached images ({} frames, camera calibration included): {:.2} s, {:.1} frames/s, {:.1} ms/frame",
        frames,
        full,
        frames as f64 / full,
        full * 1e3 / frames as f64
    );
    if let Some(mb) = probecal::report::page::provenance::peak_memory_mb() {
        println!("peak memory of this process: {mb:.0} MB");
    }
}

/// Each stage over every frame of the dataset, one thread, once: the real run's
/// frames, not a favourable one. Prints the total, the median and the slowest frame.
fn all_frames(
    folder: &Path,
    camera: &probecal::io::camera_model::CameraIntrinsics,
    rig: &RigBoards,
    settings: &probecal::detect::arc::ArcSettings,
) {
    let list = probecal::io::dataset::load_frame_list(folder).unwrap();
    let mut stages: [(&str, Vec<f64>); 4] = [
        ("decode photo", vec![]),
        ("both boards", vec![]),
        ("decode B-scan", vec![]),
        ("arc", vec![]),
    ];
    for frame in &list {
        let t = Instant::now();
        let photo = probecal::io::image::read_gray(&folder.join(frame.camera_image.as_ref().unwrap())).unwrap();
        stages[0].1.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        black_box(probecal::detect::rig_pose::estimate(&photo, camera, rig).unwrap().ok());
        stages[1].1.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let bscan = probecal::io::image::read_gray(&folder.join(&frame.bscan_image)).unwrap();
        stages[2].1.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        black_box(probecal::detect::arc::detect(&bscan, settings).unwrap().ok());
        stages[3].1.push(t.elapsed().as_secs_f64());
    }
    for (name, mut times) in stages {
        let total: f64 = times.iter().sum();
        times.sort_by(f64::total_cmp);
        println!(
            "all {} frames, {name}: {:.0} ms in all, median {:.1} ms, slowest {:.1} ms",
            times.len(),
            total * 1e3,
            times[times.len() / 2] * 1e3,
            times[times.len() - 1] * 1e3
        );
    }
}
