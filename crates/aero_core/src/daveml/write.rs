//! Placeholder (filled below).
use serde::{Deserialize, Serialize};
/// A model to write.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ModelSpec {}
/// Write.
pub fn write_model(_spec: &ModelSpec, _path: &std::path::Path) -> crate::Result<()> {
    Ok(())
}
