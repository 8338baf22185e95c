//! The reports in their real readers: the LaTeX report compiled by Debian's
//! pdflatex, the HTML page rendered by headless Chromium (screenshot, console,
//! DOM). Both tools are installed by `scripts/setup.sh`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use opencv::core::{mean_std_dev, Mat};
use opencv::prelude::*;

/// The small fixture, with special characters in its description, run once.
fn run_folder() -> &'static PathBuf {
    static RUN: OnceLock<PathBuf> = OnceLock::new();
    RUN.get_or_init(|| {
        let work = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report_formats");
        let _ = std::fs::remove_dir_all(&work);
        std::fs::create_dir_all(&work).unwrap();
        let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hemisphere_small.yaml");
        let text = std::fs::read_to_string(&fixture).unwrap();
        let edited = text.replace(
            "description: Test fixture, 14 frames and 8 camera-calibration views.",
            "description: \"Test fixture: 100% of #1 & $2, a_b {c} ~d ^e \\\\f <g> — 0.5 ± 0.1 mm, 3°\"",
        );
        assert_ne!(edited, text, "fixture edit did not apply");
        let manifest = work.join("special.yaml");
        std::fs::write(&manifest, edited).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_probecal"))
            .arg("run")
            .arg(&manifest)
            .arg("--out")
            .arg(work.join("out"))
            .arg("--datasets")
            .arg(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("end_to_end_datasets"))
            .arg("--quiet")
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        work.join("out/hemisphere_small/small")
    })
}

#[test]
#[ignore = "needs pdflatex and Chromium, runs an experiment (long reproductions: scripts/reproduce.sh)"]
fn latex_report_compiles_with_pdflatex() {
    let folder = run_folder();
    let tex = std::fs::read_to_string(folder.join("report.tex")).unwrap();
    // Special characters are escaped, not passed through.
    assert!(
        tex.contains(r"100\% of \#1 \& \$2, a\_b \{c\} \textasciitilde{}d"),
        "{}",
        &tex[..600]
    );
    assert!(tex.contains(r"hemisphere\_small"));
    assert!(folder.join("bre_per_frame.png").is_file());
    assert!(
        tex.contains(r"\includegraphics[width=\linewidth]{gallery/frame_"),
        "gallery in the LaTeX report"
    );
    let (pages, log) = compile_in(folder, "report");
    assert!(pages >= 2, "{pages} pages:\n{log}");
    let pdf = std::fs::read(folder.join("report.pdf")).unwrap();
    assert!(pdf.starts_with(b"%PDF"));
    assert!(!log.contains("Missing character"), "{log}");
}

#[test]
#[ignore = "needs pdflatex (long reproductions: scripts/reproduce.sh)"]
fn every_committed_run_report_compiles_without_an_overfull_line() {
    // Each run folder of reports/ (camera and tracked runs alike) copied and compiled:
    // no table or path runs into the margin, no float is taller than its page.
    let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
    let work = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("committed_tex");
    let _ = std::fs::remove_dir_all(&work);
    let mut compiled = 0;
    let mut overfull = Vec::new();
    for experiment in std::fs::read_dir(&reports).unwrap().flatten() {
        for run in std::fs::read_dir(experiment.path()).into_iter().flatten().flatten() {
            if !run.path().join("report.tex").is_file() {
                continue;
            }
            let copy = work.join(experiment.file_name()).join(run.file_name());
            copy_folder(&run.path(), &copy);
            let (pages, log) = compile_in(&copy, "report");
            assert!(pages >= 1, "{}", copy.display());
            let full = std::fs::read_to_string(copy.join("report.log")).unwrap_or(log);
            for line in full.lines().filter(|l| l.starts_with("Overfull")) {
                overfull.push(format!("{}: {line}", copy.display()));
            }
            compiled += 1;
        }
    }
    assert!(compiled >= 15, "only {compiled} run reports in reports/");
    assert!(overfull.is_empty(), "{}", overfull.join("\n"));
}

fn copy_folder(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap().flatten() {
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            copy_folder(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// `pdflatex` on `<name>.tex` in `folder` (it must succeed); the number of pages and the log.
fn compile_in(folder: &Path, name: &str) -> (usize, String) {
    let out = Command::new("pdflatex")
        .args(["-interaction=nonstopmode", "-halt-on-error", &format!("{name}.tex")])
        .current_dir(folder)
        .output()
        .expect("pdflatex is installed (scripts/setup.sh)");
    let log = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(out.status.success(), "pdflatex failed on {name}.tex:\n{log}");
    // "Output written on <name>.pdf (N pages, ...)"
    let pages = log
        .split(&format!("Output written on {name}.pdf ("))
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    (pages, log)
}

/// `pdflatex` on `tex` in a fresh folder; the number of pages.
fn compile(name: &str, tex: &str) -> usize {
    let work = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("tex_{name}"));
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).unwrap();
    std::fs::write(work.join(format!("{name}.tex")), tex).unwrap();
    compile_in(&work, name).0
}

#[test]
#[ignore = "needs pdflatex and Chromium, runs an experiment (long reproductions: scripts/reproduce.sh)"]
fn comparison_page_compiles_with_pdflatex() {
    // As the main job wrote it from the default experiments.
    let tex = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/compare.tex")).unwrap();
    assert!(tex.contains(r"hemisphere\_checkerboard / dataset3"));
    assert!(compile("compare", &tex) >= 1);
}

#[test]
#[ignore = "needs pdflatex and Chromium, runs an experiment (long reproductions: scripts/reproduce.sh)"]
fn thesis_chapter_compiles_with_pdflatex() {
    // The chapter from the default experiments' runs.
    let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
    let (_, _, tex) = probecal::report::thesis::render(&reports)
        .unwrap_or_else(|e| panic!("{e}"))
        .expect("the default experiments' runs are in reports/");
    assert!(compile("thesis", &tex) >= 1);
}

fn chromium(args: &[&str], profile: &Path) -> std::process::Output {
    Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .output()
        .expect("chromium is installed (scripts/setup.sh)")
}

#[test]
#[ignore = "needs pdflatex and Chromium, runs an experiment (long reproductions: scripts/reproduce.sh)"]
fn html_report_renders_in_headless_chromium() {
    let folder = run_folder();
    let page = format!("file://{}", folder.join("report.html").display());
    let profile = folder.join("chromium-profile");
    let _ = std::fs::remove_dir_all(&profile);
    // The DOM as the browser built it, with the console on stderr.
    let dom = chromium(&["--enable-logging=stderr", "--v=0", "--dump-dom", &page], &profile);
    let html = String::from_utf8_lossy(&dom.stdout);
    let console = String::from_utf8_lossy(&dom.stderr);
    assert!(dom.status.success(), "{console}");
    let errors: Vec<&str> = console
        .lines()
        .filter(|l| l.contains("CONSOLE") || l.contains("Uncaught"))
        .collect();
    assert!(errors.is_empty(), "console messages: {errors:?}");
    // The BRE table is there with its four rows of three numbers.
    let table = html.split("id=\"bre-table\"").nth(1).expect("BRE table in the DOM");
    let body = table.split("</table>").next().unwrap();
    for row in ["Std.", "Mean", "Min", "Max"] {
        assert!(body.contains(row), "row {row} missing: {body}");
    }
    let numbers = body
        .split("<td>")
        .skip(1)
        .filter(|c| c.split('<').next().is_some_and(|v| v.trim().parse::<f64>().is_ok()))
        .count();
    assert_eq!(numbers, 12, "{body}");
    // The BRE plot, its histogram, the boards' reprojection, the camera views and
    // the pose overview: inline SVG.
    let svgs = html.matches("<svg").count();
    assert!(svgs >= 6, "{svgs} inline SVG figures");
    // The gallery's B-scans are inline too (the page is one self-contained file).
    assert!(
        html.contains("<img src=\"data:image/jpeg;base64,"),
        "gallery images inline"
    );
    assert!(
        html.contains("id=\"setup\"") && html.contains("OpenCV 4."),
        "setup with versions"
    );
    // A screenshot: the page is drawn, not blank.
    let shot = folder.join("report_screenshot.png");
    let _ = std::fs::remove_file(&shot);
    let out = chromium(
        &[
            &format!("--screenshot={}", shot.display()),
            "--window-size=1280,2400",
            &page,
        ],
        &profile,
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = probecal::io::image::read_gray(&shot).unwrap();
    assert_eq!((image.cols(), image.rows()), (1280, 2400));
    let (mut mean, mut sd) = (Mat::default(), Mat::default());
    mean_std_dev(&image, &mut mean, &mut sd, &opencv::core::no_array()).unwrap();
    let sd = *sd.at::<f64>(0).unwrap();
    assert!(sd > 10.0, "the screenshot looks blank (grey SD {sd})");
}
