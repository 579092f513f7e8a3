//! Resource limits: the memory budget of a run and capped reading of input files
//! (`docs/RELIABILITY.md`).
//!
//! - **Memory budget** ([`memory_limit`], default [`DEFAULT_MEMORY_LIMIT`] = 4 GiB,
//!   raised or lowered with `--memory-limit` or [`MEMORY_LIMIT_ENV`]). Before a frame is
//!   decoded its cost is estimated from its header, `pixels × (stored bytes per sample +
//!   4 × frames in flight + the command's bytes per pixel)` ([`work_per_pixel`]: the
//!   Stokes, DoLP and view planes a command keeps per input pixel), and a frame over the
//!   budget is refused before anything is allocated ([`IoError::TooLarge`]).
//! - **Decompression bombs**: a compressed frame that would expand more than
//!   [`MAX_EXPANSION`] times its file size (beyond what deflate or LZW give on any real
//!   image) into more than [`EXPANSION_FLOOR`] bytes is refused too.
//! - **Capped reads** ([`read_capped`], [`read_text`]): inputs must be regular files or
//!   streams — a FIFO (a named pipe, `/dev/stdin` fed by a shell pipe) or [`STDIN`]
//!   (`-`, standard input) — (`/dev/zero`, sockets, other devices and directories are
//!   refused, [`IoError::NotRegular`]) and are read with a size cap: images up to the
//!   budget, text files (CSV, JSON, TOML, YAML) up to [`text_cap`] = budget / 16
//!   (256 MiB by default). A stream's size is not known in advance: it is read up to
//!   the cap and refused ([`IoError::TooLarge`]) as soon as it holds more. Reading a
//!   named pipe waits for its writer, as every Unix tool does.

use std::io::Read;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{IoError, Result};

/// Default memory budget of a run, in bytes (4 GiB).
pub const DEFAULT_MEMORY_LIMIT: u64 = 4 << 30;

/// Environment variable that sets the memory budget (same syntax as `--memory-limit`,
/// e.g. `8G`, `512M`, `1073741824`).
pub const MEMORY_LIMIT_ENV: &str = "POLARID_MEMORY_LIMIT";

/// Largest expansion ratio (decoded bytes / file bytes) of a compressed frame: deflate
/// cannot exceed about 1032:1 on one stream and LZW about 1300:1, so a larger ratio
/// means blocks reused by several strips (a decompression bomb).
pub const MAX_EXPANSION: u64 = 4096;

/// Frames decoding to fewer bytes than this are never refused for their expansion
/// ratio (64 MiB).
pub const EXPANSION_FLOOR: u64 = 64 << 20;

/// Smallest budget accepted (16 MiB): below it no command can run.
pub const MIN_MEMORY_LIMIT: u64 = 16 << 20;

static LIMIT: AtomicU64 = AtomicU64::new(DEFAULT_MEMORY_LIMIT);
static WORK: AtomicU64 = AtomicU64::new(0);

/// The memory budget of this run, in bytes.
pub fn memory_limit() -> u64 {
    LIMIT.load(Ordering::Relaxed)
}

/// Set the memory budget of this run (process-wide), at least [`MIN_MEMORY_LIMIT`].
pub fn set_memory_limit(bytes: u64) {
    LIMIT.store(bytes.max(MIN_MEMORY_LIMIT), Ordering::Relaxed);
}

/// Bytes the running command keeps per pixel of an input frame besides the frame
/// itself (Stokes planes, DoLP and AoLP, masks, views): part of a frame's cost.
pub fn work_per_pixel() -> u64 {
    WORK.load(Ordering::Relaxed)
}

/// Set [`work_per_pixel`] for the running command (process-wide).
pub fn set_work_per_pixel(bytes: u64) {
    WORK.store(bytes, Ordering::Relaxed);
}

/// Largest text input (CSV, JSON, TOML, YAML) read: a sixteenth of the budget (the
/// parsed tables take several times their text), at least 1 MiB.
pub fn text_cap() -> u64 {
    (memory_limit() / 16).max(1 << 20)
}

/// Parse a size: a number of bytes with an optional unit `K`, `M`, `G`, `T` (powers
/// of 1024; `KB`/`KiB`, ... and lower case accepted), e.g. `4G`, `1.5GiB`, `512m`.
pub fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let unit = unit.trim().to_ascii_lowercase();
    let scale: u64 = match unit.trim_end_matches("ib").trim_end_matches('b') {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => {
            return Err(format!(
                "unknown unit `{}` (use a number of bytes with K, M, G or T)",
                short(&unit)
            ));
        }
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("not a size: `{}` (e.g. 4G, 512M)", short(t)))?;
    let bytes = v * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < 1.8e19) {
        return Err(format!("size out of range: `{}`", short(t)));
    }
    Ok(bytes as u64)
}

/// `s` shortened to at most 60 characters for an error message (an ellipsis and the
/// total length mark a cut).
pub fn short(s: &str) -> String {
    const MAX: usize = 60;
    let n = s.chars().count();
    if n <= MAX {
        s.to_string()
    } else {
        let head: String = s.chars().take(MAX - 20).collect();
        format!("{head}... ({n} characters)")
    }
}

/// A byte count for messages (defined beside the errors that print it).
pub use crate::error::human;

/// Error unless `need` bytes (to do `what` with `path`) fit in the budget.
pub fn check_budget(path: &Path, what: &str, need: u64) -> Result<()> {
    let limit = memory_limit();
    if need > limit {
        return Err(IoError::TooLarge {
            path: path.to_path_buf(),
            what: format!("{what} needs about {}", human(need)),
            limit,
        });
    }
    Ok(())
}

/// The path that means standard input for the readers ([`read_capped`], and so
/// [`read_text`] and the CSV tables): `-`.
pub const STDIN: &str = "-";

/// True when `path` is [`STDIN`] (`-`).
pub fn is_stdin(path: &Path) -> bool {
    path.as_os_str() == STDIN
}

/// Error unless `path` can be read as an input: `Some(size)` for a regular file (after
/// following symbolic links), `None` for a stream (a FIFO: a named pipe, or
/// `/dev/stdin` when standard input is a pipe), whose size is not known in advance.
/// `/dev/zero` and other devices, sockets and directories are refused.
pub fn check_readable(path: &Path) -> Result<Option<u64>> {
    let md = std::fs::metadata(path).map_err(|e| IoError::io(path, e))?;
    if is_fifo(&md.file_type()) {
        return Ok(None);
    }
    check_regular(path).map(Some)
}

#[cfg(unix)]
fn is_fifo(ft: &std::fs::FileType) -> bool {
    use std::os::unix::fs::FileTypeExt;
    ft.is_fifo()
}

#[cfg(not(unix))]
fn is_fifo(_ft: &std::fs::FileType) -> bool {
    false
}

/// Error unless `path` is a regular file (after following symbolic links): `/dev/zero`,
/// FIFOs, sockets, devices and directories are refused. Returns its size in bytes.
pub fn check_regular(path: &Path) -> Result<u64> {
    let md = std::fs::metadata(path).map_err(|e| IoError::io(path, e))?;
    let ft = md.file_type();
    if ft.is_file() {
        return Ok(md.len());
    }
    let kind = if ft.is_dir() {
        "a directory"
    } else {
        special_kind(&ft)
    };
    Err(IoError::NotRegular {
        path: path.to_path_buf(),
        kind,
    })
}

#[cfg(unix)]
fn special_kind(ft: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_fifo() {
        "a FIFO (named pipe)"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

#[cfg(not(unix))]
fn special_kind(_ft: &std::fs::FileType) -> &'static str {
    "not a regular file"
}

/// Read the input `path` (a `what`, e.g. `image`): a regular file, a FIFO, or standard
/// input when `path` is [`STDIN`] (`-`); refused when it holds more than `cap` bytes
/// (checked from a file's size, and again while reading, in case it grows; a stream is
/// read up to `cap + 1` bytes and refused then).
pub fn read_capped(path: &Path, cap: u64, what: &str) -> Result<Vec<u8>> {
    let too_big = |size: String| IoError::TooLarge {
        path: path.to_path_buf(),
        what: format!("{what} input of {size}, more than the {} read", human(cap)),
        limit: memory_limit(),
    };
    let mut out = Vec::new();
    if is_stdin(path) {
        std::io::stdin()
            .lock()
            .take(cap.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|e| IoError::io("<stdin>", e))?;
    } else {
        let len = check_readable(path)?;
        if let Some(len) = len {
            if len > cap {
                return Err(too_big(human(len)));
            }
            out.reserve(usize::try_from(len).unwrap_or(0));
        }
        let f = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
        f.take(cap.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|e| IoError::io(path, e))?;
    }
    if out.len() as u64 > cap {
        return Err(too_big(format!("more than {}", human(cap))));
    }
    Ok(out)
}

/// Read a text input (CSV, JSON, TOML, YAML) of at most [`text_cap`] bytes as UTF-8,
/// without a leading byte-order mark.
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read_capped(path, text_cap(), "text")?;
    let text = String::from_utf8(bytes).map_err(|e| {
        IoError::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
            ),
        )
    })?;
    Ok(strip_bom(text))
}

/// `text` without a leading UTF-8 byte-order mark.
pub fn strip_bom(text: String) -> String {
    match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("4G").unwrap(), 4 << 30);
        assert_eq!(parse_size("512m").unwrap(), 512 << 20);
        assert_eq!(parse_size("1.5GiB").unwrap(), 3 << 29);
        assert_eq!(parse_size("1000").unwrap(), 1000);
        assert_eq!(parse_size("2 KB").unwrap(), 2048);
        assert!(parse_size("4X").is_err());
        assert!(parse_size("-1").is_err());
        assert!(parse_size("").is_err());
        assert!(parse_size("1e400").is_err());
    }

    #[test]
    fn short_cuts_long_values() {
        assert_eq!(short("abc"), "abc");
        let long = "9".repeat(309);
        let s = short(&long);
        assert!(s.len() < 70 && s.ends_with("(309 characters)"), "{s}");
    }

    #[cfg(unix)]
    #[test]
    fn fifos_are_read_to_their_end_within_the_cap() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&p).status();
        if !made.is_ok_and(|s| s.success()) {
            return;
        }
        assert_eq!(check_readable(&p).unwrap(), None);
        let w = {
            let p = p.clone();
            std::thread::spawn(move || std::fs::write(&p, vec![b'x'; 3000]).unwrap())
        };
        assert_eq!(read_capped(&p, 4000, "text").unwrap().len(), 3000);
        w.join().unwrap();
        // Over the cap: refused once more than the cap has arrived.
        let w = {
            let p = p.clone();
            std::thread::spawn(move || {
                // The reader stops at cap + 1 bytes: the writer may see a closed pipe.
                let _ = std::fs::write(&p, vec![b'x'; 5000]);
            })
        };
        let e = read_capped(&p, 4000, "text").unwrap_err();
        assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
        w.join().unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_refused() {
        let e = read_text(Path::new("/dev/zero")).unwrap_err();
        assert!(matches!(e, IoError::NotRegular { .. }), "{e}");
        assert!(e.to_string().contains("character device"), "{e}");
        let d = tempfile::tempdir().unwrap();
        let e = read_text(d.path()).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
        let p = d.path().join("big.csv");
        std::fs::write(&p, vec![b'a'; 3 << 20]).unwrap();
        assert_eq!(read_capped(&p, 4 << 20, "text").unwrap().len(), 3 << 20);
        let e = read_capped(&p, 1 << 20, "text").unwrap_err();
        assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
    }

    #[test]
    fn bom_is_stripped() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("m.json");
        std::fs::write(&p, "\u{feff}{}").unwrap();
        assert_eq!(read_text(&p).unwrap(), "{}");
    }
}
