//! The HTML report of fogline: one self-contained page that a safety engineer can file as
//! evidence — the figures and tables of *When and How Severely: Scenario-Specific Safety
//! Envelopes for Driving VLAs* for one envelope, a plain-language summary, every statistic,
//! the run's parameters, the input's checksum and every convention.
//!
//! Use it after the envelope analysis: [`render`] turns a [`ReportInput`] (the envelope, and
//! optionally the changed pairs' L2 values for the histogram and closed-loop scores) into
//! HTML. The page has inline CSS and inline SVG only: it makes no request, opens from disk
//! and prints. Output is deterministic: the same input gives the same bytes.
//!
//! ```
//! use fogline_envelope::{analyze, synthetic, EnvelopeParams};
//! use fogline_report::{render, ReportInput, ReportParams};
//!
//! let table = synthetic::corpus(&synthetic::SyntheticParams { n_clips: 120, seed: 7 });
//! let params = EnvelopeParams { bootstrap: 50, restarts: 2, ..EnvelopeParams::default() };
//! let env = analyze(&table, &params).unwrap();
//! let input = ReportInput::from_envelope(&env).unwrap().with_pairs(&table).unwrap();
//! let report = render(&input, &ReportParams::default()).unwrap();
//! assert!(report.html.starts_with("<!DOCTYPE html>"));
//! assert!(report.figures.iter().any(|f| f.id == "fig-1" && f.drawn));
//! assert!(!report.html.contains("NaN"));
//! ```

pub mod closed_loop;
mod ctx;
pub mod deficit;
mod draw;
pub mod error;
mod figures;
mod summary;
mod tables;

use std::fmt::Write as _;

use fogline_envelope::Envelope;
use serde::{Deserialize, Serialize};

pub use closed_loop::{ClosedLoop, ClosedLoopRow, check_closed_loop, closed_loop_from_json};
pub use error::{ReportError, Result};
pub use figures::Figure;

use ctx::Ctx;
use draw::esc;

/// What a report shows.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReportInput {
    /// The envelope: the analysis's own model of `envelope.json` (its one typed definition).
    pub envelope: Envelope,
    /// L2 deviations (m) of the changed pairs the mixture was fitted on, for the histogram of
    /// figure 2a. `envelope.json` does not hold them; without them the figure shows the
    /// mixture alone, with a note.
    #[serde(default)]
    pub changed_l2_m: Option<Vec<f64>>,
    /// Closed-loop scores; without them the closed-loop section says how to get them.
    #[serde(default)]
    pub closed_loop: Option<ClosedLoop>,
    /// The DriveLM-Deficit evaluation with its gallery (`fogline rco eval`); without it the
    /// page has no such section. In memory only (the gallery holds pixels).
    #[serde(skip)]
    pub deficit: Option<deficit::DeficitSection>,
}

impl ReportInput {
    /// A report of an envelope alone (checked by [`render`]).
    pub fn new(envelope: Envelope) -> Self {
        Self {
            envelope,
            changed_l2_m: None,
            closed_loop: None,
            deficit: None,
        }
    }

    /// From an in-memory analysis result (checked with [`check_envelope`]).
    pub fn from_envelope(env: &Envelope) -> Result<Self> {
        check_envelope(env)?;
        Ok(Self::new(env.clone()))
    }

    /// From the text of an `envelope.json`, read with [`Envelope::from_json`] (schema version
    /// first; a missing or mistyped field is named by its JSON path) and checked with
    /// [`check_envelope`]; `what` names the file in errors (e.g. its path).
    pub fn from_envelope_json(text: &str, what: &str) -> Result<Self> {
        let env = Envelope::from_json(text, what)?;
        check_envelope(&env)?;
        Ok(Self::new(env))
    }

    /// Takes the changed pairs' L2 values from the pairs table the envelope was computed
    /// from. Refuses a table whose checksum differs from the envelope's input, or whose
    /// changed pairs are not the ones the mixture was fitted on.
    pub fn with_pairs(mut self, table: &fogline_envelope::PairTable) -> Result<Self> {
        let want = &self.envelope.input.sha256;
        let have = &table.input.sha256;
        if !want.is_empty() && !have.is_empty() && want != have {
            return Err(ReportError::PairsMismatch {
                pairs: table.input.path.clone(),
                pairs_sha256: have.clone(),
                envelope_sha256: want.clone(),
            });
        }
        let l2: Vec<f64> = table
            .l2_m
            .iter()
            .zip(&table.changed)
            .filter(|(_, c)| **c)
            .map(|(l, _)| *l)
            .collect();
        if l2.len() != self.envelope.severity.n_changed {
            return Err(ReportError::Invalid {
                what: format!("pairs table {}", table.input.path),
                reason: format!(
                    "it has {} changed pairs, the envelope's mixture was fitted on {}",
                    l2.len(),
                    self.envelope.severity.n_changed
                ),
            });
        }
        self.changed_l2_m = Some(l2);
        Ok(self)
    }

    /// Adds closed-loop scores (checked).
    pub fn with_closed_loop(mut self, cl: ClosedLoop) -> Result<Self> {
        check_closed_loop(&cl)?;
        self.closed_loop = Some(cl);
        Ok(self)
    }

    /// Adds the DriveLM-Deficit evaluation's section (checked by
    /// [`deficit::DeficitSection::new`]).
    pub fn with_deficit(mut self, d: deficit::DeficitSection) -> Self {
        self.deficit = Some(d);
        self
    }
}

/// Parameters of [`render`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReportParams {
    /// Bins of the L2 histogram (figure 2a).
    pub histogram_bins: usize,
    /// Page title; default: "Safety envelope — <input file name>".
    pub title: Option<String>,
}

impl Default for ReportParams {
    fn default() -> Self {
        Self {
            histogram_bins: 60,
            title: None,
        }
    }
}

impl ReportParams {
    /// Checks every parameter; [`render`] calls it first.
    pub fn validate(&self) -> Result<()> {
        if !(5..=500).contains(&self.histogram_bins) {
            return Err(ReportError::InvalidParam {
                name: "histogram_bins",
                reason: "must be in 5..=500".into(),
            });
        }
        Ok(())
    }
}

/// What a figure of the rendered page shows.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FigureInfo {
    /// Element id of the `<figure>`.
    pub id: String,
    /// Title.
    pub title: String,
    /// Whether a chart was drawn (otherwise the page explains why not).
    pub drawn: bool,
}

/// A rendered report.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// The whole page.
    pub html: String,
    /// The page's fragments by id (`summary`, `fig-1`, `table-1`, …), in page order; the
    /// page is built from exactly these (for snapshot tests and embedding).
    pub fragments: Vec<(String, String)>,
    /// The figures.
    pub figures: Vec<FigureInfo>,
}

pub(crate) const CSS: &str = include_str!("report.css");

/// Renders the page.
pub fn render(input: &ReportInput, params: &ReportParams) -> Result<Report> {
    params.validate()?;
    check_envelope(&input.envelope)?;
    if let Some(cl) = &input.closed_loop {
        check_closed_loop(cl)?;
    }
    let cx = Ctx::new(
        &input.envelope,
        input.changed_l2_m.as_deref(),
        input.closed_loop.as_ref(),
        params,
    );
    let d = &input.envelope;
    let figs = [
        figures::dose_response(&cx),
        figures::delta_map(&cx),
        figures::severity(&cx),
        figures::transitions(&cx),
        figures::joint(&cx),
        figures::closed_loop(&cx),
    ];
    let fig_html = |id: &str| -> String {
        figs.iter()
            .find(|f| f.id == id)
            .map(Figure::html)
            .unwrap_or_default()
    };
    let mut fragments: Vec<(String, String)> = Vec::new();
    let mut push = |id: &str, html: String| fragments.push((id.to_string(), html));
    push("summary", summary::render(&cx));
    push("notes", notes(d));
    push("table-1", tables::table1(&cx));
    push("fig-1", fig_html("fig-1"));
    push("table-2", tables::table2(&cx));
    push("fig-4", fig_html("fig-4"));
    push("table-3", tables::table3(&cx));
    push("fig-2a", fig_html("fig-2a"));
    push("fig-2b", fig_html("fig-2b"));
    push("fig-3", fig_html("fig-3"));
    push("table-high", tables::high_tables(&cx));
    push("table-4", tables::table4(&cx));
    push("table-5", tables::table5(&cx));
    push("statistics", tables::statistics(&cx));
    push("fig-5", fig_html("fig-5"));
    push("table-closed-loop", tables::closed_loop(&cx));
    push("table-dose", tables::dose_table(&cx));
    push("parameters", tables::parameters(&cx));
    push("conventions", tables::conventions(&cx));
    if let Some(dx) = &input.deficit {
        push("deficit", deficit::fragment(dx)?);
    }
    let _ = tables::has_aggregate(&cx);

    let frag = |id: &str| -> &str {
        fragments
            .iter()
            .find(|(k, _)| k == id)
            .map_or("", |(_, v)| v.as_str())
    };
    let file = d
        .input
        .path
        .rsplit(['/', '\\'])
        .next()
        .unwrap_or(&d.input.path)
        .to_string();
    let title = params
        .title
        .clone()
        .unwrap_or_else(|| format!("Safety envelope — {file}"));
    let mut h = String::with_capacity(256 * 1024);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<meta name=\"generator\" content=\"fogline-report {}\">\n<title>{}</title>\n<style>\n{CSS}</style>\n</head>\n<body>\n<main>\n",
        env!("CARGO_PKG_VERSION"),
        esc(&title)
    );
    let _ = write!(
        h,
        "<header>\n<h1>{}</h1>\n<p class=\"meta\">{} clips · {} pairs · input <code>{}</code> · sha256 <code class=\"hash\">{}</code> · {} · <a href=\"#run\">parameters</a></p>\n</header>\n",
        esc(&title),
        d.corpus.n_clips,
        d.corpus.n_pairs,
        esc(&d.input.path),
        esc(if d.input.sha256.is_empty() {
            "—"
        } else {
            &d.input.sha256
        }),
        esc(&d.generated_by)
    );
    let mut sections: Vec<(&str, &str, &[&str])> = vec![
        ("summary", "Summary", &["summary", "notes"]),
        (
            "when",
            "When: per-scenario thresholds",
            &["table-1", "fig-1", "table-2", "fig-4"],
        ),
        (
            "severity",
            "How severely: severity bands",
            &["table-3", "fig-2a", "fig-2b"],
        ),
        (
            "envelope",
            "The two-dimensional envelope",
            &["fig-3", "table-high", "table-4"],
        ),
        ("assurance", "ISO 21448 assurance mapping", &["table-5"]),
        ("statistics", "Statistics", &["statistics"]),
        (
            "closed-loop",
            "Closed loop",
            &["fig-5", "table-closed-loop"],
        ),
        ("data", "Data behind figure 1", &["table-dose"]),
        (
            "run",
            "The run: input, checksum, parameters",
            &["parameters"],
        ),
        ("conventions", "Conventions", &["conventions"]),
    ];
    if input.deficit.is_some() {
        sections.insert(
            7,
            (
                "deficit",
                "Hazard inference and planning under perception deficits (DriveLM-Deficit)",
                &["deficit"],
            ),
        );
    }
    // Every section but the summary is numbered in page order.
    let sections: Vec<(&str, String, &[&str])> = sections
        .into_iter()
        .enumerate()
        .map(|(i, (id, name, parts))| {
            let name = if i == 0 {
                name.to_string()
            } else {
                format!("{i}. {name}")
            };
            (id, name, parts)
        })
        .collect();
    h.push_str("<nav aria-label=\"Contents\"><ol>\n");
    for (id, name, _) in &sections {
        let _ = writeln!(h, "<li><a href=\"#{id}\">{}</a></li>", esc(name));
    }
    h.push_str("</ol></nav>\n");
    for (id, name, parts) in &sections {
        let _ = writeln!(h, "<section id=\"{id}\">\n<h2>{}</h2>", esc(name));
        if *id == "closed-loop"
            && let Some(cl) = &input.closed_loop
        {
            let _ = writeln!(h, "<p class=\"meta\">Source: {}</p>", esc(&cl.source));
        }
        for p in *parts {
            h.push_str(frag(p));
        }
        h.push_str("</section>\n");
    }
    let _ = write!(
        h,
        "<footer>Generated by fogline-report {} from {} (envelope schema {}). Self-contained: no scripts, no external resources.</footer>\n</main>\n</body>\n</html>\n",
        env!("CARGO_PKG_VERSION"),
        esc(&d.generated_by),
        d.schema_version
    );
    let figures = figs
        .iter()
        .map(|f| FigureInfo {
            id: f.id.to_string(),
            title: f.title.clone(),
            drawn: f.svg.is_some(),
        })
        .collect();
    Ok(Report {
        html: h,
        fragments,
        figures,
    })
}

/// What the drawing relies on beyond the envelope's types: the schema version this report
/// reads, and matrix shapes and finite axis levels.
pub fn check_envelope(env: &Envelope) -> Result<()> {
    let expected = fogline_envelope::model::SCHEMA_VERSION;
    if env.schema_version != expected {
        return Err(ReportError::SchemaVersion {
            found: env.schema_version,
            expected,
        });
    }
    let bad = |what: String, reason: &str| {
        Err(ReportError::Invalid {
            what,
            reason: reason.to_string(),
        })
    };
    let j = &env.joint;
    if j.counts.len() != j.scenarios.len() || j.counts.iter().any(|r| r.len() != j.bands.len()) {
        return bad(
            "joint.counts".into(),
            "shape differs from scenarios × bands",
        );
    }
    let t = &env.transitions;
    if t.counts.len() != t.labels.len() || t.counts.iter().any(|r| r.len() != t.labels.len()) {
        return bad(
            "transitions.counts".into(),
            "shape differs from labels × labels",
        );
    }
    for a in &env.axes {
        if a.levels.iter().any(|l| !l.is_finite()) {
            return bad(format!("axes[{}].levels", a.axis), "not finite");
        }
    }
    Ok(())
}

fn notes(d: &Envelope) -> String {
    if d.notes.is_empty() {
        return String::new();
    }
    let mut s =
        String::from("<div class=\"notes\" role=\"note\"><h3>Notes from the analysis</h3>\n<ul>\n");
    for n in &d.notes {
        let _ = writeln!(s, "<li>{}</li>", esc(n));
    }
    s.push_str("</ul></div>\n");
    s
}
