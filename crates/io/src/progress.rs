//! The progress bar of long jobs (perturbing a directory, generating or planning clips,
//! running a campaign).
//!
//! On a terminal it redraws one line on stderr at most every 100 ms: a bar, done / total,
//! failures, the rate and the time left. Elsewhere (a CI log, a batch job's file) it logs that
//! line every 30 s instead. Only with info logging on (`-q` silences it). Safe to share
//! between threads: counting is one atomic add.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// A progress bar over a number of items.
#[derive(Debug)]
pub struct Progress {
    total: AtomicUsize,
    done: AtomicUsize,
    failed: AtomicUsize,
    unit: &'static str,
    start: Instant,
    last: Mutex<Instant>,
    tty: bool,
    enabled: bool,
}

impl Progress {
    /// A bar over `total` items called `unit` (`frames`, `clips`, `runs`).
    pub fn new(total: usize, unit: &'static str) -> Self {
        Self {
            total: AtomicUsize::new(total),
            done: AtomicUsize::new(0),
            failed: AtomicUsize::new(0),
            unit,
            start: Instant::now(),
            last: Mutex::new(Instant::now()),
            tty: std::io::stderr().is_terminal(),
            enabled: log::log_enabled!(log::Level::Info),
        }
    }

    /// Changes the total (when it is known only once the job starts).
    pub fn set_total(&self, total: usize) {
        self.total.store(total, Ordering::Relaxed);
    }

    /// Items done so far.
    pub fn done(&self) -> usize {
        self.done.load(Ordering::Relaxed)
    }

    /// One more item done.
    pub fn inc(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
        self.draw();
    }

    /// One more item done, and it failed.
    pub fn inc_failed(&self) {
        self.failed.fetch_add(1, Ordering::Relaxed);
        self.inc();
    }

    /// Ends the bar's line (on a terminal).
    pub fn finish(&self) {
        if self.enabled && self.tty && self.total.load(Ordering::Relaxed) > 0 {
            eprintln!("\r{}", self.line());
        }
    }

    /// The bar's text.
    pub fn line(&self) -> String {
        let total = self.total.load(Ordering::Relaxed);
        let done = self.done.load(Ordering::Relaxed);
        let failed = self.failed.load(Ordering::Relaxed);
        let secs = self.start.elapsed().as_secs_f64().max(1e-9);
        let rate = done as f64 / secs;
        let eta = if rate > 0.0 {
            duration(total.saturating_sub(done) as f64 / rate)
        } else {
            "?".into()
        };
        let width = 28;
        let filled = (width * done / total.max(1)).min(width);
        let failed = if failed > 0 {
            format!(" · {failed} failed")
        } else {
            String::new()
        };
        format!(
            "[{}{}] {done}/{total} {}{failed} · {rate:.1}/s · ETA {eta}",
            "#".repeat(filled),
            " ".repeat(width - filled),
            self.unit,
        )
    }

    fn draw(&self) {
        if !self.enabled {
            return;
        }
        let every = if self.tty {
            Duration::from_millis(100)
        } else {
            Duration::from_secs(30)
        };
        let last_item = self.done.load(Ordering::Relaxed) == self.total.load(Ordering::Relaxed);
        if let Ok(mut last) = self.last.try_lock()
            && (last.elapsed() >= every || (self.tty && last_item))
        {
            *last = Instant::now();
            if self.tty {
                eprint!("\r{}", self.line());
            } else {
                log::info!("{}", self.line());
            }
        }
    }
}

/// `42s`, `3m07s`, `2h05m`.
pub fn duration(s: f64) -> String {
    let s = s.round().max(0.0) as u64;
    if s >= 3600 {
        format!("{}h{:02}m", s / 3600, (s % 3600) / 60)
    } else if s >= 60 {
        format!("{}m{:02}s", s / 60, s % 60)
    } else {
        format!("{s}s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_counts_items_failures_and_time_left() {
        let p = Progress::new(10, "clips");
        for _ in 0..4 {
            p.inc();
        }
        p.inc_failed();
        let line = p.line();
        assert!(
            line.starts_with("[##############              ] 5/10 clips · 1 failed"),
            "{line}"
        );
        assert!(line.contains("/s · ETA "), "{line}");
        p.set_total(5);
        assert!(p.line().contains("5/5 clips"));
        assert_eq!(p.done(), 5);
        assert_eq!(duration(42.4), "42s");
        assert_eq!(duration(187.0), "3m07s");
        assert_eq!(duration(7500.0), "2h05m");
    }
}
