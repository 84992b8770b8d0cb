//! The photon hash grid of `sppm`'s gather, rebuilt every pass.
//!
//! Photons are bucketed by a spatial hash of their grid cell with a counting sort
//! into flat arrays (bucket b holds slots `start[b]..start[b + 1]`), stable: each
//! bucket keeps photon (path) order, so a pixel adds its photons in the same order
//! for any thread count. The sort runs in parallel straight from the photon pass's
//! chunks (no merged copy): the chunks are split into one run of consecutive chunks
//! per thread, each run counts its photons per bucket, a prefix sum over (bucket,
//! run) gives every run its own slots in every bucket, and the runs scatter into
//! them at once. How the chunks are split changes which thread writes a slot, never
//! what it holds. Positions are stored apart from the rest of a photon, one array per
//! coordinate, and tested against the radius 8 at a time (SSE on x86-64, the same
//! operations as the scalar test, so the same photons): a photon outside the radius
//! costs the gather 12 bytes of reads instead of 48.
//! All buffers are reused when the grid is rebuilt (no fresh pages per pass).

use crate::math::{Color, mix64};
use crate::photon::nearest::prefetch;
use glam::{IVec3, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// A kept photon, as the photon pass stores it (48 bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridPhoton {
    /// Position.
    pub pos: Vec3,
    /// Incoming direction (towards the photon's origin).
    pub dir: Vec3,
    /// Surface normal on the arrival side.
    pub normal: Vec3,
    /// Power (not yet divided by the number of emitted paths).
    pub power: Color,
}

impl From<&crate::photon::RawPhoton> for GridPhoton {
    fn from(p: &crate::photon::RawPhoton) -> Self {
        GridPhoton { pos: p.pos, dir: p.dir, normal: p.normal, power: p.power }
    }
}

/// What the gather reads of a photon within the radius (its position is stored apart).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhotonShade {
    /// Incoming direction (towards the photon's origin).
    pub dir: Vec3,
    /// Surface normal on the arrival side.
    pub normal: Vec3,
    /// Power (not yet divided by the number of emitted paths).
    pub power: Color,
}

/// One thread's run of consecutive chunks while the grid is built.
#[derive(Default)]
struct Run {
    /// Chunks of the run.
    chunks: Range<usize>,
    /// Its photons per bucket, then its next free slot in each bucket.
    slots: Vec<u32>,
    /// Bucket of each of its photons, in order.
    keys: Vec<u32>,
}

/// Photons bucketed by a spatial hash of their grid cell (see the module docs).
#[derive(Default)]
pub struct PhotonGrid {
    inv_cell: f32,
    mask: usize,
    start: Vec<u32>,
    /// Positions' coordinates, each padded with [`BLOCK`] zeros (whole blocks load).
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    shade: Vec<PhotonShade>,
    runs: Vec<Run>,
}

/// Photons tested at once by [`PhotonGrid::for_each_within`].
const BLOCK: usize = 8;
/// Buckets per block of the parallel prefix sum.
const SCAN_BLOCK: usize = 1 << 12;

#[inline]
fn cell_hash(c: IVec3, mask: usize) -> usize {
    let h = (c.x as u32).wrapping_mul(73_856_093) ^ (c.y as u32).wrapping_mul(19_349_663) ^ (c.z as u32).wrapping_mul(83_492_791);
    (mix64(h as u64) as usize) & mask
}

/// The grid's output arrays, written by several runs at once at disjoint slots.
#[derive(Clone, Copy)]
struct Out {
    x: *mut f32,
    y: *mut f32,
    z: *mut f32,
    shade: *mut PhotonShade,
    len: usize,
}

// SAFETY: `Out` only hands its pointers to `PhotonGrid::build`'s scatter, where every
// slot is written by exactly one run (see there) while the arrays are borrowed mutably.
unsafe impl Send for Out {}
// SAFETY: as above.
unsafe impl Sync for Out {}

impl Out {
    /// Writes photon `p` to slot `i`.
    ///
    /// # Safety
    /// No other thread may access slot `i` meanwhile.
    #[inline]
    unsafe fn write(&self, i: usize, p: &GridPhoton) {
        assert!(i < self.len);
        // SAFETY: `i` is in bounds (checked) and the caller owns slot `i`.
        unsafe {
            self.x.add(i).write(p.pos.x);
            self.y.add(i).write(p.pos.y);
            self.z.add(i).write(p.pos.z);
            self.shade.add(i).write(PhotonShade { dir: p.dir, normal: p.normal, power: p.power });
        }
    }
}

impl PhotonGrid {
    /// Rebuilds the grid with cubic cells of edge `cell` over the photons of `chunks`,
    /// taken in order (chunk 0's photons first).
    pub fn build<C: AsRef<[GridPhoton]> + Sync>(&mut self, chunks: &[C], cell: f32) {
        let n: usize = chunks.iter().map(|c| c.as_ref().len()).sum();
        assert!(n < u32::MAX as usize, "too many photons for one grid ({n})");
        self.inv_cell = 1.0 / cell.max(1e-30);
        let buckets = n.next_power_of_two().max(64);
        self.mask = buckets - 1;
        let (inv_cell, mask) = (self.inv_cell, self.mask);

        // Runs of consecutive chunks holding about n / threads photons each.
        let k = rayon::current_num_threads().clamp(1, chunks.len().max(1));
        self.runs.resize_with(k, Run::default);
        let (mut c0, mut acc) = (0, 0);
        for (i, run) in self.runs.iter_mut().enumerate() {
            let goal = n * (i + 1) / k;
            let mut c1 = c0;
            while c1 < chunks.len() && (acc < goal || i + 1 == k) {
                acc += chunks[c1].as_ref().len();
                c1 += 1;
            }
            run.chunks = c0..c1;
            c0 = c1;
        }

        // 1. Each run's bucket of every photon, and its count per bucket.
        self.runs.par_iter_mut().for_each(|run| {
            run.slots.clear();
            run.slots.resize(buckets, 0);
            run.keys.clear();
            for c in &chunks[run.chunks.clone()] {
                for p in c.as_ref() {
                    let key = cell_hash((p.pos * inv_cell).floor().as_ivec3(), mask);
                    run.keys.push(key as u32);
                    run.slots[key] += 1;
                }
            }
        });

        // 2. Prefix sum over (bucket, run), block by block in parallel: start[b] is
        // bucket b's first slot, and run r's slots in bucket b follow those of runs < r.
        self.start.resize(buckets + 1, 0);
        let blocks = buckets.div_ceil(SCAN_BLOCK);
        let runs = &self.runs;
        let mut offset: Vec<u32> = (0..blocks)
            .into_par_iter()
            .map(|j| {
                let b = j * SCAN_BLOCK..((j + 1) * SCAN_BLOCK).min(buckets);
                runs.iter().map(|r| r.slots[b.clone()].iter().sum::<u32>()).sum()
            })
            .collect();
        let mut sum = 0u32;
        for o in &mut offset {
            sum += std::mem::replace(o, sum);
        }
        self.start[buckets] = sum;
        let mut views: Vec<(&mut [u32], Vec<&mut [u32]>)> =
            self.start[..buckets].chunks_mut(SCAN_BLOCK).map(|s| (s, Vec::with_capacity(k))).collect();
        for run in &mut self.runs {
            for (v, s) in views.iter_mut().zip(run.slots.chunks_mut(SCAN_BLOCK)) {
                v.1.push(s);
            }
        }
        views.into_par_iter().zip(offset).for_each(|((start, mut slots), mut next)| {
            for (b, s) in start.iter_mut().enumerate() {
                *s = next;
                for r in slots.iter_mut() {
                    next += std::mem::replace(&mut r[b], next);
                }
            }
        });

        // 3. Scatter: each run fills its own slots, in photon order.
        for v in [&mut self.x, &mut self.y, &mut self.z] {
            v.resize(n + BLOCK, 0.0);
            v.truncate(n + BLOCK);
            v[n..].fill(0.0);
        }
        self.shade.resize(n, PhotonShade::default());
        self.shade.truncate(n);
        let out = Out { x: self.x.as_mut_ptr(), y: self.y.as_mut_ptr(), z: self.z.as_mut_ptr(), shade: self.shade.as_mut_ptr(), len: n };
        self.runs.par_iter_mut().for_each(|run| {
            let photons = chunks[run.chunks.clone()].iter().flat_map(|c| c.as_ref());
            for (p, &key) in photons.zip(&run.keys) {
                let slot = &mut run.slots[key as usize];
                let i = *slot as usize;
                *slot += 1;
                // SAFETY: no other run writes slot `i`: run r owns slots start[b] +
                // Σ_{q<r} count_q[b] + (0..count_r[b]) of bucket b, disjoint for distinct
                // (run, bucket) and covering 0..n; `pos` and `shade` stay mutably
                // borrowed by `self` meanwhile.
                unsafe { out.write(i, p) };
            }
        });
    }

    /// A bit per photon of `i..i + BLOCK` whose distance² to `p`, computed as
    /// `(pos − p).length_squared()`, is not above `r2` (NaN counts as not above).
    #[inline(always)]
    fn block(&self, i: usize, p: Vec3, r2: f32) -> u32 {
        fn lanes(v: &[f32], i: usize) -> &[f32; BLOCK] {
            v[i..i + BLOCK].try_into().expect("padded")
        }
        let (x, y, z) = (lanes(&self.x, i), lanes(&self.y, i), lanes(&self.z, i));
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::*;
            let mut mask = 0u32;
            // SAFETY: SSE is part of x86-64; every load is within a BLOCK-long array
            // (h·4 + 4 ≤ BLOCK).
            unsafe {
                let (px, py, pz, rv) = (_mm_set1_ps(p.x), _mm_set1_ps(p.y), _mm_set1_ps(p.z), _mm_set1_ps(r2));
                for h in 0..BLOCK / 4 {
                    let o = 4 * h;
                    let dx = _mm_sub_ps(_mm_loadu_ps(x.as_ptr().add(o)), px);
                    let dy = _mm_sub_ps(_mm_loadu_ps(y.as_ptr().add(o)), py);
                    let dz = _mm_sub_ps(_mm_loadu_ps(z.as_ptr().add(o)), pz);
                    let dd = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
                    mask |= (_mm_movemask_ps(_mm_cmpngt_ps(dd, rv)) as u32) << o;
                }
            }
            mask
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let mut mask = 0u32;
            for j in 0..BLOCK {
                let d = Vec3::new(x[j], y[j], z[j]) - p;
                mask |= (!(d.length_squared() > r2) as u32) << j;
            }
            mask
        }
    }

    /// Photons stored.
    pub fn len(&self) -> usize {
        self.shade.len()
    }

    /// Whether the grid holds no photon.
    pub fn is_empty(&self) -> bool {
        self.shade.is_empty()
    }

    /// Calls `f` with the position and the shading data of every photon within `r`
    /// of `p` (distance² ≤ r², computed as `(pos − p).length_squared()`), each once,
    /// cell by cell in photon order.
    #[inline]
    pub fn for_each_within(&self, p: Vec3, r: f32, mut f: impl FnMut(Vec3, &PhotonShade)) {
        if self.shade.is_empty() {
            return;
        }
        let r2 = r * r;
        let lo = ((p - Vec3::splat(r)) * self.inv_cell).floor().as_ivec3();
        let hi = ((p + Vec3::splat(r)) * self.inv_cell).floor().as_ivec3();
        // The distinct buckets of the (up to) 3 × 3 × 3 cells, then their ranges, each
        // step's loads requested before any is used, so the cache misses of the
        // buckets overlap instead of forming one chain per bucket.
        let mut seen = [0usize; 27];
        let mut n = 0;
        for z in lo.z..=hi.z.min(lo.z + 2) {
            for y in lo.y..=hi.y.min(lo.y + 2) {
                for x in lo.x..=hi.x.min(lo.x + 2) {
                    let b = cell_hash(IVec3::new(x, y, z), self.mask);
                    if !seen[..n].contains(&b) {
                        prefetch(&self.start[b]);
                        seen[n] = b;
                        n += 1;
                    }
                }
            }
        }
        let mut ranges = [(0usize, 0usize); 27];
        for (r, &b) in ranges.iter_mut().zip(&seen[..n]) {
            *r = (self.start[b] as usize, self.start[b + 1] as usize);
            if r.0 < r.1 {
                for v in [&self.x, &self.y, &self.z] {
                    prefetch(&v[r.0]);
                }
            }
        }
        for &(mut i, end) in &ranges[..n] {
            while i < end {
                let mut mask = self.block(i, p, r2);
                if end - i < BLOCK {
                    mask &= (1 << (end - i)) - 1;
                }
                while mask != 0 {
                    let j = i + mask.trailing_zeros() as usize;
                    f(Vec3::new(self.x[j], self.y[j], self.z[j]), &self.shade[j]);
                    mask &= mask - 1;
                }
                i += BLOCK;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_photons(count: usize) -> Vec<GridPhoton> {
        let mut h = 7u64;
        let mut u = || {
            h = mix64(h);
            (h >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..count)
            .map(|i| {
                let pos = Vec3::new(u() * 4.0 - 2.0, u() * 4.0 - 2.0, u() * 0.5);
                // The power carries the photon's index, to find it again in the grid.
                GridPhoton { pos, power: Color::splat(i as f32), dir: Vec3::Z, normal: Vec3::Z }
            })
            .collect()
    }

    /// `photons` cut into chunks of the given sizes, cycled.
    fn chunked(photons: &[GridPhoton], sizes: &[usize]) -> Vec<Vec<GridPhoton>> {
        let (mut out, mut i) = (Vec::new(), 0);
        for s in sizes.iter().cycle() {
            if i >= photons.len() {
                break;
            }
            out.push(photons[i..(i + s).min(photons.len())].to_vec());
            i += s;
        }
        out
    }

    #[test]
    fn grid_visits_every_photon_within_the_radius_once_in_photon_order() {
        let photons = random_photons(5000);
        let r = 0.3f32;
        let mut grid = PhotonGrid::default();
        grid.for_each_within(Vec3::ZERO, r, |_, _| panic!("an empty grid has no photons"));
        grid.build(&chunked(&photons, &[700, 0, 33, 1024]), 2.0 * r);
        assert_eq!(grid.len(), photons.len());
        let mut u = 0.1f32;
        for q in 0..200 {
            u = (u * 7.31 + 0.17).fract();
            let p = Vec3::new(u * 4.0 - 2.0, (u * 13.7).fract() * 4.0 - 2.0, (u * 5.3).fract() * 0.5);
            let rq = r * (0.2 + 0.8 * (q % 5) as f32 / 4.0);
            let mut seen = vec![0u32; photons.len()];
            grid.for_each_within(p, rq, |_, ph| seen[ph.power.x as usize] += 1);
            for (i, ph) in photons.iter().enumerate() {
                let within = (ph.pos - p).length_squared() <= rq * rq;
                assert_eq!(seen[i], within as u32, "photon {i}: visited {} times, within {within}", seen[i]);
            }
        }
        // Each bucket keeps photon order.
        for b in 0..grid.start.len() - 1 {
            let idx: Vec<f32> = grid.shade[grid.start[b] as usize..grid.start[b + 1] as usize].iter().map(|s| s.power.x).collect();
            assert!(idx.windows(2).all(|w| w[0] < w[1]), "bucket {b} out of photon order");
        }
    }

    #[test]
    fn the_grid_is_the_same_for_any_chunking_and_thread_count() {
        let photons = random_photons(20_000);
        let build = |threads: usize, sizes: &[usize]| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut grid = PhotonGrid::default();
            pool.install(|| {
                // Built twice: a reused grid equals a fresh one.
                grid.build(&chunked(&photons[..5000], &[100]), 0.05);
                grid.build(&chunked(&photons, sizes), 0.2);
            });
            (grid.start, grid.x, grid.y, grid.z, grid.shade)
        };
        let one = build(1, &[20_000]);
        for (threads, sizes) in [(1, &[1024usize][..]), (2, &[1024]), (3, &[1, 5000, 0, 77]), (4, &[20_000])] {
            assert!(build(threads, sizes) == one, "{threads} threads, chunks {sizes:?}");
        }
        let empty: Vec<Vec<GridPhoton>> = vec![Vec::new(); 3];
        let mut grid = PhotonGrid::default();
        grid.build(&empty, 1.0);
        assert!(grid.is_empty());
        grid.for_each_within(Vec3::ZERO, 1.0, |_, _| panic!("no photons"));
    }
}
