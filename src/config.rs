//! Typed render configuration. The same struct is read from experiment manifests
//! (unknown keys rejected) and filled from command-line flags. Names are resolved to
//! plug-ins in one place: [`crate::registry`].

use serde::{Deserialize, Serialize};

/// Every setting of a render.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderConfig {
    /// Integrator name (`path`).
    pub integrator: String,
    /// Samples per pixel.
    pub spp: u32,
    /// Sampler name (`random`, `halton`, `hammersley`, `sobol`).
    pub sampler: String,
    /// Accelerator name (`none`, `bvh`, `bvh4`, `bvh8`, `bvh8q`).
    pub accel: String,
    /// Russian-roulette policy `NAME[:PARAM]` (`off`, `fixed:q`, `albedo`, `throughput:min_depth`).
    pub rr: String,
    /// Maximum number of bounces; absent = unbounded up to [`SAFETY_MAX_DEPTH`].
    pub max_depth: Option<u32>,
    /// Random seed.
    pub seed: u64,
    /// Worker threads; 0 = all cores.
    pub threads: usize,
    /// Override of the scene camera's resolution `[width, height]`.
    pub resolution: Option<[u32; 2]>,

    // ---- photon integrator (ignored by `path`) ----
    /// Photons stored in the direct + indirect (global) maps.
    pub photons: u32,
    /// Photons stored in the caustic map.
    pub caustic_photons: u32,
    /// Emit exactly this many photon paths (required by the `hammersley` sampler)
    /// instead of emitting until the maps hold the requested counts.
    pub emit_photons: Option<u64>,
    /// Cap on emitted photon paths.
    pub max_emitted: u64,
    /// Indirect-light method: `direct`, `final_gather`, `precomputed`, `irradiance_cache`.
    pub gather: String,
    /// Final-gather rays at the first level.
    pub gather_samples: u32,
    /// Final-gather levels (≥ 1); each deeper level uses 1/8 of the rays of the one above.
    pub gather_bounces: u32,
    /// Let `irradiance_cache` gather over Christensen's precomputed irradiance
    /// (`precomputed` always uses it, `final_gather` never does).
    pub precomputed_irradiance: bool,
    /// Precompute irradiance at every n-th global photon.
    pub precompute_stride: u32,
    /// Photons per global radiance estimate.
    pub k: u32,
    /// Photons per caustic radiance estimate.
    pub caustic_k: u32,
    /// Maximum search radius of global estimates (scene units); default 3 × the
    /// radius holding `k` photons at the mean density of the stored global photons
    /// over the triangles they landed on.
    pub max_radius: Option<f32>,
    /// Maximum search radius of caustic estimates; default 3 × the radius holding
    /// `caustic_k` caustic photons at their mean density.
    pub caustic_max_radius: Option<f32>,
    /// Density-estimation filter: `box`, `cone`, `gaussian`.
    pub filter: String,
    /// Half thickness of the disc photons must lie in, as a fraction of the maximum
    /// radius (≥ 1: a sphere, i.e. no disc).
    pub disc: f32,
    /// Shadow rays per shading point for direct light (distribution ray tracing).
    pub direct_samples: u32,
    /// Sampler for direct-light samples at each shading point.
    pub direct_sampler: String,
    /// Irradiance-cache error tolerance a (Ward): entries with weight > 1/a are used.
    pub ic_tolerance: f32,
    /// Smallest irradiance-cache valid radius, fraction of the bounding radius.
    pub ic_min_radius: f32,
    /// Largest irradiance-cache valid radius, fraction of the bounding radius.
    pub ic_max_radius: f32,
    /// Smallest irradiance-cache valid radius in pixel footprints at the entry
    /// (Tabellion & Lamorlette 2004); an entry is used within `ic_tolerance` × radius.
    pub ic_min_pixels: f32,
    /// Largest irradiance-cache valid radius in pixel footprints at the entry.
    pub ic_max_pixels: f32,
    /// Irradiance gradients (Ward & Heckbert 1992) in the cache's interpolation, and
    /// the radius limit E/|∇E| (Křivánek et al. 2006).
    pub ic_gradients: bool,
    /// Rays per irradiance-cache entry (stratified M × N with N ≈ πM). Entries are
    /// few and each is reused over many pixels, so an entry's noise becomes a blotch:
    /// they get more rays than a per-pixel final gather.
    pub ic_samples: u32,
    /// Neighbour clamping of cache radii (Křivánek et al. 2006): R_i ≤ R_j + |p_i − p_j|.
    pub ic_neighbor_clamp: bool,
    /// Rays drawn from the glossy lobe at glossy gathering points (the diffuse part
    /// uses the final gather or the cache).
    pub glossy_samples: u32,

    // ---- progressive integrators (`sppm`, `ppm`; ignored by the others) ----
    /// Passes to run; absent = 16, or unbounded when `time_limit` is set.
    pub passes: Option<u32>,
    /// Photon paths emitted per pass (`sppm`: default 2^17; `ppm`: when set, each
    /// pass emits exactly this many instead of filling `photons` / `caustic_photons`).
    pub photons_per_pass: Option<u64>,
    /// Radius-reduction parameter α ∈ (0, 1] (1 = radius never shrinks).
    pub alpha: f32,
    /// Stop after the pass that crosses this many seconds.
    pub time_limit: Option<f64>,
    /// `sppm`: initial per-pixel radius (scene units); default 0.02 × the scene radius.
    pub sppm_radius: Option<f32>,
    /// `sppm`: direct light by `trace` (shadow rays at the visible point) or `photons`.
    pub sppm_direct: String,
    /// Experiment runner: also measure the image after these passes.
    pub record_passes: Vec<u32>,
    /// Write the progressive state to `checkpoint_file` after every this many passes.
    pub checkpoint_every: Option<u32>,
    /// State file of `checkpoint_every` / `resume` (`render` sets OUT.checkpoint.json).
    pub checkpoint_file: Option<String>,
    /// Continue from `checkpoint_file` (bit-identical to an uninterrupted run).
    pub resume: bool,
}

/// Depth cap when `max_depth` is unset. A path (or photon) caught by total internal
/// reflection in tessellated glass, or between perfect mirrors, keeps a throughput of 1,
/// so throughput- and albedo-based roulette never end it; measured on McGuire's
/// CornellBox-Sphere, about 1 path in 30,000 is trapped this way. Trapped paths carry no
/// emission, so cutting them changes the image only by light that escapes after more
/// than this many bounces.
pub const SAFETY_MAX_DEPTH: u32 = 1024;

impl RenderConfig {
    /// The bounce limit in force: `max_depth`, or [`SAFETY_MAX_DEPTH`] when unset.
    pub fn depth_limit(&self) -> u32 {
        self.max_depth.unwrap_or(SAFETY_MAX_DEPTH)
    }
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            integrator: "path".into(),
            spp: 16,
            sampler: "halton".into(),
            accel: "bvh8".into(),
            rr: "throughput".into(),
            max_depth: None,
            seed: 0,
            threads: 0,
            resolution: None,
            photons: 200_000,
            caustic_photons: 50_000,
            emit_photons: None,
            max_emitted: 20_000_000,
            gather: "irradiance_cache".into(),
            gather_samples: 64,
            gather_bounces: 1,
            precomputed_irradiance: true,
            precompute_stride: 4,
            k: 100,
            caustic_k: 60,
            max_radius: None,
            caustic_max_radius: None,
            filter: "cone".into(),
            disc: 0.25,
            direct_samples: 4,
            direct_sampler: "hammersley".into(),
            ic_tolerance: 0.3,
            ic_min_radius: 0.01,
            ic_max_radius: 0.25,
            ic_min_pixels: 10.0,
            ic_max_pixels: 100.0,
            ic_gradients: true,
            ic_samples: 256,
            ic_neighbor_clamp: true,
            glossy_samples: 16,
            passes: None,
            photons_per_pass: None,
            alpha: 2.0 / 3.0,
            time_limit: None,
            sppm_radius: None,
            sppm_direct: "trace".into(),
            record_passes: Vec::new(),
            checkpoint_every: None,
            checkpoint_file: None,
            resume: false,
        }
    }
}

/// A `NAME[:PARAM]` strategy reference.
#[derive(Clone, Debug, PartialEq)]
pub struct StrategySpec {
    /// Plug-in name.
    pub name: String,
    /// Optional parameter text after the colon.
    pub param: Option<String>,
}

impl StrategySpec {
    /// Parses `NAME` or `NAME:PARAM`.
    pub fn parse(s: &str) -> Self {
        match s.split_once(':') {
            Some((n, p)) => StrategySpec { name: n.trim().into(), param: Some(p.trim().into()) },
            None => StrategySpec { name: s.trim().into(), param: None },
        }
    }
}

/// Parses "WxH".
pub fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("resolution `{s}` is not WIDTHxHEIGHT"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("resolution `{s}`: bad width"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("resolution `{s}`: bad height"))?;
    if w == 0 || h == 0 {
        return Err(format!("resolution `{s}` must be positive"));
    }
    Ok([w, h])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_rejected() {
        let ok: RenderConfig = toml::from_str("spp = 4\nsampler = \"random\"").unwrap();
        assert_eq!(ok.spp, 4);
        assert_eq!(ok.accel, "bvh8");
        let err = toml::from_str::<RenderConfig>("spp = 4\nbogus = 1").unwrap_err();
        assert!(err.to_string().contains("bogus"), "{err}");
    }

    #[test]
    fn specs_and_resolutions() {
        assert_eq!(StrategySpec::parse("fixed:0.5").param.as_deref(), Some("0.5"));
        assert_eq!(StrategySpec::parse("albedo").param, None);
        assert_eq!(parse_resolution("64x32").unwrap(), [64, 32]);
        assert!(parse_resolution("0x3").is_err());
        assert!(parse_resolution("64").is_err());
    }
}
