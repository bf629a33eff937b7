//! Integration tests of the `fogline` binary and of the workspace's shape.

#![allow(clippy::unwrap_used)]

mod architecture;
mod envelope_cmd;
mod perturb_cmd;
