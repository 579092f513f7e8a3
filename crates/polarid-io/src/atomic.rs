//! Atomic outputs: every file is written to a temporary file beside its destination and
//! renamed into place only when complete, so a failed command leaves no partial output.
//! Existing outputs are kept unless the caller passes `force`; inputs are never
//! overwritten.
//!
//! Output directories ([`StagedDir`]) are built in a hidden staging directory
//! `.polarid-staging-<pid>-<random>` beside the destination and published in one step
//! (`docs/RELIABILITY.md`):
//!
//! - a new directory by one `rename` that refuses to replace anything (Linux
//!   `renameat2(RENAME_NOREPLACE)`): of two runs writing the same new directory exactly
//!   one wins, the other fails ([`IoError::Concurrent`], exit status 2);
//! - over an existing directory, the files of the old one that the run does not write
//!   are hard-linked into the staging directory, which is then exchanged with the old
//!   one in one step (`renameat2(RENAME_EXCHANGE)`); the old one is removed after. A
//!   run that finds the directory was replaced by another run meanwhile swaps back and
//!   fails. Where the exchange is not possible (other systems, the current directory),
//!   files are moved in one by one as before.
//!
//! Live staging directories and temporary files are registered so that a signal handler
//! can remove them ([`remove_registered`]); staging left by a run that was killed
//! (`kill -9`, power loss) is removed by the next run writing beside it once its
//! process is gone ([`clean_stale`]).

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{IoError, Result};

/// Directory a file will be created in (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Give a temporary output file the usual mode of a new file (`0644`, not the `0600`
/// of temporary files), so that outputs are readable like any other file.
fn set_default_mode(path: &Path) {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = fs::set_permissions(path, fs::Permissions::from_mode(0o644));
    }
    #[cfg(not(unix))]
    let _ = path;
}

/// True when `a` and `b` name the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    match (fs::canonicalize(a), fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// Check that `path` may be written: it must not be one of `inputs`, and must not exist
/// unless `force`.
pub fn check_output(path: &Path, force: bool, inputs: &[&Path]) -> Result<()> {
    if inputs.iter().any(|i| same_file(i, path)) {
        return Err(IoError::OverwritesInput {
            path: path.to_path_buf(),
        });
    }
    if !force && path.exists() {
        return Err(IoError::OutputExists {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

/// Write a file atomically: `write` fills a buffered temporary file in the destination's
/// directory, which is renamed to `path` only if `write` succeeds.
pub fn write_atomic<F>(path: &Path, force: bool, write: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    check_output(path, force, &[])?;
    check_not_terminating(path)?;
    let dir = parent_dir(path);
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".polarid-tmp-{}-", std::process::id()))
        .tempfile_in(&dir)
        .map_err(|e| IoError::io(&dir, e))?;
    let tmp_path = tmp.path().to_path_buf();
    register(&tmp_path);
    let result = (|| {
        set_default_mode(tmp.path());
        {
            let mut w = BufWriter::new(tmp.as_file());
            write(&mut w)?;
            w.flush().map_err(|e| IoError::io(path, e))?;
        }
        if force {
            tmp.persist(path).map_err(|e| IoError::io(path, e.error))?;
        } else {
            tmp.persist_noclobber(path)
                .map_err(|e| IoError::io(path, e.error))?;
        }
        Ok(())
    })();
    unregister(&tmp_path);
    result
}

/// Prefix of every hidden entry polarid creates beside its outputs.
const PREFIXES: [&str; 2] = [".polarid-staging-", ".polarid-tmp-"];

/// Paths of the live staging directories and temporary files of this process.
static REGISTRY: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Set once a signal handler started cleaning up: no new staging is created.
static TERMINATING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

fn register(p: &Path) {
    if let Ok(mut r) = REGISTRY.lock() {
        r.push(p.to_path_buf());
    }
}

fn unregister(p: &Path) {
    if let Ok(mut r) = REGISTRY.lock()
        && let Some(i) = r.iter().position(|x| x == p)
    {
        r.swap_remove(i);
    }
}

/// Remove every live staging directory and temporary file of this process (for a
/// signal handler, before it exits); later attempts to stage fail. Returns how many
/// were removed.
pub fn remove_registered() -> usize {
    TERMINATING.store(true, std::sync::atomic::Ordering::SeqCst);
    let paths: Vec<PathBuf> = match REGISTRY.lock() {
        Ok(r) => r.clone(),
        Err(p) => p.into_inner().clone(),
    };
    let mut n = 0;
    for p in paths {
        // Another thread may still be adding files: retry a few times.
        for _ in 0..20 {
            let r = if p.is_dir() {
                fs::remove_dir_all(&p)
            } else {
                fs::remove_file(&p)
            };
            match r {
                Ok(()) => {
                    n += 1;
                    break;
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => break,
                Err(_) => std::thread::sleep(std::time::Duration::from_millis(5)),
            }
        }
    }
    n
}

/// The signal that made the run stop (0: none yet).
static SIGNAL: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

/// Write end of the pipe that wakes the signal thread (-1: not installed).
#[cfg(unix)]
static SIGNAL_PIPE: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(-1);

/// The signals after which polarid removes its staging and exits with status 128 + the
/// signal's number: SIGINT (130), SIGTERM (143), SIGHUP (129).
#[cfg(unix)]
pub const CLEANUP_SIGNALS: [i32; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// The signal handler proper: only async-signal-safe work (an atomic store and one
/// `write(2)`); the cleaning runs on the thread of [`on_termination_signal`].
#[cfg(unix)]
extern "C" fn note_signal(sig: libc::c_int) {
    use std::sync::atomic::Ordering::SeqCst;
    let _ = SIGNAL.compare_exchange(0, sig, SeqCst, SeqCst);
    let fd = SIGNAL_PIPE.load(SeqCst);
    if fd >= 0 {
        let b = [sig as u8];
        // SAFETY: write(2) is async-signal-safe; `b` lives across the call.
        let _ = unsafe { libc::write(fd, b.as_ptr().cast(), 1) };
    }
}

/// Run `action(signal)` on a dedicated thread when SIGINT, SIGTERM or SIGHUP arrives
/// ([`CLEANUP_SIGNALS`]); `action` is expected to call [`remove_registered`] and exit
/// with [`exit_status_of_signal`]. Install it once, at the start of `main`.
#[cfg(unix)]
pub fn on_termination_signal(action: impl Fn(i32) + Send + 'static) -> std::io::Result<()> {
    use std::sync::atomic::Ordering::SeqCst;
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: `fds` has room for the two descriptors pipe(2) writes.
    if unsafe { libc::pipe(fds.as_mut_ptr()) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    for fd in fds {
        // SAFETY: fd is a descriptor just returned by pipe(2).
        unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) };
    }
    let [read_fd, write_fd] = fds;
    SIGNAL_PIPE.store(write_fd, SeqCst);
    std::thread::Builder::new()
        .name("polarid-signals".into())
        .spawn(move || {
            let mut b = [0u8; 1];
            loop {
                // SAFETY: reads at most one byte into `b`, which outlives the call.
                let r = unsafe { libc::read(read_fd, b.as_mut_ptr().cast(), 1) };
                if r == 1 {
                    action(SIGNAL.load(SeqCst));
                } else if r < 0
                    && std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted
                {
                    continue;
                } else {
                    return;
                }
            }
        })?;
    for sig in CLEANUP_SIGNALS {
        // SAFETY: a zeroed sigaction with a valid handler and an empty mask is a valid
        // argument; the handler only does async-signal-safe work.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = note_signal as *const () as libc::sighandler_t;
            sa.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut sa.sa_mask);
            if libc::sigaction(sig, &sa, std::ptr::null_mut()) != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
    }
    Ok(())
}

/// The signal that stopped the run, if any (its number: SIGINT 2, SIGTERM 15, SIGHUP 1).
pub fn signal_received() -> Option<i32> {
    Some(SIGNAL.load(std::sync::atomic::Ordering::SeqCst)).filter(|&s| s != 0)
}

/// The exit status after signal `sig`: 128 + its number, as a shell reports a process
/// killed by it (SIGINT 130, SIGTERM 143, SIGHUP 129).
pub fn exit_status_of_signal(sig: i32) -> i32 {
    128 + sig
}

/// Note that `sig` stopped the run (for platforms whose handler is installed elsewhere).
pub fn note_signal_received(sig: i32) {
    use std::sync::atomic::Ordering::SeqCst;
    let _ = SIGNAL.compare_exchange(0, sig, SeqCst, SeqCst);
}

/// True once [`remove_registered`] was called (a signal is being handled): the caller
/// should exit with the signal's status rather than report its own error.
pub fn terminating() -> bool {
    TERMINATING.load(std::sync::atomic::Ordering::SeqCst)
}

fn check_not_terminating(path: &Path) -> Result<()> {
    if TERMINATING.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(IoError::io(
            path,
            std::io::Error::new(std::io::ErrorKind::Interrupted, "interrupted"),
        ));
    }
    Ok(())
}

/// The process id in a hidden polarid entry's name (`.polarid-staging-<pid>-...`).
fn owner_pid(name: &str) -> Option<u32> {
    let rest = PREFIXES.iter().find_map(|p| name.strip_prefix(p))?;
    rest.split('-').next()?.parse().ok()
}

/// True when process `pid` may still be running (always true where this cannot be
/// told).
fn pid_alive(pid: u32) -> bool {
    #[cfg(target_os = "linux")]
    {
        Path::new("/proc").join(pid.to_string()).exists() || !Path::new("/proc/self").exists()
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = pid;
        true
    }
}

/// Remove the staging directories and temporary files that polarid runs left in `dir`
/// when they were killed: only entries named `.polarid-staging-<pid>-*` or
/// `.polarid-tmp-<pid>-*` whose process `<pid>` no longer runs (never this process's).
/// Returns the paths removed. Errors are ignored (another run may be cleaning too).
pub fn clean_stale(dir: &Path) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    let Ok(entries) = fs::read_dir(dir) else {
        return removed;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(pid) = name.to_str().and_then(owner_pid) else {
            continue;
        };
        if pid == std::process::id() || pid_alive(pid) {
            continue;
        }
        let p = e.path();
        let r = match e.file_type() {
            Ok(t) if t.is_dir() => fs::remove_dir_all(&p),
            Ok(_) => fs::remove_file(&p),
            Err(err) => Err(err),
        };
        if r.is_ok() {
            removed.push(p);
        }
    }
    removed
}

/// How [`rename2`] treats an existing destination.
#[derive(Clone, Copy, PartialEq, Eq)]
enum RenameMode {
    /// Fail if the destination exists.
    NoReplace,
    /// Swap the two paths atomically (both must exist).
    Exchange,
}

/// `rename` with `RENAME_NOREPLACE` / `RENAME_EXCHANGE`; `Ok(false)` when the system
/// cannot do it (then the caller falls back).
fn rename2(from: &Path, to: &Path, mode: RenameMode) -> std::io::Result<bool> {
    #[cfg(target_os = "linux")]
    {
        use std::ffi::CString;
        use std::os::unix::ffi::OsStrExt;
        let cstr = |p: &Path| {
            CString::new(p.as_os_str().as_bytes())
                .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))
        };
        let (a, b) = (cstr(from)?, cstr(to)?);
        let flags: libc::c_uint = match mode {
            RenameMode::NoReplace => 1, // RENAME_NOREPLACE
            RenameMode::Exchange => 2,  // RENAME_EXCHANGE
        };
        // SAFETY: both are valid NUL-terminated paths that live across the call;
        // renameat2 only reads them.
        let r = unsafe {
            libc::syscall(
                libc::SYS_renameat2,
                libc::AT_FDCWD,
                a.as_ptr(),
                libc::AT_FDCWD,
                b.as_ptr(),
                flags,
            )
        };
        if r == 0 {
            return Ok(true);
        }
        let e = std::io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::ENOSYS | libc::EINVAL) => Ok(false),
            _ => Err(e),
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = (from, to, mode);
        Ok(false)
    }
}

/// Identity of an existing directory (device and inode), to notice it was replaced.
fn identity(path: &Path) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        fs::symlink_metadata(path).ok().map(|m| (m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        // No inode: only existence can be told.
        fs::symlink_metadata(path).ok().map(|_| (0, 0))
    }
}

/// A staging directory for commands that write several files into an output directory.
///
/// Files are created inside a hidden staging directory next to the destination;
/// [`StagedDir::commit`] publishes them in one step (module documentation). Dropping
/// a `StagedDir` without committing removes everything it holds.
#[derive(Debug)]
pub struct StagedDir {
    dest: PathBuf,
    tmp: Option<tempfile::TempDir>,
    force: bool,
    /// Identity of `dest` when staging started (`None`: it did not exist).
    dest_id: Option<(u64, u64)>,
}

impl StagedDir {
    /// Prepare to write into `dest`, which must be a directory or not exist yet (an
    /// existing file of that name is an error, even with `force`: it is not replaced by
    /// a directory). Stale staging of killed runs beside `dest` is removed first.
    pub fn new(dest: &Path, force: bool) -> Result<Self> {
        if dest.exists() && !dest.is_dir() {
            return Err(IoError::io(
                dest,
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "exists and is not a directory (the output must be a directory)",
                ),
            ));
        }
        check_not_terminating(dest)?;
        let parent = parent_dir(dest);
        fs::create_dir_all(&parent).map_err(|e| IoError::io(&parent, e))?;
        clean_stale(&parent);
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".polarid-staging-{}-", std::process::id()))
            .tempdir_in(&parent)
            .map_err(|e| IoError::io(&parent, e))?;
        register(tmp.path());
        Ok(Self {
            dest: dest.to_path_buf(),
            tmp: Some(tmp),
            force,
            dest_id: identity(dest).filter(|_| dest.is_dir()),
        })
    }

    fn root(&self) -> &Path {
        // ok: `tmp` is only taken by `commit`, which consumes `self`.
        self.tmp.as_ref().map_or(Path::new(""), |t| t.path())
    }

    /// Path at which to write the staged file `name` (a relative path; sub-directories
    /// are created).
    pub fn path(&self, name: &str) -> Result<PathBuf> {
        check_not_terminating(&self.dest)?;
        let p = self.root().join(name);
        if let Some(parent) = p.parent() {
            fs::create_dir_all(parent).map_err(|e| IoError::io(parent, e))?;
        }
        Ok(p)
    }

    /// Final location of the staged file `name` once committed.
    pub fn final_path(&self, name: &str) -> PathBuf {
        self.dest.join(name)
    }

    /// Publish the staged files (module documentation) and return their final paths.
    /// Fails before publishing anything if a destination file exists and `force` was
    /// not given, if a destination is a directory (which a file cannot replace), or if
    /// another run published the same directory meanwhile ([`IoError::Concurrent`]).
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let root = self.root().to_path_buf();
        let mut files = Vec::new();
        collect_files(&root, Path::new(""), &mut files)?;
        for rel in &files {
            let d = self.dest.join(rel);
            if d.is_dir() {
                return Err(IoError::io(
                    &d,
                    std::io::Error::new(
                        std::io::ErrorKind::InvalidInput,
                        "is a directory; cannot write an output file there",
                    ),
                ));
            }
            if !self.force && d.exists() {
                return Err(IoError::OutputExists { path: d });
            }
        }
        let out: Vec<PathBuf> = files.iter().map(|r| self.dest.join(r)).collect();
        check_not_terminating(&self.dest)?;
        if !self.dest.exists() {
            if self.dest_id.is_some() {
                return Err(self.concurrent());
            }
            match rename2(&root, &self.dest, RenameMode::NoReplace) {
                Ok(true) => {
                    self.published(&root);
                    return Ok(out);
                }
                Ok(false) => {}
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    return Err(self.concurrent());
                }
                Err(e) => return Err(IoError::io(&self.dest, e)),
            }
            // No RENAME_NOREPLACE: a plain rename (an empty directory made meanwhile
            // would be replaced; a non-empty one makes it fail).
            if !self.dest.exists() {
                match fs::rename(&root, &self.dest) {
                    Ok(()) => {
                        self.published(&root);
                        return Ok(out);
                    }
                    Err(_) if self.dest.exists() => return Err(self.concurrent()),
                    Err(e) => return Err(IoError::io(&self.dest, e)),
                }
            }
        }
        if self.dest_id.is_none() || identity(&self.dest) != self.dest_id {
            return Err(self.concurrent());
        }
        let is_link = fs::symlink_metadata(&self.dest).is_ok_and(|m| m.file_type().is_symlink());
        // An existing directory: keep what the run does not replace, then swap (a
        // symbolic link to a directory, `.` or `..` is written into, file by file).
        let swapped = if is_link || self.dest.file_name().is_none() {
            Ok(false)
        } else {
            link_missing(&self.dest, &root, Path::new(""))?;
            rename2(&root, &self.dest, RenameMode::Exchange)
        };
        match swapped {
            Ok(true) => {
                // `root` now holds the old directory; was it the one we started from?
                if identity(&root) != self.dest_id {
                    let _ = rename2(&root, &self.dest, RenameMode::Exchange);
                    return Err(self.concurrent());
                }
                let _ = fs::remove_dir_all(&root);
                self.published(&root);
                Ok(out)
            }
            Ok(false) | Err(_) => {
                // Fall back to moving the files one by one.
                for (rel, to) in files.iter().zip(&out) {
                    if let Some(parent) = to.parent() {
                        fs::create_dir_all(parent).map_err(|e| IoError::io(parent, e))?;
                    }
                    fs::rename(root.join(rel), to).map_err(|e| IoError::io(to, e))?;
                }
                Ok(out)
            }
        }
    }

    /// The staging directory `root` was renamed away: forget it.
    fn published(&mut self, root: &Path) {
        unregister(root);
        if let Some(t) = self.tmp.take() {
            // The directory is gone from its staging path (or removed): do not delete.
            let _ = t.keep();
        }
    }

    fn concurrent(&self) -> IoError {
        IoError::Concurrent {
            path: self.dest.clone(),
        }
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if let Some(t) = self.tmp.take() {
            unregister(t.path());
            // TempDir's own drop removes the directory.
        }
    }
}

/// Hard-link (or, for symbolic links, re-create) every entry of `old/rel` that
/// `new/rel` lacks, recursively: the new directory then holds the old one's other
/// files. polarid's own hidden entries are skipped.
fn link_missing(old: &Path, new: &Path, rel: &Path) -> Result<()> {
    let dir = old.join(rel);
    let entries = fs::read_dir(&dir).map_err(|e| IoError::io(&dir, e))?;
    for e in entries {
        let e = e.map_err(|err| IoError::io(&dir, err))?;
        let name = e.file_name();
        if name.to_str().is_some_and(|n| owner_pid(n).is_some()) {
            continue;
        }
        let r = rel.join(&name);
        let (from, to) = (old.join(&r), new.join(&r));
        let ft = e.file_type().map_err(|err| IoError::io(&from, err))?;
        if ft.is_dir() {
            if to.exists() && !to.is_dir() {
                return Err(IoError::io(
                    &from,
                    std::io::Error::new(
                        std::io::ErrorKind::InvalidInput,
                        "is a directory; cannot write an output file there",
                    ),
                ));
            }
            fs::create_dir_all(&to).map_err(|err| IoError::io(&to, err))?;
            link_missing(old, new, &r)?;
        } else if fs::symlink_metadata(&to).is_err() {
            #[cfg(unix)]
            if ft.is_symlink() {
                let target = fs::read_link(&from).map_err(|err| IoError::io(&from, err))?;
                std::os::unix::fs::symlink(target, &to).map_err(|err| IoError::io(&to, err))?;
                continue;
            }
            fs::hard_link(&from, &to)
                .or_else(|_| fs::copy(&from, &to).map(|_| ()))
                .map_err(|err| IoError::io(&to, err))?;
        }
    }
    Ok(())
}

fn collect_files(root: &Path, rel: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    let dir = root.join(rel);
    let mut entries: Vec<_> = fs::read_dir(&dir)
        .map_err(|e| IoError::io(&dir, e))?
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| IoError::io(&dir, e))?;
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let r = rel.join(e.file_name());
        let ft = e.file_type().map_err(|err| IoError::io(e.path(), err))?;
        if ft.is_dir() {
            collect_files(root, &r, out)?;
        } else {
            out.push(r);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("out.csv");
        let r = write_atomic(&p, false, |w| {
            w.write_all(b"partial").map_err(|e| IoError::io("x", e))?;
            Err(IoError::Model {
                path: "x".into(),
                reason: "boom".into(),
            })
        });
        assert!(r.is_err());
        assert!(!p.exists());
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 0);
    }

    #[test]
    fn existing_output_kept_without_force() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("out.csv");
        fs::write(&p, "old").unwrap();
        let r = write_atomic(&p, false, |w| {
            w.write_all(b"new").map_err(|e| IoError::io("x", e))
        });
        assert!(matches!(r, Err(IoError::OutputExists { .. })));
        assert_eq!(fs::read_to_string(&p).unwrap(), "old");
        write_atomic(&p, true, |w| {
            w.write_all(b"new").map_err(|e| IoError::io("x", e))
        })
        .unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "new");
    }

    #[test]
    fn staged_dir_commits_or_vanishes() {
        let d = tempfile::tempdir().unwrap();
        let dest = d.path().join("maps");
        {
            let s = StagedDir::new(&dest, false).unwrap();
            fs::write(s.path("a.txt").unwrap(), "a").unwrap();
        }
        assert!(!dest.exists());
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 0);
        let s = StagedDir::new(&dest, false).unwrap();
        fs::write(s.path("sub/b.txt").unwrap(), "b").unwrap();
        s.commit().unwrap();
        assert_eq!(fs::read_to_string(dest.join("sub/b.txt")).unwrap(), "b");
    }

    #[test]
    fn existing_directory_is_swapped_keeping_other_files() {
        let d = tempfile::tempdir().unwrap();
        let dest = d.path().join("out");
        fs::create_dir_all(dest.join("sub")).unwrap();
        fs::write(dest.join("a.txt"), "old a").unwrap();
        fs::write(dest.join("sub/keep.txt"), "keep").unwrap();
        let s = StagedDir::new(&dest, false).unwrap();
        fs::write(s.path("a.txt").unwrap(), "new a").unwrap();
        // Without force the existing a.txt is kept and nothing is published.
        assert!(matches!(s.commit(), Err(IoError::OutputExists { .. })));
        assert_eq!(fs::read_to_string(dest.join("a.txt")).unwrap(), "old a");
        let s = StagedDir::new(&dest, true).unwrap();
        fs::write(s.path("a.txt").unwrap(), "new a").unwrap();
        fs::write(s.path("sub/b.txt").unwrap(), "b").unwrap();
        s.commit().unwrap();
        assert_eq!(fs::read_to_string(dest.join("a.txt")).unwrap(), "new a");
        assert_eq!(fs::read_to_string(dest.join("sub/b.txt")).unwrap(), "b");
        assert_eq!(
            fs::read_to_string(dest.join("sub/keep.txt")).unwrap(),
            "keep"
        );
        let names: Vec<_> = fs::read_dir(d.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "staging or old directory left behind");
    }

    #[test]
    fn dot_dot_destination_is_written_file_by_file() {
        let d = tempfile::tempdir().unwrap();
        let sub = d.path().join("sub");
        fs::create_dir_all(&sub).unwrap();
        fs::write(d.path().join("other.txt"), "x").unwrap();
        let dest = sub.join("..");
        let s = StagedDir::new(&dest, false).unwrap();
        fs::write(s.path("new.txt").unwrap(), "n").unwrap();
        s.commit().unwrap();
        assert_eq!(fs::read_to_string(d.path().join("new.txt")).unwrap(), "n");
        assert_eq!(fs::read_to_string(d.path().join("other.txt")).unwrap(), "x");
        assert_eq!(fs::read_dir(&sub).unwrap().count(), 0);
    }

    #[test]
    fn registered_staging_is_removed_and_stale_names_parsed() {
        assert_eq!(owner_pid(".polarid-staging-123-abc"), Some(123));
        assert_eq!(owner_pid(".polarid-tmp-77-x"), Some(77));
        assert_eq!(owner_pid(".polarid-staging-abc"), None);
        assert_eq!(owner_pid("polarid-staging-1-x"), None);
    }
}
