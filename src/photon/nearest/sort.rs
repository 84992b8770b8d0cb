//! The grid build's sort of points by cell, in two cache-friendly passes.
//!
//! One counting sort over all the points increments counters and writes the
//! output at random places of arrays far larger than the caches (at 10⁸ photons,
//! 400 MB per 4-byte array), and permuting each array by the resulting order reads
//! its input at random places again. Here the cells are first cut into buckets of
//! whole tiles holding about [`BUCKET_POINTS`] points each (from a histogram of
//! points per tile): the first pass moves the points, in input order, into their
//! bucket — a sequential read and one sequential write stream per bucket —, the
//! second sorts each bucket by cell on its own, within the caches, in parallel
//! over buckets. Both passes are stable, so the order is the counting sort's
//! (by cell, input order within a cell), the same for any thread count; the
//! arrays of the grid are permuted through the same two passes ([`CellSort::apply`]).

use super::TILE_CELLS;
use super::starts::{CellStarts, EMPTY};
use rayon::prelude::*;

/// Points a bucket of the first pass aims at: a bucket's 8-byte payloads and their
/// copy (1 MiB) stay in a core's level-2 cache during the second pass.
const BUCKET_POINTS: usize = 1 << 16;
/// Fewest points per chunk of the first pass (each chunk keeps an output position
/// per bucket; at most [`MAX_CHUNKS`] chunks).
const MIN_CHUNK: usize = 1 << 16;
const MAX_CHUNKS: usize = 1024;

/// How the points move from input order to grid order: the bucket of each point,
/// where each chunk's points of each bucket go, and the order within each bucket.
#[derive(Debug, Default)]
pub(super) struct CellSort {
    /// Bucket of each input point.
    bucket: Vec<u16>,
    /// Points per chunk of the first pass.
    chunk: usize,
    /// Buckets.
    buckets: usize,
    /// First output position of chunk c's points of bucket b, at `c * buckets + b`.
    chunk_start: Vec<u32>,
    /// Output range of each bucket (`buckets + 1` entries).
    bucket_start: Vec<u32>,
    /// Per output position: the position, within its bucket in the first pass's
    /// order, of the point that goes there.
    local: Vec<u32>,
}

/// A raw pointer shared by the first pass's chunks, which write disjoint positions.
struct Shared<T>(*mut T);
// SAFETY: the chunks of the first pass write disjoint positions (each output
// position belongs to exactly one chunk's range of one bucket).
unsafe impl<T: Send> Sync for Shared<T> {}
unsafe impl<T: Send> Send for Shared<T> {}
impl<T> Shared<T> {
    #[inline(always)]
    fn get(&self) -> *mut T {
        self.0
    }
}

impl CellSort {
    /// Sorts points by cell: `cells[i]` is point i's cell (tile order) in a grid of
    /// `tiles` tiles. Returns the cell starts and the sort (consuming `cells`).
    pub(super) fn build(cells: Vec<u32>, tiles: usize) -> (CellStarts, CellSort) {
        let n = cells.len();
        if n == 0 {
            return (CellStarts::default(), CellSort::default());
        }
        assert!(n <= u32::MAX as usize, "grid build: more than 2^32 - 1 points");
        let chunk = MIN_CHUNK.max(n.div_ceil(MAX_CHUNKS));
        // Points per tile, one histogram per thread's share (integer sums: the same
        // for any split; one share per thread keeps the histograms few).
        let share = n.div_ceil(rayon::current_num_threads().max(1));
        let per_tile = cells
            .par_chunks(share)
            .map(|ch| {
                let mut h = vec![0u32; tiles];
                for &c in ch {
                    h[c as usize / TILE_CELLS] += 1;
                }
                h
            })
            .reduce_with(|mut a, b| {
                for (x, y) in a.iter_mut().zip(&b) {
                    *x += y;
                }
                a
            })
            .unwrap_or_default();
        // Starts of the non-empty tiles, and buckets of whole tiles of at least
        // `target` points (at most 2^15 + 1 buckets: a bucket number fits 16 bits).
        let target = BUCKET_POINTS.max(n.div_ceil(1 << 15)) as u64;
        let mut slot = vec![EMPTY; tiles];
        let mut tile_bucket = vec![0u16; tiles];
        let (mut bucket_start, mut starts_cut) = (vec![0u32], vec![0usize]);
        let (mut next, mut acc, mut total) = (0usize, 0u64, 0u64);
        for (t, &count) in per_tile.iter().enumerate() {
            tile_bucket[t] = (bucket_start.len() - 1) as u16;
            if count == 0 {
                continue;
            }
            slot[t] = next as u32;
            next += TILE_CELLS + 1;
            acc += count as u64;
            total += count as u64;
            if acc >= target {
                bucket_start.push(total as u32);
                starts_cut.push(next);
                acc = 0;
            }
        }
        if acc > 0 {
            bucket_start.push(total as u32);
            starts_cut.push(next);
        }
        drop(per_tile);
        let buckets = bucket_start.len() - 1;
        let bucket: Vec<u16> = cells.par_iter().map(|&c| tile_bucket[c as usize / TILE_CELLS]).collect();
        drop(tile_bucket);
        // Where each chunk's points of each bucket go: chunks in order, then buckets.
        let hist: Vec<Vec<u32>> = bucket
            .par_chunks(chunk)
            .map(|ch| {
                let mut h = vec![0u32; buckets];
                for &b in ch {
                    h[b as usize] += 1;
                }
                h
            })
            .collect();
        let mut chunk_start = vec![0u32; hist.len() * buckets];
        for b in 0..buckets {
            let mut run = bucket_start[b];
            for (c, h) in hist.iter().enumerate() {
                chunk_start[c * buckets + b] = run;
                run += h[b];
            }
        }
        drop(hist);
        let mut sort = CellSort { bucket, chunk, buckets, chunk_start, bucket_start, local: Vec::new() };
        // First pass: the cell numbers, bucket by bucket.
        let mut local = sort.scatter(|i| cells[i], 0);
        drop(cells);
        // Second pass: per bucket, a counting sort by cell into its tiles' starts;
        // each bucket's cell numbers are replaced by its order (`local`).
        let mut starts = vec![0u32; next];
        let starts_parts = split(&mut starts, &starts_cut);
        let local_parts = split(&mut local, &sort.bounds());
        let slot_ref = &slot;
        starts_parts.into_par_iter().zip(local_parts).enumerate().for_each_init(Vec::new, |keys, (b, (st, loc))| {
            keys.clear();
            keys.extend_from_slice(loc);
            let (first, cut) = (sort.bucket_start[b], starts_cut[b]);
            let at = |c: u32| slot_ref[c as usize / TILE_CELLS] as usize - cut + c as usize % TILE_CELLS;
            for &c in keys.iter() {
                st[at(c) + 1] += 1;
            }
            let mut run = first;
            for tile in st.chunks_exact_mut(TILE_CELLS + 1) {
                tile[0] = run;
                for s in &mut tile[1..] {
                    run += *s;
                    *s = run;
                }
            }
            let mut fill = st.to_vec();
            for (t, &c) in keys.iter().enumerate() {
                let f = &mut fill[at(c)];
                loc[(*f - first) as usize] = t as u32;
                *f += 1;
            }
        });
        sort.local = local;
        (CellStarts::from_parts(slot, starts), sort)
    }

    /// The buckets' output ranges as `usize`.
    fn bounds(&self) -> Vec<usize> {
        self.bucket_start.iter().map(|&b| b as usize).collect()
    }

    /// Number of points.
    pub(super) fn len(&self) -> usize {
        self.bucket.len()
    }

    /// The first pass: `src(i)` for every point i, bucket by bucket (input order
    /// within a bucket), in a vector with room for `extra` more.
    fn scatter<T: Copy + Send + Sync>(&self, src: impl Fn(usize) -> T + Sync, extra: usize) -> Vec<T> {
        let n = self.len();
        let mut out: Vec<T> = Vec::with_capacity(n + extra);
        if n == 0 {
            return out;
        }
        let ptr = Shared(out.as_mut_ptr());
        let (buckets, chunk) = (self.buckets, self.chunk);
        self.bucket.par_chunks(chunk).enumerate().for_each(|(c, bs)| {
            let mut at = self.chunk_start[c * buckets..(c + 1) * buckets].to_vec();
            for (j, &b) in bs.iter().enumerate() {
                let pos = &mut at[b as usize];
                // SAFETY: `*pos` < n (the capacity), and no other chunk or point
                // writes it (the chunk starts partition 0..n).
                unsafe { ptr.get().add(*pos as usize).write(src(c * chunk + j)) };
                *pos += 1;
            }
        });
        // SAFETY: every position 0..n was written once (the chunks' ranges of all
        // buckets cover 0..n, and each chunk writes its count of each bucket).
        unsafe { out.set_len(n) };
        out
    }

    /// The second pass on the first pass's output: each bucket reordered by cell.
    fn gather_buckets<T: Copy + Send + Sync>(&self, v: &mut [T]) {
        let parts = split(v, &self.bounds());
        parts.into_par_iter().enumerate().for_each_init(Vec::new, |copy, (b, part)| {
            let loc = &self.local[self.bucket_start[b] as usize..self.bucket_start[b + 1] as usize];
            copy.clear();
            copy.extend_from_slice(part);
            for (o, &l) in part.iter_mut().zip(loc) {
                *o = copy[l as usize];
            }
        });
    }

    /// `v` (at least [`CellSort::len`] long; the rest is ignored) in grid order, with
    /// room for `extra` more; `v` is freed after the first pass.
    pub(super) fn apply<T: Copy + Send + Sync>(&self, v: Vec<T>, extra: usize) -> Vec<T> {
        assert!(v.len() >= self.len());
        let mut out = self.scatter(|i| v[i], extra);
        drop(v);
        self.gather_buckets(&mut out);
        out
    }

    /// The input index of each point in grid order.
    pub(super) fn order(&self) -> Vec<u32> {
        let mut out = self.scatter(|i| i as u32, 0);
        self.gather_buckets(&mut out);
        out
    }
}

/// `v` cut at `bounds` (ascending, from 0 to `v.len()`): `bounds.len() - 1` slices.
fn split<'a, T>(mut v: &'a mut [T], bounds: &[usize]) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(bounds.len().saturating_sub(1));
    for w in bounds.windows(2) {
        let (a, b) = v.split_at_mut(w[1] - w[0]);
        parts.push(a);
        v = b;
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::hash_words;

    /// Cells with dense and empty tiles, clustered and scattered.
    fn cells(n: usize, tiles: usize) -> Vec<u32> {
        (0..n as u64)
            .map(|i| {
                let h = hash_words(&[i, 3]);
                let tile = if h.is_multiple_of(4) { (h >> 8) % tiles as u64 } else { ((h >> 8) % 7 * 3 + tiles as u64 / 2) % tiles as u64 };
                (tile * TILE_CELLS as u64 + (h >> 40) % TILE_CELLS as u64) as u32
            })
            .collect()
    }

    #[test]
    fn two_passes_equal_one_counting_sort() {
        for (n, tiles) in [(1usize, 1usize), (5, 3), (1000, 40), (300_000, 5000), (700_000, 17)] {
            let c = cells(n, tiles);
            let (want_starts, want_order) = CellStarts::build_reference(&c, tiles);
            let (starts, sort) = CellSort::build(c.clone(), tiles);
            assert_eq!(starts, want_starts, "n {n}");
            assert_eq!(sort.order(), want_order, "n {n}");
            // Any array moves as the order says (and keeps its spare capacity).
            let v: Vec<u64> = (0..n as u64).map(|i| i * 7 + 1).collect();
            let out = sort.apply(v, 8);
            assert!(out.capacity() >= n + 8);
            assert!(out.iter().zip(&want_order).all(|(&o, &i)| o == i as u64 * 7 + 1));
        }
        let (starts, sort) = CellSort::build(Vec::new(), 4);
        assert_eq!(starts, CellStarts::default());
        assert!(sort.order().is_empty() && sort.apply(Vec::<u8>::new(), 0).is_empty());
    }
}
