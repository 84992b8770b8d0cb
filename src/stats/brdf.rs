//! stub
use super::{FamilyReport, Settings};
use anyhow::Result;

/// Runs the family.
pub fn run(_s: &Settings) -> Result<FamilyReport> {
    Ok(FamilyReport::default())
}
