//! Integration tests of the `fogline` binary and of the workspace's shape.

mod architecture;
mod envelope_cmd;
