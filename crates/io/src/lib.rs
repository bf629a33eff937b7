//! The small helpers every fogline crate shares, written once: atomic file writes
//! ([`atomic`]), the progress bar ([`progress`]) and frame encoding ([`image`]).
//!
//! A level-0 crate: it depends on no other fogline crate, so every crate can use it. Before
//! writing a helper of this kind in another crate, use (or extend) the one here.

pub mod atomic;
pub mod image;
pub mod progress;

pub use atomic::{write_atomic, write_atomic_with};
pub use image::{ImageFormat, PngSpeed, encode, encode_png};
pub use progress::Progress;
