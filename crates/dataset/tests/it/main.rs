//! Integration tests of fogline-dataset: the "must show" list of issue 21.

#![allow(clippy::unwrap_used)]

#[path = "../../../rco/tests/it/mock_server.rs"]
mod mock_server;

mod building;
mod eval;
mod import;
mod labels;

use std::path::Path;
use std::sync::OnceLock;

use fogline_dataset::{BuildParams, build};

/// A small data set built once for the tests that only read it (32 samples, 8 towns).
pub fn small_set() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let p = BuildParams {
            samples: 32,
            seed: 21,
            split_fractions: [0.5, 0.25, 0.25],
            threads: 2,
            ..BuildParams::default()
        };
        build(&p, dir.path()).unwrap();
        dir
    })
    .path()
}
