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

/// A set of files replaced together: all of them or none.
///
/// Each file's new content is written to a temporary file beside its target and synced as it
/// is staged ([`FileSet::write`], [`FileSet::write_with`]), or an already-written file is
/// adopted ([`FileSet::adopt`], [`FileSet::adopt_dir`]); nothing visible changes until
/// [`FileSet::commit`]. Commit moves each existing target aside, renames the new file into
/// place, and on any failure puts every target back as it was. A set dropped without commit
/// removes its temporary files (adopted files stay where they were). What a commit cannot
/// make atomic is a kill or a power cut in the middle of its renames (microseconds after
/// every byte is on disk): then the directory holds some new files and the old ones moved
/// aside under `.NAME.old-*`.
///
/// ```
/// # fn main() -> std::io::Result<()> {
/// let dir = std::env::temp_dir().join(format!("fileset-doc-{}", std::process::id()));
/// let mut set = fogline_io::FileSet::new();
/// set.write(&dir.join("summary.json"), b"{}")?;
/// set.write(&dir.join("report.md"), b"# Report")?;
/// assert!(!dir.join("summary.json").exists()); // nothing visible before the commit
/// set.commit()?;
/// assert_eq!(std::fs::read(dir.join("report.md"))?, b"# Report");
/// # std::fs::remove_dir_all(&dir)?;
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Default)]
pub struct FileSet {
    entries: Vec<Entry>,
}

#[derive(Debug)]
struct Entry {
    target: std::path::PathBuf,
    source: std::path::PathBuf,
    /// A temporary file of this set (removed if the set is dropped), or an adopted file.
    owned: bool,
}

fn dir_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

fn sibling(path: &Path, tag: &str) -> std::path::PathBuf {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    dir_of(path).join(format!(
        ".{name}.{tag}-{}-{}",
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ))
}

fn named(path: &Path, source: std::io::Error) -> std::io::Error {
    std::io::Error::new(
        source.kind(),
        WriteError {
            path: path.to_path_buf(),
            source,
        },
    )
}

impl FileSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Stages `bytes` as the new content of `target` (its directory is created if needed).
    pub fn write(&mut self, target: &Path, bytes: &[u8]) -> std::io::Result<()> {
        self.write_with(target, |w| w.write_all(bytes))
    }

    /// Stages the content `fill` streams as the new content of `target`. An error names
    /// `target`; the set keeps what was staged before it.
    pub fn write_with(
        &mut self,
        target: &Path,
        fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        let dir = dir_of(target);
        std::fs::create_dir_all(dir).map_err(|e| named(target, e))?;
        let tmp = sibling(target, "tmp");
        let res = (|| -> std::io::Result<()> {
            let mut w = BufWriter::with_capacity(1 << 20, File::create(&tmp)?);
            fill(&mut w)?;
            let f = w.into_inner().map_err(|e| e.into_error())?;
            f.sync_all()
        })();
        if let Err(e) = res {
            let _ = std::fs::remove_file(&tmp);
            return Err(named(target, e));
        }
        self.entries.push(Entry {
            target: target.to_path_buf(),
            source: tmp,
            owned: true,
        });
        Ok(())
    }

    /// Adds the already-written file `staged` (on the same file system as `target`), to be
    /// moved to `target` on commit; if the commit fails it is moved back.
    pub fn adopt(&mut self, staged: &Path, target: &Path) {
        self.entries.push(Entry {
            target: target.to_path_buf(),
            source: staged.to_path_buf(),
            owned: false,
        });
    }

    /// [`FileSet::adopt`] for every file under the directory `staged`, each to the same
    /// relative path under `target`.
    pub fn adopt_dir(&mut self, staged: &Path, target: &Path) -> std::io::Result<()> {
        let mut entries: Vec<_> = std::fs::read_dir(staged)
            .map_err(|e| named(staged, e))?
            .collect::<std::io::Result<_>>()
            .map_err(|e| named(staged, e))?;
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let (from, to) = (e.path(), target.join(e.file_name()));
            if e.file_type().map_err(|err| named(&from, err))?.is_dir() {
                self.adopt_dir(&from, &to)?;
            } else {
                self.adopt(&from, &to);
            }
        }
        Ok(())
    }

    /// The targets, in the order they were added.
    pub fn targets(&self) -> impl Iterator<Item = &Path> {
        self.entries.iter().map(|e| e.target.as_path())
    }

    /// Replaces every target with its new file, or, on failure, leaves every target as it was
    /// and returns the error naming the file that failed.
    pub fn commit(mut self) -> std::io::Result<()> {
        let entries = std::mem::take(&mut self.entries);
        // Checked before anything moves: a directory in a file's place cannot be swapped.
        if let Some(e) = entries.iter().find(|e| e.target.is_dir()) {
            let err = named(
                &e.target,
                std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory is in the way",
                ),
            );
            self.entries = entries;
            return Err(err);
        }
        // (entry, the old target moved aside) for every entry already in place.
        let mut done: Vec<(&Entry, Option<std::path::PathBuf>)> = Vec::new();
        let mut failure = None;
        for e in &entries {
            let step = (|| -> std::io::Result<Option<std::path::PathBuf>> {
                std::fs::create_dir_all(dir_of(&e.target))?;
                let aside = if e.target.exists() {
                    let old = sibling(&e.target, "old");
                    std::fs::rename(&e.target, &old)?;
                    Some(old)
                } else {
                    None
                };
                if let Err(err) = std::fs::rename(&e.source, &e.target) {
                    if let Some(old) = &aside {
                        let _ = std::fs::rename(old, &e.target);
                    }
                    return Err(err);
                }
                Ok(aside)
            })();
            match step {
                Ok(aside) => done.push((e, aside)),
                Err(err) => {
                    failure = Some(named(&e.target, err));
                    break;
                }
            }
        }
        if let Some(err) = failure {
            for (e, aside) in done.into_iter().rev() {
                let _ = std::fs::rename(&e.target, &e.source);
                if let Some(old) = aside {
                    let _ = std::fs::rename(&old, &e.target);
                }
            }
            self.entries = entries;
            return Err(err);
        }
        // Each directory synced once (a set: a set of many files in many directories
        // would make a list search quadratic).
        let mut dirs: std::collections::BTreeSet<&Path> = std::collections::BTreeSet::new();
        for (e, aside) in &done {
            if let Some(old) = aside {
                let _ = std::fs::remove_file(old);
            }
            dirs.insert(dir_of(&e.target));
        }
        #[cfg(unix)]
        for d in dirs {
            if let Ok(f) = File::open(d) {
                let _ = f.sync_all();
            }
        }
        Ok(())
    }
}

impl Drop for FileSet {
    fn drop(&mut self) {
        for e in self.entries.iter().filter(|e| e.owned) {
            let _ = std::fs::remove_file(&e.source);
        }
    }
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

    fn listing(dir: &Path) -> Vec<(String, String)> {
        let mut v: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                let name = e.file_name().to_string_lossy().into_owned();
                let body = std::fs::read_to_string(e.path()).unwrap_or_else(|_| "<dir>".into());
                (name, body)
            })
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_file_set_replaces_all_its_files_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let (a, b, c) = (d.join("a.json"), d.join("b.md"), d.join("sub/c.html"));
        for (p, body) in [(&a, "old a"), (&b, "old b")] {
            write_atomic(p, body.as_bytes()).unwrap();
        }
        // Staged files are invisible until the commit.
        let mut set = FileSet::new();
        set.write(&a, b"new a").unwrap();
        set.write_with(&b, |w| w.write_all(b"new b")).unwrap();
        set.write(&c, b"new c").unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        set.commit().unwrap();
        assert_eq!(
            listing(d),
            [
                ("a.json".into(), "new a".into()),
                ("b.md".into(), "new b".into()),
                ("sub".into(), "<dir>".into())
            ]
        );
        assert_eq!(std::fs::read_to_string(&c).unwrap(), "new c");

        // A directory where the last file goes: nothing moves, no temporary is left.
        std::fs::remove_file(&c).unwrap();
        std::fs::create_dir(&c).unwrap();
        let before = listing(d);
        let mut set = FileSet::new();
        set.write(&a, b"newer a").unwrap();
        set.write(&b, b"newer b").unwrap();
        set.write(&c, b"newer c").unwrap();
        let err = set.commit().unwrap_err();
        assert!(err.to_string().contains("c.html"), "{err}");
        assert_eq!(listing(d), before);
        assert_eq!(listing(&d.join("sub")), [("c.html".into(), "<dir>".into())]);

        // A rename that fails half-way (the third file's source is gone): the two already
        // in place are rolled back, the adopted file goes back where it was.
        let staged = tempfile::tempdir_in(d).unwrap();
        let s1 = staged.path().join("a.json");
        std::fs::write(&s1, "adopted a").unwrap();
        let mut set = FileSet::new();
        set.adopt(&s1, &a);
        set.write(&b, b"newest b").unwrap();
        set.adopt(&staged.path().join("missing"), &d.join("m.txt"));
        let err = set.commit().unwrap_err();
        assert!(err.to_string().contains("m.txt"), "{err}");
        assert_eq!(
            listing(d).len(),
            before.len() + 1,
            "only the staging dir is new"
        );
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(std::fs::read_to_string(&s1).unwrap(), "adopted a");

        // A set dropped without commit leaves nothing behind.
        let mut set = FileSet::new();
        set.write(&d.join("x"), b"x").unwrap();
        drop(set);
        assert_eq!(listing(d).len(), before.len() + 1);

        // A whole directory adopted.
        std::fs::create_dir(staged.path().join("deep")).unwrap();
        std::fs::write(staged.path().join("deep/z.txt"), "z").unwrap();
        let mut set = FileSet::new();
        set.adopt_dir(staged.path(), &d.join("out")).unwrap();
        set.commit().unwrap();
        assert_eq!(
            std::fs::read_to_string(d.join("out/a.json")).unwrap(),
            "adopted a"
        );
        assert_eq!(
            std::fs::read_to_string(d.join("out/deep/z.txt")).unwrap(),
            "z"
        );
    }
}
