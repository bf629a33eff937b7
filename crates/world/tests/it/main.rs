//! Integration tests of fogline-world.

#![allow(clippy::unwrap_used)]

mod format;
mod generate;
