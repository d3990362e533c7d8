//! Arithmetic on 8 f32 lanes (one 256-bit register) shared by placement and splatting:
//! loops over independent lanes, branch-free and without saturating float→int
//! conversions, so that they compile to vector code.

/// `e^x` for `x ≤ 0` (relative error below 1e-5, growing with |x| from rounding `x·log2 e`
/// in f32; 0 below −87): `2^(x·log2 e)` split into an exponent and a degree-6 polynomial
/// of the fraction. Deterministic and much cheaper than `f32::exp` in the splat loop.
///
/// Branch-free and without float→int conversion (the integer part is rounded by adding
/// 1.5·2²³, which leaves it in the low mantissa bits), so that loops over lanes of it
/// compile to vector instructions.
#[inline(always)]
pub fn fast_exp_neg(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2^23
    let v = x.max(-87.0) * std::f32::consts::LOG2_E;
    let r = v + MAGIC;
    let fi = r - MAGIC; // v rounded to the nearest integer, |fi| ≤ 126
    let f = v - fi;
    // 2^f for f ∈ [−½, ½]: Taylor coefficients ln2^k/k! (truncation error < 1e-8),
    // Horner steps fused.
    let p = 0.000_154_035_3f32
        .mul_add(f, 0.001_333_355_8)
        .mul_add(f, 0.009_618_129)
        .mul_add(f, 0.055_504_11)
        .mul_add(f, 0.240_226_5)
        .mul_add(f, std::f32::consts::LN_2)
        .mul_add(f, 1.0);
    // fi + 127 ∈ [1, 127]: a normal power of two.
    let bits = r
        .to_bits()
        .wrapping_sub(MAGIC.to_bits())
        .wrapping_add(127)
        .wrapping_shl(23);
    let e = p * f32::from_bits(bits);
    if x < -87.0 {
        0.0
    } else {
        e
    }
}

/// The integer value of `v`, which must be an integer of magnitude below 2²²: `v` plus
/// 1.5·2²³ holds it in the low mantissa bits. Unlike `as`, which saturates and maps
/// NaN to 0, this compiles to two vector instructions per 8 lanes (and gives some
/// value, not undefined behaviour, for other `v`).
#[inline(always)]
pub(super) fn small_int(v: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2^23
    (v + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits()) as i32
}

/// Lanes of the vectorised splat loops (one 256-bit register of f32).
pub(super) const LANES: usize = 8;
pub(super) type Lanes = [f32; LANES];
/// `1, 2, …, LANES`: lane `l`'s index plus one. Lane indices are added as `(o − 1) +
/// (l + 1)` (exact for small integers): with a `0` in the table, the compiler drops
/// that lane's addition and assembles the vector lane by lane.
const LANE_INDEX_1: Lanes = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];

/// Gaussian weights `exp(−a·(b + k)²)` of the lanes `k = o + l`. One loop over
/// independent lanes, which compiles to vector code.
#[inline(always)]
pub(super) fn gauss_lanes(a: f32, b: f32, o: f32) -> Lanes {
    let mut out = [0f32; LANES];
    let o1 = o - 1.0;
    for l in 0..LANES {
        let d = b + (o1 + LANE_INDEX_1[l]);
        out[l] = fast_exp_neg(-a * d * d);
    }
    out
}

/// `PREFIX[n][l]` is 1 for lanes `l < n`, else 0: masks lanes outside a footprint by a
/// multiplication (the weights are finite), which stays vector code where a comparison
/// of small integers became per-lane scalar code.
pub(super) const PREFIX: [Lanes; LANES + 1] = {
    let mut t = [[0f32; LANES]; LANES + 1];
    let mut n = 0;
    while n <= LANES {
        let mut l = 0;
        while l < n {
            t[n][l] = 1.0;
            l += 1;
        }
        n += 1;
    }
    t
};

/// How many samples or pixels ahead passes that visit pixels at random ask for them
/// ([`prefetch`]).
pub(super) const PREFETCH_AHEAD: usize = 16;

/// Ask the cache for `items[i]` ahead of its use (nothing where `i` is out of
/// bounds, and nothing off x86-64): passes that visit pixels at random issue it some
/// samples ahead, so that the misses of several samples overlap instead of queueing.
#[inline(always)]
pub(crate) fn prefetch<T>(items: &[T], i: usize) {
    if let Some(item) = items.get(i) {
        prefetch_addr((item as *const T).cast());
    }
}

/// Ask the cache for the line holding `addr`, whatever it points at (nothing off
/// x86-64): for a part of an item other than its start, such as the last bytes of a
/// record that spans cache lines.
#[inline(always)]
pub(crate) fn prefetch_addr(addr: *const u8) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: `_mm_prefetch` needs SSE, in every x86-64 processor's baseline, and
        // only hints the cache: it never faults and reads nothing into the program,
        // whatever the address (null or unmapped included), so no address is unsound.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(addr.cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = addr;
}

/// Write every memory page of `v` once (each page's first element, with the value it
/// holds), so that a zeroed allocation, which the system maps in lazily, is backed now
/// and not at its first use. `black_box` keeps the compiler from dropping the stores.
pub(crate) fn touch<T: Copy + Send>(v: &mut [T]) {
    use rayon::prelude::*;
    const PAGE: usize = 4096;
    let step = (PAGE / std::mem::size_of::<T>().max(1)).max(1);
    v.par_chunks_mut(step * 64).for_each(|chunk| {
        for i in (0..chunk.len()).step_by(step) {
            chunk[i] = std::hint::black_box(chunk[i]);
        }
    });
}

/// The sum of `v` in four interleaved running sums of f64, added at the end: one
/// running sum is a chain of dependent additions, a millisecond over the pixels of a
/// 1280×720 image; the order is fixed, so the sum does not depend on the thread count.
pub(super) fn lane_sum<T: Copy + Into<f64>>(v: &[T]) -> f64 {
    let mut lanes = [0f64; 4];
    let chunks = v.chunks_exact(4);
    let rest: f64 = chunks.remainder().iter().map(|&x| x.into()).sum();
    for c in chunks {
        for (l, &x) in lanes.iter_mut().zip(c) {
            *l += x.into();
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + rest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefetch_leaves_the_data_alone_in_and_out_of_bounds() {
        let v: Vec<u32> = (0..1000).collect();
        for i in [0, 1, 999, 1000, usize::MAX] {
            prefetch(&v, i);
        }
        // Any address at all: inside, just past the end, null and far out.
        let inside = v.as_ptr().cast::<u8>();
        for addr in [
            inside,
            inside.wrapping_add(4000),
            std::ptr::null(),
            std::ptr::without_provenance(usize::MAX),
        ] {
            prefetch_addr(addr);
        }
        assert!(v.iter().enumerate().all(|(i, &x)| x == i as u32));
    }

    #[test]
    fn fast_exp_is_accurate() {
        for k in 0..20000 {
            let x = -(k as f32) * 0.004;
            let (a, b) = (fast_exp_neg(x), x.exp());
            assert!((a - b).abs() <= 1e-5 * b + 1e-30, "{x} {a} {b}");
        }
    }
}
