//! `probecal live <tracked manifest> --igtl HOST:PORT --out <dir>`: calibrates
//! from a PlusServer stream and sends the calibration back. Everything is
//! written into a staged folder swapped in at the end; an interrupt (Ctrl-C)
//! ends the acquisition and the session still calibrates and writes (a second
//! one stops at once). 0 written, 2 bad input, 1 failed (no calibration: the
//! received frames are kept in `.<out>.failed/`).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use super::failure::Failure;
use crate::io::fs::Staged;
use crate::manifest::tracked::TrackedManifest;
use crate::manifest::Experiment;
use crate::pipeline::live::igtl::StreamSettings;
use crate::pipeline::live::volume::VolumeRequest;
use crate::pipeline::tracked::TrackedInputs;

pub fn command(
    manifest: &Path,
    address: &str,
    volume: Option<VolumeRequest>,
    out: &Path,
    force: bool,
) -> Result<(), Failure> {
    let mut all = crate::pipeline::experiment::load_all(&[manifest.to_path_buf()]).map_err(Failure::bad_input)?;
    let Some(Experiment::Tracked(m)) = all.pop() else {
        return Err(Failure::bad_input(format!(
            "{}: --igtl takes a tracked manifest (tracking: plus_sequence): its phantom, transforms' names and `live:` settings",
            manifest.display()
        )));
    };
    // Every file the session reads, those named inside the manifest and the device sets too.
    let mut files = m.input_files();
    if let Some(v) = &volume {
        files.push(v.config.clone());
        files.extend(crate::io::plus::volume_config::VolumeSettings::named_files(&v.config));
    }
    let mut read = vec![manifest];
    read.extend(files.iter().map(PathBuf::as_path));
    if let Some(reason) = crate::io::output::refusal(out, "live", &read, force) {
        return Err(Failure::bad_input(format!("--out {}: {reason}", out.display())));
    }
    let _lock = crate::io::output::lock(out).map_err(Failure::failed)?;
    if let Some(request) = &volume {
        crate::pipeline::live::volume::LiveVolume::open(request).map_err(Failure::bad_input)?;
    }
    session(&m, address, volume, out)
}

fn session(
    manifest: &TrackedManifest,
    address: &str,
    volume: Option<VolumeRequest>,
    out: &Path,
) -> Result<(), Failure> {
    let settings = StreamSettings {
        address: address.to_string(),
        stream: manifest.live.clone(),
        volume,
    };
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // A second interrupt while the first is honoured ends the process.
        signal_hook::flag::register_conditional_shutdown(signal, 130, Arc::clone(&stop))
            .and_then(|_| signal_hook::flag::register(signal, Arc::clone(&stop)))
            .map_err(|e| Failure::failed(format!("cannot watch for interrupts: {e}")))?;
    }
    let staged = Staged::begin(out).map_err(|e| Failure::failed(e.to_string()))?;
    let terminal = std::io::stderr().is_terminal();
    eprintln!(
        "listening to {address}: IMAGE `{}`, TRANSFORM `{}` and `{}`; ends on STRING `{}` or {} s of silence",
        settings.stream.image_device,
        manifest.probe_transform,
        manifest.reference_transform,
        settings.stream.end_device,
        settings.stream.silence_s
    );
    if let Some(v) = &settings.volume {
        eprintln!("reconstructing live: {}", crate::pipeline::live::volume::describe(v));
    }
    if let Some(note) = super::live::estimated_lag_note(&manifest.time_offset) {
        eprintln!("{note}");
    }
    let mut show = |f: &crate::pipeline::live::LiveFrame| super::live::shown(terminal, &crate::report::live::line(f));
    let inputs = TrackedInputs::from_manifest(manifest);
    let run =
        crate::pipeline::live::igtl::run(&inputs, manifest.min_frames, &settings, staged.path(), &stop, &mut show);
    if terminal {
        eprintln!();
    }
    let run = match run {
        Ok(run) => run,
        Err(e) => {
            let _ = staged.abandon();
            return Err(Failure::failed(format!("{address}: {e}")));
        }
    };
    if run.ending.abnormal() {
        eprintln!(
            "warning: the acquisition ended on {}; the {} frame(s) received before it are kept and calibrated",
            run.ending.describe(&settings.stream),
            run.counts.frames
        );
    }
    let received = staged.path().join("received.igs.mha");
    let after = (run.final_run.as_ref().ok())
        .map(|batch| crate::pipeline::tracked::resolution::after_received(batch, manifest, &received));
    let labels = crate::pipeline::labels::TrackedLabels::of(manifest);
    let s = crate::report::live::igtl::write(&run, &settings, &labels, after.as_ref(), staged.path())
        .map_err(|e| Failure::failed(format!("{}: {e}", out.display())))?;
    if s.messages.skipped > 0 {
        eprintln!(
            "warning: {} message(s) skipped; the first: {}",
            s.messages.skipped,
            s.messages.skip_reasons.first().map(String::as_str).unwrap_or("")
        );
    }
    if let Some(e) = &s.calibration_error {
        let kept = staged.abandon().map(|p| p.display().to_string()).unwrap_or_default();
        return Err(Failure::failed(format!(
            "{} images received, {} frames; no calibration: {e} (the received frames are in {kept})",
            s.images_received, s.frames
        )));
    }
    crate::io::fs::write_atomic(&staged.path().join(crate::io::output::MARKER), b"live\n")
        .map_err(|e| Failure::failed(e.to_string()))?;
    staged.commit().map_err(|e| Failure::failed(e.to_string()))?;
    let latency = s
        .latency_ms
        .as_ref()
        .map(|p| format!("{:.1} ms median, {:.1} ms p99", p.p50, p.p99))
        .unwrap_or_else(|| "—".into());
    println!(
        "{} images received ({} frames, {} without a pose), ended by {}; latency {latency}; {}; running PRE3D at the last frame {} (estimated while frames arrived, from those so far); final validation PRE3D {} (the batch calibration of every frame); written to {}",
        s.images_received,
        s.frames,
        s.frames_without_pose,
        s.ended_by,
        match &s.sent_error {
            None => format!("ImageToProbe sent as `{}`", s.sent_device),
            Some(e) => format!("ImageToProbe {e}"),
        },
        s.running_pre3d_mm.map(|v| format!("{v:.4} mm")).unwrap_or_else(|| "—".into()),
        s.final_validation_pre3d_mm.map(|v| format!("{v:.4} mm")).unwrap_or_else(|| "—".into()),
        out.display()
    );
    Ok(())
}
