//! Benchmarks of fogline: the engines behind `fogline bench` ([`perturb`], [`campaign`], [`world`], [`monitor`], [`monitor_eval`], [`guard`], [`embed`]) and `fogline rco bench` ([`rco`]) and
//! the envelope pipeline against its Python peer (`benches/envelope.rs`, this crate's README).
//!
//! Each engine takes its options and writes its report to a writer (the CLI passes stdout).
//! The crate also holds the small helpers the benchmarks share: a temporary directory that
//! removes itself, the process's peak resident memory from `/proc/self/status`, and robust
//! summaries of repeated timings.
//!
//! ```
//! let mut ms = vec![3.0, 1.0, 2.0];
//! assert_eq!(fogline_bench::median(&mut ms), 2.0);
//! ```

pub mod campaign;
pub mod embed;
pub mod guard;
pub mod monitor;
pub mod monitor_eval;
pub mod perturb;
pub mod rco;
pub mod world;

use std::path::{Path, PathBuf};

/// A directory under the system temp dir, removed (with its contents) when dropped.
#[derive(Debug)]
pub struct TempDir {
    path: PathBuf,
}

impl TempDir {
    /// Creates `<temp>/fogline-bench-<pid>-<tag>`.
    pub fn new(tag: &str) -> std::io::Result<Self> {
        let path = std::env::temp_dir().join(format!("fogline-bench-{}-{tag}", std::process::id()));
        std::fs::create_dir_all(&path)?;
        Ok(Self { path })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// One `kB` field of `/proc/self/status` (e.g. `VmHWM`), in MB (10^6 bytes); None where
/// `/proc` is unavailable.
pub fn proc_status_mb(field: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status
        .lines()
        .find(|l| l.starts_with(field) && l[field.len()..].starts_with(':'))?;
    let kb: f64 = line[field.len() + 1..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024.0 / 1e6)
}

/// Peak resident set size of this process so far (`VmHWM`), in MB.
pub fn peak_rss_mb() -> Option<f64> {
    proc_status_mb("VmHWM")
}

/// Resets the peak resident set size to the current one (writes `5` to
/// `/proc/self/clear_refs`, Linux ≥ 4.0). Returns whether it worked.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Median of the values (mean of the middle two for an even count); NaN for none.
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_unstable_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Smallest value; NaN for none.
pub fn min(values: &[f64]) -> f64 {
    values.iter().copied().fold(f64::NAN, f64::min)
}

/// An integer with thousands separators (`15968` → `15,968`).
pub fn thousands(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::with_capacity(s.len() + s.len() / 3);
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers() {
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&mut []).is_nan());
        assert_eq!(min(&[3.0, 1.0, 2.0]), 1.0);
        assert_eq!(thousands(15_968), "15,968");
        assert_eq!(thousands(10_000_000), "10,000,000");
        assert_eq!(thousands(999), "999");
        if Path::new("/proc/self/status").exists() {
            assert!(peak_rss_mb().is_some_and(|mb| mb > 0.0));
        }
        let dir = TempDir::new("selftest").unwrap();
        let p = dir.path().to_path_buf();
        assert!(p.is_dir());
        drop(dir);
        assert!(!p.exists());
    }
}
