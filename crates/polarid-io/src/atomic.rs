//! Atomic outputs: every file is written to a temporary file beside its destination and
//! renamed into place only when complete, so a failed command leaves no partial output.
//! Existing outputs are kept unless the caller passes `force`; inputs are never
//! overwritten.

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
    let dir = parent_dir(path);
    let tmp = tempfile::Builder::new()
        .prefix(".polarid-tmp-")
        .tempfile_in(&dir)
        .map_err(|e| IoError::io(&dir, e))?;
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
}

/// A staging directory for commands that write several files into an output directory.
///
/// Files are created inside a hidden temporary directory next to the destination;
/// [`StagedDir::commit`] moves them into the destination (created if needed). Dropping
/// a `StagedDir` without committing removes everything it holds.
#[derive(Debug)]
pub struct StagedDir {
    dest: PathBuf,
    tmp: tempfile::TempDir,
    force: bool,
}

impl StagedDir {
    /// Prepare to write into `dest`, which must be a directory or not exist yet (an
    /// existing file of that name is an error, even with `force`: it is not replaced by
    /// a directory).
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
        let parent = parent_dir(dest);
        fs::create_dir_all(&parent).map_err(|e| IoError::io(&parent, e))?;
        let tmp = tempfile::Builder::new()
            .prefix(".polarid-staging-")
            .tempdir_in(&parent)
            .map_err(|e| IoError::io(&parent, e))?;
        Ok(Self {
            dest: dest.to_path_buf(),
            tmp,
            force,
        })
    }

    /// Path at which to write the staged file `name` (a relative path; sub-directories
    /// are created).
    pub fn path(&self, name: &str) -> Result<PathBuf> {
        let p = self.tmp.path().join(name);
        if let Some(parent) = p.parent() {
            fs::create_dir_all(parent).map_err(|e| IoError::io(parent, e))?;
        }
        Ok(p)
    }

    /// Final location of the staged file `name` once committed.
    pub fn final_path(&self, name: &str) -> PathBuf {
        self.dest.join(name)
    }

    /// Move every staged file into the destination. Fails before moving anything if a
    /// destination file exists and `force` was not given, or if a destination is a
    /// directory (which a file cannot replace).
    pub fn commit(self) -> Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        collect_files(self.tmp.path(), Path::new(""), &mut files)?;
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
        let mut out = Vec::with_capacity(files.len());
        for rel in files {
            let from = self.tmp.path().join(&rel);
            let to = self.dest.join(&rel);
            if let Some(parent) = to.parent() {
                fs::create_dir_all(parent).map_err(|e| IoError::io(parent, e))?;
            }
            fs::rename(&from, &to).map_err(|e| IoError::io(&to, e))?;
            out.push(to);
        }
        Ok(out)
    }
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
}
