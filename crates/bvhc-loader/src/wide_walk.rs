//! One ray's traversal of the wide sections, as a state machine that advances one wide node or leaf a step, so
//! a single ray runs it to the end and a stream of rays interleaves several (each ray's steps, and so its hits,
//! are the same either way; interleaving lets one ray's cache misses overlap with another's work).
//!
//! A step at a wide node tests the ray against the eight child boxes at once (AVX2, or a portable loop with the
//! same operations in the same order, so both give the same lanes bit for bit) with the binary kernel's robust
//! slab test (Ize 2013: exit distances padded by `1 + 2 gamma(3)` through the ray's padded reciprocal,
//! compare-selects that ignore the NaN of an origin on the slab plane of a zero direction component; nothing
//! fused). For a closest hit the hit children go nearest first: one or two without a sort, more by insertion
//! sort; the others are pushed with their entry distance and skipped on pop when a closer hit was found (with
//! the binary kernel's cull padding). For any hit the order does not matter: the hit children are pushed in
//! slot order and the walk goes on with the last, with no distance compared (Embree's occlusion traversal does
//! the same), and a leaf ends the walk at its first hit. On the SIMD path pushed children are prefetched, so
//! their misses overlap with the work on the nearer ones. A step at a leaf tests its packets four triangles at
//! a time (`wide_packets`).
//!
//! Safe on any bytes: every index is bounds-checked, and a walk visits at most `node_count` wide nodes (so a
//! node referenced from many slots cannot make it run long); on a file that fails verification the hits are
//! unspecified.

use std::mem::MaybeUninit;

use crate::format::{EMPTY_SLOT, LEAF_BIT, MAX_DEPTH, PackedNode, TrianglePacket4, WIDE, WideNode8};
use crate::intersect::{PreparedRay, Ray, TriangleHit, slab};
use crate::traverse::{CULL_PADDING, TraversalCounter};

/// Stack entries: each visited node pushes at most 7, and a verified file is at most `MAX_DEPTH` deep.
pub(crate) const STACK_LEN: usize = (WIDE - 1) * MAX_DEPTH + 1;

/// A walk's stack of (child reference, entry distance). Never initialized as a whole: 14 KiB of memset per ray
/// cost more than a node visit; a walk only reads entries it wrote.
pub(crate) type Stack = [MaybeUninit<(u32, f32)>; STACK_LEN];

/// A new, unwritten stack.
pub(crate) const fn new_stack() -> Stack {
    [const { MaybeUninit::uninit() }; STACK_LEN]
}

/// The wide sections a walk runs over, and the binary root's box.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sections<'a> {
    pub nodes: &'a [WideNode8],
    pub packets: &'a [TrianglePacket4],
    /// The binary root's box, tested first (as an inner node for the binary kernel's box test).
    pub root: PackedNode,
}

/// One ray's traversal state; its stack is kept by the caller (one per walk in flight).
pub(crate) struct Walk {
    ray: PreparedRay,
    t_max: f32,
    found: Option<(u32, TriangleHit)>,
    visits_left: usize,
    current: u32,
    /// Entries below this index of the walk's stack are written.
    stack_len: usize,
}

impl Walk {
    /// The walk of `ray` from the wide root, or `None` when the ray misses the root's box (or there is no tree).
    #[inline(always)]
    pub(crate) fn start(sections: &Sections<'_>, ray: &Ray) -> Option<Walk> {
        let prepared = PreparedRay::new(ray);
        if sections.nodes.is_empty() || prepared.enter_box(&sections.root, ray.t_max).is_none() {
            return None;
        }
        Some(Walk {
            ray: prepared,
            t_max: ray.t_max,
            found: None,
            visits_left: sections.nodes.len(),
            current: 0,
            stack_len: 0,
        })
    }

    /// The closest hit so far (any hit, for `ANY_HIT` walks), as (triangle index, hit).
    pub(crate) fn found(&self) -> Option<(u32, TriangleHit)> {
        self.found
    }

    /// Processes the current wide node or leaf and moves to the next; `false` when the walk has ended.
    /// `stack` must be the one this walk has used since it started.
    #[inline(always)]
    pub(crate) fn step<const ANY_HIT: bool, const SIMD: bool>(
        &mut self,
        sections: &Sections<'_>,
        stack: &mut Stack,
        counter: &mut impl TraversalCounter,
    ) -> bool {
        let current = self.current;
        if current & LEAF_BIT != 0 {
            let (first, count) = WideNode8::leaf_packets(current);
            if let Some(hit) =
                leaf_hit::<ANY_HIT, SIMD>(sections, &self.ray, first as usize, count as usize, self.t_max, counter)
            {
                self.found = Some(hit);
                if ANY_HIT {
                    return false;
                }
                self.t_max = hit.1.t;
            }
        } else if let Some(node) = sections.nodes.get(current as usize).filter(|_| self.visits_left > 0) {
            self.visits_left -= 1;
            counter.node_visited();
            let (mask, t_near) = box_test::<SIMD>(node, &self.ray, self.t_max * CULL_PADDING);
            let first = mask.trailing_zeros() as usize;
            let rest = mask & mask.wrapping_sub(1);
            if rest == 0 {
                if let Some(&child) = node.child.get(first) {
                    self.current = child;
                    return true;
                }
            } else if ANY_HIT {
                // Any hit needs no order: the hit children go on the stack in slot order and the walk goes on
                // with the last (as Embree's occlusion traversal does), without comparing distances.
                let mut lanes = mask;
                loop {
                    let lane = lanes.trailing_zeros() as usize & (WIDE - 1);
                    lanes &= lanes - 1;
                    if lanes == 0 {
                        self.descend::<SIMD>(sections, node.child[lane]);
                        return true;
                    }
                    self.push::<SIMD>(sections, stack, (node.child[lane], t_near[lane]));
                }
            } else if rest & (rest - 1) == 0 {
                let second = rest.trailing_zeros() as usize & (WIDE - 1);
                let (near, far) = if t_near[second] < t_near[first] { (second, first) } else { (first, second) };
                self.push::<SIMD>(sections, stack, (node.child[far], t_near[far]));
                self.descend::<SIMD>(sections, node.child[near]);
                return true;
            } else {
                let mut order = [(0u32, 0f32); WIDE];
                let mut n = 0;
                let mut lanes = mask;
                while lanes != 0 {
                    let lane = lanes.trailing_zeros() as usize & (WIDE - 1);
                    lanes &= lanes - 1;
                    let entry = (node.child[lane], t_near[lane]);
                    let mut at = n;
                    while at > 0 && order[at - 1].1 > entry.1 {
                        order[at] = order[at - 1];
                        at -= 1;
                    }
                    order[at] = entry;
                    n += 1;
                }
                for &entry in order[1..n].iter().rev() {
                    self.push::<SIMD>(sections, stack, entry);
                }
                self.descend::<SIMD>(sections, order[0].0);
                return true;
            }
        }
        self.pop(stack)
    }

    /// Continues with `child`, prefetched on the SIMD path (its loads then start together).
    #[inline(always)]
    fn descend<const SIMD: bool>(&mut self, sections: &Sections<'_>, child: u32) {
        if SIMD {
            prefetch(sections, child);
        }
        self.current = child;
    }

    /// Pushes `entry` (dropped when the stack is full, which only a file that breaks V30 can cause) and, on
    /// the SIMD path, prefetches what it references.
    #[inline(always)]
    fn push<const SIMD: bool>(&mut self, sections: &Sections<'_>, stack: &mut Stack, entry: (u32, f32)) {
        if SIMD {
            prefetch(sections, entry.0);
        }
        if let Some(slot) = stack.get_mut(self.stack_len) {
            slot.write(entry);
            self.stack_len += 1;
        }
    }

    /// Continues with the nearest pushed entry not beyond the closest hit; `false` when there is none.
    #[inline(always)]
    #[allow(unsafe_code)] // reading the stack, see the SAFETY note
    fn pop(&mut self, stack: &Stack) -> bool {
        while self.stack_len > 0 {
            self.stack_len -= 1;
            // SAFETY: every index below `stack_len` was written by `push` before `stack_len` passed it (on this
            // stack, as `step` requires), and `stack_len` only moves down by one here, so the entry is initialized.
            let (next, t_entry) = unsafe { stack[self.stack_len].assume_init() };
            if t_entry <= self.t_max * CULL_PADDING {
                self.current = next;
                return true;
            }
        }
        false
    }
}

/// The closest hit in packets `first .. first + count`, within `t_max`, as (triangle index, hit); for
/// `ANY_HIT`, the first packet's hit.
#[inline(always)]
fn leaf_hit<const ANY_HIT: bool, const SIMD: bool>(
    sections: &Sections<'_>,
    ray: &PreparedRay,
    first: usize,
    count: usize,
    t_max: f32,
    counter: &mut impl TraversalCounter,
) -> Option<(u32, TriangleHit)> {
    let packets = sections.packets.get(first..first.saturating_add(count))?;
    let mut best = None;
    let mut limit = t_max;
    for packet in packets {
        counter.triangle_tested();
        if let Some((lane, hit)) = crate::wide_packets::closest_in_packet::<ANY_HIT, SIMD>(packet, ray, limit) {
            limit = hit.t;
            best = Some((packet.triangle_index[lane], hit));
            if ANY_HIT {
                break;
            }
        }
    }
    best
}

/// Asks the cache for the wide node or the first packets `child` references (a hint: no effect on results; a
/// reference out of range fetches nothing).
#[inline(always)]
fn prefetch(sections: &Sections<'_>, child: u32) {
    if child & LEAF_BIT == 0 {
        if let Some(node) = sections.nodes.get(child as usize..child as usize + 1) {
            prefetch_lines::<4>(node);
        }
    } else {
        // A packet spans 3 cache lines (160 bytes from a multiple of 32); the first two packets of a leaf.
        let (first, count) = WideNode8::leaf_packets(child);
        if let Some(packets) = sections.packets.get(first as usize..first as usize + 1) {
            prefetch_lines::<3>(packets);
        }
        if let Some(packets) = sections.packets.get(first as usize + 1..first as usize + 2).filter(|_| count > 1) {
            prefetch_lines::<3>(packets);
        }
    }
}

#[inline(always)]
#[allow(unsafe_code)] // the AVX2 call, only reached on the SIMD path
fn box_test<const SIMD: bool>(node: &WideNode8, ray: &PreparedRay, t_far: f32) -> (u8, [f32; WIDE]) {
    #[cfg(target_arch = "x86_64")]
    if SIMD {
        // SAFETY: SIMD is true only inside the tracer's `target_feature(enable = "avx2")` entries, which run only
        // after the AVX2 check of `WideTracer::over`.
        return unsafe { avx2::box_test(node, ray, t_far) };
    }
    portable_box_test(node, ray, t_far)
}

/// Prefetches the cache lines of the first `LINES * 64` bytes of `value` (at most its size) into all cache
/// levels (x86-64; elsewhere nothing).
#[inline(always)]
#[allow(unsafe_code)] // the prefetch hint, see the SAFETY note
fn prefetch_lines<const LINES: usize>(value: &[impl Sized]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = value.as_ptr().cast::<i8>();
        let last = size_of_val(value).saturating_sub(1);
        for line in 0..LINES {
            // SAFETY: a prefetch is a hint that never faults nor changes memory; the offset is clamped to the
            // last byte of `value`, so the address lies inside it.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add((line * 64).min(last))) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// The slab test of all eight lanes, in plain Rust: the binary kernel's `enter_box` per lane.
fn portable_box_test(node: &WideNode8, ray: &PreparedRay, t_far: f32) -> (u8, [f32; WIDE]) {
    let mut near = [ray.t_min; WIDE];
    let mut far = [t_far; WIDE];
    for axis in 0..3 {
        let (entry, exit) =
            if ray.negative[axis] { (&node.max[axis], &node.min[axis]) } else { (&node.min[axis], &node.max[axis]) };
        let inverses = (ray.inverse_direction[axis], ray.exit_inverse[axis]);
        for lane in 0..WIDE {
            (near[lane], far[lane]) = slab(entry[lane], exit[lane], ray.origin[axis], inverses, near[lane], far[lane]);
        }
    }
    let mask = near
        .iter()
        .zip(&far)
        .zip(&node.child)
        .enumerate()
        .fold(0u8, |m, (lane, ((n, f), &child))| if n <= f && child != EMPTY_SLOT { m | 1 << lane } else { m });
    (mask, near)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // intrinsics: every block states what it relies on
mod avx2 {
    use std::arch::x86_64::*;

    use crate::format::{WIDE, WideNode8};
    use crate::intersect::PreparedRay;

    /// The slab test of all eight lanes in AVX2; the same operations, in the same order, as the portable one.
    /// The entry and exit rows are found through the ray's precomputed plane offsets, without a branch.
    /// Empty slots are left out of the mask (they never hit a finite ray, but a NaN origin makes every
    /// comparison fail and so every slot look hit).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn box_test(node: &WideNode8, ray: &PreparedRay, t_far: f32) -> (u8, [f32; WIDE]) {
        let mut near = _mm256_set1_ps(ray.t_min);
        let mut far = _mm256_set1_ps(t_far);
        let rows = (node as *const WideNode8).cast::<f32>();
        let (entry_offsets, exit_offsets) = ray.wide_plane_offsets;
        for axis in 0..3 {
            let o = _mm256_set1_ps(ray.origin[axis]);
            let inv = _mm256_set1_ps(ray.inverse_direction[axis]);
            let exit_inv = _mm256_set1_ps(ray.exit_inverse[axis]);
            // SAFETY: the offsets are `axis * WIDE` or `(axis + 3) * WIDE` with axis < 3 (`PreparedRay::new`), so
            // each row `offset .. offset + WIDE` lies in the node's `min` and `max` arrays (its first `6 * WIDE`
            // f32s, at offsets 0 and 96 bytes as `format.rs` asserts); unaligned loads need no more.
            let (entry, exit) = unsafe {
                (_mm256_loadu_ps(rows.add(entry_offsets[axis])), _mm256_loadu_ps(rows.add(exit_offsets[axis])))
            };
            let t_entry = _mm256_mul_ps(_mm256_sub_ps(entry, o), inv);
            let t_exit = _mm256_mul_ps(_mm256_sub_ps(exit, o), exit_inv);
            // max_ps(a, b) = a > b ? a : b and min_ps(a, b) = a < b ? a : b: the portable compare-selects.
            near = _mm256_max_ps(t_entry, near);
            far = _mm256_min_ps(t_exit, far);
        }
        let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u8;
        // SAFETY: `node.child` is `[u32; 8]`, 32 readable bytes.
        let children = unsafe { _mm256_loadu_si256(node.child.as_ptr().cast()) };
        let empty = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(children, _mm256_set1_epi32(-1))));
        let mask = hit & !(empty as u8);
        let mut out = [0f32; WIDE];
        // SAFETY: `out` has room for 8 f32.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), near) };
        (mask, out)
    }
}
