//! Traversal of the wide sections of format 1.1 (`wide_nodes`, `triangle_packets`): one ray against the eight
//! child boxes of a `WideNode8` at a time,
//! in SIMD lanes (AVX2) or in a portable loop that gives bit-identical box results; leaves are `TrianglePacket4`s
//! tested four triangles at a time (`wide_packets`, SSE2) on the SIMD path and one lane at a time with the binary
//! kernel's watertight test on the portable one, with identical hits. Layout: `format::WideNode8`.
//!
//! The box test is the binary kernel's (Ize 2013: exit distances scaled by `1 + 2 gamma(3)`, compare-selects
//! that ignore the NaN of an origin on the slab plane of a zero direction component), lane by lane: `max_ps` and
//! `min_ps` are exactly those compare-selects, and no operation is fused, so both paths visit the same nodes.
//! Children are visited nearest first; every pushed entry keeps its entry distance and is skipped on pop when a
//! closer hit was found (with the binary kernel's cull padding).
//!
//! Safe on any bytes: every index is bounds-checked, and a ray visits at most `node_count` inner nodes (so a
//! node referenced from many slots cannot make a traversal run long); on a file that fails verification the hits
//! are unspecified.

use std::mem::MaybeUninit;

use crate::error::Violation;
use crate::format::{EMPTY_SLOT, LEAF_BIT, MAX_DEPTH, PackedNode, PackedTriangle, TrianglePacket4, WIDE, WideNode8};
use crate::intersect::{EXIT_PADDING, PreparedRay, Ray, TriangleHit};
use crate::traverse::{CULL_PADDING, Hit, TraversalCounter};
use crate::verify_wide::{WideContext, verify_wide};

/// The wide sections in memory (owned), checked at construction against the triangles they index.
#[derive(Clone, Debug)]
pub struct WideBvh {
    nodes: Vec<WideNode8>,
    packets: Vec<TrianglePacket4>,
    root: PackedNode,
}

impl WideBvh {
    /// `nodes` (the root first) and `packets` over `triangles` (whose indices the packets' lanes hold), inside
    /// `root_box` (the binary root's box). Fails with the first broken rule of V29-V35, naming the node, slot,
    /// packet or lane.
    pub fn new(
        nodes: Vec<WideNode8>,
        packets: Vec<TrianglePacket4>,
        root_box: ([f32; 3], [f32; 3]),
        triangles: &[PackedTriangle],
    ) -> Result<WideBvh, Violation> {
        let context = WideContext { triangles, triangle_ids: None, root_box: Some(root_box), split_references: false };
        verify_wide(&nodes, &packets, &context)?;
        let root = PackedNode { min: root_box.0, max: root_box.1, index: 0, count: 0 };
        Ok(WideBvh { nodes, packets, root })
    }

    /// The nodes (the `wide_nodes` section).
    pub fn nodes(&self) -> &[WideNode8] {
        &self.nodes
    }

    /// The packets (the `triangle_packets` section).
    pub fn packets(&self) -> &[TrianglePacket4] {
        &self.packets
    }
}

/// Which implementation of the box test runs.
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
            #[cfg(target_arch = "x86_64")]
            KernelPath::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2 => false,
        }
    }
}

/// Closest-hit and any-hit queries over wide sections (a file's, or a [`WideBvh`]).
#[derive(Clone, Copy, Debug)]
pub struct WideTracer<'a> {
    nodes: &'a [WideNode8],
    packets: &'a [TrianglePacket4],
    /// The binary root's box, tested first (as an inner node for the binary kernel's box test).
    root: PackedNode,
    triangle_ids: Option<&'a [u32]>,
    path: KernelPath,
}

/// Stack entries: each visited node pushes at most 7.
const STACK_LEN: usize = (WIDE - 1) * MAX_DEPTH + 1;

impl<'a> WideTracer<'a> {
    /// A tracer over `bvh` on `path` (the portable one when `path` is not supported here). `triangle_ids` are
    /// indexed by the packets' triangle indices.
    pub fn new(bvh: &'a WideBvh, triangle_ids: Option<&'a [u32]>, path: KernelPath) -> WideTracer<'a> {
        WideTracer::over(&bvh.nodes, &bvh.packets, (bvh.root.min, bvh.root.max), triangle_ids, path)
    }

    /// A tracer over borrowed wide sections (a [`crate::BvhView`]'s) inside `root_box`, the binary root's box.
    /// Safe on any contents; the hits are those of the binary kernel when the sections pass V29-V35.
    pub fn over(
        nodes: &'a [WideNode8],
        packets: &'a [TrianglePacket4],
        root_box: ([f32; 3], [f32; 3]),
        triangle_ids: Option<&'a [u32]>,
        path: KernelPath,
    ) -> WideTracer<'a> {
        let path = if path.is_supported() { path } else { KernelPath::Portable };
        let root = PackedNode { min: root_box.0, max: root_box.1, index: 0, count: 0 };
        WideTracer { nodes, packets, root, triangle_ids, path }
    }

    /// The path this tracer runs.
    pub fn path(&self) -> KernelPath {
        self.path
    }

    /// The closest hit.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_counted(ray, &mut ())
    }

    /// [`WideTracer::closest_hit`], counting wide node visits and triangle tests (on the SIMD path, packets of
    /// four count as one test each) into `counter`.
    pub fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        let (triangle_index, hit) = self.dispatch::<false>(ray, counter)?;
        Some(Hit::new(triangle_index, hit, self.triangle_ids))
    }

    /// Whether any triangle is hit.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        self.any_hit_counted(ray, &mut ())
    }

    /// [`WideTracer::any_hit`], counting as [`WideTracer::closest_hit_counted`] does.
    pub fn any_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool {
        self.dispatch::<true>(ray, counter).is_some()
    }

    /// The traversal compiled for the tracer's path: for AVX2 the whole loop is one `target_feature` function,
    /// so the box test and the packets inline into it instead of being called per node.
    #[inline(always)]
    #[allow(unsafe_code)] // the AVX2 entry, under the runtime check of `WideTracer::new`
    fn dispatch<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        match self.path {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `path` is Avx2 only when `is_x86_feature_detected!("avx2")` said so (`WideTracer::new`).
            KernelPath::Avx2 => unsafe { self.traverse_avx2::<ANY_HIT>(ray, counter) },
            _ => self.traverse::<ANY_HIT, false>(ray, counter),
        }
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn traverse_avx2<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        self.traverse::<ANY_HIT, true>(ray, counter)
    }

    #[inline(always)]
    #[allow(unsafe_code)] // reading the uninitialized-by-default stack, see the SAFETY note
    fn traverse<const ANY_HIT: bool, const SIMD: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        let prepared = PreparedRay::new(ray);
        if self.nodes.is_empty() || prepared.enter_box(&self.root, ray.t_max).is_none() {
            return None;
        }
        let mut visits_left = self.nodes.len();
        let mut t_max = ray.t_max;
        let mut found = None;
        // Not zeroed: 14 KiB of memset per ray cost more than a node visit. Entries below `stack_len` are written.
        let mut stack = [const { MaybeUninit::<(u32, f32)>::uninit() }; STACK_LEN];
        let mut stack_len = 0usize;
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT != 0 {
                let (first, count) = WideNode8::leaf_packets(current);
                if let Some(hit) = self.leaf_hit::<SIMD>(&prepared, first as usize, count as usize, t_max, counter) {
                    found = Some(hit);
                    if ANY_HIT {
                        return found;
                    }
                    t_max = hit.1.t;
                }
            } else if let Some(node) = self.nodes.get(current as usize).filter(|_| visits_left > 0) {
                visits_left -= 1;
                counter.node_visited();
                let (mask, t_near) = Self::box_test::<SIMD>(node, &prepared, t_max * CULL_PADDING);
                // The hit children, nearest first (ties in slot order): one or two without a sort, which is most
                // visits; more by insertion sort. Pushed children are prefetched, so the misses of their nodes or
                // packets overlap with the work on the nearer ones instead of stalling when they are popped.
                let first = mask.trailing_zeros() as usize;
                let rest = mask & mask.wrapping_sub(1);
                if rest == 0 {
                    if let Some(&child) = node.child.get(first) {
                        current = child;
                        continue;
                    }
                } else if rest & (rest - 1) == 0 {
                    let second = rest.trailing_zeros() as usize & (WIDE - 1);
                    let (near, far) = if t_near[second] < t_near[first] { (second, first) } else { (first, second) };
                    self.push::<SIMD>(&mut stack, &mut stack_len, (node.child[far], t_near[far]));
                    current = node.child[near];
                    if SIMD {
                        self.prefetch(current);
                    }
                    continue;
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
                        self.push::<SIMD>(&mut stack, &mut stack_len, entry);
                    }
                    current = order[0].0;
                    if SIMD {
                        self.prefetch(current);
                    }
                    continue;
                }
            }
            loop {
                if stack_len == 0 {
                    return found;
                }
                stack_len -= 1;
                // SAFETY: every index below `stack_len` was written by the push above before `stack_len` passed it,
                // and `stack_len` only moves down by one here, so entry `stack_len` is initialized.
                let (next, t_entry) = unsafe { stack[stack_len].assume_init() };
                if t_entry <= t_max * CULL_PADDING {
                    current = next;
                    break;
                }
            }
        }
    }

    /// Pushes `entry` (dropped when the stack is full, which only a file that breaks V30 can cause) and, on
    /// the SIMD path, prefetches what it references.
    #[inline(always)]
    fn push<const SIMD: bool>(
        &self,
        stack: &mut [MaybeUninit<(u32, f32)>; STACK_LEN],
        stack_len: &mut usize,
        entry: (u32, f32),
    ) {
        if SIMD {
            self.prefetch(entry.0);
        }
        if let Some(slot) = stack.get_mut(*stack_len) {
            slot.write(entry);
            *stack_len += 1;
        }
    }

    /// Asks the cache for the wide node or the packets `child` references (a hint: no effect on results; a
    /// reference out of range fetches nothing).
    #[inline(always)]
    fn prefetch(&self, child: u32) {
        if child & LEAF_BIT == 0 {
            if let Some(node) = self.nodes.get(child as usize..child as usize + 1) {
                prefetch_lines::<4>(node);
            }
        } else {
            // A packet spans 3 cache lines (160 bytes from a multiple of 32); the first two packets of a leaf.
            let (first, count) = WideNode8::leaf_packets(child);
            if let Some(packets) = self.packets.get(first as usize..first as usize + 1) {
                prefetch_lines::<3>(packets);
            }
            if let Some(packets) = self.packets.get(first as usize + 1..first as usize + 2).filter(|_| count > 1) {
                prefetch_lines::<3>(packets);
            }
        }
    }

    /// The closest hit in packets `first .. first + count`, within `t_max`, as (triangle index, hit).
    #[inline(always)]
    fn leaf_hit<const SIMD: bool>(
        &self,
        ray: &PreparedRay,
        first: usize,
        count: usize,
        t_max: f32,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        let packets = self.packets.get(first..first.saturating_add(count))?;
        let mut best = None;
        let mut limit = t_max;
        for packet in packets {
            counter.triangle_tested();
            if let Some((lane, hit)) = crate::wide_packets::closest_in_packet::<SIMD>(packet, ray, limit) {
                limit = hit.t;
                best = Some((packet.triangle_index[lane], hit));
            }
        }
        best
    }

    #[inline(always)]
    #[allow(unsafe_code)] // the AVX2 call, only reached from `traverse_avx2`
    fn box_test<const SIMD: bool>(node: &WideNode8, ray: &PreparedRay, t_far: f32) -> (u8, [f32; WIDE]) {
        #[cfg(target_arch = "x86_64")]
        if SIMD {
            // SAFETY: SIMD is true only inside `traverse_avx2`, which runs only after the AVX2 check of
            // `WideTracer::new`.
            return unsafe { avx2::box_test(node, ray, t_far) };
        }
        portable_box_test(node, ray, t_far)
    }
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
        let (o, inv) = (ray.origin[axis], ray.inverse_direction[axis]);
        for lane in 0..WIDE {
            let t_entry = (entry[lane] - o) * inv;
            let t_exit = (exit[lane] - o) * inv * EXIT_PADDING;
            near[lane] = if t_entry > near[lane] { t_entry } else { near[lane] };
            far[lane] = if t_exit < far[lane] { t_exit } else { far[lane] };
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
    use crate::intersect::EXIT_PADDING;
    use crate::intersect::PreparedRay;

    /// The slab test of all eight lanes in AVX2; the same operations, in the same order, as the portable one.
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
        let pad = _mm256_set1_ps(EXIT_PADDING);
        for axis in 0..3 {
            let (entry, exit) = if ray.negative[axis] {
                (&node.max[axis], &node.min[axis])
            } else {
                (&node.min[axis], &node.max[axis])
            };
            let o = _mm256_set1_ps(ray.origin[axis]);
            let inv = _mm256_set1_ps(ray.inverse_direction[axis]);
            // SAFETY: `entry` and `exit` are `[f32; 8]`, 32 readable bytes each; unaligned loads need no more.
            let (entry, exit) = unsafe { (_mm256_loadu_ps(entry.as_ptr()), _mm256_loadu_ps(exit.as_ptr())) };
            let t_entry = _mm256_mul_ps(_mm256_sub_ps(entry, o), inv);
            let t_exit = _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(exit, o), inv), pad);
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
