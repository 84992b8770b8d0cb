//! A uniform grid of points with normals and a payload, searched with the
//! estimates' disc filter: points within a half-thickness of the query's tangent
//! plane whose normals agree with the query's. The photon maps' k-nearest search at
//! final-gather hits ([`super::PhotonGrid`]) and the nearest precomputed-irradiance
//! point ([`DiscGrid::nearest_disc`]) run on it, tens of millions of queries per
//! render.
//!
//! The cells are the [`PointGrid`]'s; positions and normals are stored apart,
//! coordinate by coordinate, and tested eight points at a time with no branch but
//! one per eight (SSE on x86-64, the same arithmetic as the scalar filters, so the
//! same points pass).

use super::PointGrid;
use crate::photon::record::{decode_dir, dir_table, encode_dir};
use glam::Vec3;

/// Points tested per block of a scan.
pub(super) const BLOCK: usize = 8;

/// Points with normals and payloads in grid cells, for searches with a disc filter.
///
/// Per point: three coordinates (12 bytes), the normal's 16-bit octahedral code
/// ([`encode_dir`]; the filter reads its decoded value from [`dir_table`]), the
/// payload, and with [`DiscGrid::build_soa`]'s `keep_order` the input index (4 bytes).
#[derive(Clone, Debug, Default)]
pub struct DiscGrid<P> {
    /// The cells (no entries; searches read the arrays below).
    pub(super) cells: PointGrid<()>,
    /// Coordinates in grid order, then `BLOCK` far-away entries (a block may read
    /// past its range's end; those lanes are masked).
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    /// Normal codes, grid order, padded likewise.
    normals: Vec<u16>,
    /// Payload in grid order.
    items: Vec<P>,
    /// Input index of each point (grid order), when kept.
    order: Vec<u32>,
}

impl<P: Copy + Send + Sync> DiscGrid<P> {
    /// Indexes `items` at `positions` with `normals` (same lengths; the shortest
    /// counts), cells `spacings` × the points' median nearest-neighbour distance.
    /// Normals are stored as 16-bit octahedral codes ([`encode_dir`]): a normal
    /// decoded from such a code (a photon's) is kept exactly, any other within the
    /// code's precision. Deterministic: the order within a cell is the input order.
    pub fn build(positions: &[Vec3], normals: &[Vec3], items: &[P], spacings: f32) -> Self {
        let n = positions.len().min(normals.len()).min(items.len());
        let coord = |a: usize| positions[..n].iter().map(|p| p[a]).collect();
        let codes = normals[..n].iter().map(|&v| encode_dir(v)).collect();
        Self::build_soa(coord(0), coord(1), coord(2), codes, items[..n].to_vec(), spacings, false)
    }

    /// [`DiscGrid::build`] from coordinate arrays and normal codes, which it consumes
    /// (each input array is freed once its grid-order copy is made, so the build
    /// needs little beyond the grid itself); `keep_order` keeps each point's input
    /// index ([`DiscGrid::source`]).
    #[allow(clippy::too_many_arguments)]
    pub fn build_soa(x: Vec<f32>, y: Vec<f32>, z: Vec<f32>, normals: Vec<u16>, items: Vec<P>, spacings: f32, keep_order: bool) -> Self {
        let n = x.len().min(y.len()).min(z.len()).min(normals.len()).min(items.len());
        let pos = |i: usize| Vec3::new(x[i], y[i], z[i]);
        let cell = super::spaced_cell(n, &pos, spacings);
        let (cells, sort) = PointGrid::<()>::frame_sorted(n, &pos, cell);
        // Each array moved into grid order through the sort's two passes (its input
        // freed after the first), then padded.
        let permute = |v: Vec<_>, pad: Option<_>| {
            let mut out = sort.apply(v, if pad.is_some() { BLOCK } else { 0 });
            out.extend(pad.into_iter().flat_map(|p| std::iter::repeat_n(p, BLOCK)));
            out
        };
        let far = Some(f32::INFINITY);
        let (x, y, z) = (permute(x, far), permute(y, far), permute(z, far));
        let normals = {
            let mut out = sort.apply(normals, BLOCK);
            out.extend(std::iter::repeat_n(0, BLOCK));
            out
        };
        let items = sort.apply(items, 0);
        // The input indices last, once the inputs are freed.
        let order = if keep_order { sort.order() } else { Vec::new() };
        DiscGrid { x, y, z, normals, items, order, cells }
    }
}

impl<P> DiscGrid<P> {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Payload of point `i` (grid order).
    #[inline]
    pub fn item(&self, i: usize) -> &P {
        &self.items[i]
    }

    /// Position of point `i` (grid order).
    #[inline]
    pub fn position(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// Normal of point `i` (grid order), decoded.
    #[inline]
    pub fn normal(&self, i: usize) -> Vec3 {
        decode_dir(self.normals[i])
    }

    /// Normal code of point `i` (grid order).
    #[inline]
    pub fn normal_code(&self, i: usize) -> u16 {
        self.normals[i]
    }

    /// Input index of point `i` (grid order), when the build kept them.
    #[inline]
    pub fn source(&self, i: usize) -> Option<usize> {
        self.order.get(i).map(|&s| s as usize)
    }

    /// Bytes held (coordinates, normals, payload, input indices, cell starts).
    pub fn memory_bytes(&self) -> usize {
        self.x.len() * 12
            + self.normals.len() * 2
            + self.items.len() * std::mem::size_of::<P>()
            + self.order.len() * 4
            + self.cells.start.memory_bytes()
    }

    /// The nearest point to `p` closer than distance² `max_r2` that lies within
    /// `thick` of the plane through `p` normal to `n` and whose normal has a cosine
    /// of at least `cos` with `n`: its index (grid order) and distance². Exact, and
    /// the same point as [`PointGrid::nearest`] with that filter (ties: the first in
    /// grid order): the box of half-width ρ about `p` is scanned, ρ = half a cell
    /// first, doubling (reading only cells not yet read) until the best point lies
    /// within ρ or ρ reaches the search radius.
    pub fn nearest_disc(&self, p: Vec3, n: Vec3, thick: f32, cos: f32, max_r2: f32) -> Option<(usize, f32)> {
        if self.items.is_empty() || max_r2.is_nan() || max_r2 <= 0.0 || !p.is_finite() {
            return None;
        }
        let max_r = max_r2.sqrt();
        let (mut best, mut found) = (max_r2, None);
        let mut rho = self.cells.first_rho(max_r);
        let mut done = None;
        loop {
            self.cells.scan_box(p, rho, &mut done, &mut |rows| {
                for &(a, b) in rows {
                    self.prefetch_range(a as usize, b as usize);
                }
                for &(a, b) in rows {
                    let (a, b) = (a as usize, b as usize);
                    let mut i = a;
                    while i < b {
                        // The best of the block (first lane on ties), then one compare:
                        // the same point as offering the lanes one by one in order.
                        if let Some((j, d2)) = self.block_nearest(i, b - i, p, n, thick, cos, best) {
                            best = d2;
                            found = Some(i + j);
                        }
                        i += BLOCK;
                    }
                }
            });
            // Everything closer than the best lies inside the box just scanned.
            if (found.is_some() && best <= rho * rho) || rho >= max_r {
                break;
            }
            rho = (2.0 * rho).min(max_r);
        }
        found.map(|i| (i, best))
    }

    /// Hints the cache to fetch the coordinates, normals and payload of points
    /// `a..b`: the first and last line of each array (a cell's range spans one or
    /// two lines of each; the hardware prefetcher follows longer ones). Measured:
    /// hinting only the coordinates and normals, without repeated lines, made a
    /// `precomputed` render 4–7 % slower.
    #[inline(always)]
    pub(super) fn prefetch_range(&self, a: usize, b: usize) {
        if a < b {
            for v in [&self.x, &self.y, &self.z] {
                super::prefetch(&v[a]);
                super::prefetch(&v[b - 1]);
            }
            super::prefetch(&self.normals[a]);
            super::prefetch(&self.normals[b - 1]);
            super::prefetch(&self.items[a]);
            super::prefetch(&self.items[b - 1]);
        }
    }

    /// The tests of points `i..i + BLOCK`: a bit per point that passes the filter
    /// and lies closer than `r2`, and the distances². SSE on x86-64 (the same
    /// operations in the same order as the scalar code, so the same bits).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn block(&self, i: usize, p: Vec3, n: Vec3, thick: f32, cos: f32, r2: f32) -> (u32, [f32; BLOCK]) {
        let mut d2 = [0.0f32; BLOCK];
        let mut mask = 0u32;
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::*;
            for (h, (ok, dd)) in self.halves(i, p, n, thick, cos, r2).into_iter().enumerate() {
                // SAFETY: SSE is part of x86-64; the store is within `d2` (4h + 4 ≤ BLOCK).
                unsafe {
                    mask |= (_mm_movemask_ps(ok) as u32) << (4 * h);
                    _mm_storeu_ps(d2.as_mut_ptr().add(4 * h), dd);
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        for j in 0..BLOCK {
            let (ok, dd) = self.lane(i + j, p, n, thick, cos, r2);
            d2[j] = dd;
            mask |= (ok as u32) << j;
        }
        (mask, d2)
    }

    /// The nearest of the first `valid` points of `i..i + BLOCK` that passes the
    /// filter and lies closer than `r2`: its lane (the first on ties) and distance².
    /// Branch-free over the lanes (a minimum across the block), so a scan offers a
    /// block at a time instead of one unpredictable compare per passing point.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn block_nearest(&self, i: usize, valid: usize, p: Vec3, n: Vec3, thick: f32, cos: f32, r2: f32) -> Option<(usize, f32)> {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::*;
            let [(ok0, dd0), (ok1, dd1)] = self.halves(i, p, n, thick, cos, r2);
            // SAFETY: SSE2 is part of x86-64; register operations only.
            unsafe {
                let v = _mm_set1_epi32(valid.min(BLOCK) as i32);
                let in0 = _mm_castsi128_ps(_mm_cmplt_epi32(_mm_setr_epi32(0, 1, 2, 3), v));
                let in1 = _mm_castsi128_ps(_mm_cmplt_epi32(_mm_setr_epi32(4, 5, 6, 7), v));
                let (ok0, ok1) = (_mm_and_ps(ok0, in0), _mm_and_ps(ok1, in1));
                if _mm_movemask_ps(_mm_or_ps(ok0, ok1)) == 0 {
                    return None;
                }
                let inf = _mm_set1_ps(f32::INFINITY);
                let m0 = _mm_or_ps(_mm_and_ps(ok0, dd0), _mm_andnot_ps(ok0, inf));
                let m1 = _mm_or_ps(_mm_and_ps(ok1, dd1), _mm_andnot_ps(ok1, inf));
                let mut m = _mm_min_ps(m0, m1);
                m = _mm_min_ps(m, _mm_shuffle_ps(m, m, 0b01_00_11_10));
                m = _mm_min_ps(m, _mm_shuffle_ps(m, m, 0b10_11_00_01));
                let eq = (_mm_movemask_ps(_mm_and_ps(ok0, _mm_cmpeq_ps(m0, m))) as u32)
                    | ((_mm_movemask_ps(_mm_and_ps(ok1, _mm_cmpeq_ps(m1, m))) as u32) << 4);
                Some((eq.trailing_zeros() as usize, _mm_cvtss_f32(m)))
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let mut best: Option<(usize, f32)> = None;
            for j in 0..valid.min(BLOCK) {
                let (ok, dd) = self.lane(i + j, p, n, thick, cos, r2);
                if ok && best.is_none_or(|(_, b)| dd < b) {
                    best = Some((j, dd));
                }
            }
            best
        }
    }

    /// The filter and distance² of point `i` (scalar; the SSE lanes compute the same).
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn lane(&self, i: usize, p: Vec3, n: Vec3, thick: f32, cos: f32, r2: f32) -> (bool, f32) {
        let (dx, dy, dz) = (self.x[i] - p.x, self.y[i] - p.y, self.z[i] - p.z);
        let d2 = dx * dx + dy * dy + dz * dz;
        let plane = (dx * n.x + dy * n.y + dz * n.z).abs();
        let [nx, ny, nz, _] = dir_table()[self.normals[i] as usize].0;
        let facing = nx * n.x + ny * n.y + nz * n.z;
        ((d2 < r2) & (plane <= thick) & (facing >= cos), d2)
    }

    /// Filter masks and distances² of points `i..i + BLOCK`, four lanes at a time.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn halves(
        &self,
        i: usize,
        p: Vec3,
        n: Vec3,
        thick: f32,
        cos: f32,
        r2: f32,
    ) -> [(std::arch::x86_64::__m128, std::arch::x86_64::__m128); BLOCK / 4] {
        use std::arch::x86_64::*;
        fn lanes(v: &[f32], i: usize) -> &[f32; BLOCK] {
            v[i..i + BLOCK].try_into().expect("padded")
        }
        let (x, y, z) = (lanes(&self.x, i), lanes(&self.y, i), lanes(&self.z, i));
        let codes: &[u16; BLOCK] = self.normals[i..i + BLOCK].try_into().expect("padded");
        let table = dir_table();
        // SAFETY: SSE is part of x86-64; every load is within a BLOCK-long array
        // (4h + 4 ≤ BLOCK) or a 16-byte aligned table entry.
        unsafe {
            let (px, py, pz) = (_mm_set1_ps(p.x), _mm_set1_ps(p.y), _mm_set1_ps(p.z));
            let (qx, qy, qz) = (_mm_set1_ps(n.x), _mm_set1_ps(n.y), _mm_set1_ps(n.z));
            let (rv, tv, cv, sign) = (_mm_set1_ps(r2), _mm_set1_ps(thick), _mm_set1_ps(cos), _mm_set1_ps(-0.0));
            std::array::from_fn(|h| {
                let o = 4 * h;
                let dx = _mm_sub_ps(_mm_loadu_ps(x.as_ptr().add(o)), px);
                let dy = _mm_sub_ps(_mm_loadu_ps(y.as_ptr().add(o)), py);
                let dz = _mm_sub_ps(_mm_loadu_ps(z.as_ptr().add(o)), pz);
                let dd = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
                let plane = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, qx), _mm_mul_ps(dy, qy)), _mm_mul_ps(dz, qz));
                let near = _mm_and_ps(_mm_cmplt_ps(dd, rv), _mm_cmple_ps(_mm_andnot_ps(sign, plane), tv));
                // Most lanes fail the distance or plane test: the normals (four table
                // loads) only when one passes; the mask is the same either way.
                if _mm_movemask_ps(near) == 0 {
                    return (near, dd);
                }
                // The four decoded normals (x, y, z, 0 each), transposed to x, y, z lanes.
                let row = |j: usize| _mm_load_ps(table[codes[o + j] as usize].0.as_ptr());
                let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
                let (t0, t1) = (_mm_unpacklo_ps(r0, r1), _mm_unpacklo_ps(r2, r3));
                let (t2, t3) = (_mm_unpackhi_ps(r0, r1), _mm_unpackhi_ps(r2, r3));
                let (nx, ny, nz) = (_mm_movelh_ps(t0, t1), _mm_movehl_ps(t1, t0), _mm_movelh_ps(t2, t3));
                let facing = _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, qx), _mm_mul_ps(ny, qy)), _mm_mul_ps(nz, qz));
                (_mm_and_ps(near, _mm_cmpge_ps(facing, cv)), dd)
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_disc_equals_the_point_grid() {
        // Points on the faces of a box with the face's inward normal, some inside
        // with random normals.
        let (pos, mut items) = super::super::tests::points(6000);
        // The grid keeps normals as 16-bit codes: compare on the decoded ones.
        for it in &mut items {
            it.0 = decode_dir(encode_dir(it.0));
        }
        let nrm: Vec<Vec3> = items.iter().map(|it| it.0).collect();
        let ids: Vec<u32> = (0..pos.len() as u32).collect();
        let disc = DiscGrid::build(&pos, &nrm, &ids, 4.0);
        let grid = PointGrid::build_spaced(&pos, items, 4.0);
        let mut hits = 0;
        for q in 0..3000u64 {
            let (p, n) = super::super::tests::query(q);
            for (max_r, thick) in [(0.05f32, 0.01f32), (0.3, 0.05), (10.0, 10.0)] {
                let filter = |it: &(Vec3, u32), at: Vec3| it.0.dot(n) >= 0.7 && (at - p).dot(n).abs() <= thick;
                let want = grid.nearest(p, max_r * max_r, &filter).map(|(i, d2)| (grid.item(i).1, d2));
                let got = disc.nearest_disc(p, n, thick, 0.7, max_r * max_r).map(|(i, d2)| (*disc.item(i), d2));
                assert_eq!(got, want, "query {q} r {max_r}");
                hits += got.is_some() as usize;
            }
        }
        assert!(hits > 2000, "{hits}");
        // Degenerate: empty, non-finite query.
        let none: DiscGrid<u32> = DiscGrid::build(&[], &[], &[], 4.0);
        assert!(none.is_empty() && none.nearest_disc(Vec3::ZERO, Vec3::Z, 1.0, 0.0, 1.0).is_none());
        assert!(disc.nearest_disc(Vec3::NAN, Vec3::Z, 1.0, 0.0, 1.0).is_none());
    }

    #[test]
    fn nearest_disc_resolves_ties_as_the_row_scan() {
        // Points on a lattice (exact coordinates) in three planes, queries at lattice
        // points, cell centres and edges: many points at exactly the same distance,
        // spread over the cells of a first box. The grid's scan order decides ties.
        let mut pos = Vec::new();
        for (k, z) in [0.0f32, 0.5, 3.0].into_iter().enumerate() {
            for y in 0..40 {
                for x in 0..40 {
                    if (x + y + k) % 5 != 0 {
                        pos.push(Vec3::new(x as f32 * 0.5, y as f32 * 0.5, z));
                    }
                }
            }
        }
        let nrm = vec![Vec3::Z; pos.len()];
        let items: Vec<(Vec3, u32)> = (0..pos.len() as u32).map(|i| (Vec3::Z, i)).collect();
        let ids: Vec<u32> = (0..pos.len() as u32).collect();
        let disc = DiscGrid::build(&pos, &nrm, &ids, 4.0);
        let grid = PointGrid::build_spaced(&pos, items, 4.0);
        let mut ties = 0;
        for qy in 0..80 {
            for qx in 0..80 {
                let p = Vec3::new(qx as f32 * 0.25, qy as f32 * 0.25, if (qx + qy) % 3 == 0 { 0.25 } else { 0.0 });
                for (max_r, thick) in [(0.6f32, 0.3f32), (2.0, 1.0), (40.0, 40.0)] {
                    let filter = |it: &(Vec3, u32), at: Vec3| it.0.dot(Vec3::Z) >= 0.7 && (at - p).dot(Vec3::Z).abs() <= thick;
                    let want = grid.nearest(p, max_r * max_r, &filter).map(|(i, d2)| (grid.item(i).1, d2));
                    let got = disc.nearest_disc(p, Vec3::Z, thick, 0.7, max_r * max_r).map(|(i, d2)| (*disc.item(i), d2));
                    assert_eq!(got, want, "query {p} r {max_r}");
                    if let Some((_, d2)) = want {
                        ties +=
                            (pos.iter().filter(|q| (**q - p).length_squared() == d2 && (**q - p).z.abs() <= thick).count() > 1) as usize;
                    }
                }
            }
        }
        assert!(ties > 5000, "{ties}");
    }
}
