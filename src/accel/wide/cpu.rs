//! What the machine offers the traversal: the SIMD level (run-time CPU detection,
//! overridable by `PHOTONLAB_SIMD`) and huge-page backed node arrays.

/// Instruction set of the traversal. Both x86 levels run the integer-compare node
/// test of `bvh8` (`x86::node_test8`), whose per-axis error margins keep culling
/// nearly axis-parallel rays (the float test's one margin per ray grew with the
/// largest o·inv and let them visit 2.4× the nodes); at the AVX-512 level LLVM
/// compiles its comparisons to mask registers (1.03–1.05× faster than the AVX2
/// level on a Zen 5, docs/benchmarks.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub(super) enum Simd {
    /// Lane loops only (no x86 extensions assumed).
    Portable,
    /// AVX2 and FMA (with POPCNT, BMI1 and BMI2, which every AVX2 CPU has: a
    /// population count is one instruction instead of thirteen).
    Avx2,
    /// The AVX2 level's and AVX-512 F/VL/BW/DQ.
    Avx512,
}

/// [`Simd`] levels as const-generic parameters of the traversal.
pub(super) const PORTABLE: u8 = Simd::Portable as u8;
pub(super) const AVX2: u8 = Simd::Avx2 as u8;
pub(super) const AVX512: u8 = Simd::Avx512 as u8;

/// The traversal level to use: the best this CPU supports, or a lower one named by
/// the environment variable `PHOTONLAB_SIMD` (`portable`, `avx2`, `avx512`), so the
/// levels can be compared on one machine (`bench accel`). A level above the CPU's
/// is not used; an unknown value is reported and ignored.
pub(super) fn detect_simd() -> Simd {
    let best = cpu_simd();
    let Ok(v) = std::env::var("PHOTONLAB_SIMD") else { return best };
    match v.as_str() {
        "portable" => Simd::Portable,
        "avx2" => best.min(Simd::Avx2),
        "avx512" => best,
        _ => {
            eprintln!("warning: PHOTONLAB_SIMD={v} is not one of portable, avx2, avx512; using {best:?}");
            best
        }
    }
}

/// The best traversal level this CPU supports.
fn cpu_simd() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        use std::is_x86_feature_detected as has;
        if has!("avx2") && has!("fma") && has!("popcnt") && has!("bmi1") && has!("bmi2") {
            if has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq") {
                return Simd::Avx512;
            }
            return Simd::Avx2;
        }
    }
    Simd::Portable
}

/// An empty vector with room for `cap` items whose pages the kernel is asked to back
/// with 2 MiB huge pages (Linux transparent huge pages in `madvise` mode). Incoherent
/// rays on a million-triangle tree touch a new 4 KiB page at almost every node, so
/// without this most node fetches also miss the TLB. The hint is advisory: nothing
/// changes where it is ignored. Untouched capacity costs address space only.
pub(super) fn huge_vec<T>(cap: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(cap);
    #[cfg(target_os = "linux")]
    {
        let bytes = cap * std::mem::size_of::<T>();
        const HUGE: usize = 2 << 20;
        if bytes >= 2 * HUGE {
            // Only whole huge pages inside the allocation.
            let start = (v.as_ptr() as usize).next_multiple_of(HUGE);
            let end = (v.as_ptr() as usize + bytes) & !(HUGE - 1);
            if end > start {
                // SAFETY: the range lies inside this vector's allocation, which nothing
                // has touched yet; MADV_HUGEPAGE only changes how pages are backed.
                unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
            }
        }
    }
    v
}
