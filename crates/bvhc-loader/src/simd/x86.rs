//! x86-64 lanes: SSE2 registers (part of every x86-64 CPU) for four lanes and AVX2 registers for eight, and
//! [`Avx2`], the proof that the CPU has AVX2, without which no eight-lane value can be made.
//!
//! Every operation is the one instruction that computes the IEEE operation of [`Lanes`] lane by lane: the
//! `maxps`/`minps` of [`Lanes::max_or`]/[`Lanes::min_or`], ordered compares, nothing fused.

#![allow(unsafe_code)] // intrinsics: each block states what it relies on

use std::arch::x86_64::*;

use super::lanes::{LaneMask, Lanes};
use super::{Isa, Kernel, SlabRay};
use crate::format::{EMPTY_SLOT, WIDE, WideNode8};

/// Proof that this CPU runs AVX2 (and with it SSE2): the only way to make one is [`Avx2::detect`], so a
/// function that takes one, or an [`F32x8`] made from one, cannot run where AVX2 is missing.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx2 {
    _proof: (),
}

impl Avx2 {
    /// The token, when the CPU has AVX2.
    pub(crate) fn detect() -> Option<Avx2> {
        std::arch::is_x86_feature_detected!("avx2").then_some(Avx2 { _proof: () })
    }
}

/// Runs `kernel` with AVX2 enabled for the code generator: the kernel's generic code, inlined into this one
/// function, is compiled for AVX2 as a whole (so every lane operation is one instruction).
#[inline(always)]
pub(crate) fn run_avx2<K: Kernel>(token: Avx2, kernel: K) -> K::Output {
    // SAFETY: `token` exists, so `Avx2::detect` found AVX2 on this CPU.
    unsafe { with_avx2(token, kernel) }
}

#[target_feature(enable = "avx2")]
fn with_avx2<K: Kernel>(token: Avx2, kernel: K) -> K::Output {
    kernel.run(token)
}

impl Isa for Avx2 {
    type F4 = F32x4;
    type F8 = F32x8;
    const PREFETCH: bool = true;

    #[inline(always)]
    fn f4(self, values: &[f32; 4]) -> F32x4 {
        // SAFETY: SSE2 is part of every x86-64 CPU; the load reads the 16 bytes of `values`.
        F32x4(unsafe { _mm_loadu_ps(values.as_ptr()) })
    }

    #[inline(always)]
    fn f4_splat(self, value: f32) -> F32x4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        F32x4(unsafe { _mm_set1_ps(value) })
    }

    #[inline(always)]
    fn f8(self, values: &[f32; 8]) -> F32x8 {
        // SAFETY: `self` proves AVX2; the load reads the 32 bytes of `values`.
        F32x8(unsafe { _mm256_loadu_ps(values.as_ptr()) })
    }

    #[inline(always)]
    fn f8_splat(self, value: f32) -> F32x8 {
        // SAFETY: `self` proves AVX2.
        F32x8(unsafe { _mm256_set1_ps(value) })
    }

    /// The portable test's operations in AVX2, its rows loaded at the ray's plane offsets straight from the
    /// node (offset addressing, not a bounds-checked slice: the generic form cost 3-5% more instructions a ray
    /// through the wide kernel, measured with callgrind).
    #[inline(always)]
    fn box_test(self, node: &WideNode8, ray: &SlabRay<'_>, t_far: f32) -> (u8, [f32; WIDE]) {
        // SAFETY: `self` proves AVX2.
        unsafe { box_test(node, ray, t_far) }
    }

    #[inline(always)]
    fn transpose8(self, rows: &[[f32; 8]; 8]) -> [[f32; 8]; 8] {
        // SAFETY: `self` proves AVX2.
        unsafe { transpose8(rows) }
    }
}

/// [`Isa::transpose8`] in AVX2: pairs interleaved, then quadruples, then the 128-bit halves exchanged.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn transpose8(rows: &[[f32; 8]; 8]) -> [[f32; 8]; 8] {
    let mut r = [_mm256_setzero_ps(); 8];
    for (lanes, row) in r.iter_mut().zip(rows) {
        // SAFETY: each row is 32 readable bytes.
        *lanes = unsafe { _mm256_loadu_ps(row.as_ptr()) };
    }
    let pairs = [
        _mm256_unpacklo_ps(r[0], r[1]),
        _mm256_unpackhi_ps(r[0], r[1]),
        _mm256_unpacklo_ps(r[2], r[3]),
        _mm256_unpackhi_ps(r[2], r[3]),
        _mm256_unpacklo_ps(r[4], r[5]),
        _mm256_unpackhi_ps(r[4], r[5]),
        _mm256_unpacklo_ps(r[6], r[7]),
        _mm256_unpackhi_ps(r[6], r[7]),
    ];
    let quads = [
        _mm256_shuffle_ps::<0x44>(pairs[0], pairs[2]),
        _mm256_shuffle_ps::<0xEE>(pairs[0], pairs[2]),
        _mm256_shuffle_ps::<0x44>(pairs[1], pairs[3]),
        _mm256_shuffle_ps::<0xEE>(pairs[1], pairs[3]),
        _mm256_shuffle_ps::<0x44>(pairs[4], pairs[6]),
        _mm256_shuffle_ps::<0xEE>(pairs[4], pairs[6]),
        _mm256_shuffle_ps::<0x44>(pairs[5], pairs[7]),
        _mm256_shuffle_ps::<0xEE>(pairs[5], pairs[7]),
    ];
    let columns = [
        _mm256_permute2f128_ps::<0x20>(quads[0], quads[4]),
        _mm256_permute2f128_ps::<0x20>(quads[1], quads[5]),
        _mm256_permute2f128_ps::<0x20>(quads[2], quads[6]),
        _mm256_permute2f128_ps::<0x20>(quads[3], quads[7]),
        _mm256_permute2f128_ps::<0x31>(quads[0], quads[4]),
        _mm256_permute2f128_ps::<0x31>(quads[1], quads[5]),
        _mm256_permute2f128_ps::<0x31>(quads[2], quads[6]),
        _mm256_permute2f128_ps::<0x31>(quads[3], quads[7]),
    ];
    let mut out = [[0f32; 8]; 8];
    for (row, column) in out.iter_mut().zip(columns) {
        // SAFETY: `row` has room for 8 f32.
        unsafe { _mm256_storeu_ps(row.as_mut_ptr(), column) };
    }
    out
}

/// [`Isa::box_test`] in AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn box_test(node: &WideNode8, ray: &SlabRay<'_>, t_far: f32) -> (u8, [f32; WIDE]) {
    let mut near = _mm256_set1_ps(ray.t_min);
    let mut far = _mm256_set1_ps(t_far);
    let planes = (node as *const WideNode8).cast::<f32>();
    let (entry_offsets, exit_offsets) = ray.plane_offsets;
    for axis in 0..3 {
        let origin = _mm256_set1_ps(ray.origin[axis]);
        // SAFETY: the offsets are `axis * WIDE`, plus `3 * WIDE` for a `max` row, with axis < 3 (the only
        // values `PreparedRay::new` writes), so each row `offset .. offset + WIDE` lies in the node's `min` and
        // `max` arrays (its first `6 * WIDE` f32s, at offsets 0 and 96 bytes as `format.rs` asserts); unaligned
        // loads need no more.
        let (entry, exit) = unsafe {
            (_mm256_loadu_ps(planes.add(entry_offsets[axis])), _mm256_loadu_ps(planes.add(exit_offsets[axis])))
        };
        let t_entry = _mm256_mul_ps(_mm256_sub_ps(entry, origin), _mm256_set1_ps(ray.inverse_direction[axis]));
        let t_exit = _mm256_mul_ps(_mm256_sub_ps(exit, origin), _mm256_set1_ps(ray.exit_inverse[axis]));
        // max_ps(a, b) = a > b ? a : b and min_ps(a, b) = a < b ? a : b: the portable compare-selects.
        near = _mm256_max_ps(t_entry, near);
        far = _mm256_min_ps(t_exit, far);
    }
    let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u8;
    // SAFETY: `node.child` is `[u32; 8]`, 32 readable bytes.
    let children = unsafe { _mm256_loadu_si256(node.child.as_ptr().cast()) };
    let empty = _mm256_cmpeq_epi32(children, _mm256_set1_epi32(EMPTY_SLOT as i32));
    let mut out = [0f32; WIDE];
    // SAFETY: `out` has room for 8 f32.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), near) };
    (hit & !(_mm256_movemask_ps(_mm256_castsi256_ps(empty)) as u8), out)
}

/// Four lanes in an SSE2 register (SSE2 is part of the x86-64 baseline, so these run on any x86-64 CPU).
#[derive(Clone, Copy, Debug)]
pub(crate) struct F32x4(__m128);

/// A mask of four lanes: all bits set in a lane of the mask.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mask4(__m128);

impl LaneMask for Mask4 {
    #[inline(always)]
    fn or(self, other: Mask4) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_or_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn and(self, other: Mask4) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_and_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn and_not(self, other: Mask4) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_andnot_ps(other.0, self.0)) }
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { _mm_movemask_ps(self.0) as u32 }
    }
}

impl Lanes for F32x4 {
    type Array = [f32; 4];
    type Mask = Mask4;
    #[inline(always)]
    fn to_array(self) -> [f32; 4] {
        let mut out = [0f32; 4];
        // SAFETY: the store writes the 16 bytes of `out`.
        unsafe { _mm_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_add_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_sub_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_mul_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn div(self, other: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_div_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_andnot_ps(_mm_set1_ps(-0.0), self.0)) }
    }
    #[inline(always)]
    fn max_or(self, other: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_max_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn min_or(self, other: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_min_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn eq(self, other: Self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_cmpeq_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn lt(self, other: Self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_cmplt_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn gt(self, other: Self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_cmpgt_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn le(self, other: Self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_cmple_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn ge(self, other: Self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_cmpge_ps(self.0, other.0)) }
    }
    #[inline(always)]
    fn is_number(self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_cmpord_ps(self.0, self.0)) }
    }
    #[inline(always)]
    fn is_sign_negative(self) -> Mask4 {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { Mask4(_mm_castsi128_ps(_mm_srai_epi32::<31>(_mm_castps_si128(self.0)))) }
    }
    #[inline(always)]
    fn select(mask: Mask4, if_true: Self, if_false: Self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { F32x4(_mm_or_ps(_mm_and_ps(mask.0, if_true.0), _mm_andnot_ps(mask.0, if_false.0))) }
    }
    #[inline(always)]
    fn min_across(self) -> Self {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe {
            let pairs = _mm_min_ps(self.0, _mm_shuffle_ps::<0b10_11_00_01>(self.0, self.0));
            F32x4(_mm_min_ps(pairs, _mm_shuffle_ps::<0b01_00_11_10>(pairs, pairs)))
        }
    }
}

/// Eight lanes in an AVX2 register; made only through an [`Avx2`] token (or from other `F32x8`s).
#[derive(Clone, Copy, Debug)]
pub(crate) struct F32x8(__m256);

/// A mask of eight lanes: all bits set in a lane of the mask.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mask8(__m256);

// In the two impls below, every `unsafe` block relies on one fact: an `F32x8` or `Mask8` exists only where an
// `Avx2` token made its first value, so the CPU has AVX2.
impl LaneMask for Mask8 {
    #[inline(always)]
    fn or(self, other: Mask8) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_or_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn and(self, other: Mask8) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_and_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn and_not(self, other: Mask8) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_andnot_ps(other.0, self.0) })
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        unsafe { _mm256_movemask_ps(self.0) as u32 }
    }
}

impl Lanes for F32x8 {
    type Array = [f32; 8];
    type Mask = Mask8;
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        let mut out = [0f32; 8];
        // SAFETY: an eight-lane value proves AVX2 (see above); the store writes the 32 bytes of `out`.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_add_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_sub_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_mul_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn div(self, other: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_div_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
    }
    #[inline(always)]
    fn max_or(self, other: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_max_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn min_or(self, other: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_min_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn eq(self, other: Self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn lt(self, other: Self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn gt(self, other: Self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn le(self, other: Self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn ge(self, other: Self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn is_number(self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_ORD_Q>(self.0, self.0) })
    }
    #[inline(always)]
    fn is_sign_negative(self) -> Mask8 {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        Mask8(unsafe { _mm256_castsi256_ps(_mm256_srai_epi32::<31>(_mm256_castps_si256(self.0))) })
    }
    #[inline(always)]
    fn select(mask: Mask8, if_true: Self, if_false: Self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        F32x8(unsafe { _mm256_blendv_ps(if_false.0, if_true.0, mask.0) })
    }
    #[inline(always)]
    fn min_across(self) -> Self {
        // SAFETY: an eight-lane value proves AVX2 (see above).
        unsafe {
            let halves = _mm256_min_ps(self.0, _mm256_permute2f128_ps::<1>(self.0, self.0));
            let pairs = _mm256_min_ps(halves, _mm256_shuffle_ps::<0b01_00_11_10>(halves, halves));
            F32x8(_mm256_min_ps(pairs, _mm256_shuffle_ps::<0b10_11_00_01>(pairs, pairs)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Avx2;
    use crate::simd::{Isa, Portable};

    /// The AVX2 transpose moves every bit where the portable one does (NaN payloads and signed zeros included).
    #[test]
    fn transpose8_matches_the_portable_path() {
        let Some(avx2) = Avx2::detect() else {
            eprintln!("SKIPPED: this CPU has no AVX2");
            return;
        };
        let mut rows = [[0f32; 8]; 8];
        for (i, row) in rows.iter_mut().enumerate() {
            for (j, value) in row.iter_mut().enumerate() {
                *value = f32::from_bits(0x3f80_0000 + (i * 8 + j) as u32);
            }
        }
        rows[2][5] = -0.0;
        rows[7][0] = f32::from_bits(0x7fc0_1234);
        let bits = |m: [[f32; 8]; 8]| m.map(|row| row.map(f32::to_bits));
        assert_eq!(bits(avx2.transpose8(&rows)), bits(Portable.transpose8(&rows)));
        assert_eq!(bits(Portable.transpose8(&rows))[5][2], (-0.0f32).to_bits());
    }
}
