//! An 8-wide BVH and its traversal: one ray against the eight child boxes of a node at a time, in SIMD lanes
//! (AVX2) or in a portable loop that gives bit-identical box results; leaves are tested four triangles at a time
//! (`wide_packets`, SSE2) on the SIMD path and one at a time with the binary kernel's watertight test on the
//! portable one, with identical hits. This is the in-memory form of the wide node section planned for format 1.1
//! (issue 10); it is not yet stored in `.bvh` files.
//!
//! Layout (`WideNode8`, 256 bytes, 64-byte aligned): the children's boxes in structure-of-arrays order
//! (`min[axis][lane]`, `max[axis][lane]`), so one 256-bit load feeds one slab test of all eight; then one child
//! reference per lane: an inner node's index, a leaf (`LEAF_BIT | (count - 1) << 28 | first`, triangles
//! `first .. first + count` of the tree's leaf-order triangles, 1 to 8 of them), or `EMPTY_SLOT` (its box is
//! `+inf..-inf`, which no ray enters).
//!
//! The box test is the binary kernel's (Ize 2013: exit distances scaled by `1 + 2 gamma(3)`, compare-selects
//! that ignore the NaN of an origin on the slab plane of a zero direction component), lane by lane: `max_ps` and
//! `min_ps` are exactly those compare-selects, and no operation is fused, so both paths visit the same nodes.
//! Children are visited nearest first; every pushed entry keeps its entry distance and is skipped on pop when a
//! closer hit was found (with the binary kernel's cull padding).

use std::mem::MaybeUninit;

use crate::format::{MAX_DEPTH, PackedNode, PackedTriangle};
use crate::intersect::{EXIT_PADDING, PreparedRay, Ray, TriangleHit};
use crate::traverse::{CULL_PADDING, Hit, TraversalCounter};
use crate::wide_packets::{LANES, Packet4};

/// Children per wide node.
pub const WIDE: usize = 8;
/// Marks a leaf child reference.
pub const LEAF_BIT: u32 = 1 << 31;
/// An unused child slot.
pub const EMPTY_SLOT: u32 = u32::MAX;
/// Largest first-triangle index a leaf reference can hold.
pub const MAX_LEAF_FIRST: u32 = (1 << 28) - 1;

/// One 8-wide node (see the module doc for the encoding).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode8 {
    /// Children's box minima, per axis then per lane.
    pub min: [[f32; WIDE]; 3],
    /// Children's box maxima, per axis then per lane.
    pub max: [[f32; WIDE]; 3],
    /// Child references, per lane.
    pub child: [u32; WIDE],
    /// Zero.
    pub reserved: [u32; WIDE],
}

const _: () = assert!(std::mem::size_of::<WideNode8>() == 256);

impl WideNode8 {
    /// A node with every slot empty.
    pub const EMPTY: WideNode8 = WideNode8 {
        min: [[f32::INFINITY; WIDE]; 3],
        max: [[f32::NEG_INFINITY; WIDE]; 3],
        child: [EMPTY_SLOT; WIDE],
        reserved: [0; WIDE],
    };

    /// The leaf reference for triangles `first .. first + count` (`count` in 1..=8, `first <= MAX_LEAF_FIRST`).
    pub fn leaf(first: u32, count: u32) -> Option<u32> {
        ((1..=8).contains(&count) && first <= MAX_LEAF_FIRST).then_some(LEAF_BIT | ((count - 1) << 28) | first)
    }
}

/// An 8-wide BVH checked at construction: references in range, children after their parents, leaf ranges inside
/// the triangles, depth at most `MAX_DEPTH`. Traversal relies on these (it still never indexes out of bounds).
#[derive(Clone, Debug)]
pub struct WideBvh {
    nodes: Vec<WideNode8>,
    /// Leaf-order triangles, each leaf padded to a multiple of 4 with NaN triangles (never hit).
    triangles: Vec<PackedTriangle>,
    /// The same, four to a packet.
    packets: Vec<Packet4>,
    /// Per padded slot: the triangle's index as given to `new` (`u32::MAX` for padding).
    triangle_index: Vec<u32>,
    /// The root's box, as an inner node for the binary kernel's box test.
    root: PackedNode,
}

impl WideBvh {
    /// `nodes` (the root first), `order[k]` = the index in `triangles` of leaf-order triangle `k`, and the root's
    /// box. Fails naming the first node or slot that breaks a rule.
    pub fn new(
        nodes: Vec<WideNode8>,
        order: &[u32],
        triangles: &[PackedTriangle],
        root_box: ([f32; 3], [f32; 3]),
    ) -> Result<WideBvh, String> {
        let mut depth = vec![0usize; nodes.len()];
        let mut parents = vec![0u8; nodes.len()];
        for (i, node) in nodes.iter().enumerate() {
            for (lane, &child) in node.child.iter().enumerate() {
                if child == EMPTY_SLOT {
                    continue;
                }
                if child & LEAF_BIT != 0 {
                    let (first, count) = leaf_range(child);
                    if first as usize + count as usize > order.len() {
                        return Err(format!(
                            "node {i} lane {lane}: leaf {first}+{count} outside {} triangles",
                            order.len()
                        ));
                    }
                    continue;
                }
                let c = child as usize;
                if c <= i || c >= nodes.len() {
                    return Err(format!("node {i} lane {lane}: child {c} must come after it and exist"));
                }
                parents[c] = parents[c].saturating_add(1);
                depth[c] = depth[i] + 1;
                if depth[c] > MAX_DEPTH {
                    return Err(format!("node {c}: deeper than {MAX_DEPTH}"));
                }
            }
        }
        if let Some(c) = parents.iter().skip(1).position(|&p| p != 1) {
            return Err(format!("node {}: {} parents", c + 1, parents[c + 1]));
        }
        // Lay each leaf out at a multiple of 4 and rewrite its reference.
        let mut nodes = nodes;
        let pad = PackedTriangle { vertices: [[f32::NAN; 3]; 3] };
        let mut padded = Vec::with_capacity(order.len() + order.len() / 2);
        let mut triangle_index = Vec::with_capacity(padded.capacity());
        for node in &mut nodes {
            for child in node.child.iter_mut().filter(|c| **c != EMPTY_SLOT && **c & LEAF_BIT != 0) {
                let (first, count) = leaf_range(*child);
                let new_first = padded.len() as u32;
                for &t in &order[first as usize..(first + count) as usize] {
                    padded.push(*triangles.get(t as usize).ok_or_else(|| format!("triangle {t} out of range"))?);
                    triangle_index.push(t);
                }
                while !padded.len().is_multiple_of(LANES) {
                    padded.push(pad);
                    triangle_index.push(u32::MAX);
                }
                *child = WideNode8::leaf(new_first, count)
                    .ok_or_else(|| "too many triangles for leaf references".to_string())?;
            }
        }
        let packets = padded.chunks(LANES).map(Packet4::new).collect();
        let root = PackedNode { min: root_box.0, max: root_box.1, index: 0, count: 0 };
        Ok(WideBvh { nodes, triangles: padded, packets, triangle_index, root })
    }

    /// The nodes.
    pub fn nodes(&self) -> &[WideNode8] {
        &self.nodes
    }
}

fn leaf_range(child: u32) -> (u32, u32) {
    (child & MAX_LEAF_FIRST, ((child >> 28) & 7) + 1)
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

/// Closest-hit and any-hit queries over a [`WideBvh`].
pub struct WideTracer<'a> {
    bvh: &'a WideBvh,
    triangle_ids: Option<&'a [u32]>,
    path: KernelPath,
}

/// Stack entries: each visited node pushes at most 7.
const STACK_LEN: usize = (WIDE - 1) * MAX_DEPTH + 1;

impl<'a> WideTracer<'a> {
    /// A tracer on `path` (the portable one when `path` is not supported here). `triangle_ids` are indexed by
    /// the triangles' indices as given to [`WideBvh::new`].
    pub fn new(bvh: &'a WideBvh, triangle_ids: Option<&'a [u32]>, path: KernelPath) -> WideTracer<'a> {
        let path = if path.is_supported() { path } else { KernelPath::Portable };
        WideTracer { bvh, triangle_ids, path }
    }

    /// The closest hit.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_counted(ray, &mut ())
    }

    /// [`WideTracer::closest_hit`], counting wide node visits and triangle tests (on the SIMD path, packets of
    /// four count as one test each) into `counter`.
    pub fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        let (k, hit) = self.dispatch::<false>(ray, counter)?;
        Some(Hit::new(self.bvh.triangle_index[k], hit, self.triangle_ids))
    }

    /// Whether any triangle is hit.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        self.dispatch::<true>(ray, &mut ()).is_some()
    }

    /// The traversal compiled for the tracer's path: for AVX2 the whole loop is one `target_feature` function,
    /// so the box test and the packets inline into it instead of being called per node.
    #[inline(always)]
    #[allow(unsafe_code)] // the AVX2 entry, under the runtime check of `WideTracer::new`
    fn dispatch<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(usize, TriangleHit)> {
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
    ) -> Option<(usize, TriangleHit)> {
        self.traverse::<ANY_HIT, true>(ray, counter)
    }

    #[inline(always)]
    #[allow(unsafe_code)] // reading the uninitialized-by-default stack, see the SAFETY note
    fn traverse<const ANY_HIT: bool, const SIMD: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(usize, TriangleHit)> {
        let prepared = PreparedRay::new(ray);
        if self.bvh.nodes.is_empty() || prepared.enter_box(&self.bvh.root, ray.t_max).is_none() {
            return None;
        }
        let mut t_max = ray.t_max;
        let mut found = None;
        // Not zeroed: 14 KiB of memset per ray cost more than a node visit. Entries below `stack_len` are written.
        let mut stack = [const { MaybeUninit::<(u32, f32)>::uninit() }; STACK_LEN];
        let mut stack_len = 0usize;
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT != 0 {
                let (first, count) = leaf_range(current);
                if let Some(hit) = self.leaf_hit::<SIMD>(&prepared, first as usize, count as usize, t_max, counter) {
                    found = Some(hit);
                    if ANY_HIT {
                        return found;
                    }
                    t_max = hit.1.t;
                }
            } else if let Some(node) = self.bvh.nodes.get(current as usize) {
                counter.node_visited();
                let (mask, t_near) = Self::box_test::<SIMD>(node, &prepared, t_max * CULL_PADDING);
                // The hit children, nearest first (insertion sort of at most 8).
                let mut order = [(0u32, 0f32); WIDE];
                let mut n = 0;
                let mut lanes = mask;
                while lanes != 0 {
                    let lane = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    let entry = (node.child[lane], t_near[lane]);
                    if entry.0 == EMPTY_SLOT {
                        continue; // never hit (its box is +inf..-inf); kept out for safety on odd input
                    }
                    let mut at = n;
                    while at > 0 && order[at - 1].1 > entry.1 {
                        order[at] = order[at - 1];
                        at -= 1;
                    }
                    order[at] = entry;
                    n += 1;
                }
                if n > 0 {
                    for &entry in order[1..n].iter().rev() {
                        if let Some(slot) = stack.get_mut(stack_len) {
                            slot.write(entry);
                            stack_len += 1;
                        }
                    }
                    current = order[0].0;
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

    /// The closest hit among leaf triangles `first .. first + count` (padded slots), within `t_max`.
    #[inline(always)]
    fn leaf_hit<const SIMD: bool>(
        &self,
        ray: &PreparedRay,
        first: usize,
        count: usize,
        t_max: f32,
        counter: &mut impl TraversalCounter,
    ) -> Option<(usize, TriangleHit)> {
        let triangles = self.bvh.triangles.get(first..first + count)?;
        #[cfg(target_arch = "x86_64")]
        if SIMD {
            let mut best = None;
            let mut limit = t_max;
            for (p, chunk) in triangles.chunks(LANES).enumerate() {
                let packet = self.bvh.packets.get(first / LANES + p)?;
                counter.triangle_tested();
                if let Some((lane, hit)) = crate::wide_packets::closest_in_packet(packet, chunk, ray, limit) {
                    limit = hit.t;
                    best = Some((first + p * LANES + lane, hit));
                }
            }
            return best;
        }
        let mut best = None;
        let mut limit = t_max;
        for (k, triangle) in triangles.iter().enumerate() {
            counter.triangle_tested();
            if let Some(hit) = ray.intersect_triangle(triangle, limit) {
                limit = hit.t;
                best = Some((first + k, hit));
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
    let mask = near.iter().zip(&far).enumerate().fold(0u8, |m, (lane, (n, f))| if n <= f { m | 1 << lane } else { m });
    (mask, near)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // intrinsics: every block states what it relies on
mod avx2 {
    use std::arch::x86_64::*;

    use super::{WIDE, WideNode8};
    use crate::intersect::EXIT_PADDING;
    use crate::intersect::PreparedRay;

    /// The slab test of all eight lanes in AVX2; the same operations, in the same order, as the portable one.
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
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u8;
        let mut out = [0f32; WIDE];
        // SAFETY: `out` has room for 8 f32.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), near) };
        (mask, out)
    }
}
