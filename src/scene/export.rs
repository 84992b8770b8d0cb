//! Writes a scene as TOML + OBJ/MTL following the scene contract.

use super::Scene;
use anyhow::Result;
use std::path::{Path, PathBuf};

/// Exports; returns the TOML path.
pub fn export_scene(scene: &Scene, dir: &Path) -> Result<PathBuf> {
    anyhow::bail!("{}: export of {} not built yet", dir.display(), scene.name)
}
