//! Scene TOML reading per `scene-format.md`.

use super::Scene;
use anyhow::Result;
use std::path::Path;

/// Loads a scene file.
pub fn load_scene(path: &Path) -> Result<Scene> {
    anyhow::bail!("{}: scene loading not built yet", path.display())
}
