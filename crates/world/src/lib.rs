//! A procedural driving world.
//!
//! Scenes for every scenario class of the envelope paper, rendered by the four cameras of
//! Alpamayo R1 (RGB, depth and 2-D boxes per frame), an ego history and the ground-truth
//! future from a privileged expert; plus the on-disk clip format (`format`).
//!
//! Deterministic from a seed: the same `(WorldConfig, index)` gives the same clip, byte for
//! byte.

pub mod clip;
pub mod config;
pub mod corpus;
pub mod error;
pub mod format;
pub mod generate;
pub mod objects;
pub mod render;
pub mod scenarios;
pub mod scene;

pub use clip::{CameraClip, CameraFrame, Clip, SceneInfo};
pub use config::{ScenarioMix, WorldConfig};
pub use error::WorldError;
pub use format::{list_clips, read_clip, write_clip};
pub use generate::{generate_clip, generate_clip_cameras};
