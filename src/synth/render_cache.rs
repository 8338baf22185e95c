//! Finished renders kept by their inputs, when `PROBECAL_RENDER_CACHE` names a
//! folder: a dataset whose render inputs (the lab and the render spec, as its
//! `render_spec.json` states them) were rendered before is copied from there,
//! under whatever experiment or seed folder asks for it, instead of being
//! rendered again. The long tests set it: their studies render the same seeds
//! of the same rig under several experiments' names.
//!
//! The renderer is deterministic, so a copy is byte for byte what a render
//! writes; an entry is used only when its `render_spec.json` equals the inputs
//! and every file matches its listing. The key holds the inputs, not the
//! renderer's code: a cache folder is for one build (a test run's scratch
//! folder), not to be kept across versions.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::{damage, io_err, SynthError};

/// The environment variable naming the cache's folder (unset or empty: no cache).
pub const ENV: &str = "PROBECAL_RENDER_CACHE";

/// The cache entry of these render inputs, when a cache is set.
pub fn entry(inputs_json: &str) -> Option<PathBuf> {
    let dir = std::env::var_os(ENV).filter(|v| !v.is_empty())?;
    Some(PathBuf::from(dir).join(crate::io::fs::hex(&Sha256::digest(inputs_json.as_bytes()))))
}

/// Fills the empty folder `into` from `entry` when the entry holds exactly
/// this render; `false` (nothing written) when it does not.
pub fn fetch(entry: &Path, inputs_json: &str, into: &Path) -> Result<bool, SynthError> {
    let stated = crate::io::fs::read_text_capped(
        &entry.join("render_spec.json"),
        crate::core::limits::MAX_TEXT_FILE_BYTES,
    )
    .ok();
    if stated.as_deref() != Some(inputs_json) || damage(entry).is_some() {
        return Ok(false);
    }
    copy_tree(entry, into)?;
    Ok(true)
}

/// Keeps a finished render (`folder`, with its listing and spec) as `entry`:
/// copied beside it under a name of this process, then renamed into place. An
/// entry another process stored first is kept.
pub fn store(folder: &Path, entry: &Path) -> Result<(), SynthError> {
    let parent = entry.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    let name = entry
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let staged = parent.join(format!(".{name}.{}.partial", std::process::id()));
    if staged.exists() {
        std::fs::remove_dir_all(&staged).map_err(io_err(&staged))?;
    }
    copy_tree(folder, &staged)?;
    if let Err(e) = std::fs::rename(&staged, entry) {
        std::fs::remove_dir_all(&staged).map_err(io_err(&staged))?;
        if !entry.is_dir() {
            return Err(io_err(entry)(e));
        }
    }
    Ok(())
}

/// Copies the regular files and folders under `from` into `to` (created);
/// links are not followed or copied (a render writes none).
fn copy_tree(from: &Path, to: &Path) -> Result<(), SynthError> {
    std::fs::create_dir_all(to).map_err(io_err(to))?;
    for item in std::fs::read_dir(from).map_err(io_err(from))? {
        let item = item.map_err(io_err(from))?;
        let kind = item.file_type().map_err(io_err(&item.path()))?;
        let target = to.join(item.file_name());
        if kind.is_dir() {
            copy_tree(&item.path(), &target)?;
        } else if kind.is_file() {
            std::fs::copy(item.path(), &target).map_err(io_err(&target))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("probecal-render-cache-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// A folder as a render leaves it: files, their listing and the spec.
    fn rendered(dir: &Path, spec: &str) {
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        std::fs::write(dir.join("frames/bscan_000.png"), b"pixels").unwrap();
        std::fs::write(dir.join("frames.csv"), b"frame\n0\n").unwrap();
        let listing = super::super::listing(dir).unwrap();
        std::fs::write(dir.join(super::super::RENDERED_FILES), listing).unwrap();
        std::fs::write(dir.join("render_spec.json"), spec).unwrap();
    }

    #[test]
    fn an_entry_is_used_only_for_its_own_inputs_and_intact() {
        let dir = scratch("entry");
        let render = dir.join("render");
        rendered(&render, "{\"seed\": 1}");
        let entry = dir.join("cache/abc");
        store(&render, &entry).unwrap();
        // The same inputs: a copy, byte for byte.
        let into = dir.join("copy");
        assert!(fetch(&entry, "{\"seed\": 1}", &into).unwrap());
        assert_eq!(std::fs::read(into.join("frames/bscan_000.png")).unwrap(), b"pixels");
        // Other inputs: nothing written.
        let other = dir.join("other");
        assert!(!fetch(&entry, "{\"seed\": 2}", &other).unwrap());
        assert!(!other.exists());
        // A damaged entry is not used.
        std::fs::write(entry.join("frames/bscan_000.png"), b"pixelz").unwrap();
        assert!(!fetch(&entry, "{\"seed\": 1}", &dir.join("damaged")).unwrap());
        // A second store of the same entry keeps the first and leaves no staging folder.
        store(&render, &entry).unwrap();
        let staged = std::fs::read_dir(dir.join("cache")).unwrap().count();
        assert_eq!(staged, 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
