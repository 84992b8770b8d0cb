//! Typed render configuration. The same struct is read from experiment manifests
//! (unknown keys rejected) and filled from command-line flags. Names are resolved to
//! plug-ins in one place: [`crate::registry`].

use crate::param::{ParamDef, ParamValue, Params};
use serde::{Deserialize, Serialize};

/// The keys every render has; each plug-in's own parameters are in `params` (declared
/// by the plug-in with [`crate::params!`], read when it is built).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
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
    /// Experiment runner: also measure the image after these passes (progressive integrators).
    pub record_passes: Vec<u32>,
    /// The chosen plug-ins' parameters (any other key).
    #[serde(flatten)]
    pub params: Params,
}

macro_rules! common {
    ($($name:literal : $ty:ty = $default:literal, $doc:literal;)*) => {
        /// The common keys as a parameter table (docs, the command line's `--set`, manifests).
        pub const COMMON: &[ParamDef] = &[$(ParamDef {
            name: $name,
            ty: <$ty as ParamValue>::TYPE,
            default: $default,
            doc: $doc,
            check: <$ty as ParamValue>::check,
            parse: <$ty as ParamValue>::parse_text,
            flag: false,
        }),*];
    };
}

common! {
    "integrator": String = "path", "Integrator plug-in (`integrator` family below).";
    "spp": u32 = "16", "Samples per pixel.";
    "sampler": String = "halton", "Sampler plug-in (`sampler` family below).";
    "accel": String = "bvh8", "Accelerator plug-in (`accel` family below).";
    "rr": String = "auto", "Russian-roulette policy `NAME[:PARAM]` (`rr` family below); `auto` = `throughput:5` for `path`, `throughput` (from bounce 3) for the other integrators.";
    "max_depth": Option<u32> = "auto", "Maximum number of bounces; `auto` = unbounded (a safety cap of 1024 ends paths trapped between mirrors).";
    "seed": u64 = "0", "Random seed.";
    "threads": usize = "0", "Worker threads; 0 = all cores (images are bit-identical for any count).";
    "resolution": Option<Resolution> = "auto", "Image size `WIDTHxHEIGHT` (manifests: `[w, h]`); `auto` = the scene camera's.";
    "record_passes": Vec<u32> = "", "Experiment runner: also measure the image after these passes (progressive integrators).";
}

/// An image size, `WxH` on the command line and `[w, h]` in TOML.
pub struct Resolution(pub [u32; 2]);

impl ParamValue for Resolution {
    const TYPE: &'static str = "WxH";
    fn from_toml(v: &toml::Value) -> anyhow::Result<Self> {
        let a = v.as_array().filter(|a| a.len() == 2).ok_or_else(|| anyhow::anyhow!("expected [width, height]"))?;
        let w = u32::from_toml(&a[0])?;
        let h = u32::from_toml(&a[1])?;
        if w == 0 || h == 0 {
            return Err(anyhow::anyhow!("resolution must be positive, got {w}x{h}"));
        }
        Ok(Resolution([w, h]))
    }
    fn from_text(s: &str) -> anyhow::Result<Self> {
        parse_resolution(s).map(Resolution)
    }
    fn to_toml(&self) -> Option<toml::Value> {
        Some(toml::Value::Array(self.0.iter().map(|&x| toml::Value::Integer(x as i64)).collect()))
    }
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

    /// This configuration with plug-in parameter `key` set to `value` (tests, builders).
    pub fn with(mut self, key: &str, value: impl Into<toml::Value>) -> Self {
        self.params.set(key, value);
        self
    }

    /// Sets any key from command-line text: a common key, or a plug-in parameter
    /// declared in `catalogue` (type-checked against its declaration).
    pub fn set_text(&mut self, key: &str, text: &str, catalogue: &crate::param::docs::Catalogue) -> anyhow::Result<()> {
        let def =
            catalogue.find(key).ok_or_else(|| anyhow::anyhow!("unknown parameter `{key}` (`photonlab plugins` lists every parameter)"))?;
        let v = (def.parse)(text).map_err(|e| anyhow::anyhow!("parameter `{key}`: {e}"))?;
        if COMMON.iter().any(|d| d.name == key) {
            let mut t = toml::Table::new();
            if let Some(v) = v {
                t.insert(key.to_string(), v);
            }
            let one: RenderConfig = t.try_into().map_err(|e: toml::de::Error| anyhow::anyhow!("parameter `{key}`: {}", e.message()))?;
            match key {
                "integrator" => self.integrator = one.integrator,
                "spp" => self.spp = one.spp,
                "sampler" => self.sampler = one.sampler,
                "accel" => self.accel = one.accel,
                "rr" => self.rr = one.rr,
                "max_depth" => self.max_depth = one.max_depth,
                "seed" => self.seed = one.seed,
                "threads" => self.threads = one.threads,
                "resolution" => self.resolution = one.resolution,
                "record_passes" => self.record_passes = one.record_passes,
                _ => anyhow::bail!("common key `{key}` cannot be set from text"),
            }
        } else {
            match v {
                Some(v) => self.params.set(key, v),
                None => {
                    self.params.remove(key);
                }
            }
        }
        Ok(())
    }
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            integrator: "path".into(),
            spp: 16,
            sampler: "halton".into(),
            accel: "bvh8".into(),
            rr: "auto".into(), // rr::AUTO (config must not import rr: no module cycle)
            max_depth: None,
            seed: 0,
            threads: 0,
            resolution: None,
            record_passes: Vec::new(),
            params: Params::default(),
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
pub fn parse_resolution(s: &str) -> anyhow::Result<[u32; 2]> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| anyhow::anyhow!("resolution `{s}` is not WIDTHxHEIGHT"))?;
    let w: u32 = w.trim().parse().map_err(|_| anyhow::anyhow!("resolution `{s}`: bad width"))?;
    let h: u32 = h.trim().parse().map_err(|_| anyhow::anyhow!("resolution `{s}`: bad height"))?;
    if w == 0 || h == 0 {
        return Err(anyhow::anyhow!("resolution `{s}` must be positive"));
    }
    Ok([w, h])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plugin_keys_go_to_params_and_common_defaults_match_their_table() {
        let ok: RenderConfig = toml::from_str("spp = 4\nsampler = \"random\"\nic_tolerance = 0.2").unwrap();
        assert_eq!((ok.spp, ok.accel.as_str()), (4, "bvh8"));
        assert_eq!(ok.params.raw("ic_tolerance"), Some(&toml::Value::Float(0.2)));
        // Every COMMON default, set from its text, gives the Default value.
        let cat = crate::param::docs::Catalogue { common: COMMON, families: Vec::new(), groups: Vec::new() };
        crate::param::check_defs(COMMON).unwrap();
        for d in COMMON {
            let mut c = RenderConfig { spp: 99, seed: 7, threads: 3, ..Default::default() };
            c.set_text(d.name, d.default, &cat).unwrap();
            let mut want = RenderConfig { spp: 99, seed: 7, threads: 3, ..Default::default() };
            match d.name {
                "spp" => want.spp = 16,
                "seed" => want.seed = 0,
                "threads" => want.threads = 0,
                _ => {}
            }
            assert_eq!(c, want, "{}", d.name);
        }
        let mut c = RenderConfig::default();
        c.set_text("resolution", "64x32", &cat).unwrap();
        assert_eq!(c.resolution, Some([64, 32]));
        assert!(c.set_text("bogus", "1", &cat).is_err());
        assert!(c.set_text("spp", "x", &cat).is_err());
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
