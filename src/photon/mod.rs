//! Pass 1 of photon mapping: emission, tracing and storage in the direct, indirect
//! and caustic maps (the design report's state machine, section 4.2.1):
//! a photon's first diffuse hit goes to the **direct** map; after one or more
//! specular (mirror/glass) bounces and no diffuse one, its next diffuse hit goes to
//! the **caustic** map; every later diffuse hit goes to the **indirect** map.
//!
//! Photon paths are traced in parallel in fixed-size batches; path i always uses
//! sample index i of the emission sampler, and batches are merged in path order, so
//! the maps are identical for any thread count.

pub mod emit;
pub mod estimate;
pub mod irradiance;
pub mod kdtree;
pub mod nearest;
pub mod record;
pub mod within;

use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::math::Color;
use crate::rr::{RrContext, RussianRoulette, roulette};
use crate::sampler::Sampler;
use crate::world::World;
use glam::Vec3;
use kdtree::KdTree;
use rayon::prelude::*;
use record::Photon;

/// Which map a stored photon belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// First diffuse hit.
    Direct,
    /// Diffuse hit after only specular bounces.
    Caustic,
    /// Diffuse hit after at least one diffuse bounce.
    Indirect,
}

/// Where a photon's next diffuse hit is stored, given the path so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathState {
    /// Straight from the light.
    FromLight,
    /// Only specular bounces so far (at least one).
    Specular,
    /// At least one diffuse bounce so far.
    Diffuse,
}

impl PathState {
    /// Map for a diffuse hit in this state.
    #[inline]
    pub fn map(self) -> MapKind {
        match self {
            PathState::FromLight => MapKind::Direct,
            PathState::Specular => MapKind::Caustic,
            PathState::Diffuse => MapKind::Indirect,
        }
    }
    /// State after scattering by a delta (`specular == true`) or non-delta lobe.
    #[inline]
    pub fn after(self, specular: bool) -> PathState {
        match (self, specular) {
            (_, false) => PathState::Diffuse,
            (PathState::Diffuse, true) => PathState::Diffuse,
            (_, true) => PathState::Specular,
        }
    }
}

/// Settings of the photon pass.
pub struct PhotonPassSettings {
    /// Photons wanted in the direct + indirect maps together.
    pub global_photons: usize,
    /// Photons wanted in the caustic map.
    pub caustic_photons: usize,
    /// Emit exactly this many photon paths instead of emitting until the maps are full.
    pub fixed_emit: Option<u64>,
    /// Upper bound on emitted paths.
    pub max_emitted: u64,
    /// Maximum bounces per photon path (u32::MAX = unbounded).
    pub max_depth: u32,
    /// kd-trees to build for the direct and indirect maps (the caustic map's is
    /// always built): only direct visualisation and the `photons-*` outputs search
    /// them; gathers search the global grid built from [`PhotonMaps::global`].
    pub trees: MapTrees,
}

/// Which of the direct and indirect maps get a kd-tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapTrees {
    /// The direct map's.
    pub direct: bool,
    /// The indirect map's.
    pub indirect: bool,
}

/// The stored direct photons, then the indirect ones, each in path order, normalised
/// by the paths emitted for them: what the global grid ([`global_grid`]) and, on
/// request, the two maps' kd-trees are built from. Coordinates are kept apart
/// (12 bytes a photon) beside the 8-byte records; [`global_grid`] moves them into
/// the grid, after which only the counts stay here (the kd-trees are then rebuilt
/// from the grid, [`PhotonMaps::ensure_trees_with`]).
#[derive(Clone, Debug, Default)]
pub struct GlobalPhotons {
    /// Coordinates (empty once moved into the global grid).
    pub x: Vec<f32>,
    /// y coordinates.
    pub y: Vec<f32>,
    /// z coordinates.
    pub z: Vec<f32>,
    /// Photons.
    pub photons: Vec<Photon>,
    /// How many are direct (the rest are indirect).
    pub direct: usize,
    /// How many there are (also after the move).
    pub len: usize,
}

impl GlobalPhotons {
    /// Position of photon `i` (while held here).
    pub fn position(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// True once the photons were moved into the global grid.
    pub fn moved(&self) -> bool {
        self.photons.len() < self.len
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.photons.len() * (12 + std::mem::size_of::<Photon>())
    }
}

/// The photon maps and the counts that normalise them.
pub struct PhotonMaps {
    /// Every direct and indirect photon.
    pub global: GlobalPhotons,
    /// First-hit photons, when [`PhotonPassSettings::trees`] asked for them.
    pub direct: Option<KdTree<Photon>>,
    /// Photons after at least one diffuse bounce, when asked for.
    pub indirect: Option<KdTree<Photon>>,
    /// Photons after specular-only paths.
    pub caustic: KdTree<Photon>,
    /// Paths emitted for the direct + indirect maps.
    pub emitted_global: u64,
    /// Paths emitted for the caustic map.
    pub emitted_caustic: u64,
    /// Paths emitted in all.
    pub emitted_total: u64,
    /// Rays traced by the pass.
    pub rays: TraversalStats,
    /// Warnings (e.g. a map that could not be filled).
    pub warnings: Vec<String>,
    /// Seconds spent building the kd-trees (part of the pass).
    pub build_s: f64,
    /// Area of the triangles holding at least one stored global photon.
    pub lit_area_global: f64,
    /// Area of the triangles holding at least one stored caustic photon.
    pub lit_area_caustic: f64,
}

impl PhotonMaps {
    /// Photons stored in the direct + indirect maps.
    pub fn global_len(&self) -> usize {
        self.global.len
    }

    /// Photons stored in the direct map.
    pub fn direct_len(&self) -> usize {
        self.global.direct
    }

    /// Photons stored in the indirect map.
    pub fn indirect_len(&self) -> usize {
        self.global.len - self.global.direct
    }
}

/// Total area of the distinct triangles marked in `hit`.
fn lit_area(world: &World, hit: &[bool]) -> f64 {
    hit.iter()
        .enumerate()
        .filter(|(_, h)| **h)
        .map(|(i, _)| {
            let t = &world.scene.triangles[i];
            0.5 * ((t[1] - t[0]).as_dvec3().cross((t[2] - t[0]).as_dvec3())).length()
        })
        .sum()
}

/// Every stored photon (direct, indirect, caustic) at its stored position, in one
/// grid searched by estimates of `k` photons at final-gather hits. The direct and
/// indirect photons move into the grid (`maps.global` keeps their counts; its
/// kd-trees are rebuilt from the grid when asked for later).
pub fn global_grid(maps: &mut PhotonMaps, k: usize) -> nearest::PhotonGrid {
    let g = &mut maps.global;
    let c = &maps.caustic;
    let total = g.photons.len() + c.len();
    let (mut x, mut y, mut z, mut photons) =
        (std::mem::take(&mut g.x), std::mem::take(&mut g.y), std::mem::take(&mut g.z), std::mem::take(&mut g.photons));
    for v in [&mut x, &mut y, &mut z] {
        v.reserve_exact(total - v.len());
    }
    photons.reserve_exact(total - photons.len());
    for i in 0..c.len() {
        let p = c.position(i);
        x.push(p.x);
        y.push(p.y);
        z.push(p.z);
    }
    photons.extend_from_slice(&c.points);
    nearest::PhotonGrid::build_photons_soa(x, y, z, photons, k)
}

/// The radius that holds `k` photons where `stored` photons spread evenly over
/// `area` (mean density); `None` without photons.
pub fn mean_density_radius(k: usize, stored: usize, area: f64) -> Option<f32> {
    (stored > 0 && area > 0.0).then(|| (k as f64 * area / (std::f64::consts::PI * stored as f64)).sqrt() as f32)
}

/// A photon before normalisation by the emitted count.
#[derive(Clone, Copy, Debug)]
pub struct RawPhoton {
    /// Map it belongs to.
    pub kind: MapKind,
    /// Position.
    pub pos: Vec3,
    /// Power (not yet divided by the number of emitted paths).
    pub power: Color,
    /// Incoming direction (towards the photon's origin).
    pub dir: Vec3,
    /// Surface normal on the arrival side.
    pub normal: Vec3,
    /// Triangle it landed on.
    pub tri: u32,
}

/// A photon as the pass keeps it until the emitted count is known (28 bytes):
/// direction and normal already encoded ([`record::encode_dir`]), the power not yet
/// normalised.
#[derive(Clone, Copy, Debug)]
struct PassPhoton {
    pos: Vec3,
    power: Color,
    dir: u16,
    normal: u16,
}

impl PassPhoton {
    fn new(r: &RawPhoton) -> Self {
        PassPhoton { pos: r.pos, power: r.power, dir: record::encode_dir(r.dir), normal: record::encode_dir(r.normal) }
    }
}

/// Stored photons of one map in chunks of [`PASS_CHUNK`] (no vector ever grows, so
/// no reallocation doubles the storage), and the triangles they landed on.
struct PassMap {
    chunks: Vec<Vec<PassPhoton>>,
    len: usize,
    hit: Vec<bool>,
}

/// Photons per chunk of a [`PassMap`]: 56 MiB, above the size from which the
/// allocator maps memory of its own, so each chunk goes back to the system as soon
/// as it is normalised (smaller blocks would stay in the heap, resident beside the
/// normalised copy). Untouched capacity is not resident.
const PASS_CHUNK: usize = 1 << 21;

impl PassMap {
    fn new(triangles: usize) -> Self {
        PassMap { chunks: Vec::new(), len: 0, hit: vec![false; triangles] }
    }
    fn push(&mut self, r: &RawPhoton) {
        self.hit[r.tri as usize] = true;
        self.len += 1;
        match self.chunks.last_mut() {
            Some(c) if c.len() < PASS_CHUNK => c.push(PassPhoton::new(r)),
            _ => {
                let mut c = Vec::with_capacity(PASS_CHUNK);
                c.push(PassPhoton::new(r));
                self.chunks.push(c);
            }
        }
    }
}

/// Emission sampler dimensions: light choice, position (2), direction (2); then
/// `PHOTON_DIMS_PER_BOUNCE` per bounce: lobe, direction (2), roulette.
const PHOTON_DIM_BOUNCE: u32 = 5;
const PHOTON_DIMS_PER_BOUNCE: u32 = 4;
/// Stream id of the emission sequence (distinct from every pixel stream).
pub const PHOTON_STREAM: u64 = u64::MAX - 1;
const BATCH: u64 = 1 << 14;

/// Traces one photon path, appending its stored photons to `out`.
pub fn trace_path(
    world: &World,
    sampler: &mut dyn Sampler,
    index: u64,
    rr: &dyn RussianRoulette,
    max_depth: u32,
    stats: &mut TraversalStats,
    out: &mut Vec<RawPhoton>,
) {
    trace_path_in(world, sampler, PHOTON_STREAM, index, rr, max_depth, stats, out);
}

/// [`trace_path`] with sample `index` of sampler stream `stream` instead of the one
/// emission sequence [`PHOTON_STREAM`] (`sppm` gives every pass a stream of its own,
/// so indices stay small: fewer radical-inverse digits, independent passes).
///
/// Generic over the sampler so that hot callers holding a concrete one (`sppm`, via
/// [`crate::sampler::with_sampler!`]) draw without a virtual call per dimension, and
/// over where the photons go (a `Vec<RawPhoton>`, or a caller's own sink that keeps
/// only some, in its own format).
#[allow(clippy::too_many_arguments)]
pub fn trace_path_in<S: Sampler + ?Sized>(
    world: &World,
    sampler: &mut S,
    stream: u64,
    index: u64,
    rr: &dyn RussianRoulette,
    max_depth: u32,
    stats: &mut TraversalStats,
    out: &mut impl Extend<RawPhoton>,
) {
    sampler.start(stream, index);
    let u_sel = sampler.next_1d();
    let u_pos = sampler.next_2d();
    let u_dir = sampler.next_2d();
    let Some(e) = emit::emit_photon(&world.lights, &world.scene, u_sel, u_pos, u_dir) else { return };
    let initial = e.power;
    let mut power = e.power;
    let mut ray = Ray::new(e.origin, e.dir);
    let mut state = PathState::FromLight;
    let mut depth = 0u32;
    while let Some(it) = world.intersect(&ray, stats) {
        // Textured parameters filled in: scattered power and the roulette's albedo
        // follow the texel the photon landed on.
        let bsdf = &*world.bsdf_at(&it);
        let wo = -ray.d;
        if !bsdf.is_delta() {
            let n = if wo.dot(it.sp.ng) >= 0.0 { it.sp.ng } else { -it.sp.ng };
            // Photons land per unit geometric area; radiance transport with shading
            // normals (`path`, direct light) weighs arriving light by |ω·n_s|. Stored
            // scaled by |wo·n_s|/|wo·n_g|, every estimate reading them (photon maps,
            // precomputed irradiance, `sppm`'s visible points) gets that measure: the
            // factor of the photon's own point, which tends to the query's as the
            // radius shrinks (shading normals are continuous across a mesh).
            let stored = power * it.sp.shading_to_geometric(wo);
            out.extend(std::iter::once(RawPhoton { kind: state.map(), pos: it.p, power: stored, dir: wo, normal: n, tri: it.tri }));
        }
        if depth >= max_depth {
            break;
        }
        let dim = PHOTON_DIM_BOUNCE.saturating_add(depth.saturating_mul(PHOTON_DIMS_PER_BOUNCE));
        sampler.set_dimension(dim);
        let u_lobe = sampler.next_1d();
        let u = sampler.next_2d();
        let u_rr = sampler.next_1d();
        let Some(bs) = bsdf.sample(&it.sp, wo, u_lobe, u, TransportMode::Importance) else { break };
        // Shading normals make scattering non-symmetric: the adjoint correction.
        power *= bs.weight * it.sp.importance_correction(wo, bs.wi);
        depth += 1;
        let rel = Color::new(ratio(power.x, initial.x), ratio(power.y, initial.y), ratio(power.z, initial.z));
        match roulette(rr, &RrContext { depth, throughput: rel, albedo: bsdf.albedo() }, u_rr) {
            Some(w) => power *= w,
            None => break,
        }
        if power.max_element() <= 0.0 {
            break;
        }
        state = state.after(bs.delta);
        ray = world.spawn(&it, bs.wi);
    }
}

#[inline]
fn ratio(a: f32, b: f32) -> f32 {
    if b > 0.0 { a / b } else { 0.0 }
}

/// Runs the photon pass. `sampler` is the emission sampler prototype (its sample
/// index is the photon path number).
pub fn build_maps(world: &World, sampler: &dyn Sampler, rr: &dyn RussianRoulette, s: &PhotonPassSettings, quiet: bool) -> PhotonMaps {
    let has_specular = world.scene.tri_material.iter().any(|&m| world.scene.materials[m as usize].bsdf.has_delta());
    let mut warnings = Vec::new();
    let mut want_caustic = s.caustic_photons;
    if want_caustic > 0 && !has_specular {
        warnings.push("the scene has no specular (mirror/glass) surface: the caustic map stays empty".into());
        want_caustic = 0;
    }
    let tris = world.scene.triangles.len();
    let (mut direct, mut indirect, mut caustic) = (PassMap::new(tris), PassMap::new(tris), PassMap::new(tris));
    let (mut global_done, mut caustic_done) = (s.global_photons == 0, want_caustic == 0);
    let (mut n_global, mut n_caustic) = (0u64, 0u64);
    let limit = s.fixed_emit.unwrap_or(s.max_emitted);
    let mut emitted = 0u64;
    let mut rays = TraversalStats::default();
    let pb = crate::progress::progress_bar(limit.min((s.global_photons + s.caustic_photons) as u64 * 4), quiet, "photons");
    while emitted < limit && (s.fixed_emit.is_some() || !(global_done && caustic_done)) && !crate::progress::cancelled() {
        let n = BATCH.min(limit - emitted);
        let results: Vec<(Vec<RawPhoton>, TraversalStats)> = (0..n as usize)
            .into_par_iter()
            .with_min_len(256)
            .map_init(
                || sampler.clone_box(),
                |smp, j| {
                    let mut out = Vec::new();
                    let mut st = TraversalStats::default();
                    trace_path(world, smp.as_mut(), emitted + j as u64, rr, s.max_depth, &mut st, &mut out);
                    (out, st)
                },
            )
            .collect();
        for (j, (photons, st)) in results.into_iter().enumerate() {
            rays.add(&st);
            let path = emitted + j as u64;
            for raw in &photons {
                match raw.kind {
                    MapKind::Caustic if !caustic_done => caustic.push(raw),
                    MapKind::Direct if !global_done => direct.push(raw),
                    MapKind::Indirect if !global_done => indirect.push(raw),
                    _ => {}
                }
            }
            if s.fixed_emit.is_none() {
                if !global_done && direct.len + indirect.len >= s.global_photons {
                    global_done = true;
                    n_global = path + 1;
                }
                if !caustic_done && caustic.len >= want_caustic {
                    caustic_done = true;
                    n_caustic = path + 1;
                }
            }
        }
        emitted += n;
        pb.set_position(emitted);
        // A caustic map that stays empty long after the global one filled cannot be
        // filled (specular surfaces the lights do not reach).
        if s.fixed_emit.is_none() && global_done && !caustic_done && caustic.len == 0 && emitted >= 4 * n_global.max(BATCH) {
            warnings
                .push(format!("no photon reached a diffuse surface via a specular one after {emitted} paths: the caustic map stays empty"));
            caustic_done = true;
        }
    }
    pb.finish_and_clear();
    if !global_done {
        n_global = emitted;
        if s.fixed_emit.is_none() {
            warnings.push(format!(
                "emission cap of {} paths reached with {} of {} global photons stored",
                s.max_emitted,
                direct.len + indirect.len,
                s.global_photons
            ));
        }
    }
    if !caustic_done || n_caustic == 0 {
        n_caustic = emitted;
        if s.fixed_emit.is_none() && want_caustic > 0 && caustic.len < want_caustic && caustic.len > 0 {
            warnings.push(format!(
                "emission cap of {} paths reached with {} of {} caustic photons stored",
                s.max_emitted, caustic.len, want_caustic
            ));
        }
    }
    let t_build = std::time::Instant::now();
    let inv = |n: u64| 1.0 / n.max(1) as f32;
    let mut hit_global = std::mem::take(&mut direct.hit);
    for (h, i) in hit_global.iter_mut().zip(&indirect.hit) {
        *h |= *i;
    }
    let (lit_area_global, lit_area_caustic) = (lit_area(world, &hit_global), lit_area(world, &caustic.hit));
    drop(hit_global);
    // The global photons: direct then indirect, in path order, chunk by chunk (each
    // chunk freed once normalised). Room for the caustic photons too, which the
    // global grid appends.
    let direct_count = direct.len;
    let (n, room) = (direct.len + indirect.len, direct.len + indirect.len + caustic.len);
    let mut global = GlobalPhotons {
        x: Vec::with_capacity(room),
        y: Vec::with_capacity(room),
        z: Vec::with_capacity(room),
        photons: Vec::with_capacity(room),
        direct: direct_count,
        len: n,
    };
    let inv_global = inv(n_global);
    for batch in direct.chunks.drain(..).chain(indirect.chunks.drain(..)) {
        normalise_into(&batch, inv_global, &mut global);
    }
    let c = caustic.len;
    let mut caustic_photons = GlobalPhotons {
        x: Vec::with_capacity(c),
        y: Vec::with_capacity(c),
        z: Vec::with_capacity(c),
        photons: Vec::with_capacity(c),
        ..Default::default()
    };
    for batch in caustic.chunks.drain(..) {
        normalise_into(&batch, inv(n_caustic), &mut caustic_photons);
    }
    let cp: Vec<Vec3> = (0..caustic_photons.photons.len()).map(|i| caustic_photons.position(i)).collect();
    let caustic_t = KdTree::build_with(&cp, caustic_photons.photons);
    let mut maps = PhotonMaps {
        global,
        direct: None,
        indirect: None,
        caustic: caustic_t,
        emitted_global: n_global,
        emitted_caustic: n_caustic,
        emitted_total: emitted,
        rays,
        warnings,
        build_s: 0.0,
        lit_area_global,
        lit_area_caustic,
    };
    maps.ensure_trees(s.trees);
    maps.build_s += t_build.elapsed().as_secs_f64();
    maps
}

/// Appends `batch` normalised by `inv` to `out` (records encoded in parallel, in
/// order: the same photons for any thread count).
fn normalise_into(batch: &[PassPhoton], inv: f32, out: &mut GlobalPhotons) {
    out.photons.par_extend(batch.par_iter().map(|r| Photon::from_codes(r.power * inv, r.dir, r.normal)));
    for r in batch {
        out.x.push(r.pos.x);
        out.y.push(r.pos.y);
        out.z.push(r.pos.z);
    }
}

impl PhotonMaps {
    /// Builds the kd-trees of the direct and indirect maps that `want` asks for and
    /// that do not exist yet, from the global photons held here (before
    /// [`global_grid`] moved them).
    pub fn ensure_trees(&mut self, want: MapTrees) {
        self.ensure_trees_from(want, None);
    }

    /// [`PhotonMaps::ensure_trees`], reading the photons from `grid` (the global grid
    /// built from these maps) once they were moved into it (the photon integrator
    /// calls it again when an output that searches the trees is chosen after the
    /// pre-pass). The trees are built from the same positions and records in the
    /// same order either way, so they are the same trees.
    pub fn ensure_trees_with(&mut self, want: MapTrees, grid: &nearest::PhotonGrid) {
        self.ensure_trees_from(want, Some(grid));
    }

    fn ensure_trees_from(&mut self, want: MapTrees, grid: Option<&nearest::PhotonGrid>) {
        let (need_d, need_i) = (want.direct && self.direct.is_none(), want.indirect && self.indirect.is_none());
        if !need_d && !need_i {
            return;
        }
        let g = &self.global;
        let (d, n) = (g.direct, g.len);
        // Where each global photon is: here, or at its place in the grid.
        let at: Option<Vec<u32>> = g.moved().then(|| {
            let grid = grid.expect("the global photons moved into a grid: pass it to ensure_trees_with");
            let mut at = vec![u32::MAX; n];
            for i in 0..grid.len() {
                if let Some(src) = grid.source(i).filter(|&src| src < n) {
                    at[src] = i as u32;
                }
            }
            at
        });
        let photon = |i: usize| -> (Vec3, Photon) {
            match (&at, grid) {
                (Some(at), Some(grid)) => (grid.position(at[i] as usize), *grid.item(at[i] as usize)),
                _ => (g.position(i), g.photons[i]),
            }
        };
        let tree = |need: bool, r: std::ops::Range<usize>| {
            need.then(|| {
                let (pos, ph): (Vec<Vec3>, Vec<Photon>) = r.map(photon).unzip();
                KdTree::build_with(&pos, ph)
            })
        };
        let (direct, indirect) = rayon::join(|| tree(need_d, 0..d), || tree(need_i, d..n));
        self.direct = self.direct.take().or(direct);
        self.indirect = self.indirect.take().or(indirect);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::material::{Bsdf, Material, Mirror};
    use crate::registry::{make_accel, make_rr, make_sampler};
    use crate::scene::LightDesc;
    use crate::scene::{Face, MeshData, Placement, Scene};

    /// A point light between a mirror floor (y = 0) and a white ceiling (y = 2):
    /// photons going up hit the ceiling first (direct map); photons going down are
    /// reflected by the mirror onto the ceiling (caustic map); everything after a
    /// ceiling bounce is indirect.
    #[test]
    fn storage_on_constructed_paths() {
        let quad = |y: f32, material: u32, up: bool| {
            let mut m = MeshData::default();
            let s = 50.0;
            m.positions = vec![Vec3::new(-s, y, -s), Vec3::new(s, y, -s), Vec3::new(s, y, s), Vec3::new(-s, y, s)];
            let (a, b) = if up { ([0, 2, 1], [0, 3, 2]) } else { ([0, 1, 2], [0, 2, 3]) };
            m.faces = vec![Face { v: a, n: None, material, line: 0 }, Face { v: b, n: None, material, line: 0 }];
            m
        };
        let mut floor = quad(0.0, 0, true);
        floor.materials =
            vec![Material { name: "mirror".into(), bsdf: Bsdf::Mirror(Mirror { reflectance: Color::ONE }), emission: Color::ZERO }];
        let mut ceiling = quad(2.0, 0, false);
        ceiling.materials = vec![Material::diffuse("white", Color::splat(0.5))];
        let cam = Camera::new(Vec3::new(0.0, 1.0, 5.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 40.0, 8, 8).unwrap();
        let mut scene = Scene::new("mirror-room", cam);
        scene.add_mesh(&floor, &Placement::default(), None).unwrap();
        scene.add_mesh(&ceiling, &Placement::default(), None).unwrap();
        scene.lights.push(LightDesc::Point { position: Vec3::new(0.0, 1.0, 0.0), intensity: Color::ONE });
        let accel = make_accel("bvh", &scene.triangles).unwrap();
        let world = World::new(scene, accel).unwrap();
        let rr = make_rr("albedo").unwrap();
        let mut sampler = make_sampler("halton", 1, None).unwrap();
        let (mut first, mut later) = (Vec::new(), Vec::new());
        let mut stats = TraversalStats::default();
        for i in 0..4000 {
            let mut out = Vec::new();
            trace_path(&world, sampler.as_mut(), i, rr.as_ref(), 20, &mut stats, &mut out);
            let Some((head, tail)) = out.split_first() else { continue };
            // Every stored photon is on the ceiling (the only diffuse surface).
            assert!(out.iter().all(|p| (p.pos.y - 2.0).abs() < 1e-3));
            first.push((head.kind, head.dir.y));
            later.extend(tail.iter().map(|p| p.kind));
        }
        // First stored photon: direct when it came straight up, caustic when it came
        // via the mirror; the two are about equally likely.
        for &(kind, _) in &first {
            assert!(kind == MapKind::Direct || kind == MapKind::Caustic);
        }
        let caustic = first.iter().filter(|f| f.0 == MapKind::Caustic).count() as f64 / first.len() as f64;
        assert!((caustic - 0.5).abs() < 0.05, "caustic fraction {caustic}");
        assert!(!later.is_empty() && later.iter().all(|&k| k == MapKind::Indirect));
    }

    /// The photon pass on `cornell-glass` (direct, indirect and caustic photons).
    fn glass_maps(trees: MapTrees) -> PhotonMaps {
        let scene = crate::scene::builtin::builtin("cornell-glass").unwrap();
        let accel = make_accel("bvh", &scene.triangles).unwrap();
        let world = World::new(scene, accel).unwrap();
        let rr = make_rr("albedo").unwrap();
        let sampler = make_sampler("halton", 3, None).unwrap();
        let s = PhotonPassSettings {
            global_photons: 6000,
            caustic_photons: 2000,
            fixed_emit: None,
            max_emitted: 1_000_000,
            max_depth: 32,
            trees,
        };
        build_maps(&world, sampler.as_ref(), rr.as_ref(), &s, true)
    }

    /// The kd-trees of the direct and indirect maps are the same when built from
    /// the photons held by the maps and, after they moved into the global grid, from
    /// the grid; the grid holds every photon once, at its stored position.
    #[test]
    fn trees_from_the_grid_equal_the_trees_from_the_pass() {
        let both = MapTrees { direct: true, indirect: true };
        let before = glass_maps(both);
        let mut maps = glass_maps(MapTrees::default());
        assert!(maps.direct.is_none() && maps.indirect.is_none());
        assert!(maps.direct_len() > 1000 && maps.indirect_len() > 1000 && maps.caustic.len() >= 2000);
        let held: Vec<(Vec3, Photon)> = (0..maps.global_len()).map(|i| (maps.global.position(i), maps.global.photons[i])).collect();
        let grid = global_grid(&mut maps, 50);
        assert!(maps.global.moved() && maps.global.memory_bytes() == 0);
        assert_eq!(grid.len(), maps.global_len() + maps.caustic.len());
        for i in 0..grid.len() {
            let src = grid.source(i).unwrap();
            let want =
                if src < held.len() { held[src] } else { (maps.caustic.position(src - held.len()), maps.caustic.points[src - held.len()]) };
            assert_eq!((grid.position(i), *grid.item(i)), want);
        }
        maps.ensure_trees_with(both, &grid);
        for (a, b) in [(&before.direct, &maps.direct), (&before.indirect, &maps.indirect)] {
            let (a, b) = (a.as_ref().unwrap(), b.as_ref().unwrap());
            assert_eq!(a.points, b.points);
            assert!((0..a.len()).all(|i| a.position(i) == b.position(i)));
        }
    }

    #[test]
    fn storage_state_machine() {
        // L D: direct; L S D: caustic; L S S D: caustic; L D D: indirect;
        // L D S D: indirect; L S D D: indirect.
        let run = |bounces: &[bool]| {
            let mut s = PathState::FromLight;
            for &spec in bounces {
                s = s.after(spec);
            }
            s.map()
        };
        assert_eq!(run(&[]), MapKind::Direct);
        assert_eq!(run(&[true]), MapKind::Caustic);
        assert_eq!(run(&[true, true]), MapKind::Caustic);
        assert_eq!(run(&[false]), MapKind::Indirect);
        assert_eq!(run(&[false, true]), MapKind::Indirect);
        assert_eq!(run(&[true, false]), MapKind::Indirect);
    }
}
