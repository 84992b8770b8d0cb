//! Russian-roulette policies (plug-ins chosen by name: `off`, `fixed`, `albedo`,
//! `throughput`), shared by the path tracer and the photon tracer.
//!
//! The default, `auto`, depends on the integrator ([`make_for`]): `path` starts
//! `throughput` roulette at bounce [`Throughput::PATH_MIN_DEPTH`] (5, as Mitsuba 3 does;
//! the study in docs/rendering.md), every other integrator at
//! [`Throughput::DEFAULT_MIN_DEPTH`] (3).
//!
//! A policy only says how likely a path is to survive a bounce; the caller draws the
//! uniform number from its sampler and divides survivors by the probability, which
//! keeps every estimator unbiased.

pub mod albedo;
pub mod fixed;
pub mod off;
pub mod throughput;

use crate::math::Color;
use albedo::Albedo;
use anyhow::{Result, bail};
use fixed::Fixed;
use off::Off;
use throughput::Throughput;

/// What a policy may look at when deciding.
#[derive(Clone, Copy, Debug)]
pub struct RrContext {
    /// Number of scattering events so far (1 after the first surface interaction).
    pub depth: u32,
    /// Path throughput (camera paths) or photon power relative to its emitted power.
    pub throughput: Color,
    /// Reflectance of the surface just scattered from.
    pub albedo: Color,
}

/// A Russian-roulette policy.
pub trait RussianRoulette: Send + Sync {
    /// Configuration name.
    fn name(&self) -> &'static str;
    /// Survival probability in (0, 1]; 1 means "always continue".
    fn survival_probability(&self, ctx: &RrContext) -> f32;
    /// True for policies that never terminate paths (so a finite max depth is needed).
    fn never_terminates(&self) -> bool {
        false
    }
    /// Weight of a survivor of probability `q`: 1/q keeps estimators unbiased. Only
    /// the statistics suite's deliberately broken control overrides it.
    fn survivor_weight(&self, q: f32) -> f32 {
        1.0 / q
    }
}

/// Applies a policy: returns the weight a survivor is multiplied by (1/q), or `None`
/// when the path is terminated. `u` is a uniform number in [0,1).
#[inline]
pub fn roulette(policy: &dyn RussianRoulette, ctx: &RrContext, u: f32) -> Option<f32> {
    let q = policy.survival_probability(ctx);
    if q >= 1.0 {
        return Some(1.0);
    }
    if q <= 0.0 || u >= q { None } else { Some(policy.survivor_weight(q)) }
}

/// Clamps a probability into [0, 1], mapping NaN to 0.
#[inline]
pub(crate) fn clamp01(q: f32) -> f32 {
    if q.is_nan() { 0.0 } else { q.clamp(0.0, 1.0) }
}

/// Russian-roulette policy names.
pub const NAMES: &[&str] = &["off", "fixed", "albedo", "throughput"];

/// The default policy's spec: `throughput` with a minimum depth that depends on the
/// integrator (see [`make_for`]).
pub const AUTO: &str = "auto";

/// Builds the policy `spec` for `integrator`: [`AUTO`] is `throughput` from bounce
/// [`Throughput::PATH_MIN_DEPTH`] for `path` and from [`Throughput::DEFAULT_MIN_DEPTH`]
/// for every other integrator (their images stay those of the earlier default);
/// anything else as [`make`].
pub fn make_for(spec: &str, integrator: &str) -> Result<Box<dyn RussianRoulette>> {
    if spec == AUTO {
        let d = if integrator == "path" { Throughput::PATH_MIN_DEPTH } else { Throughput::DEFAULT_MIN_DEPTH };
        return Ok(Box::new(Throughput::new(d)));
    }
    make(spec)
}

/// Builds a Russian-roulette policy from `NAME[:PARAM]` ([`AUTO`]: `throughput` from
/// bounce [`Throughput::DEFAULT_MIN_DEPTH`], what it means for every integrator but `path`).
pub fn make(spec: &str) -> Result<Box<dyn RussianRoulette>> {
    if spec == AUTO {
        return make_for(spec, "");
    }
    let s = crate::config::StrategySpec::parse(spec);
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
            "fixed" => Box::new(Fixed::new(param_f(Fixed::DEFAULT_Q)?)?),
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
        _ => bail!("unknown rr policy `{}` (known: {})", s.name, NAMES.join(", ")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roulette_weights_survivors() {
        let p = fixed::Fixed::new(0.25).unwrap();
        let ctx = RrContext { depth: 1, throughput: Color::ONE, albedo: Color::ONE };
        assert_eq!(roulette(&p, &ctx, 0.1), Some(4.0));
        assert_eq!(roulette(&p, &ctx, 0.3), None);
        let off = off::Off;
        assert_eq!(roulette(&off, &ctx, 0.999), Some(1.0));
        assert!(off.never_terminates());
        // Expected weight is exactly 1 over a uniform grid of u.
        let mut s = 0.0;
        for i in 0..1000 {
            s += roulette(&p, &ctx, (i as f32 + 0.5) / 1000.0).unwrap_or(0.0);
        }
        assert!((s / 1000.0 - 1.0).abs() < 1e-6);
    }

    /// `auto` starts roulette at bounce 5 for `path` only; other integrators keep 3.
    #[test]
    fn auto_depends_on_the_integrator() {
        let q = |p: &dyn RussianRoulette, depth| {
            p.survival_probability(&RrContext { depth, throughput: Color::splat(0.25), albedo: Color::ONE })
        };
        let path = make_for(AUTO, "path").unwrap();
        assert_eq!(path.name(), "throughput");
        assert_eq!((q(path.as_ref(), 4), q(path.as_ref(), 5)), (1.0, 0.25));
        for other in ["photon", "sppm", "ppm", "bdpt", "vcm", ""] {
            let p = make_for(AUTO, other).unwrap();
            assert_eq!((q(p.as_ref(), 2), q(p.as_ref(), 3)), (1.0, 0.25), "{other}");
        }
        let p = make(AUTO).unwrap();
        assert_eq!((q(p.as_ref(), 2), q(p.as_ref(), 3)), (1.0, 0.25));
        // An explicit policy is taken as written, also for `path`.
        let p = make_for("throughput", "path").unwrap();
        assert_eq!(q(p.as_ref(), 3), 0.25);
    }
}
