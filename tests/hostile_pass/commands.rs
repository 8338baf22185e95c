//! Hostile manifests, clocks, studies, run summaries, baselines and outputs
//! aimed at inputs.

use std::path::Path;

use super::*;

/// The fCal manifest of the fixtures with absolute paths and `from` replaced
/// by `to`, as `<dir>/<name>`.
pub(super) fn tracked_manifest(dir: &Path, name: &str, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(root().join("tests/fixtures/fcal2_nwire_yaml.yaml"))
        .unwrap()
        .replace("../../../shared/data", &s(root().join("../shared/data")));
    assert!(text.contains(from), "`{from}` is not in the fCal manifest");
    write(dir, name, text.replacen(from, to, 1).as_bytes())
}

pub(super) fn manifest_case(name: &str, from: &'static str, to: &'static str, expect: &str) -> Case {
    case(&format!("manifest: {name}"), 2, expect, move |d| {
        let m = tracked_manifest(d, "m.yaml", from, to);
        args(&["validate", &m])
    })
}

pub(super) fn manifest_cases() -> Vec<Case> {
    let frame = "[-0.0167397, -0.0153548, -0.999742, 15.6642]";
    vec![
        case("manifest: aliases that expand a billion times", 2, "m.yaml", |d| {
            let mut doc = String::from("a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n");
            for k in 1..10 {
                doc += &format!("a{k}: &a{k} [{}]\n", vec![format!("*a{}", k - 1); 10].join(", "));
            }
            doc += "experiment: bomb\ndescription: *a9\n";
            let m = write(d, "m.yaml", doc.as_bytes());
            args(&["validate", &m])
        }),
        case("manifest: nested 100 000 deep", 2, "m.yaml", |d| {
            let doc = format!("experiment: {}{}\n", "[".repeat(100_000), "]".repeat(100_000));
            let m = write(d, "m.yaml", doc.as_bytes());
            args(&["validate", &m])
        }),
        case("manifest: 60 MB", 2, "m.yaml", |d| {
            let doc = format!("# {}\nexperiment: big\n", "x".repeat(60 << 20));
            let m = write(d, "m.yaml", doc.as_bytes());
            args(&["validate", &m])
        }),
        case("manifest: not UTF-8", 2, "m.yaml", |d| {
            let m = write(d, "m.yaml", b"experiment: \xff\xfe\n");
            args(&["validate", &m])
        }),
        manifest_case("experiment named out of its folder", "experiment: fcal2_nwire_yaml", "experiment: ../../escape", "m.yaml:3"),
        manifest_case("dataset named out of its folder", "dataset: fcal2_3nwires", "dataset: ../escape", "m.yaml:6"),
        manifest_case("time offset of 30 000 years", "time_offset_s: estimate", "time_offset_s: 1e12", "m.yaml:9: field `tracking.plus_sequence.time_offset_s`: must be `estimate`, seconds between -1 and 1, or `{temporal: {tracker, video}}`, got 1000000000000 s"),
        manifest_case("time offset not a number", "time_offset_s: estimate", "time_offset_s: .nan", "m.yaml:9"),
        manifest_case("spacing zero", "approximate_spacing_mm_per_px: 0.078", "approximate_spacing_mm_per_px: 0", "m.yaml"),
        manifest_case("wire a kilometre away", "[30.0, 0.0, 20.0]", "[30.0, 1e6, 20.0]", "m.yaml"),
        manifest_case("registration scaled", frame, "[-0.0334794, -0.0307096, -1.999484, 15.6642]", "m.yaml"),
        manifest_case("registration not a number", frame, "[.nan, -0.0153548, -0.999742, 15.6642]", "m.yaml"),
        manifest_case("clip rectangle negative", "[27, 27, 766, 562]", "[-27, 27, 766, 562]", "m.yaml"),
        manifest_case("clip rectangle of 2^40 px", "[27, 27, 766, 562]", "[27, 27, 1099511627776, 562]", "m.yaml"),
        manifest_case("outlier cut not a number", "reject_sd: 3.0", "reject_sd: .nan", "m.yaml"),
        manifest_case("outlier cut negative", "reject_sd: 3.0", "reject_sd: -3.0", "m.yaml"),
        manifest_case("a key given twice", "  reject_sd: 3.0", "  reject_sd: 3.0\n  reject_sd: 2.0", "m.yaml"),
    ]
}

pub(super) fn live(d: &Path, extra: &[&str]) -> Vec<String> {
    let m = tracked_manifest(d, "m.yaml", "time_offset_s: estimate", "time_offset_s: 0.0");
    let mut a = args(&["live", &m, "--out", &s(d.join("out"))]);
    a.extend(args(extra));
    a
}

pub(super) fn temporal(d: &Path, tracker: &str, video: &str) -> Vec<String> {
    args(&[
        "temporal",
        "--tracker",
        tracker,
        "--video",
        video,
        "--out",
        &s(d.join("out")),
    ])
}

pub(super) fn time_cases() -> Vec<Case> {
    let tank = |name: &str| s(shared_data(TANK, name));
    vec![
        case("live: speed not a number", 2, "--speed", |d| {
            live(d, &["--speed", "nan"])
        }),
        case("live: speed negative", 2, "--speed -1", |d| live(d, &["--speed=-1"])),
        case("live: speed a billion", 2, "--speed", |d| live(d, &["--speed", "1e9"])),
        case("live: idle time not a number", 2, "--idle-s <IDLE_S>", |d| {
            let w = s(d.join("watch"));
            std::fs::create_dir_all(d.join("watch")).unwrap();
            live(d, &["--watch", &w, "--idle-s", "nan"])
        }),
        case("live: idle time of 30 000 years", 2, "--idle-s <IDLE_S>", |d| {
            let w = s(d.join("watch"));
            std::fs::create_dir_all(d.join("watch")).unwrap();
            live(d, &["--watch", &w, "--idle-s", "1e12"])
        }),
        case(
            "live: a volume every 0 frames",
            2,
            "--volume-every <VOLUME_EVERY>",
            |d| {
                live(
                    d,
                    &[
                        "--igtl",
                        "127.0.0.1:9",
                        "--reconstruct",
                        &s(shared_data(VOLUME, VOLUME_SET)),
                        "--volume-every",
                        "0",
                    ],
                )
            },
        ),
        case("live: a port past 65535", 2, "70000", |d| {
            live(d, &["--igtl", "127.0.0.1:70000"])
        }),
        case(
            "temporal: tracker and video swapped",
            1,
            "TrackerBuffer.igs.mha: only 0 frames are usable",
            move |d| {
                temporal(
                    d,
                    &tank("WaterTankBottomTranslationVideoBuffer.igs.mha"),
                    &tank("WaterTankBottomTranslationTrackerBuffer.igs.mha"),
                )
            },
        ),
        case("temporal: video of one frame", 1, "seq.mha", move |d| {
            let seq = write(
                d,
                "seq.mha",
                &sequence(
                    |t| t.replace("40 30 2", "40 30 1").replace("Seq_Frame0001", "X_Frame1"),
                    1200,
                ),
            );
            temporal(d, &tank("WaterTankBottomTranslationTrackerBuffer.igs.mha"), &seq)
        }),
        case("temporal: output onto the video", 2, "would replace", move |d| {
            let video = write(
                d,
                "video.mha",
                &std::fs::read(tank("WaterTankBottomTranslationVideoBuffer.igs.mha")).unwrap(),
            );
            args(&[
                "temporal",
                "--tracker",
                &tank("WaterTankBottomTranslationTrackerBuffer.igs.mha"),
                "--video",
                &video,
                "--out",
                &video,
            ])
        }),
        case("run: threads a million", 2, "--threads", |d| {
            let m = tracked_manifest(d, "m.yaml", "time_offset_s: estimate", "time_offset_s: 0.0");
            args(&["run", &m, "--out", &s(d.join("out")), "--threads", "1000000"])
        }),
    ]
}

/// A shard file of one seed with `rms` as its first method's error.
pub(super) fn shard_text(rms: &str) -> String {
    format!(
        "experiment: s\nmanifest_sha256: '00'\nfirst_seed: 1\nseeds: 1\nshard: {{index: 1, count: 1}}\nresults:\n- seed: 1\n  rms_error_mm:\n  - [horn, {rms}]\n  crlb_rms_mm: null\n  frames_used: 10\n"
    )
}

pub(super) fn study_cases() -> Vec<Case> {
    let manifest = || s(root().join("tests/fixtures/hemisphere_small.yaml"));
    let study = move |d: &Path, extra: &[&str]| {
        let mut a = args(&[
            "study",
            &manifest(),
            "--out",
            &s(d.join("out")),
            "--datasets",
            &s(d.join("datasets")),
        ]);
        a.extend(args(extra));
        a
    };
    vec![
        case("study: a billion seeds", 2, "--seeds", move |d| {
            study(d, &["--seeds", "1000000000"])
        }),
        case("study: seeds past 2^64", 2, "--first-seed", move |d| {
            study(d, &["--seeds", "3", "--first-seed", "18446744073709551615"])
        }),
        case("study: shard 0 of 2", 2, "--shard", move |d| {
            study(d, &["--shard", "0/2"])
        }),
        case("study: shard 3 of 2", 2, "--shard", move |d| {
            study(d, &["--shard", "3/2"])
        }),
        case("study: shard of 0", 2, "--shard", move |d| {
            study(d, &["--shard", "1/0"])
        }),
        case("study: output a file", 2, "is a file", move |d| {
            let f = write(d, "out", b"mine");
            let mut a = study(d, &["--seeds", "0"]);
            let k = a.iter().position(|x| x == "--out").unwrap();
            a[k + 1] = f;
            a
        }),
        case(
            "study: output over files it did not write",
            2,
            "which this command did not write",
            move |d| {
                write(&d.join("out"), "study.json", b"{}");
                study(d, &["--seeds", "0"])
            },
        ),
        case("study: output inside the datasets folder", 2, "lies inside", move |d| {
            std::fs::create_dir_all(d.join("datasets")).unwrap();
            let mut a = study(d, &["--seeds", "0"]);
            let k = a.iter().position(|x| x == "--out").unwrap();
            a[k + 1] = s(d.join("datasets/study"));
            a
        }),
        case("study merge: a shard of garbage", 2, "shard.yaml", |d| {
            let sh = write(d, "shard.yaml", b"\x00\x01 not yaml [");
            args(&["study", "merge", &sh, "--out", &s(d.join("out"))])
        }),
        case("study merge: a negative error", 2, "shard.yaml", |d| {
            let sh = write(d, "shard.yaml", shard_text("-1.0").as_bytes());
            args(&["study", "merge", &sh, "--out", &s(d.join("out"))])
        }),
        case("study merge: an error not a number", 2, "shard.yaml", |d| {
            let sh = write(d, "shard.yaml", shard_text(".nan").as_bytes());
            args(&["study", "merge", &sh, "--out", &s(d.join("out"))])
        }),
        case("study merge: a key given twice", 2, "shard.yaml", |d| {
            let sh = write(
                d,
                "shard.yaml",
                shard_text("1.0")
                    .replace("seeds: 1\n", "seeds: 1\nseeds: 2\n")
                    .as_bytes(),
            );
            args(&["study", "merge", &sh, "--out", &s(d.join("out"))])
        }),
        case("study compare: not JSON", 2, "a.json", |d| {
            let a = write(d, "a.json", b"{\"sigma_table\": [");
            args(&["study", "compare", &a, &a])
        }),
        case("study compare: a key given twice", 2, "a.json", |d| {
            let a = write(
                d,
                "a.json",
                b"{\"sigma_table\": [], \"sigma_table\": [], \"monte_carlo\": null}",
            );
            args(&["study", "compare", &a, &a])
        }),
        case("study compare: output onto a study", 2, "a.json", |d| {
            let a = write(d, "a.json", b"{\"sigma_table\": [], \"monte_carlo\": null}");
            args(&["study", "compare", &a, &a, "--out", &a])
        }),
    ]
}

/// A run folder `<dir>/runs/e/d` holding `summary` as its summary.json.
pub(super) fn run_folder(dir: &Path, summary: &[u8]) -> String {
    write(&dir.join("runs/e/d"), "summary.json", summary);
    s(dir.join("runs/e/d"))
}

pub(super) fn committed_summary() -> String {
    std::fs::read_to_string(root().join("reports/point_checkerboard/dataset3/summary.json")).unwrap()
}

pub(super) fn check_cases() -> Vec<Case> {
    vec![
        case("check: a summary with a key given twice", 2, "summary.json", |d| {
            let text = committed_summary().replacen("{", "{\n  \"experiment\": \"other\",", 1);
            let f = run_folder(d, text.as_bytes());
            args(&[
                "check",
                &format!("{f}/summary.json"),
                "--baselines",
                &s(root().join("experiments/baselines")),
            ])
        }),
        case("check: a summary cut off", 2, "summary.json", |d| {
            let text = committed_summary();
            let f = run_folder(d, &text.as_bytes()[..text.len() / 2]);
            args(&[
                "check",
                &format!("{f}/summary.json"),
                "--baselines",
                &s(root().join("experiments/baselines")),
            ])
        }),
        case("check: a summary that is not one", 2, "summary.json", |d| {
            let f = run_folder(d, b"[1, 2, 3]");
            args(&["check", &format!("{f}/summary.json")])
        }),
        case(
            "check: a baseline with a key given twice",
            2,
            "point_checkerboard.yaml",
            |d| {
                let text =
                    std::fs::read_to_string(root().join("experiments/baselines/point_checkerboard.yaml")).unwrap();
                let doubled = text.replacen("experiment:", "experiment: x\nexperiment:", 1);
                write(&d.join("baselines"), "point_checkerboard.yaml", doubled.as_bytes());
                let f = run_folder(d, committed_summary().as_bytes());
                args(&[
                    "check",
                    &format!("{f}/summary.json"),
                    "--baselines",
                    &s(d.join("baselines")),
                ])
            },
        ),
        case(
            "check: a baseline tolerance not a number",
            2,
            "point_checkerboard.yaml",
            |d| {
                let text =
                    std::fs::read_to_string(root().join("experiments/baselines/point_checkerboard.yaml")).unwrap();
                let k = text.find("tolerance:").expect("a tolerance in the baseline");
                let end = k + text[k..].find('\n').unwrap();
                let edited = format!("{}tolerance: .nan{}", &text[..k], &text[end..]);
                write(&d.join("baselines"), "point_checkerboard.yaml", edited.as_bytes());
                let f = run_folder(d, committed_summary().as_bytes());
                args(&[
                    "check",
                    &format!("{f}/summary.json"),
                    "--baselines",
                    &s(d.join("baselines")),
                ])
            },
        ),
        case("resolve: a folder with no inputs", 1, "solve_inputs", |d| {
            let f = run_folder(d, committed_summary().as_bytes());
            args(&["resolve", &f])
        }),
        case("resolve: a summary with a key given twice", 1, "summary.json", |d| {
            let text = committed_summary().replacen("{", "{\n  \"experiment\": \"other\",", 1);
            let f = run_folder(d, text.as_bytes());
            args(&["resolve", &f])
        }),
        case(
            "reconstruct: a calibration folder whose summary gives a key twice",
            2,
            "summary.json",
            |d| {
                let text = "{\"image_to_probe\": {\"matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}, \"image_to_probe\": {}}";
                let f = run_folder(d, text.as_bytes());
                args(&[
                    "reconstruct",
                    &s(shared_data(VOLUME, SWEEP)),
                    "--config",
                    &s(shared_data(VOLUME, VOLUME_SET)),
                    "--calibration",
                    &f,
                    "--out",
                    &s(d.join("out")),
                ])
            },
        ),
    ]
}

pub(super) fn output_cases() -> Vec<Case> {
    vec![
        case(
            "segment: output onto its device set's folder",
            2,
            "would replace",
            |d| {
                let set = fcal_set(d, "<Segmentation", "<Segmentation");
                args(&[
                    "segment",
                    &s(shared_data(FCAL, FCAL_VALIDATION)),
                    "--config",
                    &set,
                    "--out",
                    &s(d),
                ])
            },
        ),
        case("segment: output inside a file", 1, "v.mha", |d| {
            let data = d.join("data");
            std::fs::create_dir_all(&data).unwrap();
            let seq = write(
                &data,
                "v.mha",
                &std::fs::read(shared_data(FCAL, FCAL_VALIDATION)).unwrap(),
            );
            let set = fcal_set(&data, "<Segmentation", "<Segmentation");
            let _ = set;
            args(&[
                "segment",
                &seq,
                "--config",
                &s(data.join("set.xml")),
                "--out",
                &s(data.join("v.mha/out")),
            ])
        }),
        case("segment: a lock planted as a link", 1, ".out.lock", |d| {
            std::fs::create_dir_all(d).unwrap();
            write(&d.join("canary"), "keep.txt", b"keep");
            std::os::unix::fs::symlink(d.join("canary/keep.txt"), d.join(".out.lock")).unwrap();
            segment(d, s(shared_data(FCAL, FCAL_VALIDATION)))
        }),
        case("run: output onto its manifest", 2, "is a file", |d| {
            let m = tracked_manifest(d, "m.yaml", "time_offset_s: estimate", "time_offset_s: 0.0");
            args(&["run", &m, "--out", &m])
        }),
        case("compare: a page onto its manifest", 2, "would replace", |d| {
            let m = tracked_manifest(
                &d.join("out"),
                "compare.md",
                "time_offset_s: estimate",
                "time_offset_s: 0.0",
            );
            args(&["compare", &m, "--out", &s(d.join("out"))])
        }),
        case("phantom: the model onto its manifest", 2, "reads", |d| {
            let m = write(
                d,
                "m.yaml",
                &std::fs::read(root().join("tests/fixtures/hemisphere_small.yaml")).unwrap(),
            );
            args(&["phantom", &m, "--stl", &m])
        }),
        case("init: the manifest onto its device set", 2, "reads", |d| {
            let set = fcal_set(d, "<Segmentation", "<Segmentation");
            args(&[
                "init",
                "--plus-config",
                &set,
                "--calibration",
                &s(shared_data(FCAL, FCAL_VALIDATION)),
                "--out",
                &set,
                "--force",
            ])
        }),
        case("init: a device set that is not XML", 2, "set.xml", |d| {
            let set = write(d, "set.xml", b"<PlusConfiguration");
            args(&[
                "init",
                "--plus-config",
                &set,
                "--calibration",
                &s(shared_data(FCAL, FCAL_VALIDATION)),
                "--out",
                &s(d.join("out/m.yaml")),
            ])
        }),
        case("reconstruct: output onto its sweep", 2, "would replace", |d| {
            let sweep = write(d, "sweep.mha", &std::fs::read(shared_data(VOLUME, SWEEP)).unwrap());
            args(&[
                "reconstruct",
                &sweep,
                "--config",
                &s(shared_data(VOLUME, VOLUME_SET)),
                "--out",
                &sweep,
            ])
        }),
        case("design: output onto its manifest's folder", 2, "would replace", |d| {
            let m = write(
                d,
                "m.yaml",
                &std::fs::read(root().join("tests/fixtures/hemisphere_small.yaml")).unwrap(),
            );
            args(&["design", &m, "--out", &s(d)])
        }),
    ]
}
