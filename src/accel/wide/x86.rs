//! The node test with explicit vector instructions: the lane loop of
//! [`super::node_test`] compiles to the same arithmetic, but LLVM turns its hit mask
//! into a chain of packs instead of one `movmskps`, which cost ~15 % of the traversal.
//! Also the branch-free ordering of a node's hit children at the AVX-512 level.

use super::ray::{FAR_ULPS, ROBUST, RayPre};
use super::stack::Entry;
use std::arch::x86_64::*;

/// 8 lanes with AVX2/FMA: t = plane·c − b in one fused operation per plane
/// (measured 1.1–1.3× faster traversal than subtract-then-multiply), with the
/// absolute margins in b and the relative one an integer addition to the exit
/// ([`RayPre::fast_planes`]). The distances are
/// compared as signed integers, which order non-negative floats as floats do and
/// put every negative float below +0: the entry distance max(near, +0) and a
/// negative far distance (box behind the origin) come out right, and the folds
/// form trees of integer min/max (shorter than the float test's chain, and
/// compiled with AVX-512 into a mask-register compare; this is the `bvh8` test of
/// both x86 levels). An empty lane (box +∞…−∞) gets entry +∞ and exit −∞ from any axis with
/// a non-zero coefficient; a parallel axis (coefficient 0) gives 0·∞ = NaN, which
/// the integer folds never prefer to those, and if all three are parallel, NaN
/// entry and exit still fail the comparison, so it is never entered. Safety: the CPU must
/// support AVX2 and FMA; `planes` (near x, y, z, far x, y, z) and `tmin` must
/// point to 8 floats each.
#[inline(always)]
pub(super) unsafe fn node_test8(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
    // SAFETY: the caller's guarantees (AVX2/FMA; 8 floats behind every pointer).
    unsafe {
        let t = |k: usize| {
            let a = k % 3;
            let b = if k < 3 { r.near_b[a] } else { r.far_b[a] };
            _mm256_castps_si256(_mm256_fmsub_ps(_mm256_loadu_ps(planes[k]), _mm256_set1_ps(r.c[a]), _mm256_set1_ps(b)))
        };
        let t0 = _mm256_max_epi32(_mm256_max_epi32(t(0), t(1)), _mm256_max_epi32(t(2), _mm256_setzero_si256()));
        let t1 = _mm256_min_epi32(_mm256_min_epi32(t(3), t(4)), _mm256_min_epi32(t(5), _mm256_set1_epi32(t_max.to_bits() as i32)));
        // Widened as integers: a non-negative float grows by FAR_ULPS ulps, a
        // negative one (a box behind the origin, or NaN) stays negative; one more, so
        // that t0 ≤ t1 + FAR_ULPS is one comparison, t1 + FAR_ULPS + 1 > t0.
        let t1 = _mm256_add_epi32(t1, _mm256_set1_epi32(FAR_ULPS + 1));
        _mm256_storeu_si256(tmin as *mut __m256i, t0);
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(t1, t0))) as u32
    }
}

/// Orders the hit children of a node with three or more hits, without branches:
/// the nearest child is returned (a minimum over keys distance | lane), and all
/// hit children go to `out` farthest first (a bitonic network over the same keys,
/// non-hit lanes last), so the caller counts the first popcount − 1 of them as
/// pushed. Stored distances have their 3 low bits cleared (at most 7 ulps
/// smaller, which only ever keeps an entry on pop). AVX2 only (the blends of the
/// network have constant masks), so both x86 levels order the same way. Safety:
/// AVX2; `tmin` (non-negative distances, as `node_test8` leaves them) and `child`
/// must point to 8 values.
#[inline(always)]
pub(super) unsafe fn sort_hits8(tmin: *const f32, mask: u32, child: *const u32, out: &mut [std::mem::MaybeUninit<Entry>; 8]) -> u32 {
    // SAFETY: the caller's guarantees; `out` holds 8 entries of 8 bytes.
    unsafe {
        let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let hit = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(mask as i32), bits), bits);
        let t = _mm256_loadu_si256(tmin as *const __m256i);
        let key = _mm256_or_si256(_mm256_and_si256(t, _mm256_set1_epi32(!7)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        let m = _mm256_blendv_epi8(_mm256_set1_epi32(i32::MAX), key, hit);
        let m = _mm256_min_epi32(m, _mm256_permute4x64_epi64::<0x4E>(m));
        let m = _mm256_min_epi32(m, _mm256_shuffle_epi32::<0x4E>(m));
        let m = _mm256_min_epi32(m, _mm256_shuffle_epi32::<0xB1>(m));
        let nearest = *child.add((_mm256_cvtsi256_si32(m) & 7) as usize);
        // Bitonic sort, descending: per layer, each lane meets its partner and
        // keeps the larger key where the mask bit is set.
        let mut v = _mm256_blendv_epi8(_mm256_set1_epi32(-1), key, hit);
        macro_rules! layer {
            ($partner:expr, $max:literal) => {
                let p = $partner;
                v = _mm256_blend_epi32::<$max>(_mm256_min_epi32(v, p), _mm256_max_epi32(v, p));
            };
        }
        layer!(_mm256_shuffle_epi32::<0xB1>(v), 0x99);
        layer!(_mm256_shuffle_epi32::<0x4E>(v), 0xc3);
        layer!(_mm256_shuffle_epi32::<0xB1>(v), 0xa5);
        layer!(_mm256_permute4x64_epi64::<0x4E>(v), 0x0f);
        layer!(_mm256_shuffle_epi32::<0x4E>(v), 0x33);
        layer!(_mm256_shuffle_epi32::<0xB1>(v), 0x55);
        let cs = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(child as *const __m256i), _mm256_and_si256(v, _mm256_set1_epi32(7)));
        let ts = _mm256_and_si256(v, _mm256_set1_epi32(!7));
        let lo = _mm256_unpacklo_epi32(cs, ts);
        let hi = _mm256_unpackhi_epi32(cs, ts);
        let p = out.as_mut_ptr() as *mut __m256i;
        _mm256_storeu_si256(p, _mm256_permute2x128_si256::<0x20>(lo, hi));
        _mm256_storeu_si256(p.add(1), _mm256_permute2x128_si256::<0x31>(lo, hi));
        nearest
    }
}

/// 8 quantised lanes with AVX2/FMA: bytes widened to floats, then one fused
/// multiply-add per plane. Safety: the CPU must support AVX2 and FMA; `planes`
/// must point to 8 bytes each and `tmin` to 8 floats.
#[inline(always)]
pub(super) unsafe fn qnode_test8(planes: &[*const u8; 6], s: &[f32; 3], b: &[f32; 3], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
    // SAFETY: the caller's guarantees (AVX2/FMA; 8 bytes behind every plane
    // pointer, 8 floats at `tmin`).
    unsafe {
        slabs8(
            |k| {
                let a = k % 3;
                let q = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(planes[k] as *const __m128i)));
                _mm256_fmadd_ps(q, _mm256_set1_ps(s[a]), _mm256_set1_ps(b[a]))
            },
            r,
            t_max,
            tmin,
        )
    }
}

/// The slab test of 8 boxes given the plane distances `t(k)` (near x, y, z, far
/// x, y, z): entry distances to `tmin`, the hit mask returned, the far distance
/// widened by [`ROBUST`] and the ray's slack. Safety: AVX2 and FMA; `tmin` must
/// point to 8 floats.
#[inline(always)]
unsafe fn slabs8(t: impl Fn(usize) -> __m256, r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
    unsafe {
        let mut t0 = _mm256_setzero_ps();
        let mut t1 = _mm256_set1_ps(t_max);
        for a in 0..3 {
            // max/min return the second operand when either is NaN: the accumulator.
            t0 = _mm256_max_ps(t(a), t0);
            t1 = _mm256_min_ps(t(3 + a), t1);
        }
        t1 = _mm256_fmadd_ps(t1, _mm256_set1_ps(ROBUST), _mm256_set1_ps(r.slack));
        _mm256_storeu_ps(tmin, t0);
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32
    }
}

/// 4 lanes with FMA, as [`node_test8`]. Safety: the CPU must support FMA;
/// `planes` and `tmin` must point to 4 floats each.
#[inline(always)]
pub(super) unsafe fn node_test4_fma(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
    unsafe {
        let mut t0 = _mm_setzero_ps();
        let mut t1 = _mm_set1_ps(t_max);
        for a in 0..3 {
            let oi = _mm_set1_ps(r.oi[a]);
            let inv = _mm_set1_ps(r.inv[a]);
            t0 = _mm_max_ps(_mm_fmsub_ps(_mm_loadu_ps(planes[a]), inv, oi), t0);
            t1 = _mm_min_ps(_mm_fmsub_ps(_mm_loadu_ps(planes[3 + a]), inv, oi), t1);
        }
        t1 = _mm_fmadd_ps(t1, _mm_set1_ps(ROBUST), _mm_set1_ps(r.slack));
        _mm_storeu_ps(tmin, t0);
        _mm_movemask_ps(_mm_cmple_ps(t0, t1)) as u32
    }
}

/// 4 lanes with SSE (always present on x86-64). Safety: `planes` and `tmin` must
/// point to 4 floats each.
#[inline(always)]
pub(super) unsafe fn node_test4(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
    unsafe {
        let mut t0 = _mm_setzero_ps();
        let mut t1 = _mm_set1_ps(t_max);
        for a in 0..3 {
            let o = _mm_set1_ps(r.o[a]);
            let inv = _mm_set1_ps(r.inv[a]);
            let tn = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(planes[a]), o), inv);
            let tf = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(planes[3 + a]), o), inv);
            t0 = _mm_max_ps(tn, t0);
            t1 = _mm_min_ps(tf, t1);
        }
        t1 = _mm_mul_ps(t1, _mm_set1_ps(ROBUST));
        _mm_storeu_ps(tmin, t0);
        _mm_movemask_ps(_mm_cmple_ps(t0, t1)) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::super::cpu::{Simd, detect_simd};
    use super::super::node::Node;
    use super::super::rnd;
    use super::super::x86;
    use super::*;
    use crate::geometry::Ray;
    use glam::Vec3;
    use std::mem::MaybeUninit;

    /// Whether this CPU lacks AVX2 (and the test is skipped, saying so).
    fn no_avx2() -> bool {
        let none = detect_simd() == Simd::Portable;
        if none {
            eprintln!("skipped: no AVX2 on this CPU");
        }
        none
    }

    /// [`x86::node_test8`] on node `n` for `ray` in a scene of coordinates up to
    /// `cmax`: the hit mask and the entry distances. The caller checked AVX2.
    fn test_node(n: &Node<8>, ray: &Ray, cmax: [f32; 3], t_max: f32) -> (u32, [f32; 8]) {
        let mut r = RayPre::new::<8>(ray);
        r.fast_planes(cmax);
        let base = n as *const Node<8> as *const u8;
        let planes = r.planes.map(|off| base.wrapping_add(off) as *const f32);
        let mut tmin = [0.0f32; 8];
        // SAFETY: AVX2 and FMA checked by the caller; every plane array and `tmin` hold 8 floats.
        let mask = unsafe { x86::node_test8(&planes, &r, t_max, tmin.as_mut_ptr()) };
        (mask, tmin)
    }

    /// The integer node test against exact slab intersection in f64: it must report
    /// every box the ray meets on [0, t_max] (closed), never an empty lane, an entry
    /// distance no larger than the exact one times [`ROBUST`], and otherwise agree
    /// with the exact answer on almost every lane. Rays include directions with
    /// zero components and origins on box planes; boxes include flat ones.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn integer_node_test_is_conservative_and_skips_empty_lanes() {
        use crate::math::hash_words;
        if no_avx2() {
            return;
        }
        let unit = |k: u64, s: u64| (hash_words(&[k, s]) >> 40) as f32 / (1u64 << 24) as f32;
        let (mut lanes, mut agree, mut hits) = (0u32, 0u32, 0u32);
        let cmax = [4.0f32; 3];
        for k in 0..40_000u64 {
            let mut n = Node::<8>::empty();
            let filled = 1 + (k % 8) as usize;
            let grid = |v: f32| (v * 8.0).round() / 4.0 - 2.0; // planes on a coarse grid, so origins land on them
            for i in 0..filled {
                for a in 0..3 {
                    let (x, y) = (grid(unit(k, 10 + 2 * (3 * i + a) as u64)), grid(unit(k, 11 + 2 * (3 * i + a) as u64)));
                    (n.lo[a][i], n.hi[a][i]) = (x.min(y), x.max(y));
                }
                n.child[i] = i as u32;
            }
            let mut o = [0.0f32; 3];
            let mut d = [0.0f32; 3];
            for a in 0..3 {
                o[a] = if k % 3 == 0 { grid(unit(k, 100 + a as u64)) } else { unit(k, 100 + a as u64) * 6.0 - 3.0 };
                // About a quarter of the rays have one or two zero direction components.
                let zero = (k % 7 == 1 && a == (k % 3) as usize) || (k % 11 == 2 && a != (k % 3) as usize);
                d[a] = if zero { 0.0 } else { unit(k, 200 + a as u64) * 2.0 - 1.0 };
            }
            if d == [0.0; 3] {
                continue;
            }
            let t_max = if k % 4 == 0 { 1.5 } else { f32::INFINITY };
            let (mask, tmin) = test_node(&n, &Ray::new(Vec3::from(o), Vec3::from(d)), cmax, t_max);
            for (i, &entry) in tmin.iter().enumerate() {
                let got = mask >> i & 1 == 1;
                if i >= filled {
                    assert!(!got, "ray {k}: empty lane {i} entered");
                    continue;
                }
                // Exact slab interval in f64.
                let (mut t0, mut t1) = (0.0f64, t_max as f64);
                for a in 0..3 {
                    let (lo, hi, oa, da) = (n.lo[a][i] as f64, n.hi[a][i] as f64, o[a] as f64, d[a] as f64);
                    if da == 0.0 {
                        if oa < lo || oa > hi {
                            t1 = -1.0;
                        }
                        continue;
                    }
                    let (x, y) = ((lo - oa) / da, (hi - oa) / da);
                    t0 = t0.max(x.min(y));
                    t1 = t1.min(x.max(y));
                }
                let exact = t0 <= t1;
                if exact {
                    assert!(got, "ray {k}: lane {i} culled, exact entry {t0} exit {t1}");
                    assert!((0.0..=t0 * ROBUST as f64).contains(&(entry as f64)), "ray {k}: lane {i} entry {entry}, exact {t0}");
                    hits += 1;
                }
                // Axes with a zero direction component are ignored (they never
                // cull), so agreement is counted on the other rays only.
                if !d.contains(&0.0) {
                    lanes += 1;
                    agree += (got == exact) as u32;
                }
            }
        }
        assert!(hits > 5_000, "{hits} boxes hit");
        assert!(agree as f64 > 0.9998 * lanes as f64, "{agree} of {lanes} lanes agree with the exact test");
    }

    /// Boxes the ray only grazes, entry = exit = T exactly (its near y plane and far
    /// x plane both at T = 2^k, from the world origin, where o·inv is 0 and no
    /// absolute margin helps): the rounding of 1/d puts the computed entry above
    /// the exit about as often as below, so this fails without the exit's relative
    /// widening ([`FAR_ULPS`]).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn grazed_boxes_are_kept() {
        if no_avx2() {
            return;
        }
        let mut seed = 3u64;
        for k in 0..4000 {
            let t = 2f32.powi(k % 20 - 10);
            let d = [0.1 + rnd(&mut seed), 0.1 + rnd(&mut seed), 0.1 + rnd(&mut seed)];
            let mut n = Node::<8>::empty();
            for i in 0..8 {
                // Exact products: t is a power of two.
                let (px, py) = (t * d[0], t * d[1]);
                (n.lo[0][i], n.hi[0][i]) = (px - (1 + i) as f32 * t, px);
                (n.lo[1][i], n.hi[1][i]) = (py, py + (1 + i) as f32 * t);
                (n.lo[2][i], n.hi[2][i]) = (-1e3, 1e3);
                n.child[i] = i as u32;
            }
            let (mask, _) = test_node(&n, &Ray::new(Vec3::ZERO, Vec3::from(d)), [1e3; 3], f32::INFINITY);
            assert_eq!(mask, 0xff, "ray {k}: d {d:?}, t {t}: grazed lanes culled");
        }
    }

    /// The branch-free ordering of three or more hit children: the nearest is
    /// returned, the others come farthest first, none is lost or invented.
    #[test]
    fn sorted_push_of_many_hits() {
        if no_avx2() {
            return;
        }
        let mut seed = 11u64;
        let mut checked = 0;
        for _ in 0..20_000 {
            let mask = (rnd(&mut seed) * 256.0) as u32 & 0xff;
            if mask.count_ones() < 3 {
                continue;
            }
            // Distances with ties and zeros; child references arbitrary.
            let tmin: [f32; 8] =
                std::array::from_fn(
                    |_| if rnd(&mut seed) < 0.2 { 0.0 } else { (rnd(&mut seed) * 8.0).floor() * 0.5 + rnd(&mut seed) * 1e-6 },
                );
            let child: [u32; 8] = std::array::from_fn(|i| 1000 + i as u32 * 7);
            let mut out = [const { MaybeUninit::uninit() }; 8];
            // SAFETY: AVX2 checked above; 8 non-negative distances and children.
            let near = unsafe { x86::sort_hits8(tmin.as_ptr(), mask, child.as_ptr(), &mut out) };
            let k = mask.count_ones() as usize;
            // SAFETY: the function wrote all 8 entries.
            let got: Vec<Entry> = out[..k - 1].iter().map(|e| unsafe { e.assume_init() }).collect();
            let lane = |c: u32| ((c - 1000) / 7) as usize;
            let tmin_hit = (0..8).filter(|i| mask >> i & 1 == 1).map(|i| tmin[i]).fold(f32::INFINITY, f32::min);
            assert!(mask >> lane(near) & 1 == 1 && tmin[lane(near)] - tmin_hit <= 1e-6, "nearest {near} of {tmin:?} {mask:#b}");
            let mut lanes: Vec<usize> = got.iter().map(|e| lane(e.child)).chain([lane(near)]).collect();
            for w in got.windows(2) {
                assert!(w[0].t >= w[1].t, "not farthest first: {tmin:?} {mask:#b}");
            }
            for e in &got {
                let t = tmin[lane(e.child)];
                assert!(e.t <= t && e.t >= t * (1.0 - 1e-6) && e.t >= tmin[lane(near)] * (1.0 - 1e-6), "distance {} for {t}", e.t);
            }
            lanes.sort();
            assert_eq!(lanes, (0..8).filter(|i| mask >> i & 1 == 1).collect::<Vec<_>>(), "{tmin:?} {mask:#b}");
            checked += 1;
        }
        assert!(checked > 5000);
    }
}
