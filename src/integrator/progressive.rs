//! What the progressive integrators (`sppm`, `ppm`) share: the pass budget
//! (`passes`, `time_limit`), the radius schedule of Knaus & Zwicker (2011) and the
//! validation of the progressive settings.

use crate::config::RenderConfig;
use crate::film::Film;
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize, de::DeserializeOwned};
use std::time::Instant;

/// Called after every pass with (passes done, seconds since the first pass began,
/// the image so far). The image after each pass is a complete estimate.
pub type OnPass<'a> = &'a mut (dyn FnMut(u32, f64, &Film) + Send);

/// Passes run when neither `passes` nor `time_limit` is given.
pub const DEFAULT_PASSES: u32 = 16;

/// Checks the settings every progressive integrator uses.
pub fn validate(cfg: &RenderConfig) -> Result<()> {
    if cfg.alpha.is_nan() || cfg.alpha <= 0.0 || cfg.alpha > 1.0 {
        bail!("alpha must lie in (0, 1], got {}", cfg.alpha);
    }
    if cfg.passes == Some(0) {
        bail!("passes must be at least 1");
    }
    if let Some(t) = cfg.time_limit
        && (t.is_nan() || t <= 0.0 || t.is_infinite())
    {
        bail!("time_limit must be a positive number of seconds, got {t}");
    }
    if cfg.photons_per_pass == Some(0) {
        bail!("photons_per_pass must be at least 1");
    }
    if cfg.record_passes.contains(&0) {
        bail!("record_passes counts passes from 1; 0 is not a pass");
    }
    if cfg.checkpoint_every == Some(0) {
        bail!("checkpoint_every must be at least 1 pass");
    }
    if (cfg.checkpoint_every.is_some() || cfg.resume) && cfg.checkpoint_file.is_none() {
        bail!("checkpoint_every / resume need a checkpoint_file (give `render` an output, -o OUT: the state goes to OUT.checkpoint.json)");
    }
    if cfg.sampler == "hammersley" && cfg.passes.is_none() {
        bail!("sampler `hammersley` needs the number of passes up front: set passes (--passes N) or use `halton`");
    }
    Ok(())
}

/// Checks that the configuration does not set progressive keys for a fixed-budget
/// integrator, where they would be silently ignored.
pub fn reject_for_fixed_budget(cfg: &RenderConfig) -> Result<()> {
    let d = RenderConfig::default();
    let set: Vec<&str> = [
        ("passes", cfg.passes != d.passes),
        ("photons_per_pass", cfg.photons_per_pass != d.photons_per_pass),
        ("time_limit", cfg.time_limit != d.time_limit),
        ("sppm_radius", cfg.sppm_radius != d.sppm_radius),
        ("sppm_direct", cfg.sppm_direct != d.sppm_direct),
        ("record_passes", cfg.record_passes != d.record_passes),
        ("checkpoint_every", cfg.checkpoint_every != d.checkpoint_every),
        ("resume", cfg.resume != d.resume),
    ]
    .iter()
    .filter(|x| x.1)
    .map(|x| x.0)
    .collect();
    if !set.is_empty() {
        bail!("{} only apply to the progressive integrators (sppm, ppm), not `{}`", set.join(", "), cfg.integrator);
    }
    Ok(())
}

/// A saved progressive state (`checkpoint_file`, JSON; floats stored as their bits so
/// that a resumed run continues bit for bit).
#[derive(Serialize, Deserialize)]
struct Checkpoint<S> {
    format: String,
    integrator: String,
    key: String,
    pass: u32,
    state: S,
}

const CHECKPOINT_FORMAT: &str = "photonlab-progressive-checkpoint-v1";

/// What a checkpoint must match: the configuration without the keys that only say
/// how long or where to run, and the scene.
fn checkpoint_key(cfg: &RenderConfig, world: &crate::world::World) -> Result<String> {
    let mut c = cfg.clone();
    (c.passes, c.time_limit, c.threads, c.record_passes) = (None, None, 0, Vec::new());
    (c.checkpoint_every, c.checkpoint_file, c.resume) = (None, None, false);
    let text = toml::to_string(&c)?;
    let words: Vec<u64> = text.bytes().map(u64::from).collect();
    let scene = crate::experiment::scene_fingerprint(&world.scene);
    Ok(format!("{:016x}{scene:016x}", crate::math::hash_words(&words)))
}

/// With `resume`: the pass count and state saved in `checkpoint_file`, after checking
/// that they were written for this configuration and scene.
pub fn load_checkpoint<S: DeserializeOwned>(cfg: &RenderConfig, world: &crate::world::World) -> Result<Option<(u32, S)>> {
    let (true, Some(path)) = (cfg.resume, &cfg.checkpoint_file) else { return Ok(None) };
    let text = std::fs::read_to_string(path).with_context(|| format!("{path}: cannot read the checkpoint to resume from"))?;
    let c: Checkpoint<S> = serde_json::from_str(&text).with_context(|| format!("{path}: not a readable checkpoint"))?;
    if c.format != CHECKPOINT_FORMAT || c.integrator != cfg.integrator {
        bail!("{path}: a checkpoint of `{}` ({}), not of `{}`", c.integrator, c.format, cfg.integrator);
    }
    if c.key != checkpoint_key(cfg, world)? {
        bail!("{path}: the checkpoint was written for another configuration or scene (only passes, time_limit and threads may change)");
    }
    Ok(Some((c.pass, c.state)))
}

/// Writes the state after pass `pass` when `checkpoint_every` divides it.
pub fn save_checkpoint<S: Serialize>(cfg: &RenderConfig, world: &crate::world::World, pass: u32, state: &S) -> Result<()> {
    let (Some(every), Some(path)) = (cfg.checkpoint_every, &cfg.checkpoint_file) else { return Ok(()) };
    if !pass.is_multiple_of(every) {
        return Ok(());
    }
    let c =
        Checkpoint { format: CHECKPOINT_FORMAT.into(), integrator: cfg.integrator.clone(), key: checkpoint_key(cfg, world)?, pass, state };
    crate::film::write_atomic(std::path::Path::new(path), serde_json::to_string(&c)?.as_bytes())
}

/// The pass budget of a run.
pub struct Budget {
    /// Most passes to run.
    pub max_passes: u32,
    /// Seconds after which no new pass starts.
    pub time_limit: Option<f64>,
    start: Instant,
}

impl Budget {
    /// Starts the clock.
    pub fn new(cfg: &RenderConfig) -> Self {
        let max_passes = cfg.passes.unwrap_or(if cfg.time_limit.is_some() { u32::MAX } else { DEFAULT_PASSES });
        Budget { max_passes, time_limit: cfg.time_limit, start: Instant::now() }
    }
    /// Seconds since the start.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
    /// True when another pass may start after `done` passes (the first always runs).
    pub fn more(&self, done: u32) -> bool {
        done < self.max_passes && (done == 0 || self.time_limit.is_none_or(|t| self.elapsed() < t))
    }
}

/// Knaus & Zwicker's radius schedule: r²_{i+1} = r²_i (i + α) / (i + 1), passes
/// numbered from 1. Returns r²_{i+1}.
#[inline]
pub fn next_radius2(r2: f64, i: u32, alpha: f64) -> f64 {
    r2 * (i as f64 + alpha) / (i as f64 + 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radius_schedule_follows_the_power_law() {
        // r²_i ∝ i^(α−1) asymptotically: over 10^4 passes the log–log slope is α − 1.
        for alpha in [0.5, 2.0 / 3.0, 0.9] {
            let mut r2 = 1.0;
            let (mut at_100, mut at_10000) = (0.0, 0.0);
            for i in 1..10000u32 {
                r2 = next_radius2(r2, i, alpha);
                if i + 1 == 100 {
                    at_100 = r2;
                }
                if i + 1 == 10000 {
                    at_10000 = r2;
                }
            }
            let slope = (at_10000 / at_100).ln() / 100f64.ln();
            assert!((slope - (alpha - 1.0)).abs() < 0.01, "alpha {alpha}: slope {slope}");
        }
        // α = 1: the radius never shrinks.
        assert_eq!(next_radius2(2.0, 7, 1.0), 2.0);
    }

    #[test]
    fn bad_settings_are_named() {
        let bad = |c: RenderConfig, what: &str| {
            let e = validate(&c).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        };
        bad(RenderConfig { alpha: 0.0, ..Default::default() }, "alpha");
        bad(RenderConfig { alpha: 1.5, ..Default::default() }, "alpha");
        bad(RenderConfig { passes: Some(0), ..Default::default() }, "passes");
        bad(RenderConfig { time_limit: Some(-1.0), ..Default::default() }, "time_limit");
        bad(RenderConfig { record_passes: vec![0, 4], ..Default::default() }, "record_passes");
        bad(RenderConfig { sampler: "hammersley".into(), ..Default::default() }, "passes");
        let e = reject_for_fixed_budget(&RenderConfig { passes: Some(3), ..Default::default() }).unwrap_err();
        assert!(e.to_string().contains("passes only apply"), "{e}");
    }

    #[test]
    fn budget_counts_passes() {
        let b = Budget::new(&RenderConfig::default());
        assert!(b.more(DEFAULT_PASSES - 1) && !b.more(DEFAULT_PASSES));
        let b = Budget::new(&RenderConfig { time_limit: Some(1e-9), ..Default::default() });
        std::thread::sleep(std::time::Duration::from_millis(2));
        assert!(b.more(0) && !b.more(1));
    }
}
