//! Frames out of an MP4 held in memory, decoded by an `ffmpeg` child process.
//!
//! - **Finding ffmpeg** ([`Ffmpeg::locate`]): an explicit path (`--ffmpeg`), else the
//!   environment variable `FOGLINE_FFMPEG`, else `ffmpeg` on `PATH`, else the static build
//!   that the PyPI package `imageio-ffmpeg` ships, in a `pyenv` virtual environment next to
//!   the running executable (`target/pyenv`, what `scripts/python-peers.sh` installs) or under
//!   `./target/pyenv`. It is run once (`ffmpeg -version`) to check that it works.
//! - **Which frames** ([`frame_index`]): for a requested time, the last frame whose timestamp
//!   is at or before it (the devkit's `SeekVideoReader` rule); frame `i` of the timestamps
//!   table is the `i`-th decoded frame.
//! - **Decoding** ([`Ffmpeg::decode`]): one ffmpeg run per video keeps only the frames asked
//!   for (`select` on the decoded frame number, which means decoding every frame up to the
//!   last one asked for), resizes them (`scale`, area averaging) and writes raw RGB24 on
//!   stdout. An MP4 whose index (`moov`) comes before its data is piped on stdin; one with the
//!   index at the end cannot be read from a pipe and is written to a private temporary file
//!   (mode 0600, removed afterwards) — the one member, never the whole zip.
//! - **Checks before ffmpeg** ([`mp4_layout`]): the top-level boxes of the file (a `ftyp`
//!   first, sizes inside the file, a `moov` and an `mdat`), so that a truncated or foreign
//!   member is named as such instead of as an ffmpeg failure.

use std::ffi::OsString;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::error::{ImportError, Result};

/// The environment variable naming the ffmpeg binary.
pub const FFMPEG_ENV: &str = "FOGLINE_FFMPEG";

/// How to get ffmpeg, for error messages.
pub const FFMPEG_ADVICE: &str = "give --ffmpeg PATH or set FOGLINE_FFMPEG, put ffmpeg on PATH \
     (e.g. apt-get install ffmpeg), or run scripts/python-peers.sh, which installs the static \
     ffmpeg of the PyPI package imageio-ffmpeg into target/pyenv (docs/data.md)";

/// A working ffmpeg binary.
#[derive(Debug, Clone)]
pub struct Ffmpeg {
    path: PathBuf,
    version: String,
}

impl Ffmpeg {
    /// Finds ffmpeg (see the module's documentation for the order) and checks that it runs.
    pub fn locate(explicit: Option<&Path>) -> Result<Self> {
        let exe_dir = std::env::current_exe()
            .ok()
            .and_then(|p| p.parent().map(Path::to_path_buf));
        let path = find(
            explicit,
            std::env::var_os(FFMPEG_ENV),
            std::env::var_os("PATH"),
            exe_dir.as_deref(),
            std::env::current_dir().ok().as_deref(),
        )?;
        Self::at(&path)
    }

    /// The ffmpeg at `path`, checked by running `ffmpeg -version`.
    pub fn at(path: &Path) -> Result<Self> {
        let out = Command::new(path)
            .args(["-hide_banner", "-version"])
            .stdin(Stdio::null())
            .output()
            .map_err(|e| ImportError::Ffmpeg {
                detail: format!("cannot run {}: {e}; {FFMPEG_ADVICE}", path.display()),
            })?;
        let text = String::from_utf8_lossy(&out.stdout);
        let first = text.lines().next().unwrap_or_default().trim().to_string();
        if !out.status.success() || !first.starts_with("ffmpeg version") {
            return Err(ImportError::Ffmpeg {
                detail: format!(
                    "{} -version did not answer as ffmpeg does ({}): {FFMPEG_ADVICE}",
                    path.display(),
                    if first.is_empty() {
                        out.status.to_string()
                    } else {
                        first
                    }
                ),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
            version: first,
        })
    }

    /// The binary.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The first line of `ffmpeg -version` (`ffmpeg version 9.0.2 …`).
    pub fn version(&self) -> &str {
        &self.version
    }

    /// Decodes frames `indices` (strictly increasing decoded-frame numbers, from 0) of the
    /// MP4 `mp4`, resized to `width × height`, as RGB8 buffers in the order asked.
    /// `location` names the video in errors.
    pub fn decode(
        &self,
        location: &str,
        mp4: &[u8],
        indices: &[usize],
        width: u32,
        height: u32,
    ) -> Result<Vec<Vec<u8>>> {
        if indices.is_empty() {
            return Ok(Vec::new());
        }
        if indices.windows(2).any(|w| w[1] <= w[0]) {
            return Err(ImportError::data(
                location,
                "frame numbers to decode must be strictly increasing (a bug)",
            ));
        }
        let layout = mp4_layout(mp4).map_err(|d| ImportError::data(location, d))?;
        let select: Vec<String> = indices.iter().map(|i| format!("eq(n\\,{i})")).collect();
        let filter = format!(
            "select='{}',scale={width}:{height}:flags=area",
            select.join("+")
        );
        // A video indexed at its end is not readable from a pipe: one private temporary file.
        let temp = if layout.index_first {
            None
        } else {
            let mut f = tempfile::Builder::new()
                .prefix(".fogline-video-")
                .suffix(".mp4")
                .tempfile()
                .map_err(|e| ImportError::io(std::env::temp_dir(), e))?;
            f.write_all(mp4)
                .and_then(|()| f.flush())
                .map_err(|e| ImportError::io(f.path(), e))?;
            Some(f)
        };
        let input: OsString = match &temp {
            Some(f) => f.path().as_os_str().to_owned(),
            None => "pipe:0".into(),
        };
        let mut cmd = Command::new(&self.path);
        cmd.args([
            "-nostdin",
            "-hide_banner",
            "-loglevel",
            "error",
            "-threads",
            "1",
        ])
        .arg("-i")
        .arg(&input)
        .args(["-map", "0:v:0", "-an", "-sn", "-dn", "-vf", &filter])
        .args(["-fps_mode", "passthrough", "-frames:v"])
        .arg(indices.len().to_string())
        .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "pipe:1"])
        .stdin(if temp.is_some() {
            Stdio::null()
        } else {
            Stdio::piped()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
        let mut child = cmd.spawn().map_err(|e| ImportError::Ffmpeg {
            detail: format!("cannot start {}: {e}", self.path.display()),
        })?;
        let stdin = child.stdin.take();
        let out = std::thread::scope(|s| {
            if let Some(mut stdin) = stdin {
                // ffmpeg stops reading once it has its frames: a broken pipe is expected.
                s.spawn(move || {
                    let _ = stdin.write_all(mp4);
                });
            }
            child.wait_with_output()
        })
        .map_err(|e| ImportError::Ffmpeg {
            detail: format!(
                "{} failed while decoding {location}: {e}",
                self.path.display()
            ),
        })?;
        drop(temp);
        let stderr = String::from_utf8_lossy(&out.stderr);
        let said = stderr
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .take(3)
            .collect::<Vec<_>>()
            .join(" | ");
        let frame_len = width as usize * height as usize * 3;
        let got = out.stdout.len() / frame_len;
        if !out.status.success() || out.stdout.len() != frame_len * indices.len() {
            return Err(ImportError::data(
                location,
                format!(
                    "ffmpeg decoded {got} of the {} frames asked for (frame numbers {}; exit \
                     status {}){}",
                    indices.len(),
                    brief(indices),
                    out.status,
                    if said.is_empty() {
                        " — the video has fewer frames than its timestamps list".to_string()
                    } else {
                        format!(": {said}")
                    }
                ),
            ));
        }
        if !said.is_empty() {
            log::warn!("{location}: ffmpeg reported problems while decoding: {said}");
        }
        Ok(out
            .stdout
            .chunks_exact(frame_len)
            .map(<[u8]>::to_vec)
            .collect())
    }
}

fn brief(v: &[usize]) -> String {
    let s: Vec<String> = v.iter().take(8).map(usize::to_string).collect();
    if v.len() > 8 {
        format!("{}, …", s.join(", "))
    } else {
        s.join(", ")
    }
}

/// Where ffmpeg is: `explicit`, else `env` (`FOGLINE_FFMPEG`), else `ffmpeg` in a directory
/// of `path_var`, else imageio-ffmpeg's binary in a `pyenv` beside `exe_dir` or one of its
/// three parents, or in `cwd/target/pyenv`.
fn find(
    explicit: Option<&Path>,
    env: Option<OsString>,
    path_var: Option<OsString>,
    exe_dir: Option<&Path>,
    cwd: Option<&Path>,
) -> Result<PathBuf> {
    let not_found = |what: String| ImportError::Ffmpeg {
        detail: format!("{what}; {FFMPEG_ADVICE}"),
    };
    if let Some(p) = explicit {
        return if p.is_file() {
            Ok(p.to_path_buf())
        } else {
            Err(not_found(format!("--ffmpeg {} is not a file", p.display())))
        };
    }
    if let Some(p) = env.filter(|v| !v.is_empty()) {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(not_found(format!(
                "{FFMPEG_ENV}={} is not a file",
                p.display()
            )))
        };
    }
    if let Some(var) = path_var {
        for dir in std::env::split_paths(&var) {
            let p = dir.join("ffmpeg");
            if is_executable(&p) {
                return Ok(p);
            }
        }
    }
    let mut envs: Vec<PathBuf> = exe_dir
        .into_iter()
        .flat_map(|d| d.ancestors().take(4))
        .map(|d| d.join("pyenv"))
        .collect();
    envs.extend(cwd.map(|d| d.join("target").join("pyenv")));
    for env in envs {
        if let Some(p) = imageio_ffmpeg_in(&env) {
            return Ok(p);
        }
    }
    Err(not_found("no ffmpeg found".into()))
}

/// imageio-ffmpeg's binary (`lib/python3.*/site-packages/imageio_ffmpeg/binaries/ffmpeg-*`)
/// in the virtual environment `venv`; the last in name order when there are several.
fn imageio_ffmpeg_in(venv: &Path) -> Option<PathBuf> {
    let lib = std::fs::read_dir(venv.join("lib")).ok()?;
    let mut found: Vec<PathBuf> = Vec::new();
    for py in lib.flatten() {
        let bin = py
            .path()
            .join("site-packages")
            .join("imageio_ffmpeg")
            .join("binaries");
        let Ok(entries) = std::fs::read_dir(&bin) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with("ffmpeg-")
                && !name.ends_with(".py")
                && !name.ends_with(".md")
                && is_executable(&p)
            {
                found.push(p);
            }
        }
    }
    found.sort();
    found.pop()
}

fn is_executable(p: &Path) -> bool {
    let Ok(meta) = std::fs::metadata(p) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        meta.is_file() && meta.permissions().mode() & 0o111 != 0
    }
    #[cfg(not(unix))]
    {
        meta.is_file()
    }
}

/// What the top-level boxes of an MP4 say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mp4Layout {
    /// The index (`moov`) comes before the media data (`mdat`): readable from a pipe.
    pub index_first: bool,
}

/// Walks the top-level boxes of an MP4 file; `Err` says why it is not a complete MP4.
pub fn mp4_layout(b: &[u8]) -> std::result::Result<Mp4Layout, String> {
    let mut off = 0usize;
    let (mut moov, mut mdat) = (None, None);
    while off < b.len() {
        let rest = b.len() - off;
        if rest < 8 {
            return Err(format!(
                "truncated MP4: {rest} stray byte(s) after the last box, at offset {off}"
            ));
        }
        let size32 = u32::from_be_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]]);
        let kind = &b[off + 4..off + 8];
        if !kind.iter().all(|c| c.is_ascii_alphanumeric() || *c == b' ') {
            return Err(format!(
                "not an MP4 file: no box at offset {off} (bytes {:02x?})",
                &b[off..off + 8]
            ));
        }
        let name = String::from_utf8_lossy(kind).into_owned();
        if off == 0 && name != "ftyp" {
            return Err(format!(
                "not an MP4 file: it starts with a `{name}` box, not `ftyp`"
            ));
        }
        let (header, size) = match size32 {
            0 => (8u64, rest as u64),
            1 => {
                if rest < 16 {
                    return Err(format!("truncated MP4: box `{name}` at offset {off}"));
                }
                let mut s = [0u8; 8];
                s.copy_from_slice(&b[off + 8..off + 16]);
                (16, u64::from_be_bytes(s))
            }
            s => (8, u64::from(s)),
        };
        if size < header {
            return Err(format!(
                "box `{name}` at offset {off} has an invalid size of {size} bytes"
            ));
        }
        if size > rest as u64 {
            return Err(format!(
                "truncated MP4: box `{name}` at offset {off} needs {size} bytes, {rest} remain"
            ));
        }
        match name.as_str() {
            "moov" => moov = moov.or(Some(off)),
            "mdat" => mdat = mdat.or(Some(off)),
            _ => {}
        }
        off += size as usize;
    }
    match (moov, mdat) {
        (Some(m), Some(d)) => Ok(Mp4Layout { index_first: m < d }),
        (None, _) if b.is_empty() => Err("an empty file, not an MP4".into()),
        (None, _) => Err("no `moov` box (the video's index): not a complete MP4".into()),
        (Some(_), None) => Err("no `mdat` box (the video's data): not a complete MP4".into()),
    }
}

/// The frame shown at `t_us`: the last frame whose timestamp is at or before it, or `None`
/// when `t_us` lies outside `[first, last]` (the devkit refuses those too). `timestamps_us`
/// strictly increasing.
pub fn frame_index(timestamps_us: &[i64], t_us: i64) -> Option<usize> {
    let (first, last) = (timestamps_us.first()?, timestamps_us.last()?);
    if t_us < *first || t_us > *last {
        return None;
    }
    Some(timestamps_us.partition_point(|&t| t <= t_us) - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mp4_box(kind: &[u8; 4], body: usize) -> Vec<u8> {
        let mut v = ((body + 8) as u32).to_be_bytes().to_vec();
        v.extend_from_slice(kind);
        v.extend(std::iter::repeat_n(0u8, body));
        v
    }

    #[test]
    fn top_level_boxes() {
        let (ftyp, moov, mdat) = (
            mp4_box(b"ftyp", 16),
            mp4_box(b"moov", 40),
            mp4_box(b"mdat", 100),
        );
        let fast = [ftyp.clone(), moov.clone(), mdat.clone()].concat();
        assert_eq!(mp4_layout(&fast), Ok(Mp4Layout { index_first: true }));
        let slow = [ftyp.clone(), mdat.clone(), moov.clone()].concat();
        assert_eq!(mp4_layout(&slow), Ok(Mp4Layout { index_first: false }));
        let e = mp4_layout(&slow[..slow.len() - 3]).unwrap_err();
        assert!(e.contains("truncated MP4: box `moov`"), "{e}");
        let e = mp4_layout(&[ftyp.clone(), mdat.clone()].concat()).unwrap_err();
        assert!(e.contains("no `moov`"), "{e}");
        let e = mp4_layout(&[moov.clone(), mdat.clone()].concat()).unwrap_err();
        assert!(e.contains("starts with a `moov` box"), "{e}");
        let e = mp4_layout(b"PK\x03\x04 this is a zip").unwrap_err();
        assert!(e.contains("not an MP4 file"), "{e}");
        assert!(mp4_layout(b"").unwrap_err().contains("empty"));
        // A 64-bit size, and a size of 0 (to the end of the file).
        let mut big = 1u32.to_be_bytes().to_vec();
        big.extend_from_slice(b"mdat");
        big.extend_from_slice(&24u64.to_be_bytes());
        big.extend([0u8; 8]);
        let mut last = 0u32.to_be_bytes().to_vec();
        last.extend_from_slice(b"free");
        last.extend([0u8; 5]);
        let ok = [ftyp, moov, big, last].concat();
        assert_eq!(mp4_layout(&ok), Ok(Mp4Layout { index_first: true }));
    }

    #[test]
    fn frame_at_or_before() {
        let ts = [100, 133, 166, 200];
        assert_eq!(frame_index(&ts, 100), Some(0));
        assert_eq!(frame_index(&ts, 165), Some(1));
        assert_eq!(frame_index(&ts, 166), Some(2));
        assert_eq!(frame_index(&ts, 200), Some(3));
        assert_eq!(frame_index(&ts, 99), None);
        assert_eq!(frame_index(&ts, 201), None);
        assert_eq!(frame_index(&[], 0), None);
    }

    #[test]
    fn finding_ffmpeg() {
        let dir = tempfile::tempdir().unwrap();
        let exe = |p: &Path| {
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"#!/bin/sh\n").unwrap();
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt as _;
                std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755)).unwrap();
            }
        };
        // imageio-ffmpeg's binary in target/pyenv, two levels above target/debug/deps.
        let bin = dir
            .path()
            .join("target/pyenv/lib/python3.11/site-packages/imageio_ffmpeg/binaries");
        exe(&bin.join("ffmpeg-linux-x86_64-v9.0.2"));
        std::fs::write(bin.join("__init__.py"), b"").unwrap();
        let deps = dir.path().join("target/debug/deps");
        std::fs::create_dir_all(&deps).unwrap();
        let found = find(None, None, None, Some(&deps), None).unwrap();
        assert!(found.ends_with("ffmpeg-linux-x86_64-v9.0.2"), "{found:?}");
        // …or under the working directory's target/pyenv.
        let found = find(None, None, None, None, Some(dir.path())).unwrap();
        assert!(found.ends_with("ffmpeg-linux-x86_64-v9.0.2"), "{found:?}");
        // PATH comes first, the environment variable before it, an explicit path first of all.
        exe(&dir.path().join("bin/ffmpeg"));
        let path = Some(OsString::from(dir.path().join("bin")));
        let found = find(None, None, path.clone(), Some(&deps), None).unwrap();
        assert_eq!(found, dir.path().join("bin/ffmpeg"));
        let env = Some(OsString::from(bin.join("__init__.py")));
        assert_eq!(
            find(None, env, path.clone(), None, None).unwrap(),
            bin.join("__init__.py")
        );
        let e = find(
            Some(Path::new("/nonexistent/ffmpeg")),
            None,
            path,
            None,
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("--ffmpeg /nonexistent/ffmpeg is not a file"),
            "{e}"
        );
        let e = find(None, Some("/no/such".into()), None, None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("FOGLINE_FFMPEG=/no/such"), "{e}");
        let e = find(None, None, None, None, None).unwrap_err().to_string();
        assert!(
            e.contains("no ffmpeg found") && e.contains("scripts/python-peers.sh"),
            "{e}"
        );
    }
}
