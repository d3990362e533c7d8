//! BART AFF loader (placeholder until the loader lands).

use std::path::Path;

use super::{Scene, SceneError};

/// Load an AFF scene from its main file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    Err(SceneError::Invalid { name: path.display().to_string(), message: "AFF loader not yet implemented".into() })
}
