//! Integration tests of fogline-envelope.

#![allow(clippy::unwrap_used)]

mod analysis;
mod golden;
mod readers;

use fogline_envelope::{EnvelopeParams, PairTable, ReadOptions, input::Format, read_pairs_bytes};

/// Small, fast analysis parameters for tests.
pub fn quick_params() -> EnvelopeParams {
    EnvelopeParams {
        bootstrap: 200,
        restarts: 3,
        k_max: 5,
        cv_folds: 3,
        ..EnvelopeParams::default()
    }
}

/// Reads CSV text.
pub fn csv(text: &str) -> fogline_envelope::Result<PairTable> {
    read_pairs_bytes(
        "test.csv",
        Format::Csv,
        text.as_bytes(),
        &ReadOptions::default(),
    )
}

/// A valid CSV with `n_clips` clips under the paper's eight conditions.
pub fn valid_csv(n_clips: usize) -> String {
    let mut s = String::new();
    fogline_envelope::synthetic::write_csv(
        &fogline_envelope::synthetic::SyntheticParams { n_clips, seed: 11 },
        &mut unsafe_free_vec(&mut s),
    )
    .unwrap();
    s
}

struct StringWriter<'a>(&'a mut String);

impl std::io::Write for StringWriter<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0
            .push_str(std::str::from_utf8(buf).map_err(std::io::Error::other)?);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn unsafe_free_vec(s: &mut String) -> StringWriter<'_> {
    StringWriter(s)
}
