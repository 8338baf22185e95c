//! `probecal live`: calibrates while a tracked recording is replayed, or while
//! a camera experiment's frames arrive in a folder; a line per frame (one
//! updated line on a terminal), then the session's files. 0 written, 2 bad
//! input, 1 failed.

use std::io::{IsTerminal, Write as _};
use std::path::{Path, PathBuf};

use super::failure::{Failure, ValueError};
use crate::manifest::{Experiment, Manifest};
use crate::pipeline::live::folder::Watch;
use crate::pipeline::live::Replay;
use crate::pipeline::tracked::TrackedInputs;

/// How `probecal live` gets its frames: a tracked manifest's sequence replayed,
/// or a camera manifest's frames from a folder being written.
pub struct LiveSource {
    pub speed: f64,
    pub watch: Option<PathBuf>,
    pub idle_s: f64,
    /// Replace --out even when another command (or no command) wrote it.
    pub force: bool,
}

/// Shows a frame's line: replacing the last on a terminal, one per line otherwise.
pub(super) fn shown(terminal: bool, text: &str) {
    if terminal {
        eprint!("\r\x1b[2K{text}");
        let _ = std::io::stderr().flush();
    } else {
        eprintln!("{text}");
    }
}

pub fn command(manifest: &Path, out: &Path, source: &LiveSource) -> Result<(), Failure> {
    let speed = source.speed;
    if !(speed == 0.0 || (0.01..=100.0).contains(&speed)) {
        return Err(Failure::bad_input(format!(
            "--speed {speed}: a replay speed is 0 (as fast as the frames are processed) or 0.01 to 100 (times the recorded pace)"
        )));
    }
    let mut all = crate::pipeline::experiment::load_all(&[manifest.to_path_buf()]).map_err(Failure::bad_input)?;
    let m = match (all.pop(), &source.watch) {
        (Some(Experiment::Tracked(m)), None) => m,
        (Some(Experiment::Camera(m)), Some(folder)) => {
            let watch = Watch {
                folder: folder.clone(),
                idle_s: source.idle_s,
                poll_ms: 20,
            };
            let folder = crate::io::output::OutputFolder::claim(out, "live", &[manifest, &watch.folder], source.force)?;
            folder_command(&m, &watch, folder.path())?;
            return folder.commit().map_err(Failure::failed);
        }
        (Some(Experiment::Tracked(_)), Some(_)) => {
            return Err(Failure::bad_input(format!(
                "{}: --watch takes a camera manifest's frames from a folder; a tracked manifest replays its sequence (leave out --watch)",
                manifest.display()
            )))
        }
        _ => {
            return Err(Failure::bad_input(format!(
                "{}: live calibration replays a tracked sequence (tracking: plus_sequence), or with --watch DIR takes a camera manifest's frames from a folder being written",
                manifest.display()
            )))
        }
    };
    let inputs = TrackedInputs::from_manifest(&m);
    let files = m.input_files();
    let mut read: Vec<&Path> = vec![manifest];
    read.extend(files.iter().map(PathBuf::as_path));
    let folder = crate::io::output::OutputFolder::claim(out, "live", &read, source.force)?;
    if let Some(note) = estimated_lag_note(&m.time_offset) {
        eprintln!("{note}");
    }
    let replay = Replay { speed };
    let terminal = std::io::stderr().is_terminal();
    let mut show = |f: &crate::pipeline::live::LiveFrame| shown(terminal, &crate::report::live::line(f));
    let run = crate::pipeline::live::run(&inputs, m.min_frames, replay, &mut show);
    if terminal {
        eprintln!();
    }
    let run = run.map_err(Failure::failed)?;
    let s = crate::report::live::write(&run, replay, folder.path())
        .map_err(|e| Failure::failed(format!("{}: {e}", out.display())))?;
    folder.commit().map_err(Failure::failed)?;
    println!(
        "{} frames at {:.1} frames/s recorded; work per frame {:.1} ms mean, {:.1} ms max ({}); running PRE3D at the last frame {} (estimated while frames arrived, from those so far); final validation PRE3D {} (the batch calibration of every frame); written to {}",
        s.frames,
        s.recorded_rate_hz,
        s.processing_ms.mean,
        s.processing_ms.max,
        if s.kept_up { "kept up" } else { "fell behind" },
        s.running_pre3d_mm.map(|v| format!("{v:.4} mm")).unwrap_or_else(|| "—".into()),
        s.final_validation_pre3d_mm.map(|v| format!("{v:.4} mm")).unwrap_or_else(|| "—".into()),
        out.display()
    );
    Ok(())
}

/// `probecal live <camera manifest> --watch <folder> --out <dir>`.
fn folder_command(manifest: &Manifest, watch: &Watch, out: &Path) -> Result<(), Failure> {
    let terminal = std::io::stderr().is_terminal();
    let mut show =
        |f: &crate::pipeline::live::folder::FolderFrame| shown(terminal, &crate::report::live::folder::line(f));
    let run = crate::pipeline::live::folder::run(manifest, watch, &mut show);
    if terminal {
        eprintln!();
    }
    let run = run.map_err(Failure::failed)?;
    let s = crate::report::live::folder::write(&run, out)
        .map_err(|e| Failure::failed(format!("{}: {e}", out.display())))?;
    println!(
        "{} frames ({} used), ended by {}; latency {:.1} ms mean, {:.1} ms max; live and batch all-frames fits differ by {}; written to {}",
        s.frames,
        s.frames_used,
        s.ended_by.replace('_', " "),
        s.latency_ms.mean,
        s.latency_ms.max,
        s.live_minus_batch_max_abs.map(|v| format!("{v:.2e}")).unwrap_or_else(|| "— (no batch run)".into()),
        out.display()
    );
    Ok(())
}

/// What the live lag is while frames arrive, when the manifest estimates it.
pub(super) fn estimated_lag_note(offset: &crate::manifest::tracked::TimeOffset) -> Option<&'static str> {
    matches!(offset, crate::manifest::tracked::TimeOffset::Estimate).then_some(
        "lag: 0 s while frames arrive (time_offset_s: estimate); the final calibration estimates it from all frames",
    )
}

/// `--idle-s`: a positive number of seconds, at most a day.
pub(crate) fn parse_idle_s(text: &str) -> Result<f64, ValueError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 86_400.0 => Ok(v),
        _ => Err(ValueError::IdleSeconds(text.to_string())),
    }
}

/// `--igtl`: HOST:PORT, the port 1 to 65535.
pub(crate) fn parse_address(text: &str) -> Result<String, ValueError> {
    let fail = || ValueError::Address(text.to_string());
    let (host, port) = text.rsplit_once(':').ok_or_else(fail)?;
    match port.parse::<u16>() {
        Ok(p) if p > 0 && !host.is_empty() => Ok(text.to_string()),
        _ => Err(fail()),
    }
}
