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
