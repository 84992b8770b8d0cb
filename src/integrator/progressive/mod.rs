//! The progressive integrators: `sppm` (stochastic progressive photon mapping, its
//! photon hash grid in `grid.rs`) and `ppm` (probabilistic progressive photon
//! mapping), and what they share: the pass budget (`passes`, `time_limit`), the
//! radius schedule of Knaus & Zwicker (2011), checkpoints and the validation of the
//! progressive settings.

pub mod grid;
pub mod ppm;
pub mod sppm;
pub mod sppm_phases;

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

crate::params! {
    /// What the progressive integrators (`sppm`, `ppm`) share.
    pub struct ProgressiveParams {
        /// Passes to run; `auto` = 16, or unbounded when `time_limit` is set.
        passes: Option<u32> = "auto",
        /// Photon paths emitted per pass; `auto`: `sppm` 2 per pixel, `ppm` fills `photons` / `caustic_photons` every pass.
        photons_per_pass: Option<u64> = "auto",
        /// Radius-reduction parameter α ∈ (0, 1] (1 = the radius never shrinks).
        alpha: f32 = "2/3",
        /// Stop after the pass that crosses this many seconds.
        time_limit: Option<f64> = "auto",
        /// Write the image and the state to `checkpoint_file` every this many passes.
        checkpoint_every: Option<u32> = "auto",
        /// State file of `checkpoint_every` / `resume` (`render -o OUT` sets OUT.checkpoint.json).
        checkpoint_file: Option<String> = "auto",
        /// Continue from `checkpoint_file` (bit-identical to an uninterrupted run).
        resume: bool = "false",
    }
}

/// Keys that say how long or where to run, not what is computed (a checkpoint may be
/// resumed with other values).
const RUN_KEYS: &[&str] = &["passes", "time_limit", "checkpoint_every", "checkpoint_file", "resume"];

impl ProgressiveParams {
    /// Reads the parameters and checks them with the common keys of `cfg`.
    pub fn read_checked(cfg: &RenderConfig, r: &crate::param::Reader) -> Result<Self> {
        let p = Self::read(r)?;
        p.validate(cfg)?;
        Ok(p)
    }

    /// Checks the settings every progressive integrator uses.
    pub fn validate(&self, cfg: &RenderConfig) -> Result<()> {
        if self.alpha.is_nan() || self.alpha <= 0.0 || self.alpha > 1.0 {
            bail!("alpha must lie in (0, 1], got {}", self.alpha);
        }
        if self.passes == Some(0) {
            bail!("passes must be at least 1");
        }
        if let Some(t) = self.time_limit
            && (t.is_nan() || t <= 0.0 || t.is_infinite())
        {
            bail!("time_limit must be a positive number of seconds, got {t}");
        }
        if self.photons_per_pass == Some(0) {
            bail!("photons_per_pass must be at least 1");
        }
        if cfg.record_passes.contains(&0) {
            bail!("record_passes counts passes from 1; 0 is not a pass");
        }
        if self.checkpoint_every == Some(0) {
            bail!("checkpoint_every must be at least 1 pass");
        }
        if (self.checkpoint_every.is_some() || self.resume) && self.checkpoint_file.is_none() {
            bail!(
                "checkpoint_every / resume need a checkpoint_file (give `render` an output, -o OUT: the state goes to OUT.checkpoint.json)"
            );
        }
        if cfg.sampler == "hammersley" && self.passes.is_none() {
            bail!("sampler `hammersley` needs the number of passes up front: set passes (--passes N) or use `halton`");
        }
        Ok(())
    }
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

/// v2: `sppm` pixels hold 10 numbers (area-probe counts added); v3: `ppm` keeps the
/// first pass's radius too.
const CHECKPOINT_FORMAT: &str = "photonlab-progressive-checkpoint-v3";

/// What a checkpoint must match: the configuration without the keys that only say
/// how long or where to run, and the scene.
fn checkpoint_key(cfg: &RenderConfig, world: &crate::world::World) -> Result<String> {
    let mut c = cfg.clone();
    (c.threads, c.record_passes) = (0, Vec::new());
    for k in RUN_KEYS {
        c.params.remove(k);
    }
    let text = toml::to_string(&c)?;
    let words: Vec<u64> = text.bytes().map(u64::from).collect();
    let scene = world.scene.fingerprint();
    Ok(format!("{:016x}{scene:016x}", crate::math::hash_words(&words)))
}

/// With `resume`: the pass count and state saved in `checkpoint_file`, after checking
/// that they were written for this configuration and scene.
pub fn load_checkpoint<S: DeserializeOwned>(
    cfg: &RenderConfig,
    prog: &ProgressiveParams,
    world: &crate::world::World,
) -> Result<Option<(u32, S)>> {
    let (true, Some(path)) = (prog.resume, &prog.checkpoint_file) else { return Ok(None) };
    let text = std::fs::read_to_string(path).with_context(|| format!("{path}: cannot read the checkpoint to resume from"))?;
    // The format first, so a checkpoint of an older version says so.
    let head: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{path}: not a readable checkpoint"))?;
    let format = head.get("format").and_then(|f| f.as_str()).unwrap_or("none");
    if format != CHECKPOINT_FORMAT {
        bail!("{path}: checkpoint format `{format}`, this build reads `{CHECKPOINT_FORMAT}` (re-render from the start)");
    }
    let c: Checkpoint<S> = serde_json::from_value(head).with_context(|| format!("{path}: not a readable checkpoint"))?;
    if c.integrator != cfg.integrator {
        bail!("{path}: a checkpoint of `{}`, not of `{}`", c.integrator, cfg.integrator);
    }
    if c.key != checkpoint_key(cfg, world)? {
        bail!("{path}: the checkpoint was written for another configuration or scene (only passes, time_limit and threads may change)");
    }
    Ok(Some((c.pass, c.state)))
}

/// Writes the state after pass `pass` when `checkpoint_every` divides it.
pub fn save_checkpoint<S: Serialize>(
    cfg: &RenderConfig,
    prog: &ProgressiveParams,
    world: &crate::world::World,
    pass: u32,
    state: &S,
) -> Result<()> {
    let (Some(every), Some(path)) = (prog.checkpoint_every, &prog.checkpoint_file) else { return Ok(()) };
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
    pub fn new(p: &ProgressiveParams) -> Self {
        let max_passes = p.passes.unwrap_or(if p.time_limit.is_some() { u32::MAX } else { DEFAULT_PASSES });
        Budget { max_passes, time_limit: p.time_limit, start: Instant::now() }
    }
    /// Seconds since the start.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
    /// True when another pass may start after `done` passes (the first always runs),
    /// unless the render was cancelled (`progress::cancel`).
    pub fn more(&self, done: u32) -> bool {
        done < self.max_passes && (done == 0 || self.time_limit.is_none_or(|t| self.elapsed() < t)) && !crate::progress::cancelled()
    }
}

/// Knaus & Zwicker's radius schedule: r²_{i+1} = r²_i (i + α) / (i + 1), passes
/// numbered from 1. Returns r²_{i+1}.
#[inline]
pub fn next_radius2(r2: f64, i: u32, alpha: f64) -> f64 {
    r2 * (i as f64 + alpha) / (i as f64 + 1.0)
}

/// `impl Integrator` for a progressive integrator with a `run(&mut self, world,
/// on_pass)` method and a `counters` map: it renders itself pass by pass, so the
/// per-ray `li` of the render pass is never called.
macro_rules! progressive_integrator {
    ($ty:ty, $name:literal) => {
        impl $crate::integrator::Integrator for $ty {
            fn name(&self) -> &'static str {
                $name
            }
            /// Not used: the pipeline renders progressive integrators through
            /// [`Integrator::render_progressive`](crate::integrator::Integrator::render_progressive).
            fn li(
                &self,
                _world: &$crate::world::World,
                _ray: &$crate::geometry::Ray,
                _sampler: &mut dyn $crate::sampler::Sampler,
                _stats: &mut $crate::accel::TraversalStats,
            ) -> $crate::math::Color {
                $crate::math::Color::ZERO
            }
            fn is_progressive(&self) -> bool {
                true
            }
            fn render_progressive(
                &mut self,
                world: &$crate::world::World,
                on_pass: $crate::integrator::progressive::OnPass,
            ) -> Option<::anyhow::Result<($crate::film::Film, $crate::integrator::render::RenderStats)>> {
                Some(self.run(world, on_pass))
            }
            fn stats(&self) -> ::std::collections::BTreeMap<String, f64> {
                self.counters.clone()
            }
        }
    };
}
pub(crate) use progressive_integrator;

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
        let bad = |c: RenderConfig, p: ProgressiveParams, what: &str| {
            let e = p.validate(&c).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        };
        let (c, p) = (RenderConfig::default(), ProgressiveParams::default());
        bad(c.clone(), ProgressiveParams { alpha: 0.0, ..p.clone() }, "alpha");
        bad(c.clone(), ProgressiveParams { alpha: 1.5, ..p.clone() }, "alpha");
        bad(c.clone(), ProgressiveParams { passes: Some(0), ..p.clone() }, "passes");
        bad(c.clone(), ProgressiveParams { time_limit: Some(-1.0), ..p.clone() }, "time_limit");
        bad(RenderConfig { record_passes: vec![0, 4], ..c.clone() }, p.clone(), "record_passes");
        bad(RenderConfig { sampler: "hammersley".into(), ..c.clone() }, p.clone(), "passes");
        bad(c.clone(), ProgressiveParams { resume: true, ..p.clone() }, "checkpoint_file");
        p.validate(&c).unwrap();
    }

    #[test]
    fn budget_counts_passes() {
        let b = Budget::new(&ProgressiveParams::default());
        assert!(b.more(DEFAULT_PASSES - 1) && !b.more(DEFAULT_PASSES));
        let b = Budget::new(&ProgressiveParams { time_limit: Some(1e-9), ..Default::default() });
        std::thread::sleep(std::time::Duration::from_millis(2));
        assert!(b.more(0) && !b.more(1));
    }
}
