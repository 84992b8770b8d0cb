//! The one place where configuration names become plug-ins. To add a strategy,
//! implement its trait in its family's folder and add one arm here.

use crate::accel::{Accel, bvh::Bvh, bvh4::Bvh4, bvh8::Bvh8, bvh8q::Bvh8q, linear::Linear};
use crate::config::{RenderConfig, StrategySpec};
use crate::integrator::{Integrator, path::PathIntegrator, photon::PhotonIntegrator, ppm::PpmIntegrator, sppm::SppmIntegrator};
use crate::rr::{RussianRoulette, albedo::Albedo, fixed::Fixed, off::Off, throughput::Throughput};
use crate::sampler::{Sampler, halton::HaltonSampler, hammersley::HammersleySampler, random::RandomSampler, sobol::SobolSampler};
use anyhow::{Result, bail};
use glam::Vec3;

/// Sampler names.
pub const SAMPLERS: &[&str] = &["random", "halton", "hammersley", "sobol"];
/// Accelerator names.
pub const ACCELS: &[&str] = &["none", "bvh", "bvh4", "bvh8", "bvh8q"];
/// Russian-roulette policy names.
pub const RR_POLICIES: &[&str] = &["off", "fixed", "albedo", "throughput"];
/// Integrator names.
pub const INTEGRATORS: &[&str] = &["path", "photon", "sppm", "ppm"];

fn unknown(kind: &str, name: &str, known: &[&str]) -> anyhow::Error {
    anyhow::anyhow!("unknown {kind} `{name}` (known: {})", known.join(", "))
}

/// Builds a sampler. `count` is the number of samples per stream when known up
/// front (required by `hammersley`).
pub fn make_sampler(name: &str, seed: u64, count: Option<u64>) -> Result<Box<dyn Sampler>> {
    Ok(match name {
        "random" => Box::new(RandomSampler::new(seed)),
        "halton" => Box::new(HaltonSampler::new(seed)),
        "sobol" => Box::new(SobolSampler::new(seed)),
        "hammersley" => match count {
            Some(n) => Box::new(HammersleySampler::new(seed, n).map_err(anyhow::Error::msg)?),
            None => bail!("sampler `hammersley` needs the sample count up front, which is unknown here; use `halton` or `random`"),
        },
        _ => return Err(unknown("sampler", name, SAMPLERS)),
    })
}

/// Checks a sampler name without building it.
pub fn check_sampler(name: &str) -> Result<()> {
    if SAMPLERS.contains(&name) { Ok(()) } else { Err(unknown("sampler", name, SAMPLERS)) }
}

/// Builds an accelerator over the triangles.
pub fn make_accel(name: &str, tris: &[[Vec3; 3]]) -> Result<Box<dyn Accel>> {
    Ok(match name {
        "none" | "linear" => Box::new(Linear::build(tris)),
        "bvh" => Box::new(Bvh::build(tris)),
        "bvh4" => Box::new(Bvh4::build(tris)),
        "bvh8" => Box::new(Bvh8::build(tris)),
        "bvh8q" => Box::new(Bvh8q::build_quantized(tris)),
        _ => return Err(unknown("accel", name, ACCELS)),
    })
}

/// Checks an accelerator name.
pub fn check_accel(name: &str) -> Result<()> {
    if ACCELS.contains(&name) || name == "linear" { Ok(()) } else { Err(unknown("accel", name, ACCELS)) }
}

/// Builds a Russian-roulette policy from `NAME[:PARAM]`.
pub fn make_rr(spec: &str) -> Result<Box<dyn RussianRoulette>> {
    let s = StrategySpec::parse(spec);
    let param_f = |default: f32| -> Result<f32> {
        match &s.param {
            None => Ok(default),
            Some(p) => p.parse::<f32>().map_err(|_| anyhow::anyhow!("rr `{spec}`: parameter `{p}` is not a number")),
        }
    };
    Ok(match s.name.as_str() {
        "off" | "fixed" | "albedo" | "throughput" => match s.name.as_str() {
            "off" => {
                if s.param.is_some() {
                    bail!("rr `off` takes no parameter (set the depth with max_depth)");
                }
                Box::new(Off)
            }
            "fixed" => Box::new(Fixed::new(param_f(Fixed::DEFAULT_Q)?).map_err(anyhow::Error::msg)?),
            "albedo" => {
                if s.param.is_some() {
                    bail!("rr `albedo` takes no parameter");
                }
                Box::new(Albedo)
            }
            _ => {
                let d = match &s.param {
                    None => Throughput::DEFAULT_MIN_DEPTH,
                    Some(p) => p.parse::<u32>().map_err(|_| anyhow::anyhow!("rr `{spec}`: minimum depth `{p}` is not a whole number"))?,
                };
                Box::new(Throughput::new(d))
            }
        },
        _ => return Err(unknown("rr policy", &s.name, RR_POLICIES)),
    })
}

/// Builds the integrator a configuration names (checking its settings).
pub fn make_integrator(cfg: &RenderConfig) -> Result<Box<dyn Integrator>> {
    make_integrator_with(cfg, true)
}

/// As [`make_integrator`], with progress bars for long pre-passes unless `quiet`.
pub fn make_integrator_with(cfg: &RenderConfig, quiet: bool) -> Result<Box<dyn Integrator>> {
    let rr = make_rr(&cfg.rr)?;
    let max_depth = cfg.depth_limit();
    if rr.never_terminates() && cfg.max_depth.is_none() {
        bail!("rr `off` never ends a path: give a finite max_depth (--max-depth N)");
    }
    Ok(match cfg.integrator.as_str() {
        "path" | "photon" => {
            crate::integrator::progressive::reject_for_fixed_budget(cfg)?;
            match cfg.integrator.as_str() {
                "path" => Box::new(PathIntegrator { max_depth, rr, output: Default::default() }),
                _ => Box::new(PhotonIntegrator::new(cfg, rr, quiet)?),
            }
        }
        "sppm" => Box::new(SppmIntegrator::new(cfg, rr, quiet)?),
        "ppm" => Box::new(PpmIntegrator::new(cfg, quiet)?),
        other => return Err(unknown("integrator", other, INTEGRATORS)),
    })
}

/// Validates every name and number of a configuration without building anything heavy.
pub fn validate(cfg: &RenderConfig) -> Result<()> {
    check_sampler(&cfg.sampler)?;
    check_accel(&cfg.accel)?;
    make_integrator(cfg)?;
    if cfg.spp == 0 {
        bail!("spp must be at least 1");
    }
    if let Some([w, h]) = cfg.resolution
        && (w == 0 || h == 0)
    {
        bail!("resolution must be positive, got {w}x{h}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_and_unknown_names_fail() {
        for n in SAMPLERS {
            assert!(make_sampler(n, 1, Some(4)).is_ok());
        }
        assert!(make_sampler("hammersley", 1, None).err().unwrap().to_string().contains("up front"));
        assert!(make_sampler("latin", 1, None).err().unwrap().to_string().contains("known: random"));
        for n in ACCELS {
            assert_eq!(make_accel(n, &[]).unwrap().name(), *n);
        }
        assert!(make_accel("kdtree", &[]).is_err());
        for spec in ["off", "fixed", "fixed:0.5", "albedo", "throughput", "throughput:5"] {
            assert!(make_rr(spec).is_ok(), "{spec}");
        }
        for spec in ["fixed:2", "fixed:x", "throughput:-1", "nope", "off:3"] {
            assert!(make_rr(spec).is_err(), "{spec}");
        }
        let cfg = RenderConfig { rr: "off".into(), ..Default::default() };
        assert!(validate(&cfg).unwrap_err().to_string().contains("max_depth"));
        let cfg = RenderConfig { rr: "off".into(), max_depth: Some(5), ..Default::default() };
        assert!(validate(&cfg).is_ok());
        assert!(validate(&RenderConfig { spp: 0, ..Default::default() }).is_err());
    }
}
