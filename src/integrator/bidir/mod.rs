//! Bidirectional estimators: `bdpt` (bidirectional path tracing, Veach 1997) and `vcm`
//! (vertex connection and merging, Georgiev et al. 2012), organised as SmallVCM.
//!
//! Both run in passes. In each pass N light subpaths are traced (subpath j on its own
//! sampler stream, [`pass::light_stream`]; N = W·H for `bdpt`, `vcm_light_paths` × W·H
//! for `vcm`) and one camera subpath per pixel (the pixel's stream; sample index =
//! pass), so the light-tracing technique has N samples per pass. Pixel p's camera
//! subpath is joined to light subpath p mod N by every technique: emitters hit
//! (s = 0), direct light sampling (s = 1), connections of inner vertices, and the
//! light subpath's vertices are joined to the eye (t = 1, splatted into the pixel
//! they project to). `vcm` by default joins each camera vertex to one vertex drawn
//! from all light vertices of the pass instead of to those of its own subpath
//! (`vcm_connect_draws`), and merges its first non-delta vertex (every non-delta one
//! with `vcm_merge = "all"`) with all light vertices of the pass within a shrinking
//! radius. One MIS weight covers all techniques ([`mis`], constant cost per
//! connection).
//!
//! Files: [`lights`] (emission and direct-sampling densities), [`subpath`] (light
//! subpaths, the scattering step), [`eye`] (camera subpaths and the techniques
//! ending on them), [`grid`] (merging), [`pass`] (one pass, deterministic splats),
//! [`bdpt`] and [`vcm`] (the integrators), [`strategies`] (per-technique images).

pub mod bdpt;
pub mod eye;
pub mod grid;
pub mod lights;
pub mod mis;
pub mod pass;
pub mod select;
pub mod strategies;
pub mod subpath;
pub mod vcm;

#[cfg(test)]
mod mis_tests;

use crate::rr::RussianRoulette;
use crate::world::World;
use mis::Factors;

crate::params! {
    /// Parameters shared by `bdpt` and `vcm`.
    pub struct BidirParams {
        /// MIS heuristic of the bidirectional techniques: `balance` (pbrt-v4, SmallVCM) or `power` (β = 2).
        bdpt_mis: String = "balance",
    }
}

/// Which techniques run (SmallVCM's algorithms).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mode {
    /// Vertex connection: s = 0, 1, inner connections and light tracing.
    pub connect: bool,
    /// Vertex merging.
    pub merge: bool,
    /// Light tracing alone (plus emitters seen directly).
    pub lt: bool,
    /// Progressive photon mapping: merge at the first non-delta camera vertex only,
    /// unweighted.
    pub ppm: bool,
    /// Merging (weighted) only at the first non-delta camera vertex (`vcm_merge =
    /// "first"`) instead of at every one.
    pub merge_first: bool,
}

impl Mode {
    /// `vcm_mode` names.
    pub const NAMES: &'static [&'static str] = &["vcm", "bpt", "ppm", "lt"];

    /// Parses a `vcm_mode`.
    pub fn parse(s: &str) -> anyhow::Result<Self> {
        let m = |connect, merge, lt, ppm| Mode { connect, merge, lt, ppm, merge_first: false };
        Ok(match s {
            "vcm" => m(true, true, false, false),
            "bpt" => m(true, false, false, false),
            "ppm" => m(false, true, false, true),
            "lt" => m(false, false, true, false),
            _ => anyhow::bail!("unknown vcm_mode `{s}` (known: {})", Self::NAMES.join(", ")),
        })
    }

    /// `vcm_merge` names.
    pub const MERGE_NAMES: &'static [&'static str] = &["all", "first"];

    /// Sets where merging happens from a `vcm_merge` value.
    pub fn with_merge(self, s: &str) -> anyhow::Result<Self> {
        let merge_first = match s {
            "all" => false,
            "first" => true,
            _ => anyhow::bail!("unknown vcm_merge `{s}` (known: {})", Self::MERGE_NAMES.join(", ")),
        };
        Ok(Mode { merge_first, ..self })
    }
}

/// Everything a pass needs.
pub struct Ctx<'a> {
    /// The scene.
    pub world: &'a World,
    /// MIS constants.
    pub f: Factors,
    /// Techniques.
    pub mode: Mode,
    /// Most edges of a full path (`max_depth` + 1).
    pub max_len: u32,
    /// Russian roulette.
    pub rr: &'a dyn RussianRoulette,
    /// Merging radius of this pass.
    pub radius: f32,
    /// 1 / (π r² · light subpaths): the merging density normalisation.
    pub vm_norm: f32,
    /// Light subpaths per pass (camera subpath p is joined to light subpath p mod this).
    pub light_paths: u32,
    /// Light vertices each camera vertex is joined to, drawn from the pass's pool; 0:
    /// every vertex of its own light subpath (SmallVCM).
    pub pool_draws: u32,
}

impl<'a> Ctx<'a> {
    /// Context of a pass with merging radius `radius` and `light_paths` light subpaths
    /// (at least 1): the light-tracing and merging normalisations and the MIS sample
    /// counts use that count. `joins` is how camera vertices are joined to light
    /// vertices: `None` to every vertex of their own light subpath, `Some((m, lbar))`
    /// to m vertices drawn from the pass's pool, whose MIS count is m / `lbar` (`lbar`:
    /// light vertices per light subpath, a constant of the run so that the weights do
    /// not depend on the pass's own samples).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        world: &'a World,
        h: mis::Heuristic,
        mode: Mode,
        max_depth: u32,
        rr: &'a dyn RussianRoulette,
        radius: f32,
        light_paths: u32,
        joins: Option<(u32, f32)>,
    ) -> Self {
        let light_paths = light_paths.max(1);
        let n = light_paths as f32;
        let (pool_draws, conn_count) = match joins {
            Some((m, lbar)) if m > 0 && lbar > 0.0 => (m, m as f32 / lbar),
            _ => (0, 1.0),
        };
        let f = Factors::new(h, mode.connect, mode.merge, !mode.merge_first, radius, n, conn_count);
        let vm_norm = 1.0 / (std::f32::consts::PI * radius * radius * n);
        Ctx { world, f, mode, max_len: max_depth.saturating_add(1), rr, radius, vm_norm, light_paths, pool_draws }
    }
}
