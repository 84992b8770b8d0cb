//! Uniform grid for exact nearest-point queries with a filter: the lookup structure
//! of precomputed irradiance, which answers tens of millions of k = 1 queries per
//! render (one per final-gather ray).
//!
//! Points are sorted by cell (stable, in two cache-friendly passes: `nearest/sort.rs`),
//! cells numbered tile by tile (4³ cells, x fastest), so a row of cells along x
//! inside a tile is one contiguous range and the rows a query reads lie close
//! together; each point's (small) payload sits beside its position, so the filter reads the cache line the distance test loaded. A query scans the
//! cells overlapping the box of half-width ρ about it, starting at ρ = half a cell
//! (2 × 2 × 2 cells, 4 contiguous ranges):
//! when the best point passing the filter lies within ρ, every point closer than it
//! was in the box, so the answer is exact; otherwise ρ doubles (up to the search
//! radius) and only the cells not yet scanned are read.
//!
//! Against the kd-tree's k = 1 search this reads a few short contiguous ranges
//! instead of a root-to-leaf descent with its dependent loads and back-tracking.
//! The cell size follows the points' own spacing ([`CELL_SPACINGS`] × the median
//! distance from a point to its nearest neighbour, measured on a sample); the dense
//! grid is capped at 4 cells per point.

use glam::Vec3;
use rayon::prelude::*;
use sort::CellSort;
use starts::CellStarts;

mod disc;
mod photons;
mod sort;
mod starts;
pub use disc::DiscGrid;
pub use photons::PhotonGrid;

/// Points of a grid built over at most this many cells per point (plus a constant).
const CELLS_PER_POINT: usize = 4;
/// Cells of a grid at most (2^30: a cell number fits in 32 bits, and the starts of a
/// grid's non-empty tiles fit 32-bit indices). A lower cap (2^26) made the cells of
/// grids above ~5·10^7 surface photons wider than their spacing asks for, so each
/// estimate scanned more photons: the precomputation's time per point grew with the
/// count.
const MAX_CELLS: usize = 1 << 30;
/// Cell side in median nearest-neighbour distances: about a dozen points per cell
/// of a surface, so the first box (one cell wide) nearly always holds the answer.
pub(crate) const CELL_SPACINGS: f32 = 4.0;
/// Points sampled to measure the spacing.
const SPACING_SAMPLE: usize = 2048;

/// A point and its payload, side by side: a cell's points and what the filter reads
/// of them share cache lines.
#[derive(Clone, Copy, Debug)]
pub struct GridEntry<T> {
    /// Position.
    pub pos: Vec3,
    /// Payload.
    pub item: T,
}

/// A uniform grid of points with (small) payloads, for nearest-point queries.
#[derive(Clone, Debug)]
pub struct PointGrid<T> {
    origin: Vec3,
    cell: f32,
    inv_cell: f32,
    dims: [i64; 3],
    /// Tiles of TILE³ cells per axis.
    tiles: [i64; 3],
    /// Where each cell's points start (cells in tile order).
    start: CellStarts,
    /// Points in grid order.
    entries: Vec<GridEntry<T>>,
    /// Input index of each point (grid order).
    order: Vec<u32>,
}

impl<T> Default for PointGrid<T> {
    fn default() -> Self {
        PointGrid {
            origin: Vec3::ZERO,
            cell: 1.0,
            inv_cell: 1.0,
            dims: [1; 3],
            tiles: [1; 3],
            start: CellStarts::default(),
            entries: Vec::new(),
            order: Vec::new(),
        }
    }
}

/// Cells per tile side: cells are numbered tile by tile (x fastest inside a tile),
/// so the few rows of cells a query reads, and their points, lie close together in
/// memory instead of a whole grid row or plane apart.
const TILE: i64 = 4;
const TILE_CELLS: usize = (TILE * TILE * TILE) as usize;

/// Rows of cells whose point ranges are read before any is scanned (independent
/// loads, so their cache misses overlap).
const ROW_BATCH: usize = 32;

impl<T: Copy> PointGrid<T> {
    /// Builds the grid over `items` at `positions` (same length), with a cell size
    /// from the points' spacing. Deterministic: the order within a cell is the input
    /// order.
    pub fn build(positions: &[Vec3], items: Vec<T>) -> Self {
        Self::build_spaced(positions, items, CELL_SPACINGS)
    }

    /// Builds the grid with cells `spacings` × the points' median nearest-neighbour
    /// distance.
    fn build_spaced(positions: &[Vec3], items: Vec<T>, spacings: f32) -> Self {
        let n = positions.len().min(items.len());
        let cell = spaced_cell(n, &|i| positions[i], spacings);
        Self::with_cell(&positions[..n], items[..n].to_vec(), cell)
    }

    /// Builds the grid with cells of side `cell` (enlarged if the grid would exceed
    /// [`CELLS_PER_POINT`] cells per point).
    pub fn with_cell(positions: &[Vec3], items: Vec<T>, cell: f32) -> Self {
        let n = positions.len().min(items.len());
        let (mut g, order) = Self::frame(n, &|i| positions[i], cell);
        g.entries = order.iter().map(|&i| GridEntry { pos: positions[i as usize], item: items[i as usize] }).collect();
        g.order = order;
        g
    }
}

/// The cell side of a grid over `n` points at `pos(i)` with cells `spacings` × the
/// points' median nearest-neighbour distance (measured on a first grid of about one
/// cell per point; its positions, 12 bytes a point, are the build's largest
/// temporary).
pub(super) fn spaced_cell(n: usize, pos: &(impl Fn(usize) -> Vec3 + Sync), spacings: f32) -> f32 {
    let (lo, hi) = bounds(n, pos);
    let ext = (hi - lo).max(Vec3::splat(0.0));
    let vol_cell = (ext.x.max(1e-30) * ext.y.max(1e-30) * ext.z.max(1e-30) / n.max(1) as f32).cbrt();
    let rough_cell = if vol_cell.is_finite() && vol_cell > 0.0 { vol_cell } else { ext.max_element().max(1e-6) };
    let (rough, order) = PointGrid::<()>::frame(n, pos, rough_cell);
    let spacing = rough.median_spacing_by(&order, pos);
    if spacing > 0.0 && spacing.is_finite() { spacings * spacing } else { rough_cell }
}

impl<T> PointGrid<T> {
    /// The grid's frame (bounds, cells of side `cell` — enlarged if the grid would
    /// exceed [`CELLS_PER_POINT`] cells per point — and cell starts) over `n` points
    /// at `pos(i)`, without entries, and the points in grid order (input order within
    /// a cell).
    pub(super) fn frame(n: usize, pos: &(impl Fn(usize) -> Vec3 + Sync), cell: f32) -> (Self, Vec<u32>) {
        let (g, sort) = Self::frame_sorted(n, pos, cell);
        (g, sort.order())
    }

    /// [`PointGrid::frame`] with the sort that moves arrays from input order to grid
    /// order ([`CellSort::apply`]): a stable sort by cell in two cache-friendly
    /// passes, linear in the points.
    fn frame_sorted(n: usize, pos: &(impl Fn(usize) -> Vec3 + Sync), cell: f32) -> (Self, CellSort) {
        if n == 0 {
            return (Self::default(), CellSort::default());
        }
        let (lo, hi) = bounds(n, pos);
        let (lo, hi) = if lo.x <= hi.x { (lo, hi) } else { (Vec3::ZERO, Vec3::ZERO) };
        let ext = hi - lo;
        let max_cells = (CELLS_PER_POINT * n + 1024).min(MAX_CELLS) as f64;
        let mut cell = cell.max(ext.max_element() * 1e-6).max(1e-30);
        let count = |c: f32| ext.to_array().map(|e| ((e / c).floor() as i64 + 1).max(1));
        let tiles_of = |d: [i64; 3]| d.map(|x| (x + TILE - 1) / TILE);
        let mut dims = count(cell);
        while (tiles_of(dims).iter().product::<i64>() * TILE_CELLS as i64) as f64 > max_cells {
            cell *= 1.25;
            dims = count(cell);
        }
        let tiles = tiles_of(dims);
        let mut g = PointGrid::<()> {
            origin: lo,
            cell,
            inv_cell: 1.0 / cell,
            dims,
            tiles,
            start: CellStarts::default(),
            entries: Vec::new(),
            order: Vec::new(),
        };
        // At most `MAX_CELLS` cells: a cell number fits in 32 bits.
        let index: Vec<u32> = (0..n).into_par_iter().map(|i| g.cell_index(g.cell_of(pos(i))) as u32).collect();
        let (start, sort) = CellSort::build(index, tiles.iter().product::<i64>() as usize);
        g.start = start;
        let PointGrid { origin, cell, inv_cell, dims, tiles, start, .. } = g;
        (PointGrid { origin, cell, inv_cell, dims, tiles, start, entries: Vec::new(), order: Vec::new() }, sort)
    }
}

impl<T> PointGrid<T> {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Side of a cell.
    pub fn cell_size(&self) -> f32 {
        self.cell
    }

    /// Payload of point `i` (grid order).
    #[inline]
    pub fn item(&self, i: usize) -> &T {
        &self.entries[i].item
    }

    /// Index in the input of point `i` (grid order).
    #[inline]
    pub fn source(&self, i: usize) -> usize {
        self.order[i] as usize
    }

    /// Position of point `i` (grid order).
    #[inline]
    pub fn position(&self, i: usize) -> Vec3 {
        self.entries[i].pos
    }

    /// Bytes held (positions, payload, cell starts).
    pub fn memory_bytes(&self) -> usize {
        self.entries.len() * std::mem::size_of::<GridEntry<T>>() + self.start.memory_bytes()
    }

    /// Unclamped cell coordinate of `v` on `axis`.
    #[inline(always)]
    fn coord(&self, v: f32, axis: usize) -> i64 {
        // `as` saturates (NaN → 0); the callers clamp.
        floor_i64((v - self.origin[axis]) * self.inv_cell)
    }

    #[inline(always)]
    fn cell_of(&self, p: Vec3) -> [i64; 3] {
        [0, 1, 2].map(|a| self.coord(p[a], a).clamp(0, self.dims[a] - 1))
    }

    #[inline(always)]
    fn cell_index(&self, c: [i64; 3]) -> usize {
        let t = c.map(|x| x / TILE);
        let tile = (t[2] * self.tiles[1] + t[1]) * self.tiles[0] + t[0];
        let inner = ((c[2] % TILE) * TILE + c[1] % TILE) * TILE + c[0] % TILE;
        (tile * TILE_CELLS as i64 + inner) as usize
    }

    /// The nearest point to `p` closer than distance² `max_r2` for which
    /// `filter(payload, position)` holds: its index (grid order) and distance². Exact
    /// (ties: the first in grid order).
    #[inline]
    pub fn nearest(&self, p: Vec3, max_r2: f32, filter: &impl Fn(&T, Vec3) -> bool) -> Option<(usize, f32)> {
        if self.entries.is_empty() || max_r2.is_nan() || max_r2 <= 0.0 || !p.is_finite() {
            return None;
        }
        let max_r = max_r2.sqrt();
        let (mut best, mut found) = (max_r2, None);
        let mut rho = self.first_rho(max_r);
        // Cell box already scanned (lo, hi inclusive), if any.
        let mut done: Option<([i64; 3], [i64; 3])> = None;
        loop {
            self.scan_box(p, rho, &mut done, &mut |rows| {
                // The rows' first entries are cache misses at scattered places:
                // request them all before reading any, so the misses overlap.
                for &(a, b) in rows {
                    if a < b {
                        prefetch(&self.entries[a as usize]);
                        prefetch(&self.entries[b as usize - 1]);
                    }
                }
                self.scan_rows(p, rows, &mut best, &mut found, filter)
            });
            // Everything closer than the best lies inside the box just scanned.
            if (found.is_some() && best <= rho * rho) || rho >= max_r {
                break;
            }
            rho = (2.0 * rho).min(max_r);
        }
        found.map(|i| (i, best))
    }

    /// The cells (lo, hi inclusive) overlapping the box of half-width `rho` about
    /// `p`, or `None` when the box lies outside the grid.
    #[inline(always)]
    pub(super) fn cell_box(&self, p: Vec3, rho: f32) -> Option<([i64; 3], [i64; 3])> {
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        for a in 0..3 {
            let (l, h) = (self.coord(p[a] - rho, a), self.coord(p[a] + rho, a));
            if h < 0 || l > self.dims[a] - 1 {
                return None;
            }
            lo[a] = l.clamp(0, self.dims[a] - 1);
            hi[a] = h.clamp(0, self.dims[a] - 1);
        }
        Some((lo, hi))
    }

    /// Hands `scan` the point ranges of the cells overlapping the box of half-width
    /// `rho` about `p` that are not in `done` (the box scanned before, if any, which
    /// this box contains), in batches of up to [`ROW_BATCH`] contiguous ranges, and
    /// records the box in `done`. A box entirely outside the grid scans nothing.
    #[inline(always)]
    pub(super) fn scan_box(&self, p: Vec3, rho: f32, done: &mut Option<([i64; 3], [i64; 3])>, scan: &mut impl FnMut(&[(u32, u32)])) {
        if let Some((lo, hi)) = self.cell_box(p, rho) {
            self.scan_cells(lo, hi, *done, scan);
            *done = Some((lo, hi));
        }
    }

    /// Hands `scan` the point ranges of the cells `lo..=hi` outside `done`.
    #[inline(always)]
    pub(super) fn scan_cells(&self, lo: [i64; 3], hi: [i64; 3], done: Option<([i64; 3], [i64; 3])>, scan: &mut impl FnMut(&[(u32, u32)])) {
        let mut rows = [(0u32, 0u32); ROW_BATCH];
        let mut nr = 0;
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                // Cells x0..=x1 of the row, one contiguous range per tile.
                let mut row = |x0: i64, x1: i64| {
                    let mut x = x0;
                    while x <= x1 {
                        let end = x1.min((x / TILE + 1) * TILE - 1);
                        if nr == ROW_BATCH {
                            scan(&rows);
                            nr = 0;
                        }
                        rows[nr] = self.row_range([x, y, z], end);
                        nr += 1;
                        x = end + 1;
                    }
                };
                match done {
                    Some((dl, dh)) if (dl[2]..=dh[2]).contains(&z) && (dl[1]..=dh[1]).contains(&y) => {
                        if lo[0] < dl[0] {
                            row(lo[0], dl[0] - 1);
                        }
                        if dh[0] < hi[0] {
                            row(dh[0] + 1, hi[0]);
                        }
                    }
                    _ => row(lo[0], hi[0]),
                }
            }
        }
        scan(&rows[..nr]);
    }

    /// The first box's half-width in a [`PointGrid::nearest`] query.
    #[inline]
    fn first_rho(&self, max_r: f32) -> f32 {
        (0.5 * self.cell).min(max_r)
    }

    /// Distance from `p` to the outside of the cell box `lo..=hi` (inclusive): every
    /// point closer than this lies in the box. A side on the grid's border counts as
    /// infinitely far, since every point is inside the grid.
    #[inline(always)]
    pub(super) fn inner_radius(&self, p: Vec3, lo: [i64; 3], hi: [i64; 3]) -> f32 {
        let mut g = f32::INFINITY;
        for a in 0..3 {
            if lo[a] > 0 {
                g = g.min(p[a] - (self.origin[a] + lo[a] as f32 * self.cell));
            }
            if hi[a] < self.dims[a] - 1 {
                g = g.min(self.origin[a] + (hi[a] + 1) as f32 * self.cell - p[a]);
            }
        }
        g.max(0.0)
    }

    /// Points of cells `from` … (`to_x`, from.y, from.z), all in one tile: one
    /// contiguous range.
    #[inline(always)]
    fn row_range(&self, from: [i64; 3], to_x: i64) -> (u32, u32) {
        let c0 = self.cell_index(from);
        let first = c0 % TILE_CELLS;
        self.start.range(c0 / TILE_CELLS, first, first + (to_x - from[0]) as usize)
    }

    /// Tests the points of the given ranges.
    #[inline(always)]
    fn scan_rows(&self, p: Vec3, rows: &[(u32, u32)], best: &mut f32, found: &mut Option<usize>, filter: &impl Fn(&T, Vec3) -> bool) {
        for &(a, b) in rows {
            let (a, b) = (a as usize, b as usize);
            for (j, e) in self.entries[a..b].iter().enumerate() {
                let d2 = (e.pos - p).length_squared();
                if d2 < *best && filter(&e.item, e.pos) {
                    *best = d2;
                    *found = Some(a + j);
                }
            }
        }
    }

    /// [`PointGrid::median_spacing`] of a grid without entries whose points, in grid
    /// order, are at `pos(order[i])` (the same sample, the same distances).
    fn median_spacing_by(&self, order: &[u32], pos: &(impl Fn(usize) -> Vec3 + Sync)) -> f32 {
        let n = order.len();
        if n < 2 {
            return 0.0;
        }
        let step = (n / SPACING_SAMPLE).max(1);
        let far = (self.dims[0].max(self.dims[1]).max(self.dims[2]) as f32 + 1.0) * self.cell;
        let max_r2 = far * far * 3.0;
        let mut d: Vec<f32> = (0..n)
            .step_by(step)
            .filter_map(|i| {
                // `nearest` with the filter "another position", reading positions
                // through `order`: the exact nearest distance.
                let p = pos(order[i] as usize);
                if !p.is_finite() {
                    return None;
                }
                let max_r = max_r2.sqrt();
                let (mut best, mut found) = (max_r2, false);
                let mut rho = self.first_rho(max_r);
                let mut done = None;
                loop {
                    self.scan_box(p, rho, &mut done, &mut |rows| {
                        for &(a, b) in rows {
                            for &j in &order[a as usize..b as usize] {
                                let q = pos(j as usize);
                                let d2 = (q - p).length_squared();
                                if d2 < best && q != p {
                                    best = d2;
                                    found = true;
                                }
                            }
                        }
                    });
                    if (found && best <= rho * rho) || rho >= max_r {
                        break;
                    }
                    rho = (2.0 * rho).min(max_r);
                }
                found.then(|| best.sqrt())
            })
            .collect();
        if d.is_empty() {
            return 0.0;
        }
        let m = d.len() / 2;
        *d.select_nth_unstable_by(m, f32::total_cmp).1
    }

    /// Median distance from a point to its nearest other point, over a sample
    /// (0 when fewer than two distinct points): what [`PointGrid::median_spacing_by`]
    /// computes without entries (its test's reference).
    #[cfg(test)]
    fn median_spacing(&self) -> f32 {
        let n = self.len();
        if n < 2 {
            return 0.0;
        }
        let step = (n / SPACING_SAMPLE).max(1);
        let mut d: Vec<f32> = (0..n)
            .step_by(step)
            .filter_map(|i| {
                let p = self.position(i);
                let far = (self.dims[0].max(self.dims[1]).max(self.dims[2]) as f32 + 1.0) * self.cell;
                self.nearest(p, far * far * 3.0, &|_, q| q != p).map(|(_, d2)| d2.sqrt())
            })
            .collect();
        if d.is_empty() {
            return 0.0;
        }
        let m = d.len() / 2;
        *d.select_nth_unstable_by(m, f32::total_cmp).1
    }
}

/// `x.floor() as i64` without the library call `floor` is on x86-64 without
/// SSE 4.1 (once per axis of every query): truncate, then step down below zero.
#[inline(always)]
fn floor_i64(x: f32) -> i64 {
    let t = x as i64;
    if (t as f32) > x { t.saturating_sub(1) } else { t }
}

/// Hints the cache to fetch the line holding `x`.
#[inline(always)]
pub(crate) fn prefetch<U>(x: &U) {
    prefetch_byte((x as *const U).cast());
}

/// Hints the cache to fetch every line `x` spans (values wider than a line, or
/// straddling two).
#[inline(always)]
pub(crate) fn prefetch_all<U>(x: &U) {
    let p: *const u8 = (x as *const U).cast();
    let n = std::mem::size_of::<U>();
    for o in (0..n).step_by(64) {
        prefetch_byte(p.wrapping_add(o));
    }
    prefetch_byte(p.wrapping_add(n.max(1) - 1));
}

#[inline(always)]
fn prefetch_byte(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults, whatever the address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast())
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Bounds of the finite positions `pos(0..n)` (lo > hi when there are none).
fn bounds(n: usize, pos: &(impl Fn(usize) -> Vec3 + Sync)) -> (Vec3, Vec3) {
    // In order (the sign of a zero bound depends on it).
    (0..n).map(pos).filter(|p| p.is_finite()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{hash_words, u32_to_unit};

    fn rnd(k: u64, j: u64) -> f32 {
        u32_to_unit(hash_words(&[k, j, 77]) as u32)
    }

    /// Points in a box, most on its faces (with the face's inward normal), some
    /// inside with random normals (shared with the tests of `disc`).
    pub(super) fn points(n: usize) -> (Vec<Vec3>, Vec<(Vec3, u32)>) {
        points_with(n, 5, false)
    }

    /// [`points`] with every `inside`-th point inside the box and, when `dense`, every
    /// third face point squeezed into a patch ten times denser (a caustic's density
    /// contrast; shared with the tests of `photons`).
    pub(super) fn points_with(n: usize, inside: u64, dense: bool) -> (Vec<Vec3>, Vec<(Vec3, u32)>) {
        let mut pos = Vec::new();
        let mut items = Vec::new();
        for i in 0..n as u64 {
            let mut v = Vec3::new(rnd(i, 0), rnd(i, 1), rnd(i, 2)) * Vec3::new(3.0, 1.0, 0.5) - 0.25;
            let mut nrm = Vec3::new(rnd(i, 5) - 0.5, rnd(i, 6) - 0.5, rnd(i, 7) - 0.5).normalize_or(Vec3::Z);
            if !i.is_multiple_of(inside) {
                let a = (hash_words(&[i, 9]) % 3) as usize;
                let high = rnd(i, 4) < 0.5;
                v[a] = if high { [2.75, 0.75, 0.25][a] } else { -0.25 };
                nrm = Vec3::ZERO;
                nrm[a] = if high { -1.0 } else { 1.0 };
                if dense && i.is_multiple_of(3) {
                    v[(a + 1) % 3] *= 0.1;
                }
            }
            pos.push(v);
            items.push((nrm, i as u32));
        }
        (pos, items)
    }

    /// Query `q` of the grid tests: on the faces, inside and outside the box of
    /// [`points`], with a random unit normal (shared with `disc` and `photons`).
    pub(super) fn query(q: u64) -> (Vec3, Vec3) {
        let mut p = Vec3::new(rnd(q, 10), rnd(q, 11), rnd(q, 12)) * Vec3::new(3.6, 1.6, 1.1) - 0.55;
        if q.is_multiple_of(2) {
            let a = (q / 2 % 3) as usize;
            p[a] = if q.is_multiple_of(4) { [2.75, 0.75, 0.25][a] } else { -0.25 };
        }
        (p, Vec3::new(rnd(q, 13) - 0.5, rnd(q, 14) - 0.5, rnd(q, 15) - 0.5).normalize_or(Vec3::Y))
    }

    #[test]
    fn nearest_equals_brute_force_with_filter() {
        let (pos, items) = points(4000);
        let g = PointGrid::build(&pos, items.clone());
        assert_eq!(g.len(), pos.len());
        let mut seen = vec![false; pos.len()];
        for i in 0..g.len() {
            let (_, id) = *g.item(i);
            assert!(!seen[id as usize]);
            seen[id as usize] = true;
            assert_eq!(g.position(i), pos[id as usize]);
        }
        let mut hits = 0;
        for q in 0..3000u64 {
            // Queries on the faces, inside and outside the box.
            let (p, n) = query(q);
            for (max_r, thick) in [(0.05f32, 0.01f32), (0.3, 0.05), (10.0, 10.0)] {
                let filter = |it: &(Vec3, u32), at: Vec3| it.0.dot(n) >= 0.7 && (at - p).dot(n).abs() <= thick;
                let got = g.nearest(p, max_r * max_r, &filter);
                let want = pos
                    .iter()
                    .zip(&items)
                    .filter(|(x, it)| filter(it, **x))
                    .map(|(x, it)| ((*x - p).length_squared(), it.1))
                    .filter(|&(d2, _)| d2 < max_r * max_r)
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                match (got, want) {
                    (None, None) => {}
                    (Some((i, d2)), Some((wd2, wid))) => {
                        hits += 1;
                        assert_eq!(d2, wd2, "query {q}");
                        assert_eq!(d2, (g.position(i) - p).length_squared());
                        // Exact ties aside, the same point.
                        if g.item(i).1 != wid {
                            assert_eq!((pos[wid as usize] - p).length_squared(), d2);
                        }
                    }
                    (got, want) => panic!("query {q} r {max_r}: {got:?} vs {want:?}"),
                }
            }
        }
        assert!(hits > 2000, "{hits}");
    }

    #[test]
    fn spacing_without_entries_is_the_spacing() {
        let (mut pos, _) = points(20000);
        pos.push(Vec3::NAN);
        pos.extend_from_within(..50);
        for cell in [0.01f32, 0.05, 0.3] {
            let g = PointGrid::with_cell(&pos, vec![(); pos.len()], cell);
            let (frame, order) = PointGrid::<()>::frame(pos.len(), &|i| pos[i], cell);
            assert_eq!(order, g.order);
            let (a, b) = (g.median_spacing(), frame.median_spacing_by(&order, &|i| pos[i]));
            assert!(a > 0.0 && a.to_bits() == b.to_bits(), "cell {cell}: {a} vs {b}");
        }
    }

    #[test]
    fn floor_i64_is_floor() {
        for x in [0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999, -2.999, -3.0, 1e10, -1e10, 8388607.5, -8388607.5, f32::NAN, 1e30, -1e30] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
        for i in 0..10000u64 {
            let x = (u32_to_unit(hash_words(&[i, 5]) as u32) - 0.5) * 2000.0;
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn degenerate_grids() {
        let g: PointGrid<u32> = PointGrid::build(&[], Vec::new());
        assert!(g.is_empty() && g.nearest(Vec3::ZERO, 1.0, &|_, _| true).is_none());
        // One point; all points equal; a flat set; a non-finite point; far queries.
        let one = PointGrid::build(&[Vec3::ONE], vec![7u32]);
        assert_eq!(one.nearest(Vec3::ZERO, 4.0, &|_, _| true), Some((0, 3.0)));
        assert_eq!(one.nearest(Vec3::ZERO, 2.9, &|_, _| true), None);
        assert_eq!(one.nearest(Vec3::NAN, 4.0, &|_, _| true), None);
        let mut same: Vec<Vec3> = vec![Vec3::splat(2.0); 50];
        same.push(Vec3::new(f32::NAN, 0.0, 0.0));
        let g = PointGrid::build(&same, (0..51u32).collect());
        let (i, d2) = g.nearest(Vec3::new(2.0, 2.0, 3.0), 100.0, &|&v, _| v == 30).unwrap();
        assert_eq!((*g.item(i), d2), (30, 1.0));
        let flat: Vec<Vec3> = (0..400).map(|i| Vec3::new((i % 20) as f32, 0.5, (i / 20) as f32)).collect();
        let g = PointGrid::build(&flat, (0..400u32).collect());
        let (i, d2) = g.nearest(Vec3::new(3.2, 0.5, 7.1), 1e6, &|_, _| true).unwrap();
        assert_eq!(*g.item(i), 7 * 20 + 3);
        assert!((d2 - 0.05).abs() < 1e-5);
        // Far outside the grid, the search grows until it reaches the points.
        let (i, _) = g.nearest(Vec3::new(-50.0, 40.0, -50.0), 1e6, &|_, _| true).unwrap();
        assert_eq!(*g.item(i), 0);
        assert!(g.nearest(Vec3::new(-50.0, 40.0, -50.0), 100.0, &|_, _| true).is_none());
    }
}
