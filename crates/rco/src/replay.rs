//! Recorded observations: JSON Lines, one [`Observation`] per line (blank lines are
//! skipped), as written by `serde_json`. Frames are optional (`rgb`, base64 of the RGB8
//! bytes); see `docs/rco.md` for the format and an example line.

use std::io::BufRead;

use crate::RcoError;
use crate::observation::Observation;

/// Reads every observation of `reader`; an error names the line (from 1).
pub fn read_observations<R: BufRead>(reader: R) -> Result<Vec<Observation>, RcoError> {
    let mut out = Vec::new();
    for (i, line) in reader.lines().enumerate() {
        let line = line.map_err(|e| RcoError::Replay {
            line: i + 1,
            reason: format!("cannot read: {e}"),
        })?;
        if line.trim().is_empty() {
            continue;
        }
        let obs: Observation = serde_json::from_str(&line).map_err(|e| RcoError::Replay {
            line: i + 1,
            reason: e.to_string(),
        })?;
        obs.validate().map_err(|e| RcoError::Replay {
            line: i + 1,
            reason: e.to_string(),
        })?;
        out.push(obs);
    }
    Ok(out)
}

/// Writes `observations` as JSON Lines.
pub fn to_jsonl(observations: &[Observation]) -> String {
    let mut s = String::new();
    for o in observations {
        // Serialising plain data cannot fail.
        if let Ok(line) = serde_json::to_string(o) {
            s.push_str(&line);
            s.push('\n');
        }
    }
    s
}

/// Runs `observations` through `rco` and writes one line per tick (its summary, or the whole
/// `Decision` as JSON with `json`), then a summary of the run: planning rounds, refusals,
/// fallbacks, backend calls and latency, the share of each source and speed control, and the
/// structured output mode of a backend that negotiates one. What `fogline rco replay` prints.
pub fn run(
    rco: &mut crate::Rco,
    observations: &[Observation],
    json: bool,
    out: &mut dyn std::io::Write,
) -> std::io::Result<Replayed> {
    use crate::Source;
    use std::collections::BTreeMap;
    let mut speeds: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut sources: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut last = None;
    for obs in observations {
        let d = rco.step(obs);
        if json {
            writeln!(
                out,
                "{}",
                serde_json::to_string(&d).map_err(std::io::Error::other)?
            )?;
        } else {
            writeln!(out, "{}", d.summary())?;
        }
        *speeds.entry(d.action.speed.name()).or_default() += 1;
        let s = match d.source {
            Source::Plan => "plan",
            Source::Wait => "wait",
            Source::Hold => "hold",
            Source::Fallback => "fallback",
        };
        *sources.entry(s).or_default() += 1;
        last = Some(d);
    }
    if let (false, Some(d)) = (json, last) {
        let c = d.counters;
        let n = observations.len();
        writeln!(out)?;
        writeln!(
            out,
            "{n} ticks: {} planning rounds, {} refusals, {} fallbacks; {} backend calls, {:.3} ms mean latency",
            c.replans_total,
            c.refusals_total,
            c.fallbacks_total,
            c.llm_calls_total,
            if c.llm_calls_total > 0 {
                c.llm_latency_ms_total / c.llm_calls_total as f64
            } else {
                0.0
            }
        )?;
        let share = |m: &BTreeMap<&str, usize>| {
            m.iter()
                .map(|(k, v)| format!("{k} {:.0}%", 100.0 * *v as f64 / n as f64))
                .collect::<Vec<_>>()
                .join(", ")
        };
        writeln!(out, "sources: {}", share(&sources))?;
        writeln!(out, "speed controls: {}", share(&speeds))?;
        if let Some(mode) = rco.structured_output() {
            writeln!(out, "structured output: {mode}")?;
        }
    }
    Ok(Replayed {
        ticks: observations.len(),
        fallbacks: sources.get("fallback").copied().unwrap_or(0),
    })
}

/// What a replay went through ([`run`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Replayed {
    /// Ticks replayed.
    pub ticks: usize,
    /// Ticks whose control came from the fallback (no usable answer from the backend).
    pub fallbacks: usize,
}

impl Replayed {
    /// Whether every tick fell back: the backend never gave a usable answer, so the replay
    /// measured the fallback, not the backend (`fogline rco replay` exits 1).
    pub fn all_fell_back(&self) -> bool {
        self.ticks > 0 && self.fallbacks == self.ticks
    }
}
