//! One ray's traversal of the wide sections, as a state machine that advances one wide node or leaf a step, so
//! a single ray runs it to the end and a stream of rays interleaves several (each ray's steps, and so its hits,
//! are the same either way; interleaving lets one ray's cache misses overlap with another's work).
//!
//! A step at a wide node tests the ray against the eight child boxes at once, in the instruction set's eight
//! lanes (AVX2, or portable arrays with the same operations, so both give the same lanes bit for bit), with the
//! binary kernel's robust slab test (Ize 2013: exit distances padded by `1 + 2 gamma(3)` through the ray's
//! padded reciprocal, compare-selects that ignore the NaN of an origin on the slab plane of a zero direction
//! component; nothing fused). For a closest hit the hit children go nearest first: one or two without a sort, more by insertion
//! sort; the others are pushed with their entry distance and skipped on pop when a closer hit was found (with
//! the binary kernel's reach, `crate::ray::reach`). For any hit the order does not matter: the hit children are pushed in
//! slot order and the walk goes on with the last, with no distance compared (Embree's occlusion traversal does
//! the same), and a leaf ends the walk at its first hit. On the AVX2 path pushed children are prefetched, so
//! their misses overlap with the work on the nearer ones. A step at a leaf tests its packets four triangles at
//! a time (`wide_packets`).
//!
//! Safe on any bytes: every index is bounds-checked, and a walk visits at most `node_count` wide nodes (so a
//! node referenced from many slots cannot make it run long); on a file that fails verification the hits are
//! unspecified.

use crate::format::{LEAF_BIT, MAX_DEPTH, PACKET_LANES, PackedNode, TrianglePacket4, WIDE, WideNode8};
use crate::ray::candidates::Candidates;
use crate::ray::hit::{TraversalCounter, TriangleHit, lane_address, lane_record};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::query::{Query, TieKey, TieOrder};
use crate::simd::{Isa, Kernel};
use crate::walk_stack::WalkStack;
use crate::wide::packets::closest_in_packet;
use std::marker::PhantomData;

/// Stack entries: each visited node pushes at most 7, and a verified file is at most `MAX_DEPTH` deep.
pub(crate) const STACK_LEN: usize = (WIDE - 1) * MAX_DEPTH + 1;

/// A walk's stack of (child reference, entry distance).
pub(crate) type Stack = WalkStack<(u32, f32), STACK_LEN>;

/// A new, unwritten stack.
pub(crate) const fn new_stack() -> Stack {
    WalkStack::new()
}

/// The wide sections a walk runs over, and the binary root's box.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sections<'a> {
    pub nodes: &'a [WideNode8],
    pub packets: &'a [TrianglePacket4],
    /// The binary root's box, tested first (as an inner node for the binary kernel's box test).
    pub root: PackedNode,
    /// Which [`TieKey`] orders hits at one `t`.
    pub tie: TieOrder<'a>,
    /// The tree's part in its walks' reach (`crate::ray::reach::tree_scale` of `root`, with the stretch of a
    /// top tree's instances).
    pub reach_scale: f32,
}

impl Sections<'_> {
    /// The tie key of the lane at `address` ([`lane_address`]).
    fn tie_key(&self, address: u32) -> TieKey {
        let (packet, lane) = (address as usize / PACKET_LANES, address as usize % PACKET_LANES);
        let record = lane_record(self.packets, address);
        self.tie.key(record, || self.packets.get(packet).map_or([u32::MAX; 9], |p| p.triangle(lane).coordinate_bits()))
    }

    /// Whether, of two hits at one `t`, the one in the lane at `address` comes before the one at `best` in spec
    /// 11.1's order. Cold: the walks call it only on an exact tie.
    #[cold]
    #[inline(never)]
    pub(crate) fn first_at_tie(&self, address: u32, best: u32) -> bool {
        self.tie_key(address) < self.tie_key(best)
    }

    /// Whether a hit at the limit `t` (not nearer: `t <= limit` and not `t < limit`) in the lane at `address`
    /// is taken over `best`, the closest so far: when there is none, or it comes first at the tie.
    #[cold]
    #[inline(never)]
    pub(crate) fn taken_at_limit(&self, address: u32, best: Option<u32>) -> bool {
        best.is_none_or(|best| self.first_at_tie(address, best))
    }
}

/// What a wide walk does at a leaf reference (a slot's child with [`LEAF_BIT`] set): test a mesh's triangle
/// packets ([`PacketLeaves`]) or trace one instance's mesh (`crate::instances`). Each combination is
/// monomorphized; nothing on the walk goes through `dyn`.
pub(crate) trait WideLeaves<C: TraversalCounter> {
    /// What a hit in a leaf is.
    type Found: Copy;
    /// Whether the AVX2 path prefetches what a leaf reference points at (packets do; an instance does not).
    const PREFETCH_LEAVES: bool;

    /// The nearest hit with `t <= t_max` in the leaf `reference` of `sections` (for an any-hit query, the first
    /// found), of the ray prepared as `ray`, when it comes before `best`, the walk's closest hit so far (whose
    /// `t` is `t_max`): nearer, or at that `t` first in spec 11.1's order. So the walk takes what a leaf returns
    /// as it is, and its state stays in registers (the hits come by value: a reference into that state kept
    /// it in memory, measured at 31% fewer rays a second on the kitchen's primary rays).
    #[allow(clippy::too_many_arguments)] // the walk's state, passed apart so that it stays in registers
    fn test_leaf<Q: Query, I: Isa>(
        &mut self,
        isa: I,
        sections: &Sections<'_>,
        reference: u32,
        ray: &PreparedRay,
        t_max: f32,
        best: Option<Self::Found>,
        counter: &mut C,
    ) -> Option<Self::Found>;

    /// The distance of a hit.
    fn t(found: &Self::Found) -> f32;
}

/// A hit in a mesh's packets: the lane address ([`lane_address`]) and the hit.
pub(crate) type PacketHit = (u32, TriangleHit);

/// The leaves of a mesh's wide tree: triangle packets, whose lanes `candidates` accepts or not.
pub(crate) struct PacketLeaves<'c, A>(pub &'c A);

impl<C: TraversalCounter, A: Candidates> WideLeaves<C> for PacketLeaves<'_, A> {
    type Found = PacketHit;
    const PREFETCH_LEAVES: bool = true;

    #[inline(always)]
    fn test_leaf<Q: Query, I: Isa>(
        &mut self,
        isa: I,
        sections: &Sections<'_>,
        reference: u32,
        ray: &PreparedRay,
        t_max: f32,
        best: Option<Self::Found>,
        counter: &mut C,
    ) -> Option<Self::Found> {
        let (first, count) = WideNode8::leaf_packets(reference);
        let leaf = (first as usize, count as usize);
        leaf_hit::<Q, I, A>(isa, sections, ray, leaf, (t_max, best.map(|(address, _)| address)), counter, self.0)
    }

    #[inline(always)]
    fn t(found: &Self::Found) -> f32 {
        found.1.t
    }
}

/// One ray's traversal state; its stack is kept by the caller (one per walk in flight).
pub(crate) struct Walk<F> {
    ray: PreparedRay,
    t_max: f32,
    found: Option<F>,
    visits_left: usize,
    current: u32,
}

impl<F: Copy> Walk<F> {
    /// The walk of `ray` from the wide root on `stack` (emptied here; [`Walk::step`] takes the same stack), or
    /// `None` when there is no tree. The binary root's box is not tested first: the root's slot boxes lie inside
    /// it (V32), so a ray that misses it misses them all in the first step, and one that enters it saves a
    /// scalar box test.
    #[inline(always)]
    pub(crate) fn start(sections: &Sections<'_>, ray: &Ray, stack: &mut Stack) -> Option<Walk<F>> {
        if sections.nodes.is_empty() {
            return None;
        }
        stack.clear();
        let prepared = PreparedRay::new(ray).in_tree(sections.reach_scale);
        Some(Walk { ray: prepared, t_max: ray.t_max, found: None, visits_left: sections.nodes.len(), current: 0 })
    }

    /// Whether the ray enters `node`'s box within the reach of its `t_max` (the walk's cull).
    #[inline(always)]
    pub(crate) fn enters(&self, node: &PackedNode) -> bool {
        self.ray.enter_box(node, self.ray.cull_distance(self.t_max)).is_some()
    }

    /// The closest hit so far (any hit, for an any-hit query).
    pub(crate) fn found(&self) -> Option<F> {
        self.found
    }

    /// Processes the current wide node or leaf and moves to the next; `false` when the walk has ended.
    /// `stack` must be the one this walk started on.
    #[inline(always)]
    pub(crate) fn step<Q: Query, I: Isa, C: TraversalCounter, L: WideLeaves<C, Found = F>>(
        &mut self,
        isa: I,
        sections: &Sections<'_>,
        stack: &mut Stack,
        counter: &mut C,
        leaves: &mut L,
    ) -> bool {
        let current = self.current;
        if current & LEAF_BIT != 0 {
            if let Some(hit) =
                leaves.test_leaf::<Q, I>(isa, sections, current, &self.ray, self.t_max, self.found, counter)
            {
                self.found = Some(hit);
                if Q::FIRST_HIT_ENDS {
                    return false;
                }
                self.t_max = L::t(&hit);
            }
        } else if let Some(node) = sections.nodes.get(current as usize).filter(|_| self.visits_left > 0) {
            self.visits_left -= 1;
            counter.node_visited();
            let t_cull = self.ray.cull_distance(self.t_max);
            let (mask, t_near) = isa.box_test(node, &self.ray.slab_ray(), t_cull);
            let first = mask.trailing_zeros() as usize;
            let rest = mask & mask.wrapping_sub(1);
            if rest == 0 {
                if let Some(&child) = node.child.get(first) {
                    self.current = child;
                    return true;
                }
            } else if Q::FIRST_HIT_ENDS {
                // Any hit needs no order: the hit children go on the stack in slot order and the walk goes on
                // with the last (as Embree's occlusion traversal does), without comparing distances.
                let mut lanes = mask;
                loop {
                    let lane = lanes.trailing_zeros() as usize & (WIDE - 1);
                    lanes &= lanes - 1;
                    if lanes == 0 {
                        self.descend::<I>(sections, node.child[lane], L::PREFETCH_LEAVES);
                        return true;
                    }
                    self.push::<I>(sections, stack, (node.child[lane], t_near[lane]), L::PREFETCH_LEAVES);
                }
            } else if rest & (rest - 1) == 0 {
                let second = rest.trailing_zeros() as usize & (WIDE - 1);
                let (near, far) = if t_near[second] < t_near[first] { (second, first) } else { (first, second) };
                self.push::<I>(sections, stack, (node.child[far], t_near[far]), L::PREFETCH_LEAVES);
                self.descend::<I>(sections, node.child[near], L::PREFETCH_LEAVES);
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
                    self.push::<I>(sections, stack, entry, L::PREFETCH_LEAVES);
                }
                self.descend::<I>(sections, order[0].0, L::PREFETCH_LEAVES);
                return true;
            }
        }
        self.pop(stack)
    }

    /// Continues with `child`, prefetched on the AVX2 path (its loads then start together; a leaf only when
    /// `prefetch_leaves`, a constant of the leaf type).
    #[inline(always)]
    fn descend<I: Isa>(&mut self, sections: &Sections<'_>, child: u32, prefetch_leaves: bool) {
        if I::PREFETCH && (prefetch_leaves || child & LEAF_BIT == 0) {
            prefetch(sections, child);
        }
        self.current = child;
    }

    /// Pushes `entry` (dropped when the stack is full, which only a file that breaks V30 can cause) and, on
    /// the AVX2 path, prefetches what it references (a leaf only when `prefetch_leaves`).
    #[inline(always)]
    fn push<I: Isa>(&mut self, sections: &Sections<'_>, stack: &mut Stack, entry: (u32, f32), prefetch_leaves: bool) {
        if I::PREFETCH && (prefetch_leaves || entry.0 & LEAF_BIT == 0) {
            prefetch(sections, entry.0);
        }
        stack.push(entry);
    }

    /// Continues with the nearest pushed entry not beyond the closest hit; `false` when there is none.
    #[inline(always)]
    fn pop(&mut self, stack: &mut Stack) -> bool {
        let t_cull = self.ray.cull_distance(self.t_max);
        while let Some((next, t_entry)) = stack.pop() {
            if t_entry <= t_cull {
                self.current = next;
                return true;
            }
        }
        false
    }
}

/// The closest hit in packets `first .. first + count` (`leaf`), within `t_max`, among the candidates
/// `candidates` accepts, as (lane address, hit), when it comes before the walk's closest hit so far (at lane
/// address `walk_best`, whose `t` is `t_max`): ties go to the first in spec 11.1's order. For an any-hit query,
/// the first packet's hit.
#[inline(always)]
fn leaf_hit<Q: Query, I: Isa, C: Candidates>(
    isa: I,
    sections: &Sections<'_>,
    ray: &PreparedRay,
    (first, count): (usize, usize),
    (t_max, walk_best): (f32, Option<u32>),
    counter: &mut impl TraversalCounter,
    candidates: &C,
) -> Option<(u32, TriangleHit)> {
    let packets = sections.packets.get(first..first.saturating_add(count))?;
    let mut best = None;
    let (mut limit, mut best_address) = (t_max, walk_best);
    for (p, packet) in packets.iter().enumerate() {
        counter.triangle_tested();
        if let Some((lane, hit)) =
            closest_in_packet::<Q, I, C>(isa, packet, ray, limit, candidates, sections.tie)
            // A nearer hit is taken at once; the first hit at `t_max` or a tie is decided out of line.
            && (Q::FIRST_HIT_ENDS
                || hit.t < limit
                || sections.taken_at_limit(lane_address(first + p, lane), best_address))
        {
            let address = lane_address(first + p, lane);
            limit = hit.t;
            best = Some((address, hit));
            best_address = Some(address);
            if Q::FIRST_HIT_ENDS {
                break;
            }
        }
    }
    best
}

/// Asks the cache for the wide node or the first packet `child` references: a hint with no effect on results,
/// so the address is formed without a bounds check (a prefetch never faults, whatever the address).
#[inline(always)]
pub(crate) fn prefetch(sections: &Sections<'_>, child: u32) {
    if child & LEAF_BIT == 0 {
        prefetch_lines::<4>(sections.nodes.as_ptr().wrapping_add(child as usize).cast());
    } else {
        // A packet spans 3 cache lines (160 bytes from a multiple of 32).
        let (first, _) = WideNode8::leaf_packets(child);
        prefetch_lines::<3>(sections.packets.as_ptr().wrapping_add(first as usize).cast());
    }
}

/// Prefetches `LINES` cache lines from `start` into all cache levels (x86-64; elsewhere nothing).
#[inline(always)]
#[allow(unsafe_code)] // the prefetch hint, see the SAFETY note
fn prefetch_lines<const LINES: usize>(start: *const i8) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        for line in 0..LINES {
            // SAFETY: a prefetch is a hint that never faults nor changes memory, whatever the address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(line * 64)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = start;
}

/// One ray's walk, to its end, among the candidates `candidates` accepts.
pub(crate) struct SingleRay<'s, 'r, C, A, Q: Query> {
    pub(crate) sections: &'s Sections<'s>,
    pub(crate) ray: &'r Ray,
    pub(crate) counter: &'r mut C,
    pub(crate) candidates: &'r A,
    pub(crate) query: PhantomData<Q>,
}

impl<C: TraversalCounter, A: Candidates, Q: Query> Kernel for SingleRay<'_, '_, C, A, Q> {
    type Output = Option<(u32, TriangleHit)>;

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) -> Self::Output {
        let mut stack = new_stack();
        let mut walk = Walk::start(self.sections, self.ray, &mut stack)?;
        let mut leaves = PacketLeaves(self.candidates);
        while walk.step::<Q, I, C, _>(isa, self.sections, &mut stack, self.counter, &mut leaves) {}
        walk.found()
    }
}
