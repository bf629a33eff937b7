//! The small helpers every fogline crate shares, written once: atomic file writes
//! ([`atomic`]), the progress bar ([`progress`]), frame encoding ([`image`]) and, with the
//! `http` feature, the HTTP/1 client of the LLM backend and the remote planners (`http`).
//!
//! A level-0 crate: it depends on no other fogline crate, so every crate can use it. Before
//! writing a helper of this kind in another crate, use (or extend) the one here.

pub mod atomic;
#[cfg(feature = "http")]
pub mod http;
pub mod image;
pub mod jpeg;
pub mod progress;

pub use atomic::{FileSet, write_atomic, write_atomic_with};
pub use image::{
    DecodedRgb, ImageFormat, PngSpeed, check_frame, data_url, decode_rgb, encode, encode_png,
    encode_with, encoder_name,
};
pub use progress::Progress;
