//! Campaign integration tests: determinism, resume, shards and merge, failures recorded.
#![allow(clippy::unwrap_used)]

mod faults;
mod runs;
