//! Packets of up to eight coherent rays (camera rays of neighbouring pixels) traced through the wide sections
//! together: one traversal, its stack entries carrying a mask of the rays that go there (after Wald, Slusallek,
//! Benthin, Wagner, "Interactive Rendering with Coherent Ray Tracing", Eurographics 2001, on an 8-wide BVH).
//! At a wide node each occupied slot's box is tested against all the packet's rays at once, one ray a lane
//! (AVX2, or a portable loop with the same operations in the same order), with the single-ray kernel's robust
//! slab test per lane (Ize 2013; entry and exit planes picked per lane by the sign of that ray's direction).
//! Children are visited in the order of the packet's first active ray; each stack entry keeps every lane's
//! entry distance, so on pop the rays whose closest hit is already nearer leave the packet. Leaves test their
//! triangle packets for each active ray with the single-ray packet test (`wide_packets`).
//!
//! Each ray's closest `t` (and any-hit answer) is the single-ray kernel's: the box test is the same arithmetic,
//! conservative for each ray, and culling uses the same padding; on a tie at that `t` the triangle reported may
//! differ, as section 11 of the spec allows. Safe on any bytes: indices are bounds-checked and a packet visits
//! at most `node_count` wide nodes.

use std::mem::MaybeUninit;

use crate::format::{EMPTY_SLOT, LEAF_BIT, WIDE, WideNode8};
use crate::intersect::{PreparedRay, Ray, TriangleHit, slab};
use crate::traverse::CULL_PADDING;
use crate::wide_walk::{STACK_LEN, Sections};

/// Rays in one packet.
pub(crate) const PACKET_RAYS: usize = 8;

/// A stack entry: a child reference, the rays that enter it, and each ray's entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    rays: u8,
    t_near: [f32; PACKET_RAYS],
}

/// The per-lane ray data of a packet, structure of arrays.
struct Lanes {
    origin: [[f32; PACKET_RAYS]; 3],
    inverse_direction: [[f32; PACKET_RAYS]; 3],
    exit_inverse: [[f32; PACKET_RAYS]; 3],
    /// Per axis, bit `l`: ray `l`'s direction has its sign bit set (enters through `max`).
    negative: [u8; 3],
    t_min: [f32; PACKET_RAYS],
    /// Woop et al.'s shear per lane, and whether every ray of the packet has the same axes `[kx, ky, kz]`
    /// (those of the first ray), so that a triangle can be tested against all of them in lanes.
    shear: [[f32; PACKET_RAYS]; 3],
    shared_axes: Option<[usize; 3]>,
}

/// Traces `rays` (at most [`PACKET_RAYS`]) as one packet; `done(l, found)` receives ray `l`'s result.
#[inline(always)]
#[allow(unsafe_code)] // the AVX2 leaf test, see the SAFETY note
pub(crate) fn trace_packet<const ANY_HIT: bool, const SIMD: bool>(
    sections: &Sections<'_>,
    rays: &[Ray],
    done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
) {
    let rays = &rays[..rays.len().min(PACKET_RAYS)];
    let prepared: [Option<PreparedRay>; PACKET_RAYS] = std::array::from_fn(|l| rays.get(l).map(PreparedRay::new));
    let mut t_max = [0f32; PACKET_RAYS];
    let mut found: [Option<(u32, TriangleHit)>; PACKET_RAYS] = [None; PACKET_RAYS];
    let mut root = Entry { child: 0, rays: 0, t_near: [0.0; PACKET_RAYS] };
    let mut lanes = Lanes {
        origin: [[0.0; PACKET_RAYS]; 3],
        inverse_direction: [[0.0; PACKET_RAYS]; 3],
        exit_inverse: [[0.0; PACKET_RAYS]; 3],
        negative: [0; 3],
        t_min: [0.0; PACKET_RAYS],
        shear: [[0.0; PACKET_RAYS]; 3],
        shared_axes: prepared[0].map(|p| p.shear().0),
    };
    for (l, ray) in rays.iter().enumerate() {
        let Some(p) = &prepared[l] else { continue };
        t_max[l] = ray.t_max;
        for axis in 0..3 {
            lanes.origin[axis][l] = p.origin[axis];
            lanes.inverse_direction[axis][l] = p.inverse_direction[axis];
            lanes.exit_inverse[axis][l] = p.exit_inverse[axis];
            lanes.negative[axis] |= u8::from(p.negative[axis]) << l;
        }
        lanes.t_min[l] = p.t_min;
        let (axes, shear) = p.shear();
        for (k, &value) in shear.iter().enumerate() {
            lanes.shear[k][l] = value;
        }
        if lanes.shared_axes != Some(axes) {
            lanes.shared_axes = None;
        }
        if !sections.nodes.is_empty()
            && let Some(t) = p.enter_box(&sections.root, ray.t_max)
        {
            root.rays |= 1 << l;
            root.t_near[l] = t;
        }
    }
    // Rays still looking: all of them for closest hits; for any hit, those without a hit yet.
    let mut pending = root.rays;
    let mut stack = [const { MaybeUninit::<Entry>::uninit() }; STACK_LEN];
    let mut stack_len = 0usize;
    let mut visits_left = sections.nodes.len();
    let mut next = Some(root);
    while let Some(entry) = next.take() {
        let active = entry.rays & pending;
        if active != 0 {
            if entry.child & LEAF_BIT != 0 {
                let (first, count) = WideNode8::leaf_packets(entry.child);
                let packets = sections.packets.get(first as usize..(first + count) as usize).unwrap_or(&[]);
                #[cfg(target_arch = "x86_64")]
                if SIMD && let Some(axes) = lanes.shared_axes {
                    // SAFETY: SIMD is true only inside the tracer's `target_feature(enable = "avx2")` entries,
                    // which run only after the AVX2 check of `WideTracer::over`.
                    let hit = unsafe {
                        avx2::leaf_test::<ANY_HIT>(packets, &lanes, axes, active, &prepared, &mut t_max, &mut found)
                    };
                    if ANY_HIT {
                        pending &= !hit;
                    }
                    next = pop(&mut stack, &mut stack_len, &t_max, pending);
                    continue;
                }
                for l in (0..PACKET_RAYS).filter(|l| active & (1 << l) != 0) {
                    let Some(ray) = &prepared[l] else { continue };
                    for packet in packets {
                        if let Some((lane, hit)) =
                            crate::wide_packets::closest_in_packet::<ANY_HIT, SIMD>(packet, ray, t_max[l])
                        {
                            t_max[l] = hit.t;
                            found[l] = Some((packet.triangle_index[lane], hit));
                            if ANY_HIT {
                                pending &= !(1 << l);
                                break;
                            }
                        }
                    }
                }
            } else if let Some(node) = sections.nodes.get(entry.child as usize).filter(|_| visits_left > 0) {
                visits_left -= 1;
                let t_far: [f32; PACKET_RAYS] = std::array::from_fn(|l| t_max[l] * CULL_PADDING);
                let leader = active.trailing_zeros() as usize & (PACKET_RAYS - 1);
                // The hit slots, nearest first for the leader (the first active ray), ties in slot order.
                let mut order = [Entry { child: 0, rays: 0, t_near: [0.0; PACKET_RAYS] }; WIDE];
                let mut n = 0;
                for slot in 0..WIDE {
                    let child = node.child[slot];
                    if child == EMPTY_SLOT {
                        break;
                    }
                    let (hit, t_near) = slot_test::<SIMD>(node, slot, &lanes, &t_far);
                    let hit = hit & active;
                    if hit == 0 {
                        continue;
                    }
                    let entry = Entry { child, rays: hit, t_near };
                    let key = |e: &Entry| if e.rays & (1 << leader) != 0 { e.t_near[leader] } else { f32::INFINITY };
                    let mut at = n;
                    while at > 0 && key(&order[at - 1]) > key(&entry) {
                        order[at] = order[at - 1];
                        at -= 1;
                    }
                    order[at] = entry;
                    n += 1;
                }
                if n > 0 {
                    for entry in order[1..n].iter().rev() {
                        if let Some(slot) = stack.get_mut(stack_len) {
                            slot.write(*entry);
                            stack_len += 1;
                        }
                    }
                    next = Some(order[0]);
                    continue;
                }
            }
        }
        next = pop(&mut stack, &mut stack_len, &t_max, pending);
    }
    for (l, hit) in found.iter().enumerate().take(rays.len()) {
        done(l, *hit);
    }
}

/// The next entry that still has rays in `pending` whose closest hit is not nearer than its box.
#[inline(always)]
#[allow(unsafe_code)] // reading the stack, see the SAFETY note
fn pop(
    stack: &mut [MaybeUninit<Entry>; STACK_LEN],
    stack_len: &mut usize,
    t_max: &[f32; PACKET_RAYS],
    pending: u8,
) -> Option<Entry> {
    while *stack_len > 0 {
        *stack_len -= 1;
        // SAFETY: entries below `stack_len` were written by the push in `trace_packet` before `stack_len` passed
        // them, and `stack_len` only moves down by one here, so this entry is initialized.
        let mut entry = unsafe { stack[*stack_len].assume_init() };
        for (l, (&t_near, &t_best)) in entry.t_near.iter().zip(t_max).enumerate() {
            if t_near > t_best * CULL_PADDING {
                entry.rays &= !(1 << l);
            }
        }
        if entry.rays & pending != 0 {
            return Some(entry);
        }
    }
    None
}

/// Slot `slot` of `node` against every lane: (bit mask of the lanes whose ray enters the box within
/// `[t_min, t_far]`, entry distances). The single-ray slab test per lane, on the SIMD path in AVX2.
#[inline(always)]
#[allow(unsafe_code)] // the AVX2 call, only reached on the SIMD path
fn slot_test<const SIMD: bool>(
    node: &WideNode8,
    slot: usize,
    lanes: &Lanes,
    t_far: &[f32; PACKET_RAYS],
) -> (u8, [f32; PACKET_RAYS]) {
    #[cfg(target_arch = "x86_64")]
    if SIMD {
        // SAFETY: SIMD is true only inside the tracer's `target_feature(enable = "avx2")` entries, which run only
        // after the AVX2 check of `WideTracer::over`.
        return unsafe { avx2::slot_test(node, slot, lanes, t_far) };
    }
    let mut near = lanes.t_min;
    let mut far = *t_far;
    for axis in 0..3 {
        let (lo, hi) = (node.min[axis][slot], node.max[axis][slot]);
        for l in 0..PACKET_RAYS {
            let negative = lanes.negative[axis] & (1 << l) != 0;
            let (entry, exit) = if negative { (hi, lo) } else { (lo, hi) };
            let inverses = (lanes.inverse_direction[axis][l], lanes.exit_inverse[axis][l]);
            (near[l], far[l]) = slab(entry, exit, lanes.origin[axis][l], inverses, near[l], far[l]);
        }
    }
    let mask = (0..PACKET_RAYS).fold(0u8, |m, l| if near[l] <= far[l] { m | 1 << l } else { m });
    (mask, near)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // intrinsics: every block states what it relies on
mod avx2 {
    use std::arch::x86_64::*;

    use super::{Lanes, PACKET_RAYS};
    use crate::format::{TrianglePacket4, WideNode8};
    use crate::intersect::{PreparedRay, TriangleHit};

    /// The triangles of `packets`, one after the other, against the `active` rays in lanes, when every ray has
    /// the shear axes `axes`: per (ray, triangle) the scalar watertight test's operations in its order, a lane
    /// with an edge function exactly 0 redone by the scalar test, and hits accepted in triangle order at
    /// `t <= t_max` of the ray, so each ray ends with what the single-ray packet test gives. Returns the rays
    /// that were hit.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn leaf_test<const ANY_HIT: bool>(
        packets: &[TrianglePacket4],
        lanes: &Lanes,
        [kx, ky, kz]: [usize; 3],
        mut active: u8,
        prepared: &[Option<PreparedRay>; PACKET_RAYS],
        t_max: &mut [f32; PACKET_RAYS],
        found: &mut [Option<(u32, TriangleHit)>; PACKET_RAYS],
    ) -> u8 {
        let mut hit_rays = 0u8;
        // SAFETY: every load and store touches an `[f32; 8]`, 32 bytes; unaligned accesses need no more.
        unsafe {
            let load = |values: &[f32; PACKET_RAYS]| _mm256_loadu_ps(values.as_ptr());
            let origin = [load(&lanes.origin[0]), load(&lanes.origin[1]), load(&lanes.origin[2])];
            let (sx, sy, sz) = (load(&lanes.shear[0]), load(&lanes.shear[1]), load(&lanes.shear[2]));
            let t_min = load(&lanes.t_min);
            let z = _mm256_setzero_ps();
            for packet in packets {
                for tri in 0..packet.used_lanes() {
                    let at = |vertex: usize, axis: usize| {
                        _mm256_sub_ps(_mm256_set1_ps(packet.vertices[vertex][axis][tri]), origin[axis])
                    };
                    let (akz, bkz, ckz) = (at(0, kz), at(1, kz), at(2, kz));
                    let ax = _mm256_sub_ps(at(0, kx), _mm256_mul_ps(sx, akz));
                    let ay = _mm256_sub_ps(at(0, ky), _mm256_mul_ps(sy, akz));
                    let bx = _mm256_sub_ps(at(1, kx), _mm256_mul_ps(sx, bkz));
                    let by = _mm256_sub_ps(at(1, ky), _mm256_mul_ps(sy, bkz));
                    let cx = _mm256_sub_ps(at(2, kx), _mm256_mul_ps(sx, ckz));
                    let cy = _mm256_sub_ps(at(2, ky), _mm256_mul_ps(sy, ckz));
                    let u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
                    let v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
                    let w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
                    let eq = |a| _mm256_cmp_ps::<_CMP_EQ_OQ>(a, z);
                    let lt = |a| _mm256_cmp_ps::<_CMP_LT_OQ>(a, z);
                    let gt = |a| _mm256_cmp_ps::<_CMP_GT_OQ>(a, z);
                    let zero = _mm256_or_ps(_mm256_or_ps(eq(u), eq(v)), eq(w));
                    let negative = _mm256_or_ps(_mm256_or_ps(lt(u), lt(v)), lt(w));
                    let positive = _mm256_or_ps(_mm256_or_ps(gt(u), gt(v)), gt(w));
                    let outside = _mm256_and_ps(negative, positive);
                    let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
                    let (az, bz, cz) = (_mm256_mul_ps(sz, akz), _mm256_mul_ps(sz, bkz), _mm256_mul_ps(sz, ckz));
                    let sum =
                        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(u, az), _mm256_mul_ps(v, bz)), _mm256_mul_ps(w, cz));
                    let t = _mm256_div_ps(sum, det);
                    let limit = load(t_max);
                    let in_range =
                        _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(t, t_min), _mm256_cmp_ps::<_CMP_LE_OQ>(t, limit));
                    let valid = _mm256_andnot_ps(_mm256_or_ps(outside, eq(det)), in_range);
                    let zero_rays = _mm256_movemask_ps(zero) as u8 & active;
                    let valid_rays = _mm256_movemask_ps(valid) as u8 & active & !zero_rays;
                    if valid_rays != 0 {
                        let inverse_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
                        let mut out = [[0f32; PACKET_RAYS]; 3];
                        _mm256_storeu_ps(out[0].as_mut_ptr(), t);
                        _mm256_storeu_ps(out[1].as_mut_ptr(), _mm256_mul_ps(v, inverse_det));
                        _mm256_storeu_ps(out[2].as_mut_ptr(), _mm256_mul_ps(w, inverse_det));
                        let mut rays = valid_rays;
                        while rays != 0 {
                            let l = rays.trailing_zeros() as usize & (PACKET_RAYS - 1);
                            rays &= rays - 1;
                            t_max[l] = out[0][l];
                            let hit = TriangleHit { t: out[0][l], u: out[1][l], v: out[2][l] };
                            found[l] = Some((packet.triangle_index[tri], hit));
                        }
                        hit_rays |= valid_rays;
                    }
                    let mut rays = zero_rays;
                    while rays != 0 {
                        let l = rays.trailing_zeros() as usize & (PACKET_RAYS - 1);
                        rays &= rays - 1;
                        let Some(ray) = &prepared[l] else { continue };
                        if let Some(hit) = ray.intersect_triangle(&packet.triangle(tri), t_max[l]) {
                            t_max[l] = hit.t;
                            found[l] = Some((packet.triangle_index[tri], hit));
                            hit_rays |= 1 << l;
                        }
                    }
                }
                if ANY_HIT {
                    active &= !hit_rays;
                    if active == 0 {
                        break;
                    }
                }
            }
        }
        hit_rays
    }

    /// The portable `slot_test`'s operations in AVX2 lanes, one ray a lane.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn slot_test(
        node: &WideNode8,
        slot: usize,
        lanes: &Lanes,
        t_far: &[f32; PACKET_RAYS],
    ) -> (u8, [f32; PACKET_RAYS]) {
        // SAFETY: every load and the store touch an `[f32; 8]`, 32 bytes; unaligned accesses need no more.
        unsafe {
            let mut near = _mm256_loadu_ps(lanes.t_min.as_ptr());
            let mut far = _mm256_loadu_ps(t_far.as_ptr());
            let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            for axis in 0..3 {
                let lo = _mm256_set1_ps(node.min[axis][slot]);
                let hi = _mm256_set1_ps(node.max[axis][slot]);
                let signs = _mm256_set1_epi32(i32::from(lanes.negative[axis]));
                let negative = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(signs, bit), bit));
                let entry = _mm256_blendv_ps(lo, hi, negative);
                let exit = _mm256_blendv_ps(hi, lo, negative);
                let o = _mm256_loadu_ps(lanes.origin[axis].as_ptr());
                let inv = _mm256_loadu_ps(lanes.inverse_direction[axis].as_ptr());
                let exit_inv = _mm256_loadu_ps(lanes.exit_inverse[axis].as_ptr());
                let t_entry = _mm256_mul_ps(_mm256_sub_ps(entry, o), inv);
                let t_exit = _mm256_mul_ps(_mm256_sub_ps(exit, o), exit_inv);
                // max_ps(a, b) = a > b ? a : b and min_ps(a, b) = a < b ? a : b: the portable compare-selects.
                near = _mm256_max_ps(t_entry, near);
                far = _mm256_min_ps(t_exit, far);
            }
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u8;
            let mut out = [0f32; PACKET_RAYS];
            _mm256_storeu_ps(out.as_mut_ptr(), near);
            (mask, out)
        }
    }
}
