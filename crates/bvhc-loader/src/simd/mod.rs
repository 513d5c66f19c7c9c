//! Instruction sets as values, after the pattern of `memchr`'s and `pulp`'s dispatch: a kernel is written once,
//! generic over an [`Isa`], and runs either on [`Portable`] (plain Rust, any machine) or on [`Avx2`], a
//! zero-sized token that only the CPU check can make, so no AVX2 instruction can run without that check.
//! [`run`] is the one place that picks the path: for AVX2 it enters one `target_feature` function and the
//! whole kernel inlines into it.
//!
//! Both paths compute the same IEEE operations in the same order ([`Lanes`]), so they give the same hits bit
//! for bit; the tests run every path against the portable one.

mod lanes;
#[cfg(target_arch = "x86_64")]
mod x86;
#[cfg(target_arch = "x86_64")]
pub(crate) mod x86_points;

pub(crate) use lanes::{LaneMask, Lanes, PortableLanes};
#[cfg(target_arch = "x86_64")]
pub(crate) use x86::Avx2;

use crate::format::{EMPTY_SLOT, WIDE, WideNode8};

/// Which implementation of the kernels runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelPath {
    /// Plain Rust, any machine.
    Portable,
    /// AVX2 box tests and SSE2 triangle packets (x86-64), chosen at run time.
    Avx2,
}

impl KernelPath {
    /// The fastest path this machine supports.
    pub fn best() -> KernelPath {
        if KernelPath::Avx2.is_supported() { KernelPath::Avx2 } else { KernelPath::Portable }
    }

    /// Whether this machine can run the path.
    pub fn is_supported(self) -> bool {
        match self {
            KernelPath::Portable => true,
            KernelPath::Avx2 => Avx2::detect().is_some(),
        }
    }
}

/// What the slab test of a wide node's eight child boxes needs of a ray (`PreparedRay::slab_ray`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay<'r> {
    pub origin: &'r [f32; 3],
    pub inverse_direction: &'r [f32; 3],
    /// The reciprocal direction padded for the exit distances (Ize 2013).
    pub exit_inverse: &'r [f32; 3],
    /// Per axis, where the node's entry and exit planes start, in `f32`s from the node's start: `axis * WIDE`,
    /// plus `3 * WIDE` for the `max` row.
    pub plane_offsets: &'r ([usize; 3], [usize; 3]),
    pub t_min: f32,
}

/// What the kernels need from an instruction set. [`Portable`] and [`Avx2`] give the same results bit for bit.
pub(crate) trait Isa: Copy {
    /// Four lanes (a packet's triangles).
    type F4: Lanes<Array = [f32; 4]>;
    /// Eight lanes (a wide node's child boxes, a coherent packet's rays).
    type F8: Lanes<Array = [f32; 8]>;
    /// Whether the kernels ask the cache for what they will visit next (a hint; no effect on results).
    const PREFETCH: bool;
    /// Four lanes of `values`.
    fn f4(self, values: &[f32; 4]) -> Self::F4;
    /// `value` in four lanes.
    fn f4_splat(self, value: f32) -> Self::F4;
    /// Eight lanes of `values`.
    fn f8(self, values: &[f32; 8]) -> Self::F8;
    /// `value` in eight lanes.
    fn f8_splat(self, value: f32) -> Self::F8;
    /// The robust slab test (Ize 2013) of the ray against the node's eight child boxes, one a lane: the mask of
    /// the occupied slots it enters within `[t_min, t_far]`, and the entry distances. Per lane the binary
    /// kernel's `enter_box`: `t = (plane - origin) * inverse`, the exit through the padded inverse, and the
    /// interval narrowed by compare-selects that keep the accumulator where a distance is NaN. Empty slots are
    /// left out of the mask (they never hit a finite ray, but a NaN origin makes every comparison fail and so
    /// every slot look hit).
    fn box_test(self, node: &WideNode8, ray: &SlabRay<'_>, t_far: f32) -> (u8, [f32; WIDE]);
    /// The transpose of eight rows of eight (`out[j][i] == rows[i][j]`): eight records turned into eight
    /// lanes of each field. Moves only, so the same bits on every instruction set.
    fn transpose8(self, rows: &[[f32; 8]; 8]) -> [[f32; 8]; 8] {
        let mut out = [[0f32; 8]; 8];
        for (i, row) in rows.iter().enumerate() {
            for (j, &value) in row.iter().enumerate() {
                out[j][i] = value;
            }
        }
        out
    }
}

/// The portable path: plain Rust on any machine.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable;

impl Isa for Portable {
    type F4 = PortableLanes<4>;
    type F8 = PortableLanes<8>;
    const PREFETCH: bool = false;
    #[inline(always)]
    fn f4(self, values: &[f32; 4]) -> PortableLanes<4> {
        PortableLanes(*values)
    }
    #[inline(always)]
    fn f4_splat(self, value: f32) -> PortableLanes<4> {
        PortableLanes([value; 4])
    }
    #[inline(always)]
    fn f8(self, values: &[f32; 8]) -> PortableLanes<8> {
        PortableLanes(*values)
    }
    #[inline(always)]
    fn f8_splat(self, value: f32) -> PortableLanes<8> {
        PortableLanes([value; 8])
    }
    #[inline(always)]
    fn box_test(self, node: &WideNode8, ray: &SlabRay<'_>, t_far: f32) -> (u8, [f32; WIDE]) {
        let planes: &[f32; 8 * WIDE] = bytemuck::must_cast_ref(node);
        let row = |offset: usize| self.f8(planes[offset..offset + WIDE].try_into().unwrap_or(&[f32::NAN; WIDE]));
        let (entry_offsets, exit_offsets) = ray.plane_offsets;
        let mut near = self.f8_splat(ray.t_min);
        let mut far = self.f8_splat(t_far);
        for axis in 0..3 {
            let origin = self.f8_splat(ray.origin[axis]);
            let t_entry = row(entry_offsets[axis]).sub(origin).mul(self.f8_splat(ray.inverse_direction[axis]));
            let t_exit = row(exit_offsets[axis]).sub(origin).mul(self.f8_splat(ray.exit_inverse[axis]));
            near = t_entry.max_or(near);
            far = t_exit.min_or(far);
        }
        let occupied =
            node.child.iter().enumerate().fold(0, |m, (slot, &child)| m | u32::from(child != EMPTY_SLOT) << slot);
        ((near.le(far).bits() & occupied) as u8, near.to_array())
    }
}

/// The AVX2 token where the target is not x86-64: it cannot be made.
#[cfg(not(target_arch = "x86_64"))]
#[derive(Clone, Copy, Debug)]
pub(crate) enum Avx2 {}

#[cfg(not(target_arch = "x86_64"))]
impl Avx2 {
    /// Never: this target has no AVX2.
    pub(crate) fn detect() -> Option<Avx2> {
        None
    }
}

/// A computation written once for every instruction set (`pulp`'s `WithSimd`).
pub(crate) trait Kernel {
    /// What it returns.
    type Output;
    /// Runs it on `isa`.
    fn run<I: Isa>(self, isa: I) -> Self::Output;
}

/// Runs `kernel` with AVX2 when given the token, else on the portable path. Both entries stay out of line, so
/// that callers that inline this (the tracers) stay small.
#[inline(always)]
pub(crate) fn run<K: Kernel>(avx2: Option<Avx2>, kernel: K) -> K::Output {
    match avx2 {
        #[cfg(target_arch = "x86_64")]
        Some(token) => x86::run_avx2(token, kernel),
        #[cfg(not(target_arch = "x86_64"))]
        Some(never) => match never {},
        None => run_portable(kernel),
    }
}

#[inline(never)]
fn run_portable<K: Kernel>(kernel: K) -> K::Output {
    kernel.run(Portable)
}
