//! The one place where configuration names become plug-ins, and the catalogue of
//! every plug-in and its parameters (`photonlab plugins`). To add a strategy,
//! implement its trait in its family's folder, add one arm here and one catalogue
//! entry. Families whose plug-ins others build too (samplers, RR policies) have their
//! by-name constructor in their own `mod.rs` (re-exported here), so no plug-in needs
//! this module.

use crate::accel::{Accel, bvh::Bvh, bvh4::Bvh4, bvh8::Bvh8, bvh8q::Bvh8q, linear::Linear};
use crate::config::{COMMON, RenderConfig};
use crate::integrator::bidir::{
    BidirParams,
    bdpt::BdptIntegrator,
    vcm::{VcmIntegrator, VcmParams},
};
use crate::integrator::photon::gather::{GatherParams, irradiance_cache::CacheSettings, precomputed::PrecomputedParams};
use crate::integrator::photon::{DirectParams, PhotonIntegrator, PhotonParams};
use crate::integrator::progressive::ProgressiveParams;
use crate::integrator::progressive::ppm::{PpmIntegrator, PpmParams};
use crate::integrator::progressive::sppm::{SppmIntegrator, SppmParams};
use crate::integrator::{Integrator, path::PathIntegrator};
use crate::param::Reader;
use crate::param::docs::{Catalogue, Family, Group, Plugin};
pub use crate::rr::{NAMES as RR_POLICIES, make as make_rr};
pub use crate::sampler::{NAMES as SAMPLERS, check as check_sampler, make as make_sampler};
use anyhow::{Result, bail};
use glam::Vec3;

/// Accelerator names.
pub const ACCELS: &[&str] = &["none", "bvh", "bvh4", "bvh8", "bvh8q"];
/// Integrator names.
pub const INTEGRATORS: &[&str] = &["path", "photon", "sppm", "ppm", "bdpt", "vcm"];

fn unknown(kind: &str, name: &str, known: &[&str]) -> anyhow::Error {
    anyhow::anyhow!("unknown {kind} `{name}` (known: {})", known.join(", "))
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

/// Builds the integrator a configuration names (checking its settings).
pub fn make_integrator(cfg: &RenderConfig) -> Result<Box<dyn Integrator>> {
    make_integrator_with(cfg, true)
}

/// As [`make_integrator`], with progress bars for long pre-passes unless `quiet`.
/// Every plug-in reads its own parameters; a key none of the chosen plug-ins read is
/// an error naming the key, its owner and the plug-ins chosen.
pub fn make_integrator_with(cfg: &RenderConfig, quiet: bool) -> Result<Box<dyn Integrator>> {
    make_integrator_allowing(cfg, quiet, &|_| false).map(|(i, _)| i)
}

/// As [`make_integrator_with`], but keys for which `allowed` holds may go unused;
/// returns them with the integrator (the manifest's `[base]` keys: they must be used by
/// some of its configurations, not by each).
pub fn make_integrator_allowing(
    cfg: &RenderConfig,
    quiet: bool,
    allowed: &dyn Fn(&str) -> bool,
) -> Result<(Box<dyn Integrator>, Vec<String>)> {
    let rr = crate::rr::make_for(&cfg.rr, &cfg.integrator)?;
    let max_depth = cfg.depth_limit();
    if rr.never_terminates() && cfg.max_depth.is_none() {
        bail!("rr `off` never ends a path: give a finite max_depth (--max-depth N)");
    }
    let r = Reader::new(&cfg.params);
    r.chose(format!("integrator `{}`", cfg.integrator));
    let integrator: Box<dyn Integrator> = match cfg.integrator.as_str() {
        "path" => Box::new(PathIntegrator { max_depth, rr, output: Default::default() }),
        "photon" => Box::new(PhotonIntegrator::new(cfg, &r, rr, quiet)?),
        "sppm" => Box::new(SppmIntegrator::new(cfg, &r, rr, quiet)?),
        "ppm" => Box::new(PpmIntegrator::new(cfg, &r, quiet)?),
        "bdpt" => Box::new(BdptIntegrator::new(cfg, &r, rr, quiet)?),
        "vcm" => Box::new(VcmIntegrator::new(cfg, &r, rr, quiet)?),
        other => return Err(unknown("integrator", other, INTEGRATORS)),
    };
    let unused = r.unused();
    if let Some(key) = unused.iter().find(|k| !allowed(k)) {
        return Err(unused_error(key, &r.chosen()));
    }
    if !cfg.record_passes.is_empty() && !integrator.is_progressive() {
        bail!("record_passes only applies to the progressive integrators (sppm, ppm, vcm), not `{}`", cfg.integrator);
    }
    Ok((integrator, unused))
}

/// The error for a key none of the chosen plug-ins read.
pub fn unused_error(key: &str, chosen: &str) -> anyhow::Error {
    match catalogue().owner(key) {
        Some(owner) => anyhow::anyhow!("parameter `{key}` belongs to {owner}, which this configuration does not use (chosen: {chosen})"),
        None => anyhow::anyhow!("unknown parameter `{key}` (chosen: {chosen}; `photonlab plugins` lists every parameter)"),
    }
}

/// Validates every name and number of a configuration without building anything heavy.
pub fn validate(cfg: &RenderConfig) -> Result<()> {
    validate_allowing(cfg, &|_| false).map(|_| ())
}

/// As [`validate`], letting keys for which `allowed` holds go unused; returns them.
pub fn validate_allowing(cfg: &RenderConfig, allowed: &dyn Fn(&str) -> bool) -> Result<Vec<String>> {
    check_sampler(&cfg.sampler)?;
    check_accel(&cfg.accel)?;
    let (_, unused) = make_integrator_allowing(cfg, true, allowed)?;
    if cfg.spp == 0 {
        bail!("spp must be at least 1");
    }
    if let Some([w, h]) = cfg.resolution
        && (w == 0 || h == 0)
    {
        bail!("resolution must be positive, got {w}x{h}");
    }
    Ok(unused)
}

fn plugin(name: &'static str, doc: &'static str) -> Plugin {
    Plugin { name, doc, params: &[], groups: &[] }
}

/// Every family, plug-in and parameter, from the plug-ins' own declarations.
pub fn catalogue() -> Catalogue {
    let families = vec![
        Family {
            key: "integrator",
            doc: "how radiance is estimated",
            plugins: vec![
                plugin("path", "Unbiased path tracing: next-event estimation + BSDF sampling with MIS; the reference."),
                Plugin {
                    name: "photon",
                    doc: "Photon mapping (Jensen; the design report): ray-traced direct light, caustic map, indirect light by the `gather` plug-in.",
                    params: PhotonParams::DEFS,
                    groups: &["direct-light"],
                },
                Plugin {
                    name: "sppm",
                    doc: "Stochastic progressive photon mapping (Hachisuka & Jensen 2009): per-pixel statistics, radius shrinking with `alpha`.",
                    params: SppmParams::DEFS,
                    groups: &["progressive", "direct-light"],
                },
                Plugin {
                    name: "ppm",
                    doc: "Probabilistic progressive photon mapping (Knaus & Zwicker 2011): each pass a `photon` render with shrinking radii, averaged; every photon within the pass radius counts, and `gather` defaults to `direct`.",
                    params: PpmParams::DEFS,
                    groups: &["progressive", "integrator `photon`", "direct-light"],
                },
                Plugin {
                    name: "bdpt",
                    doc: "Bidirectional path tracing (Veach 1997): every (s, t) technique incl. light tracing, one MIS weight.",
                    params: &[],
                    groups: &["bidir"],
                },
                Plugin {
                    name: "vcm",
                    doc: "Vertex connection and merging (Georgiev et al. 2012): bdpt and photon merging under one MIS weight, progressive; by default a pilot renders by path tracing or sppm instead where one is predicted more efficient (`vcm_select`).",
                    params: VcmParams::DEFS,
                    groups: &["bidir", "progressive"],
                },
            ],
        },
        Family {
            key: "gather",
            doc: "indirect light at the first diffuse hit (integrators `photon`, `ppm`)",
            plugins: vec![
                plugin("direct", "Direct visualisation of the indirect photon map (the noisy baseline)."),
                Plugin {
                    name: "final_gather",
                    doc: "Final gathering: a photon estimate where each gather ray lands.",
                    params: &[],
                    groups: &["gather"],
                },
                Plugin {
                    name: "precomputed",
                    doc: "Final gathering over Christensen's precomputed irradiance.",
                    params: PrecomputedParams::DEFS,
                    groups: &["gather"],
                },
                Plugin {
                    name: "irradiance_cache",
                    doc: "Ward's irradiance cache with gradients and neighbour clamping, prefilled deterministically.",
                    params: CacheSettings::DEFS,
                    groups: &["gather", "`precomputed`"],
                },
            ],
        },
        Family {
            key: "filter",
            doc: "density-estimation kernel of photon estimates (key of `photon`)",
            plugins: vec![
                plugin("box", "Constant weight."),
                plugin("cone", "Jensen's cone filter w = 1 − d/(k·r), k = 1.1."),
                plugin("gaussian", "Jensen's Gaussian filter (α = 0.918, β = 1.953)."),
            ],
        },
        Family {
            key: "sampler",
            doc: "sample points for pixels, bounces, photons and gathers",
            plugins: vec![
                plugin("random", "Independent uniform samples (PCG32)."),
                plugin("halton", "Halton with random digit permutations per dimension and a per-pixel Cranley–Patterson rotation."),
                plugin("hammersley", "Hammersley point set (needs the sample count up front)."),
                plugin(
                    "sobol",
                    "Owen-scrambled Sobol' (Burley 2020: shuffled index, hash-based nested scrambling, independent 4-D groups aligned with each bounce's dimensions).",
                ),
            ],
        },
        Family {
            key: "accel",
            doc: "ray-triangle acceleration structure",
            plugins: vec![
                plugin("none", "Tests every triangle (alias `linear`)."),
                plugin("bvh", "Binary binned-SAH BVH."),
                plugin("bvh4", "A spatial-split SAH tree collapsed to 4-wide SIMD nodes."),
                plugin(
                    "bvh8",
                    "The same collapsed to 8-wide nodes (AVX-512, AVX2 or baseline traversal chosen at run time; on par with Embree on the same rays, see `bench embree-compare`).",
                ),
                plugin("bvh8q", "`bvh8` with 8-bit quantised child boxes: half the node memory, 0.7–0.9× the speed."),
            ],
        },
        Family {
            key: "rr",
            doc: "Russian-roulette policy, written `NAME[:PARAM]`",
            plugins: vec![
                plugin("off", "No roulette (needs `max_depth`)."),
                plugin("fixed", "Survive with probability q, `fixed:Q` (default 0.8)."),
                plugin("albedo", "Survive with the surface reflectance."),
                plugin("throughput", "After D bounces survive with the max channel of the throughput, `throughput:D` (default 3)."),
            ],
        },
    ];
    let groups = vec![
        Group {
            name: "progressive",
            doc: "pass budget, radius schedule and checkpoints of `sppm` and `ppm`",
            params: ProgressiveParams::DEFS,
        },
        Group { name: "bidir", doc: "MIS of the bidirectional integrators `bdpt` and `vcm`", params: BidirParams::DEFS },
        Group { name: "direct-light", doc: "direct light by distribution ray tracing", params: DirectParams::DEFS },
        Group { name: "gather", doc: "the final gather shared by the gathering plug-ins", params: GatherParams::DEFS },
    ];
    Catalogue { common: COMMON, families, groups }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_is_complete_and_consistent() {
        let cat = catalogue();
        let names = |key: &str| -> Vec<&str> {
            cat.families.iter().find(|f| f.key == key).map(|f| f.plugins.iter().map(|p| p.name).collect()).unwrap_or_default()
        };
        assert_eq!(names("integrator"), INTEGRATORS);
        assert_eq!(names("sampler"), SAMPLERS);
        assert_eq!(names("accel"), ACCELS);
        assert_eq!(names("rr"), RR_POLICIES);
        assert_eq!(names("gather"), crate::integrator::photon::gather::GATHERS);
        assert_eq!(names("filter"), crate::photon::estimate::Filter::NAMES);
        // Every table's defaults parse; no key is declared twice anywhere.
        let mut seen = std::collections::BTreeSet::new();
        for d in cat.all_params() {
            assert!(seen.insert(d.name), "`{}` declared twice", d.name);
        }
        crate::param::check_defs(&cat.all_params().copied().collect::<Vec<_>>()).unwrap();
        // The RR docs state the policies' real defaults.
        let rr = &cat.families.iter().find(|f| f.key == "rr").unwrap().plugins;
        assert!(rr[1].doc.contains(&format!("default {}", crate::rr::fixed::Fixed::DEFAULT_Q)));
        assert!(rr[3].doc.contains(&format!("default {}", crate::rr::throughput::Throughput::DEFAULT_MIN_DEPTH)));
        assert!(cat.owner("ic_tolerance").unwrap().contains("irradiance_cache"));
        assert!(cat.owner("alpha").unwrap().contains("sppm"));
    }

    #[test]
    fn unused_keys_name_their_owner_and_the_chosen_plugins() {
        let e = make_integrator(&RenderConfig::default().with("ic_tolerance", 0.2)).err().unwrap().to_string();
        assert!(e.contains("ic_tolerance") && e.contains("gather `irradiance_cache`") && e.contains("integrator `path`"), "{e}");
        let photon = RenderConfig { integrator: "photon".into(), ..Default::default() };
        assert!(make_integrator(&photon.clone().with("ic_tolerance", 0.2)).is_ok());
        let e = make_integrator(&photon.clone().with("gather", "final_gather").with("ic_tolerance", 0.2)).err().unwrap().to_string();
        assert!(e.contains("gather `final_gather`"), "{e}");
        let e = make_integrator(&photon.clone().with("bogus", 1)).err().unwrap().to_string();
        assert!(e.contains("unknown parameter `bogus`"), "{e}");
        let e = make_integrator(&photon.with("passes", 3)).err().unwrap().to_string();
        assert!(e.contains("progressive"), "{e}");
        let e = make_integrator(&RenderConfig { record_passes: vec![2], ..Default::default() }).err().unwrap().to_string();
        assert!(e.contains("record_passes"), "{e}");
    }

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
        for spec in ["off", "fixed", "fixed:0.5", "albedo", "throughput", "throughput:5", "auto"] {
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
