//! Files written whole or not at all.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// A file that could not be written: its path and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{path}: {message}")]
pub struct WriteError {
    pub path: PathBuf,
    pub message: String,
}

/// Writes `bytes` to `path` through a temporary file in the same folder, renamed
/// into place: a reader sees the old file or the new one, never half of one.
/// The temporary file is created new ([`create_temp_beside`]), so nothing
/// planted at its name (a file, a link to elsewhere) is written through; a
/// link at `path` itself is replaced, not followed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    use std::io::Write;
    let err = |e: std::io::Error| WriteError {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(err)?;
    }
    let (tmp, mut file) = create_temp_beside(path).map_err(err)?;
    let written = file.write_all(bytes).and_then(|_| file.flush());
    drop(file);
    if let Err(e) = written.and_then(|_| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(err(e));
    }
    Ok(())
}

/// Temporary files made by this process so far (part of their names).
static TEMP_COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// A new, empty file beside `path` whose name no other writer predicts
/// (`.<name>.<process>-<count>-<clock>.tmp`), created exclusively
/// (`create_new`: an existing file or link there is an error, never opened),
/// with its path. Tries a few names before giving up.
pub fn create_temp_beside(path: &Path) -> std::io::Result<(PathBuf, std::fs::File)> {
    let name = path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    let mut last = None;
    for _ in 0..16 {
        let count = TEMP_COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let clock = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.subsec_nanos() ^ (d.as_secs() as u32))
            .unwrap_or(0);
        let tmp = path.with_file_name(format!(".{name}.{}-{count}-{clock:08x}.tmp", std::process::id()));
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(file) => return Ok((tmp, file)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no free temporary name")))
}

/// Writes each `(name, bytes)` under `folder` with [`write_atomic`] (folders made
/// as needed), stopping at the first failure.
pub fn write_all_atomic(folder: &Path, files: &[(String, Vec<u8>)]) -> Result<(), WriteError> {
    files
        .iter()
        .try_for_each(|(name, bytes)| write_atomic(&folder.join(name), bytes))
}

/// A path as written in outputs: forward slashes on every system.
pub fn display_path(path: &Path) -> String {
    path.to_string_lossy().replace('\\', "/")
}

/// A file's bytes, no more than `limit` of them: a file larger is an error that
/// says so, whatever its metadata claims (a device such as `/dev/zero` reports
/// no size and never ends; it is read no further than the limit). Every reader
/// of a whole file goes through here or [`read_text_capped`].
pub fn read_capped(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let declared = file.metadata()?.len();
    let too_large = |what: String| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{what}: larger than any such file probecal reads ({limit} bytes)"),
        )
    };
    if declared > limit {
        return Err(too_large(format!("{declared} bytes")));
    }
    let mut bytes = Vec::with_capacity(declared as usize);
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(format!("more than {limit} bytes")));
    }
    Ok(bytes)
}

/// A UTF-8 text file, no more than `limit` bytes of it (see [`read_capped`]).
pub fn read_text_capped(path: &Path, limit: u64) -> std::io::Result<String> {
    String::from_utf8(read_capped(path, limit)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

/// SHA-256 of a file, streamed, with its size in bytes. A file hashed before in
/// this process is not read again while its identity, size and times are the
/// same (a run checks its cached dataset's hashes, then records them in its
/// provenance): the change time, which no program can set back, moves with any
/// write.
pub fn file_sha256(path: &Path) -> std::io::Result<(u64, String)> {
    let mut file = std::fs::File::open(path)?;
    let metadata = file.metadata()?;
    // A device or a pipe has no end to hash.
    if !metadata.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file",
        ));
    }
    let stamp = memo::Stamp::of(&metadata);
    if let Some(known) = memo::lookup(path, &stamp) {
        return Ok(known);
    }
    let mut hasher = Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    let mut total = 0u64;
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            break;
        }
        total += n as u64;
        hasher.update(&buffer[..n]);
    }
    let hashed = (total, hex(&hasher.finalize()));
    // A file that changed while it was read is not remembered.
    if total == stamp.bytes && memo::Stamp::of(&file.metadata()?) == stamp {
        memo::remember(path, stamp, &hashed.1);
    }
    Ok(hashed)
}

/// The hashes of files already hashed in this process, by path and stamp.
mod memo {
    use std::collections::HashMap;
    use std::path::{Path, PathBuf};
    use std::sync::Mutex;

    /// At most this many files are remembered; then the memory starts again.
    const MAX_FILES: usize = 100_000;

    /// What identifies one version of a file: device, inode, size, modification
    /// and change times (ns). `None` parts where the system does not tell.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Stamp {
        pub bytes: u64,
        identity: Option<[i64; 6]>,
    }

    impl Stamp {
        pub fn of(meta: &std::fs::Metadata) -> Stamp {
            #[cfg(unix)]
            let identity = {
                use std::os::unix::fs::MetadataExt;
                Some([
                    meta.dev() as i64,
                    meta.ino() as i64,
                    meta.mtime(),
                    meta.mtime_nsec(),
                    meta.ctime(),
                    meta.ctime_nsec(),
                ])
            };
            #[cfg(not(unix))]
            let identity = None;
            Stamp {
                bytes: meta.len(),
                identity,
            }
        }
    }

    type Known = HashMap<PathBuf, (Stamp, String)>;
    static KNOWN: Mutex<Option<Known>> = Mutex::new(None);

    pub fn lookup(path: &Path, stamp: &Stamp) -> Option<(u64, String)> {
        stamp.identity?;
        let known = KNOWN.lock().ok()?;
        let (s, sha) = known.as_ref()?.get(path)?;
        (s == stamp).then(|| (s.bytes, sha.clone()))
    }

    /// A file changed this recently may change again within the same tick of
    /// the file system's clock without its times moving (the "racy" files of
    /// git's index): it is not remembered.
    const SETTLED_S: i64 = 2;

    /// Remembers the SHA-256 (hex) of the file version `stamp` names.
    pub fn remember(path: &Path, stamp: Stamp, sha256: &str) {
        let Some([_, _, _, _, changed_s, _]) = stamp.identity else {
            return;
        };
        let now_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        if now_s - changed_s < SETTLED_S {
            return;
        }
        if let Ok(mut known) = KNOWN.lock() {
            let map = known.get_or_insert_with(HashMap::new);
            if map.len() >= MAX_FILES {
                map.clear();
            }
            map.insert(path.to_path_buf(), (stamp, sha256.to_string()));
        }
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn only_settled_files_are_remembered_and_only_for_their_stamp() {
            let path = Path::new("/nonexistent/probecal-memo-test");
            let now_s = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_secs() as i64;
            let stamp = |changed_s: i64, bytes: u64| Stamp {
                bytes,
                identity: Some([1, 2, changed_s, 0, changed_s, 0]),
            };
            remember(path, stamp(now_s, 5), "just written");
            assert_eq!(
                lookup(path, &stamp(now_s, 5)),
                None,
                "a file changed just now is not remembered"
            );
            let settled = stamp(now_s - 60, 5);
            remember(path, settled, "settled");
            assert_eq!(lookup(path, &settled), Some((5, "settled".into())));
            assert_eq!(lookup(path, &stamp(now_s - 59, 5)), None, "changed since");
            assert_eq!(lookup(path, &stamp(now_s - 60, 6)), None, "another size");
            let unknown = Stamp {
                bytes: 5,
                identity: None,
            };
            remember(path, unknown, "unknown");
            assert_eq!(lookup(path, &unknown), None, "no identity, no memory");
        }
    }
}

pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// An exclusive claim, held while the value lives: an advisory lock
/// (`flock`) on a file that also names the holder's process id. The system
/// drops the lock when its process ends, however it ends, so a killed run never
/// leaves a claim behind; the file itself stays (removing it would let a
/// waiting process lock a file no longer at the path).
#[derive(Debug)]
pub struct Lock {
    _file: std::fs::File,
}

impl Lock {
    /// Claims `path` or fails at once; an error names the process that holds it.
    pub fn acquire(path: &Path) -> Result<Lock, LockError> {
        Lock::claim(path, None)
    }

    /// Claims `path`, waiting while another process holds it (`waiting` is told
    /// whom it waits for, once).
    pub fn acquire_waiting(path: &Path, waiting: &mut dyn FnMut(&str)) -> Result<Lock, LockError> {
        Lock::claim(path, Some(waiting))
    }

    fn claim(path: &Path, waiting: Option<&mut dyn FnMut(&str)>) -> Result<Lock, LockError> {
        use std::io::{Read, Seek, Write};
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|source| LockError::Io {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        let fail = |source: std::io::Error| LockError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut options = std::fs::OpenOptions::new();
        options.read(true).write(true).create(true).truncate(false);
        // A link planted at the lock's name is refused, not followed: the
        // claim truncates the file it opens.
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NOFOLLOW);
        let mut file = options.open(path).map_err(fail)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut text = String::new();
                let _ = file.read_to_string(&mut text);
                let holder = match text.trim().parse::<u32>() {
                    Ok(pid) => format!("another probecal (process {pid})"),
                    Err(_) => "another probecal".to_string(),
                };
                match waiting {
                    None => {
                        return Err(LockError::Held {
                            path: path.to_path_buf(),
                            holder,
                        })
                    }
                    Some(waiting) => {
                        waiting(&format!("{}: waiting for {holder} to finish with it", path.display()));
                        file.lock().map_err(fail)?;
                    }
                }
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(fail(e)),
        }
        file.set_len(0).map_err(fail)?;
        file.rewind().map_err(fail)?;
        writeln!(file, "{}", std::process::id()).map_err(fail)?;
        file.flush().map_err(fail)?;
        Ok(Lock { _file: file })
    }
}

/// Why a lock file could not be claimed.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: {holder} is writing here; wait for it to finish", path.display())]
    Held { path: PathBuf, holder: String },
}

impl LockError {
    /// What went wrong, without the path.
    pub fn reason(&self) -> String {
        match self {
            LockError::Io { source, .. } => source.to_string(),
            LockError::Held { holder, .. } => format!("{holder} is writing here; wait for it to finish"),
        }
    }
}

/// A folder's new content, written beside it (`.<name>.partial`) and swapped in
/// only when complete: until [`Staged::commit`], the old folder is untouched, and
/// a run that fails or is killed leaves it as it was.
#[derive(Debug)]
pub struct Staged {
    target: PathBuf,
    partial: PathBuf,
}

fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{suffix}"))
}

fn io_error(path: &Path) -> impl Fn(std::io::Error) -> WriteError + '_ {
    move |e| WriteError {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

impl Staged {
    /// Starts writing `target`'s new content (a stale partial folder is removed;
    /// a swap that was cut off half-way is undone first).
    pub fn begin(target: &Path) -> Result<Staged, WriteError> {
        let partial = sibling(target, "partial");
        let old = sibling(target, "old");
        if old.exists() && !target.exists() {
            std::fs::rename(&old, target).map_err(io_error(target))?;
        }
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(io_error(&partial))?;
        }
        std::fs::create_dir_all(&partial).map_err(io_error(&partial))?;
        Ok(Staged {
            target: target.to_path_buf(),
            partial,
        })
    }

    /// Where the new content is written.
    pub fn path(&self) -> &Path {
        &self.partial
    }

    /// Swaps the new content in; the old folder is removed only then.
    pub fn commit(self) -> Result<(), WriteError> {
        let old = sibling(&self.target, "old");
        if old.exists() {
            std::fs::remove_dir_all(&old).map_err(io_error(&old))?;
        }
        if self.target.exists() {
            std::fs::rename(&self.target, &old).map_err(io_error(&self.target))?;
        }
        std::fs::rename(&self.partial, &self.target).map_err(io_error(&self.target))?;
        if old.exists() {
            std::fs::remove_dir_all(&old).map_err(io_error(&old))?;
        }
        Ok(())
    }

    /// Keeps the old folder and moves what was written to `.<name>.failed` (for
    /// a look; replaced by the next failure); its path.
    pub fn abandon(self) -> Result<PathBuf, WriteError> {
        let failed = sibling(&self.target, "failed");
        if failed.exists() {
            std::fs::remove_dir_all(&failed).map_err(io_error(&failed))?;
        }
        std::fs::rename(&self.partial, &failed).map_err(io_error(&failed))?;
        Ok(failed)
    }
}

/// Whether two paths are one recording: the same file, or files of the same bytes.
pub fn same_recording(a: &Path, b: &Path) -> bool {
    let same_file = matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y);
    let size = |p: &Path| std::fs::metadata(p).map(|m| m.len()).ok();
    same_file
        || (size(a).is_some_and(|s| Some(s) == size(b))
            && matches!((file_sha256(a), file_sha256(b)), (Ok(x), Ok(y)) if x == y))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Links planted where a writer puts its files lead nowhere: the old fixed
    /// temporary name, the output itself, the lock.
    #[cfg(unix)]
    #[test]
    fn planted_links_are_never_written_through() {
        let dir = std::env::temp_dir().join(format!("probecal-links-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("out")).unwrap();
        let outside = dir.join("outside.txt");
        std::fs::write(&outside, "precious").unwrap();
        let out = dir.join("out");
        std::os::unix::fs::symlink(&outside, out.join(".summary.json.tmp")).unwrap();
        std::os::unix::fs::symlink(&outside, out.join("report.html")).unwrap();
        write_atomic(&out.join("summary.json"), b"{}").unwrap();
        write_atomic(&out.join("report.html"), b"<p>").unwrap();
        assert_eq!(std::fs::read_to_string(&outside).unwrap(), "precious");
        assert_eq!(std::fs::read_to_string(out.join("summary.json")).unwrap(), "{}");
        assert!(!out.join("report.html").is_symlink(), "the link is replaced");
        std::os::unix::fs::symlink(&outside, out.join(".probecal.lock")).unwrap();
        let refused = Lock::acquire(&out.join(".probecal.lock")).unwrap_err();
        assert!(refused.to_string().contains(".probecal.lock"), "{refused}");
        assert_eq!(std::fs::read_to_string(&outside).unwrap(), "precious");
        // Temporary names differ call by call and are all gone afterwards.
        let (a, fa) = create_temp_beside(&out.join("x")).unwrap();
        let (b, fb) = create_temp_beside(&out.join("x")).unwrap();
        assert_ne!(a, b);
        drop((fa, fb));
        std::fs::remove_file(a).unwrap();
        std::fs::remove_file(b).unwrap();
        let tmp: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp") && !e.path().is_symlink())
            .collect();
        assert!(tmp.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_file_rewritten_at_once_is_hashed_again() {
        let dir = scratch("memo");
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.bin");
        for text in [&b"first"[..], b"other", b"third"] {
            std::fs::write(&path, text).unwrap();
            // Same size, same clock tick: only the content tells them apart.
            assert_eq!(file_sha256(&path).unwrap(), (5, hex(&Sha256::digest(text))));
            assert_eq!(file_sha256(&path).unwrap(), (5, hex(&Sha256::digest(text))));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("probecal-fs-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn staged_content_replaces_the_old_only_on_commit() {
        let dir = scratch("staged");
        let target = dir.join("exp");
        std::fs::create_dir_all(&target).unwrap();
        std::fs::write(target.join("old.txt"), "old").unwrap();
        let staged = Staged::begin(&target).unwrap();
        std::fs::write(staged.path().join("new.txt"), "new").unwrap();
        assert!(
            target.join("old.txt").is_file(),
            "the old content stays until the commit"
        );
        staged.commit().unwrap();
        assert!(target.join("new.txt").is_file() && !target.join("old.txt").exists());
        let staged = Staged::begin(&target).unwrap();
        std::fs::write(staged.path().join("half.txt"), "half").unwrap();
        let failed = staged.abandon().unwrap();
        assert!(target.join("new.txt").is_file(), "a failure keeps the previous content");
        assert!(failed.join("half.txt").is_file());
        // A swap cut off between its two renames is undone by the next begin.
        std::fs::rename(&target, dir.join(".exp.old")).unwrap();
        let staged = Staged::begin(&target).unwrap();
        assert!(target.join("new.txt").is_file());
        drop(staged);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_lock_is_exclusive_and_released_with_its_holder() {
        let dir = scratch("lock");
        let path = dir.join(".probecal.lock");
        let lock = Lock::acquire(&path).unwrap();
        let again = Lock::acquire(&path).unwrap_err().to_string();
        assert!(
            again.contains(&format!("another probecal (process {})", std::process::id())),
            "{again}"
        );
        drop(lock);
        // A file left with a dead process's id holds no claim.
        std::fs::write(&path, "4294967295\n").unwrap();
        let taken = Lock::acquire(&path).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{}\n", std::process::id())
        );
        drop(taken);
        // A waiting claim is told whom it waits for and gets the lock once the
        // holder lets go.
        let held = Lock::acquire(&path).unwrap();
        let waiter = {
            let path = path.clone();
            std::thread::spawn(move || {
                let mut told = Vec::new();
                let lock = Lock::acquire_waiting(&path, &mut |m| told.push(m.to_string()));
                (lock.is_ok(), told)
            })
        };
        std::thread::sleep(std::time::Duration::from_millis(200));
        drop(held);
        let (claimed, told) = waiter.join().unwrap();
        assert!(claimed);
        assert_eq!(told.len(), 1, "{told:?}");
        assert!(told[0].contains("waiting for another probecal (process"), "{told:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
