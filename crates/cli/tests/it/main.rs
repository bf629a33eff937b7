//! Integration tests of the `fogline` binary and of the workspace's shape.

#![allow(clippy::unwrap_used)]

mod architecture;
mod campaign_cmd;
mod envelope_cmd;
mod import_cmd;
mod interop;
mod llama_cpp;
#[path = "../../../rco/tests/it/mock_server.rs"]
mod mock_server;
mod mutations;
mod perturb_cmd;
mod planner_cmd;
mod rco_cmd;
mod reference_planner;
mod report_cmd;
mod serve_load;
mod sim_cmd;
mod tls_cmd;
#[path = "../../../remote/tests/it/tls_support.rs"]
mod tls_support;
mod world_cmd;

/// Runs the `fogline` binary with `args`.
pub fn fogline(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(args)
        .output()
        .unwrap()
}

/// A finished command's stdout and stderr, for assertion messages.
pub fn text(o: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}
