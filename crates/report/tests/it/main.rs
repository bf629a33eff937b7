//! Integration tests of fogline-report: snapshots of the fragments, degenerate inputs, the
//! public API, and the page in a real headless Chromium.
#![allow(clippy::unwrap_used)]

mod browser;
mod cdp;
mod deficit;
mod degenerate;
mod fixture;
mod render;
mod snapshots;
