//! The frustum of a packet of rays whose directions share their signs, and its test against a wide node's
//! eight child boxes at once: one slab test for the whole packet instead of one a ray (the coherent traversal
//! of Embree's hybrid kernels, after Reshetov, Soupikov and Hurley, "Multi-level ray tracing algorithm",
//! SIGGRAPH 2005, and Benthin's frustum culling for packets).
//!
//! The test is conservative against the single-ray kernel's own arithmetic, not only against exact arithmetic:
//! whenever the single-ray slab test (`Isa::box_test`: `t = (plane - origin) * inverse` rounded twice, Ize's
//! padded inverse on exits, compare-selects that skip a NaN) lets one of the packet's rays enter a box, the
//! frustum test lets the packet enter it, and the entry distance it gives is at most that ray's. The proof,
//! per axis and plane, for rays whose direction components share their sign bit (so the same plane is each
//! ray's entry, and the same its exit):
//!
//! - `fl(plane - o)` does not increase as `o` grows, so over the packet's origins it is least at the largest
//!   origin and greatest at the smallest; `fl(x * i)` is monotone in `x` for a fixed `i` and in `i` for a
//!   fixed `x` (rounding to nearest is monotone). For an entry plane the bound is therefore
//!   `fl(x * i)` with `x` the difference at the origin that makes the distance least (the largest origin when
//!   the direction is positive, the smallest when it is negative, where the largest `x` gives the least `t`)
//!   and `i` the packet's smallest inverse when `x > 0`, its largest otherwise; for an exit plane, `x` at the
//!   other origin and the largest padded inverse when `x > 0`, the smallest when `x < 0`, and at `x == 0` the
//!   one of largest magnitude. Each bound is then at most (entry) or at least (exit) every ray's own value,
//!   case by case on the signs of `x` and `i`.
//! - A ray's value is NaN only for `0 * inf`: an origin on the plane and a zero direction component. Then an
//!   entry bound is NaN, `-inf` or at most 0 (every ray's `t_min` is at least 0), and an exit bound NaN or
//!   `+inf` (the infinite inverse is the one chosen): never a constraint that ray does not have alone.
//! - The packet's interval starts at the smallest `t_min` and the largest `t_max` (each padded by the walk's
//!   cull padding as the single-ray walk does), so a ray whose own interval is not empty leaves the packet's
//!   not empty: its entry is at least the packet's, its exit at most the packet's.
//!
//! So a packet traversal that culls with this test and tests its leaves ray by ray visits every node each of
//! its rays would visit alone, and finds each ray's closest hit (spec 11.1 decides ties, whatever the order).

use crate::format::{WIDE, WideNode8};

/// Rays in one packet.
pub(crate) const PACKET_RAYS: usize = 8;
use crate::simd::{Isa, LaneMask, Lanes};

/// The per-lane ray data of a packet, structure of arrays.
pub(crate) struct RayLanes {
    pub origin: [[f32; PACKET_RAYS]; 3],
    pub inverse_direction: [[f32; PACKET_RAYS]; 3],
    pub exit_inverse: [[f32; PACKET_RAYS]; 3],
    /// Per axis and lane: -1 where the ray's direction has its sign bit set (it enters through `max`), else 1.
    pub sign: [[f32; PACKET_RAYS]; 3],
    pub t_min: [f32; PACKET_RAYS],
    /// Woop et al.'s shear per lane, and whether every ray of the packet has the same axes `[kx, ky, kz]`
    /// (those of the first ray), so that a triangle can be tested against all of them in lanes.
    pub shear: [[f32; PACKET_RAYS]; 3],
    pub shared_axes: Option<[usize; 3]>,
}

/// The bounds of a packet's rays per axis, for the frustum test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frustum {
    /// Per axis: whether every ray's direction has its sign bit set (each enters the slab through `max`).
    negative: [bool; 3],
    /// Per axis: the origin that makes the entry distance least (the largest for a positive direction, the
    /// smallest for a negative one).
    entry_origin: [f32; 3],
    /// Per axis: the origin that makes the exit distance greatest (the smallest for a positive direction, the
    /// largest for a negative one).
    exit_origin: [f32; 3],
    /// Per axis: the smallest and largest inverse direction.
    inverse: [[f32; 2]; 3],
    /// Per axis: the smallest and largest padded exit inverse.
    exit_inverse: [[f32; 2]; 3],
    /// The smallest `t_min`.
    t_min: f32,
}

impl Frustum {
    /// The frustum of the rays `rays` (bit `l` for lane `l` of `lanes`), or `None` when there is none or when
    /// two of them differ in the sign bit of a direction component (their entry planes differ).
    #[inline(always)]
    pub(crate) fn around<I: Isa>(isa: I, lanes: &RayLanes, rays: u8) -> Option<Frustum> {
        let members = u32::from(rays);
        let mut negative = [false; 3];
        for (axis, sign) in lanes.sign.iter().enumerate() {
            let negatives = isa.f8(sign).is_sign_negative().bits() & members;
            if negatives != 0 && negatives != members {
                return None;
            }
            negative[axis] = negatives != 0;
        }
        if members == 0 {
            return None;
        }
        // Plain loops: a closure around the lane operations would not be compiled for the instruction set.
        let (mut origin, mut inverse, mut exit_inverse) = ([[0f32; 2]; 3], [[0f32; 2]; 3], [[0f32; 2]; 3]);
        for axis in 0..3 {
            origin[axis] = [least(isa, &lanes.origin[axis], rays), greatest(isa, &lanes.origin[axis], rays)];
            inverse[axis] =
                [least(isa, &lanes.inverse_direction[axis], rays), greatest(isa, &lanes.inverse_direction[axis], rays)];
            exit_inverse[axis] =
                [least(isa, &lanes.exit_inverse[axis], rays), greatest(isa, &lanes.exit_inverse[axis], rays)];
        }
        let (mut entry_origin, mut exit_origin) = ([0f32; 3], [0f32; 3]);
        for axis in 0..3 {
            entry_origin[axis] = origin[axis][usize::from(!negative[axis])];
            exit_origin[axis] = origin[axis][usize::from(negative[axis])];
        }
        Some(Frustum {
            negative,
            entry_origin,
            exit_origin,
            inverse,
            exit_inverse,
            t_min: least(isa, &lanes.t_min, rays),
        })
    }

    /// The slots of `node` the packet may enter within `[t_min, t_far]` (`t_far`: the largest of its rays'
    /// padded `t_max`), and per slot an entry distance at most that of any ray that enters it. An empty slot's
    /// box (`+inf` minima, `-inf` maxima) is never entered by a valid ray; on other bytes the slots are
    /// unspecified (and the walk stays safe).
    #[inline(always)]
    pub(crate) fn test<I: Isa>(&self, isa: I, node: &WideNode8, t_far: f32) -> (u8, [f32; WIDE]) {
        let zero = isa.f8_splat(0.0);
        let mut near = isa.f8_splat(self.t_min);
        let mut far = isa.f8_splat(t_far);
        for axis in 0..3 {
            let (entry, exit) = if self.negative[axis] {
                (&node.max[axis], &node.min[axis])
            } else {
                (&node.min[axis], &node.max[axis])
            };
            let [low, high] = self.inverse[axis];
            let x = isa.f8(entry).sub(isa.f8_splat(self.entry_origin[axis]));
            let inverse = I::F8::select(x.gt(zero), isa.f8_splat(low), isa.f8_splat(high));
            near = x.mul(inverse).max_or(near);
            let [low, high] = self.exit_inverse[axis];
            let x = isa.f8(exit).sub(isa.f8_splat(self.exit_origin[axis]));
            // At `x == 0` the inverse of largest magnitude, so that a ray with a zero direction component
            // on the plane gives NaN (no bound) as it does alone.
            let larger = if self.negative[axis] { x.gt(zero) } else { x.ge(zero) };
            let exit_inverse = I::F8::select(larger, isa.f8_splat(high), isa.f8_splat(low));
            far = x.mul(exit_inverse).min_or(far);
        }
        (near.le(far).bits() as u8, near.to_array())
    }
}

/// The lanes of `rays` (bit `l` for lane `l`) as a mask, the others `+inf`.
#[inline(always)]
fn only<I: Isa>(isa: I, values: I::F8, rays: u8) -> I::F8 {
    let mut lane_bits = [f32::NAN; PACKET_RAYS];
    for (l, bits) in lane_bits.iter_mut().enumerate() {
        if rays >> l & 1 != 0 {
            *bits = 0.0;
        }
    }
    I::F8::select(isa.f8(&lane_bits).is_number(), values, isa.f8_splat(f32::INFINITY))
}

/// The least of `values` in the lanes of `rays` (`+inf` for none; values without NaN).
#[inline(always)]
pub(crate) fn least<I: Isa>(isa: I, values: &[f32; PACKET_RAYS], rays: u8) -> f32 {
    only(isa, isa.f8(values), rays).min_across().to_array()[0]
}

/// The greatest of `values` in the lanes of `rays` (`-inf` for none; values without NaN), as the least of
/// the negated values (negation is exact; the sign of a zero may differ, which no caller tells apart).
#[inline(always)]
pub(crate) fn greatest<I: Isa>(isa: I, values: &[f32; PACKET_RAYS], rays: u8) -> f32 {
    let zero = isa.f8_splat(0.0);
    -only(isa, zero.sub(isa.f8(values)), rays).min_across().to_array()[0]
}
