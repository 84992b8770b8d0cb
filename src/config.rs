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
    /// Sampler name (`random`, `halton`, `hammersley`).
    pub sampler: String,
    /// Accelerator name (`none`, `bvh`).
    pub accel: String,
    /// Russian-roulette policy `NAME[:PARAM]` (`off`, `fixed:q`, `albedo`, `throughput:min_depth`).
    pub rr: String,
    /// Maximum number of bounces; absent = unbounded.
    pub max_depth: Option<u32>,
    /// Random seed.
    pub seed: u64,
    /// Worker threads; 0 = all cores.
    pub threads: usize,
    /// Override of the scene camera's resolution `[width, height]`.
    pub resolution: Option<[u32; 2]>,
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            integrator: "path".into(),
            spp: 16,
            sampler: "halton".into(),
            accel: "bvh".into(),
            rr: "throughput".into(),
            max_depth: None,
            seed: 0,
            threads: 0,
            resolution: None,
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
        assert_eq!(ok.accel, "bvh");
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
