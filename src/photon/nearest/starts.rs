//! Where each grid cell's points start, kept for the tiles that hold points only.
//!
//! Points lie on surfaces, so most of a grid's tiles are empty; a start per cell of
//! the whole grid (4 bytes a cell, 4–16 MB for a million cells) made each row
//! lookup of a query a cache miss. Here a table of one slot per tile (4 bytes per
//! 64 cells) leads to the `TILE_CELLS + 1` starts of each non-empty tile, so the
//! starts a query reads stay in the caches.

#[cfg(test)]
use super::TILE_CELLS;

/// Slot of a tile without points.
pub(super) const EMPTY: u32 = u32::MAX;

/// Starts of the cells of the non-empty tiles (cells numbered tile by tile).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct CellStarts {
    /// Per tile: where its `TILE_CELLS + 1` starts begin in `starts`, or [`EMPTY`].
    slot: Vec<u32>,
    /// Per non-empty tile (in tile order): the first point of each of its cells and
    /// the end of its last cell (the next tile's first point).
    starts: Vec<u32>,
}

impl Default for CellStarts {
    fn default() -> Self {
        CellStarts { slot: vec![EMPTY], starts: Vec::new() }
    }
}

impl CellStarts {
    /// The starts from the per-tile slot table ([`EMPTY`] for a tile without points)
    /// and the starts of the non-empty tiles' cells (built by [`super::sort::CellSort`]).
    pub(super) fn from_parts(slot: Vec<u32>, starts: Vec<u32>) -> Self {
        CellStarts { slot, starts }
    }

    /// Counting sort of points by cell in one pass: `cells[i]` is point i's cell
    /// (tile order) in a grid of `tiles` tiles. Returns the starts and the points in
    /// cell order (input order within a cell): the reference of the two-pass sort
    /// the grids are built with ([`super::sort::CellSort`]).
    #[cfg(test)]
    pub(super) fn build_reference(cells: &[u32], tiles: usize) -> (Self, Vec<u32>) {
        let mut used = vec![false; tiles];
        for &c in cells {
            used[c as usize / TILE_CELLS] = true;
        }
        let mut next = 0usize;
        let slot: Vec<u32> = used
            .iter()
            .map(|&u| {
                if !u {
                    return EMPTY;
                }
                let s = next as u32;
                next += TILE_CELLS + 1;
                s
            })
            .collect();
        let mut starts = vec![0u32; next];
        let at = |c: usize| slot[c / TILE_CELLS] as usize + c % TILE_CELLS;
        for &c in cells {
            starts[at(c as usize) + 1] += 1;
        }
        let mut run = 0u32;
        for tile in starts.chunks_exact_mut(TILE_CELLS + 1) {
            tile[0] = run;
            for s in &mut tile[1..] {
                run += *s;
                *s = run;
            }
        }
        let mut fill = starts.clone();
        let mut order = vec![0u32; cells.len()];
        for (i, &c) in cells.iter().enumerate() {
            let f = &mut fill[at(c as usize)];
            order[*f as usize] = i as u32;
            *f += 1;
        }
        (CellStarts { slot, starts }, order)
    }

    /// Points of cells `first..=last` of tile `tile` (cell numbers within the tile):
    /// one contiguous range, empty for an empty tile.
    #[inline(always)]
    pub(super) fn range(&self, tile: usize, first: usize, last: usize) -> (u32, u32) {
        match self.slot[tile] {
            EMPTY => (0, 0),
            s => (self.starts[s as usize + first], self.starts[s as usize + last + 1]),
        }
    }

    /// Bytes held.
    pub(super) fn memory_bytes(&self) -> usize {
        (self.slot.len() + self.starts.len()) * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_equal_a_dense_counting_sort() {
        // Three tiles, the middle one empty; cells visited out of order.
        let cells: Vec<u32> = (0..500u32).map(|i| (i * 37 + i / 7) % 64 + if i % 3 == 0 { 128 } else { 0 }).collect();
        let (s, order) = CellStarts::build_reference(&cells, 3);
        let mut dense = vec![0u32; 3 * TILE_CELLS + 1];
        for &c in &cells {
            dense[c as usize + 1] += 1;
        }
        for c in 0..3 * TILE_CELLS {
            dense[c + 1] += dense[c];
        }
        for tile in 0..3 {
            for first in 0..TILE_CELLS {
                for last in first..TILE_CELLS {
                    let (a, b) = s.range(tile, first, last);
                    let (c0, c1) = (tile * TILE_CELLS + first, tile * TILE_CELLS + last);
                    let want = (dense[c0], dense[c1 + 1]);
                    assert!((a, b) == want || (a == b && want.0 == want.1), "tile {tile} cells {first}..={last}");
                }
            }
        }
        assert_eq!(s.slot[1], EMPTY);
        // Every point once, grouped by cell, input order within a cell.
        let mut seen = vec![false; cells.len()];
        for w in order.windows(2) {
            let (a, b) = (w[0] as usize, w[1] as usize);
            assert!(cells[a] < cells[b] || (cells[a] == cells[b] && a < b));
        }
        for &i in &order {
            assert!(!std::mem::replace(&mut seen[i as usize], true));
        }
        assert!(seen.iter().all(|&x| x));
    }
}
