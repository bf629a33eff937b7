//! Atomic file writes: a reader sees the old file or the new one, never half of one.
//!
//! The content goes to a temporary file in the target's directory (so the rename stays on one
//! file system), is flushed and `fsync`ed, then renamed over the target; on Unix the
//! directory is synced too, so the rename survives a power cut. On any failure the temporary
//! file is removed and the previous file is left in place.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `bytes` to `path` atomically (see the module documentation).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// [`write_atomic`] for content streamed by `fill` into a buffered writer. An error names
/// `path`.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = dir.join(format!(
        ".{name}.tmp-{}-{}",
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ));
    let res = (|| -> std::io::Result<()> {
        let mut w = BufWriter::with_capacity(1 << 20, File::create(&tmp)?);
        fill(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)?;
        #[cfg(unix)]
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    if let Err(e) = res {
        let _ = std::fs::remove_file(&tmp);
        let kind = e.kind();
        return Err(std::io::Error::new(
            kind,
            WriteError {
                path: path.to_path_buf(),
                source: e,
            },
        ));
    }
    Ok(())
}

/// What an atomic write's error carries: the file and the underlying error (displayed as
/// `cannot write PATH: ERROR`; [`WriteError::of`] recovers it from an `io::Error`).
#[derive(Debug)]
pub struct WriteError {
    /// The file that was being written.
    pub path: std::path::PathBuf,
    /// What went wrong.
    pub source: std::io::Error,
}

impl WriteError {
    /// The write error inside an error returned by [`write_atomic`] or
    /// [`write_atomic_with`].
    pub fn of(e: &std::io::Error) -> Option<&WriteError> {
        e.get_ref()
            .and_then(|inner| inner.downcast_ref::<WriteError>())
    }
}

impl std::fmt::Display for WriteError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot write {}: {}", self.path.display(), self.source)
    }
}

impl std::error::Error for WriteError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.json");
        write_atomic(&path, b"first").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"first");
        let err = write_atomic_with(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("out.json") && err.to_string().contains("disk on fire"));
        let inner = WriteError::of(&err).unwrap();
        assert_eq!(
            (inner.path.as_path(), inner.source.to_string().as_str()),
            (path.as_path(), "disk on fire")
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"first");
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "a temporary file was left behind");
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        // A missing directory is an error naming the file.
        let err = write_atomic(&dir.path().join("no/such/dir/x"), b"x").unwrap_err();
        assert!(err.to_string().contains("no/such/dir/x"), "{err}");
    }
}
