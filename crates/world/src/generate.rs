//! Clip generation: scene → cameras → expert.

use crate::clip::Clip;
use crate::config::WorldConfig;
use crate::error::WorldError;

/// Generates clip `index` of the corpus described by `config` (deterministic: the same
/// config and index give the same clip, byte for byte).
pub fn generate_clip(config: &WorldConfig, index: usize) -> Result<Clip, WorldError> {
    config.validate()?;
    let _ = index;
    Err(WorldError::invalid("index", index, "generation is being written"))
}
