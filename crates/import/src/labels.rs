//! Scenario labels from the user: a CSV file with the columns `clip_id` and `scenario`
//! (other columns are ignored), one row per dataset clip. The public dataset has no
//! maneuver labels (the envelope paper's annotations are internal), so clips without a row
//! are labelled `OTHER`. Any label set works: the paper's seven classes, or the user's own.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::{ImportError, Result};

/// The label of a clip the CSV does not name.
pub const UNLABELLED: &str = "OTHER";

/// Reads the labels: dataset clip id → scenario. Cells are trimmed; an empty id or label, or
/// a clip given two different labels, is an error naming the row.
pub fn read_labels(path: &Path) -> Result<BTreeMap<String, String>> {
    let loc = path.display().to_string();
    let bad = |e: csv::Error| ImportError::data(&loc, format!("not a readable CSV file: {e}"));
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .flexible(true)
        .from_path(path)
        .map_err(|e| match e.kind() {
            csv::ErrorKind::Io(_) => ImportError::data(&loc, format!("cannot read: {e}")),
            _ => bad(e),
        })?;
    let headers = r.headers().map_err(bad)?.clone();
    let col = |name: &str| {
        headers
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                ImportError::data(
                    &loc,
                    format!(
                        "no column `{name}` (expected the columns clip_id,scenario; the header \
                         is: {})",
                        headers.iter().collect::<Vec<_>>().join(",")
                    ),
                )
            })
    };
    let (ci, cs) = (col("clip_id")?, col("scenario")?);
    let mut out: BTreeMap<String, String> = BTreeMap::new();
    let mut first_row: BTreeMap<String, u64> = BTreeMap::new();
    for (i, rec) in r.records().enumerate() {
        let row = i as u64 + 1;
        let rec = rec.map_err(|e| ImportError::data(&loc, format!("row {row}: {e}")))?;
        let id = rec.get(ci).unwrap_or_default();
        let label = rec.get(cs).unwrap_or_default();
        if id.is_empty() {
            return Err(ImportError::cell(
                &loc,
                row,
                "clip_id",
                "empty; expected a clip id",
            ));
        }
        if label.is_empty() {
            return Err(ImportError::cell(
                &loc,
                row,
                "scenario",
                format!("empty for clip {id}; expected a label such as LANE_KEEPING or OTHER"),
            ));
        }
        if let Some(old) = out.get(id) {
            if old != label {
                return Err(ImportError::cell(
                    &loc,
                    row,
                    "scenario",
                    format!(
                        "clip {id} is labelled {label} here and {old} in row {}",
                        first_row.get(id).copied().unwrap_or_default()
                    ),
                ));
            }
            continue;
        }
        first_row.insert(id.to_string(), row);
        out.insert(id.to_string(), label.to_string());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_by_clip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("labels.csv");
        std::fs::write(
            &p,
            "Clip_ID, scenario ,note\na, STOP_SIGNAL,x\nb,my_label\na,STOP_SIGNAL,again\n",
        )
        .unwrap();
        let l = read_labels(&p).unwrap();
        assert_eq!(l["a"], "STOP_SIGNAL");
        assert_eq!(l["b"], "my_label");
        std::fs::write(&p, "clip_id,scenario\na,X\na,Y\n").unwrap();
        let e = read_labels(&p).unwrap_err().to_string();
        assert!(
            e.contains("row 2, column `scenario`") && e.contains("in row 1"),
            "{e}"
        );
        std::fs::write(&p, "clip_id,scenario\na,\n").unwrap();
        let e = read_labels(&p).unwrap_err().to_string();
        assert!(e.contains("row 1, column `scenario`: empty"), "{e}");
        std::fs::write(&p, "id,label\n").unwrap();
        let e = read_labels(&p).unwrap_err().to_string();
        assert!(
            e.contains("no column `clip_id`") && e.contains("id,label"),
            "{e}"
        );
        let e = read_labels(&dir.path().join("missing.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.csv: cannot read"), "{e}");
    }
}
