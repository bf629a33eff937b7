//! Compiles the egodriver contract (`proto/*.proto`) to Rust with protox, a protobuf
//! compiler written in Rust, so building needs no system `protoc`.

use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    let files = [
        "proto/common.proto",
        "proto/sensorsim.proto",
        "proto/egodriver.proto",
    ];
    for f in &files {
        println!("cargo:rerun-if-changed={f}");
    }
    let descriptors = protox::compile(files, ["proto"])?;
    tonic_prost_build::configure()
        .build_client(true)
        .build_server(true)
        .compile_fds(descriptors)?;
    Ok(())
}
