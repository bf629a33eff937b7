//! Integration tests of the `fogline` binary and of the workspace's shape.

#![allow(clippy::unwrap_used)]

mod architecture;
mod campaign_cmd;
mod envelope_cmd;
mod interop;
mod perturb_cmd;
mod planner_cmd;
mod rco_cmd;
mod reference_planner;
mod report_cmd;
mod world_cmd;
