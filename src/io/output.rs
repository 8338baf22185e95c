//! The one output discipline of every command that writes a folder: the
//! folder is claimed (a lock beside it, so two commands never write it at
//! once), refused when it holds or is one of the command's inputs, or when it
//! exists and another command (or no command) wrote it, unless `--force`; the
//! new content is written beside it and swapped in only on success, with a
//! marker naming the command; on failure the old folder is untouched and the
//! partial one removed.

use std::path::{Path, PathBuf};

use super::fs::{write_atomic, Lock, LockError, Staged, WriteError};

/// The file in an output folder naming the command that wrote it.
pub const MARKER: &str = ".probecal-output";

/// Why an output folder cannot be claimed.
#[derive(Debug, thiserror::Error)]
pub enum OutputRefusal {
    #[error("--out {}: {reason}", out.display())]
    Refused { out: PathBuf, reason: String },
    #[error("{0}")]
    Lock(#[from] LockError),
    #[error("{0}")]
    Write(#[from] WriteError),
}

/// `path` made absolute with its links resolved, as far as it exists.
pub fn resolved(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) if !parent.as_os_str().is_empty() => resolved(parent).join(name),
        _ => std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
    }
}

/// Why `out` may not be written as `command`'s output folder given its
/// `inputs`, if it may not.
pub fn refusal(out: &Path, command: &str, inputs: &[&Path], force: bool) -> Option<String> {
    let target = resolved(out);
    // The folder is replaced whole, by a sibling swapped in: the working
    // directory (`.`) or a folder holding it cannot be, and a path without a
    // name of its own (`..`, `/`) has no sibling to stage in.
    if let Ok(cwd) = std::env::current_dir().map(|d| resolved(&d)) {
        if cwd.starts_with(&target) {
            return Some(format!(
                "is the working directory{}: the output folder is replaced whole; give a new folder (e.g. {}/out)",
                if cwd == target { "" } else { " or holds it" },
                out.display()
            ));
        }
    }
    if target.file_name().is_none() || out.file_name().is_none() {
        return Some("has no name of its own (it ends in `.` or `..`); name the folder itself".into());
    }
    for input in inputs {
        let input_path = resolved(input);
        if input_path == target || input_path.starts_with(&target) {
            return Some(format!(
                "would replace {}, which `probecal {command}` reads; choose another --out",
                input.display()
            ));
        }
        if input.is_dir() && target.starts_with(&input_path) {
            return Some(format!(
                "lies inside {}, which `probecal {command}` reads; choose another --out",
                input.display()
            ));
        }
    }
    if let Some(why) = not_a_folder(out) {
        return Some(why);
    }
    if !out.is_dir() || force {
        return None;
    }
    let empty = std::fs::read_dir(out).map(|mut d| d.next().is_none()).unwrap_or(false);
    if empty {
        return None;
    }
    match written_by(out, command) {
        Some(verdict) => verdict,
        None => Some(
            "exists and was not written by this command (a run's folder, your files?); pass --force to replace it, or choose another --out"
                .into(),
        ),
    }
}

/// What `out`'s marker says: `Some(None)` written by `command`, `Some(Some(why))`
/// by another command, `None` no marker.
fn written_by(out: &Path, command: &str) -> Option<Option<String>> {
    let writer = crate::io::fs::read_text_capped(&out.join(MARKER), 4096).ok()?;
    Some((writer.trim() != command).then(|| {
        format!(
            "holds the output of `probecal {}`; pass --force to replace it, or choose another --out",
            writer.trim()
        )
    }))
}

/// Why `out` cannot be an output folder at all: it is a file (or a link to one).
fn not_a_folder(out: &Path) -> Option<String> {
    (out.is_file() || out.is_symlink() && !out.is_dir()).then(|| "is a file, not a folder; choose another --out".into())
}

/// Why `out` may not be written as an output file of `command`, if it may
/// not: it is one of the command's input files, or a folder.
pub fn file_refusal(out: &Path, command: &str, inputs: &[&Path], force: bool) -> Option<String> {
    let target = resolved(out);
    if let Some(input) = inputs.iter().find(|i| resolved(i) == target) {
        return Some(format!(
            "is {}, which `probecal {command}` reads; choose another output file",
            input.display()
        ));
    }
    if out.is_dir() {
        return Some("is a folder; name a file".to_string());
    }
    // A file of the same name may be anything (another result, your notes):
    // replaced only when asked.
    (out.exists() && !force).then(|| "exists; pass --force to replace it".to_string())
}

/// The lock that claims output folder `out` (`.<name>.lock` beside it).
pub fn lock(out: &Path) -> Result<Lock, LockError> {
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    Lock::acquire(&out.with_file_name(format!(".{name}.lock")))
}

/// A claimed output folder, being written beside its final place.
#[derive(Debug)]
pub struct OutputFolder {
    staged: Option<Staged>,
    command: String,
    _lock: Lock,
}

impl OutputFolder {
    /// Claims `out` for `command`, whose inputs are `inputs` (files or folders).
    pub fn claim(out: &Path, command: &str, inputs: &[&Path], force: bool) -> Result<OutputFolder, OutputRefusal> {
        if let Some(reason) = refusal(out, command, inputs, force) {
            return Err(OutputRefusal::Refused {
                out: out.to_path_buf(),
                reason,
            });
        }
        let lock = lock(out)?;
        let staged = Staged::begin(out)?;
        Ok(OutputFolder {
            staged: Some(staged),
            command: command.to_string(),
            _lock: lock,
        })
    }

    /// Where the new content is written.
    pub fn path(&self) -> &Path {
        self.staged.as_ref().map(|s| s.path()).unwrap_or(Path::new(""))
    }

    /// Marks the new content as this command's and swaps it in.
    pub fn commit(mut self) -> Result<(), WriteError> {
        let staged = self.staged.take().expect("an output folder is committed once");
        write_atomic(&staged.path().join(MARKER), format!("{}\n", self.command).as_bytes())?;
        staged.commit()
    }
}

impl Drop for OutputFolder {
    /// Not committed: what was written is removed; the old folder stays.
    fn drop(&mut self) {
        if let Some(staged) = self.staged.take() {
            let _ = std::fs::remove_dir_all(staged.path());
        }
    }
}

/// Why `names` may not be written into `out` as `command`'s files, if they
/// may not. The folder is shared with files the command leaves alone (studies
/// nested in a study's folder, the other shards of one study), so only the
/// named files are at stake: one of them is an input, the folder lies inside an
/// input folder, or, without `force`, the folder is another command's or holds
/// one of the names without saying this command wrote it.
pub fn files_refusal(out: &Path, command: &str, names: &[&str], inputs: &[&Path], force: bool) -> Option<String> {
    if let Some(why) = not_a_folder(out) {
        return Some(why);
    }
    let target = resolved(out);
    for input in inputs {
        let input_path = resolved(input);
        if let Some(name) = names.iter().find(|n| target.join(n) == input_path) {
            return Some(format!(
                "its {name} would replace {}, which `probecal {command}` reads; choose another --out",
                input.display()
            ));
        }
        if input.is_dir() && target.starts_with(&input_path) {
            return Some(format!(
                "lies inside {}, which `probecal {command}` reads; choose another --out",
                input.display()
            ));
        }
    }
    if force {
        return None;
    }
    match written_by(out, command) {
        Some(verdict) => verdict,
        None => names.iter().find(|n| out.join(n).exists()).map(|name| {
            format!(
                "holds {name}, which this command did not write; pass --force to replace it, or choose another --out"
            )
        }),
    }
}

/// Named files claimed in a folder they share with others: each is written
/// whole (`write_atomic`), and the folder's marker names the command once
/// they are.
#[derive(Debug)]
pub struct OutputFiles {
    folder: PathBuf,
    command: String,
    _lock: Option<Lock>,
}

impl OutputFiles {
    /// Claims `names` in `out` for `command`; `exclusive`: one process at a
    /// time (the lock beside the folder), else several may write their own
    /// names at once (the shards of one study).
    pub fn claim(
        out: &Path,
        command: &str,
        names: &[&str],
        inputs: &[&Path],
        force: bool,
        exclusive: bool,
    ) -> Result<OutputFiles, OutputRefusal> {
        if let Some(reason) = files_refusal(out, command, names, inputs, force) {
            return Err(OutputRefusal::Refused {
                out: out.to_path_buf(),
                reason,
            });
        }
        let lock = if exclusive { Some(lock(out)?) } else { None };
        Ok(OutputFiles {
            folder: out.to_path_buf(),
            command: command.to_string(),
            _lock: lock,
        })
    }

    /// Marks the folder as this command's, once its files are written.
    pub fn commit(self) -> Result<(), WriteError> {
        write_atomic(&self.folder.join(MARKER), format!("{}\n", self.command).as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_claimed_checked_and_swapped_in_whole() {
        let dir = std::env::temp_dir().join(format!("probecal-output-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("inputs")).unwrap();
        let input = dir.join("inputs/seq.mha");
        std::fs::write(&input, "x").unwrap();
        let out = dir.join("out");
        // Written whole, with its marker; the same command may write it again.
        let folder = OutputFolder::claim(&out, "segment", &[&input], false).unwrap();
        std::fs::write(folder.path().join("a.txt"), "1").unwrap();
        assert!(!out.exists(), "nothing in place before the commit");
        folder.commit().unwrap();
        assert_eq!(std::fs::read_to_string(out.join(MARKER)).unwrap(), "segment\n");
        let again = OutputFolder::claim(&out, "segment", &[&input], false).unwrap();
        // A second claim while the first holds it is refused.
        let busy = OutputFolder::claim(&out, "segment", &[&input], false).unwrap_err();
        assert!(busy.to_string().contains("is writing here"), "{busy}");
        drop(again);
        assert!(out.join("a.txt").is_file(), "a dropped claim leaves the old folder");
        // Another command's folder, a folder of one's own files, an input, the
        // folder holding an input, and a file are refused.
        let e = OutputFolder::claim(&out, "temporal", &[], false).unwrap_err();
        assert!(e.to_string().contains("holds the output of `probecal segment`"), "{e}");
        assert!(
            OutputFolder::claim(&out, "temporal", &[], true).is_ok(),
            "--force replaces it"
        );
        let e = OutputFolder::claim(&dir.join("inputs"), "segment", &[&input], true).unwrap_err();
        assert!(e.to_string().contains("would replace"), "{e}");
        let e = OutputFolder::claim(&input, "segment", &[&input], true).unwrap_err();
        assert!(e.to_string().contains("would replace"), "{e}");
        let e = OutputFolder::claim(&dir.join("inputs/sub"), "run", &[&dir.join("inputs")], true).unwrap_err();
        assert!(e.to_string().contains("lies inside"), "{e}");
        std::fs::write(dir.join("inputs/notes.txt"), "mine").unwrap();
        let e = OutputFolder::claim(&dir.join("inputs"), "segment", &[], false).unwrap_err();
        assert!(e.to_string().contains("was not written by this command"), "{e}");
        let e = OutputFolder::claim(&dir.join("inputs/notes.txt"), "segment", &[], true).unwrap_err();
        assert!(e.to_string().contains("is a file"), "{e}");
        // An output file that is an input, or a folder.
        let e = file_refusal(
            &dir.join("inputs/../inputs/seq.mha"),
            "calibrate-camera",
            &[&input],
            true,
        )
        .unwrap();
        assert!(e.contains("which `probecal calibrate-camera` reads"), "{e}");
        assert!(file_refusal(&dir.join("inputs"), "phantom", &[], true)
            .unwrap()
            .contains("is a folder"));
        assert_eq!(
            file_refusal(&dir.join("new.yml"), "calibrate-camera", &[&input], false),
            None
        );
        // An existing file of another name is replaced only with force.
        let notes = dir.join("inputs/notes.txt");
        assert!(file_refusal(&notes, "calibrate-camera", &[&input], false)
            .unwrap()
            .contains("pass --force"));
        assert_eq!(file_refusal(&notes, "calibrate-camera", &[&input], true), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn named_files_are_claimed_in_a_shared_folder() {
        let dir = std::env::temp_dir().join(format!("probecal-output-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("study/shards")).unwrap();
        let shard = dir.join("study/shards/shard_1_of_2.yaml");
        std::fs::write(&shard, "x").unwrap();
        let names = ["study.json", "study.md"];
        // Shards inside the folder are left alone; the folder is marked.
        let files = OutputFiles::claim(&dir.join("study"), "study", &names, &[&shard], false, true).unwrap();
        let busy = OutputFiles::claim(&dir.join("study"), "study", &names, &[], false, true).unwrap_err();
        assert!(busy.to_string().contains("is writing here"), "{busy}");
        std::fs::write(dir.join("study/study.json"), "{}").unwrap();
        files.commit().unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("study").join(MARKER)).unwrap(),
            "study\n"
        );
        assert!(OutputFiles::claim(&dir.join("study"), "study", &names, &[], false, true).is_ok());
        // Another command's folder; an input under an output's name; a folder
        // inside an input folder; a name present in an unmarked folder.
        let e = files_refusal(&dir.join("study"), "segment", &names, &[], false).unwrap();
        assert!(e.contains("holds the output of `probecal study`"), "{e}");
        let e = files_refusal(
            &dir.join("study/shards"),
            "study",
            &["shard_1_of_2.yaml"],
            &[&shard],
            true,
        )
        .unwrap();
        assert!(e.contains("its shard_1_of_2.yaml would replace"), "{e}");
        let e = files_refusal(
            &dir.join("study/shards/x"),
            "study",
            &names,
            &[&dir.join("study/shards")],
            true,
        )
        .unwrap();
        assert!(e.contains("lies inside"), "{e}");
        let e = files_refusal(&dir.join("study/shards"), "study", &["shard_1_of_2.yaml"], &[], false).unwrap();
        assert!(
            e.contains("holds shard_1_of_2.yaml, which this command did not write"),
            "{e}"
        );
        assert_eq!(
            files_refusal(&dir.join("study/shards"), "study", &["shard_2_of_2.yaml"], &[], false),
            None
        );
        assert!(files_refusal(&shard, "study", &names, &[], true)
            .unwrap()
            .contains("is a file"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
