//! The wide kernel's public face: [`WideBvh`] (wide sections in memory, checked by V29-V35), [`KernelPath`]
//! (which implementation runs, chosen at run time) and [`WideTracer`] (closest hit, any hit, one ray or a
//! stream of rays). The traversal itself is `wide_walk` (wide nodes, box tests) and `wide_packets` (triangle
//! packets); layout: `format::WideNode8`, `format::TrianglePacket4`.
//!
//! Paths: AVX2 box tests and SSE2 packets in one `target_feature(enable = "avx2")` function per entry point, so
//! everything inlines into it, or the portable loops, which give the same hits bit for bit.

use crate::error::Violation;
use crate::format::{PackedNode, PackedTriangle, TrianglePacket4, WideNode8};
use crate::intersect::{Ray, TriangleHit};
use crate::traverse::{Hit, TraversalCounter};
use crate::verify_wide::{WideContext, verify_wide};
use crate::wide_coherent::{PACKET_RAYS, trace_packet};
use crate::wide_walk::{Sections, Walk, new_stack};

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
        WideBvh::checked(nodes, packets, root_box, triangles, false)
    }

    /// [`WideBvh::new`] for a triangles section with `SPLIT_REFERENCES` (a triangle may be stored in several
    /// records, the records with its vertices): V35's split-reference clause applies, so a lane's triangle need
    /// only overlap its slot's box, and the slots holding a triangle's records must cover it.
    pub fn new_split_references(
        nodes: Vec<WideNode8>,
        packets: Vec<TrianglePacket4>,
        root_box: ([f32; 3], [f32; 3]),
        triangles: &[PackedTriangle],
    ) -> Result<WideBvh, Violation> {
        WideBvh::checked(nodes, packets, root_box, triangles, true)
    }

    fn checked(
        nodes: Vec<WideNode8>,
        packets: Vec<TrianglePacket4>,
        root_box: ([f32; 3], [f32; 3]),
        triangles: &[PackedTriangle],
        split_references: bool,
    ) -> Result<WideBvh, Violation> {
        let context = WideContext { triangles, triangle_ids: None, root_box: Some(root_box), split_references };
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
    sections: Sections<'a>,
    triangle_ids: Option<&'a [u32]>,
    path: KernelPath,
    interleave: bool,
}

/// Rays a stream keeps in flight, their steps interleaved.
const STREAM_WIDTH: usize = 8;

/// Streams interleave rays only over wide sections larger than this; over smaller ones, which stay in the
/// caches, the bookkeeping of interleaving costs more than it hides, and rays run one after the other. Measured
/// with `cargo bench --bench traversal` (one thread, 1M incoherent rays): interleaving 8 rays traced the
/// 871k-triangle dragon (60 MB of wide sections) 1.4x faster and the kitchen, engine and toy car (7-15 MB)
/// 0.8-0.95x as fast as single rays.
const INTERLEAVE_ABOVE_BYTES: usize = 32 << 20;

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
        let interleave = size_of_val(nodes) + size_of_val(packets) > INTERLEAVE_ABOVE_BYTES;
        WideTracer { sections: Sections { nodes, packets, root }, triangle_ids, path, interleave }
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

    /// The closest hit of each ray into the `hits` slot of the same index (pairs up to the shorter of the two).
    /// Over large sections several rays are in flight at once, their steps interleaved, so one ray's cache
    /// misses overlap with the others' work ([`WideTracer::interleaves_streams`]); each ray's hit is the one
    /// [`WideTracer::closest_hit`] returns, whichever way.
    pub fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.stream::<false>(rays, &mut hit_writer(hits, self.triangle_ids));
    }

    /// Whether each ray hits anything, into the `occluded` slot of the same index (pairs up to the shorter of
    /// the two), with rays interleaved as in [`WideTracer::closest_hits`].
    pub fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.stream::<true>(rays, &mut occlusion_writer(occluded));
    }

    /// The closest hit of each ray into the `hits` slot of the same index (pairs up to the shorter of the two),
    /// for coherent rays such as camera rays of neighbouring pixels: each 8 consecutive rays share one
    /// traversal. Each ray's `t` is the one [`WideTracer::closest_hit`] returns; on a tie at that `t` the
    /// triangle may be another one hit at the same `t`. Slower than [`WideTracer::closest_hits`] for rays that
    /// go different ways.
    pub fn closest_hits_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.packets::<false>(rays, &mut hit_writer(hits, self.triangle_ids));
    }

    /// Whether each ray hits anything, into the `occluded` slot of the same index (pairs up to the shorter of
    /// the two), 8 consecutive rays a traversal as in [`WideTracer::closest_hits_coherent`]; the same answers
    /// as [`WideTracer::any_hit`].
    pub fn any_hits_coherent(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.packets::<true>(rays, &mut occlusion_writer(occluded));
    }

    /// Packets of consecutive rays on the tracer's path; `done(i, found)` receives ray `i`'s result.
    #[allow(unsafe_code)] // the AVX2 entry, under the runtime check of `WideTracer::over`
    fn packets<const ANY_HIT: bool>(&self, rays: &[Ray], done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>)) {
        match self.path {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `path` is Avx2 only when `is_x86_feature_detected!("avx2")` said so (`WideTracer::over`).
            KernelPath::Avx2 => unsafe { self.packets_avx2::<ANY_HIT>(rays, done) },
            _ => self.packets_on::<ANY_HIT, false>(rays, done),
        }
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn packets_avx2<const ANY_HIT: bool>(
        &self,
        rays: &[Ray],
        done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
    ) {
        self.packets_on::<ANY_HIT, true>(rays, done)
    }

    #[inline(always)]
    fn packets_on<const ANY_HIT: bool, const SIMD: bool>(
        &self,
        rays: &[Ray],
        done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
    ) {
        for (p, chunk) in rays.chunks(PACKET_RAYS).enumerate() {
            trace_packet::<ANY_HIT, SIMD>(&self.sections, chunk, &mut |l, found| done(p * PACKET_RAYS + l, found));
        }
    }

    /// One ray's walk to its end on the tracer's path: for AVX2 the whole loop is one `target_feature`
    /// function, so the box test and the packets inline into it instead of being called per node.
    #[inline(always)]
    #[allow(unsafe_code)] // the AVX2 entry, under the runtime check of `WideTracer::over`
    fn dispatch<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        match self.path {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `path` is Avx2 only when `is_x86_feature_detected!("avx2")` said so (`WideTracer::over`).
            KernelPath::Avx2 => unsafe { self.walk_avx2::<ANY_HIT>(ray, counter) },
            _ => self.walk_portable::<ANY_HIT>(ray, counter),
        }
    }

    /// The portable walk, kept out of line like the AVX2 one, so that callers that inline `dispatch` (such as
    /// `Tracer`, next to the binary kernel) stay small.
    #[inline(never)]
    fn walk_portable<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        self.walk::<ANY_HIT, false>(ray, counter)
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn walk_avx2<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        self.walk::<ANY_HIT, true>(ray, counter)
    }

    #[inline(always)]
    fn walk<const ANY_HIT: bool, const SIMD: bool>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
    ) -> Option<(u32, TriangleHit)> {
        let mut walk = Walk::start(&self.sections, ray)?;
        let mut stack = new_stack();
        while walk.step::<ANY_HIT, SIMD>(&self.sections, &mut stack, counter) {}
        walk.found()
    }

    /// Whether streams interleave rays: by default when the wide sections exceed 32 MiB, where it measured
    /// faster; the results are the same either way.
    pub fn interleaves_streams(&self) -> bool {
        self.interleave
    }

    /// This tracer with streams interleaving rays (`true`) or tracing them one by one (`false`), whatever the
    /// size of the sections.
    pub fn interleaving_streams(self, interleave: bool) -> WideTracer<'a> {
        WideTracer { interleave, ..self }
    }

    /// The stream on the tracer's path; `done(i, found)` receives ray `i`'s result.
    #[allow(unsafe_code)] // the AVX2 entry, under the runtime check of `WideTracer::over`
    fn stream<const ANY_HIT: bool>(&self, rays: &[Ray], done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>)) {
        if !self.interleaves_streams() {
            for (i, ray) in rays.iter().enumerate() {
                done(i, self.dispatch::<ANY_HIT>(ray, &mut ()));
            }
            return;
        }
        match self.path {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `path` is Avx2 only when `is_x86_feature_detected!("avx2")` said so (`WideTracer::over`).
            KernelPath::Avx2 => unsafe { self.stream_avx2::<ANY_HIT>(rays, done) },
            _ => self.interleave::<ANY_HIT, false>(rays, done),
        }
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn stream_avx2<const ANY_HIT: bool>(
        &self,
        rays: &[Ray],
        done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
    ) {
        self.interleave::<ANY_HIT, true>(rays, done)
    }

    /// Keeps up to `STREAM_WIDTH` walks in flight, one step of each in turn; a finished walk's slot takes the
    /// next ray.
    #[inline(always)]
    fn interleave<const ANY_HIT: bool, const SIMD: bool>(
        &self,
        rays: &[Ray],
        done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
    ) {
        let mut stacks = [const { new_stack() }; STREAM_WIDTH];
        let mut walks: [Option<(usize, Walk)>; STREAM_WIDTH] = [const { None }; STREAM_WIDTH];
        let mut next = 0;
        let mut in_flight = 0;
        loop {
            for (slot, stack) in walks.iter_mut().zip(&mut stacks) {
                if slot.is_none() {
                    // Start the next ray that enters the root's box; the others miss at once.
                    while next < rays.len() && slot.is_none() {
                        match Walk::start(&self.sections, &rays[next]) {
                            Some(walk) => {
                                *slot = Some((next, walk));
                                in_flight += 1;
                            }
                            None => done(next, None),
                        }
                        next += 1;
                    }
                }
                if let Some((i, walk)) = slot
                    && !walk.step::<ANY_HIT, SIMD>(&self.sections, stack, &mut ())
                {
                    done(*i, walk.found());
                    *slot = None;
                    in_flight -= 1;
                }
            }
            if in_flight == 0 && next >= rays.len() {
                return;
            }
        }
    }
}

/// The `done` callback of the batch entry points for closest hits: ray `i`'s hit into `hits[i]`, its source id
/// from `triangle_ids`.
fn hit_writer<'h>(
    hits: &'h mut [Option<Hit>],
    triangle_ids: Option<&'h [u32]>,
) -> impl FnMut(usize, Option<(u32, TriangleHit)>) + 'h {
    move |i, found| {
        if let Some(slot) = hits.get_mut(i) {
            *slot = found.map(|(triangle_index, hit)| Hit::new(triangle_index, hit, triangle_ids));
        }
    }
}

/// The `done` callback of the batch entry points for any hits: whether ray `i` hit, into `occluded[i]`.
fn occlusion_writer(occluded: &mut [bool]) -> impl FnMut(usize, Option<(u32, TriangleHit)>) + '_ {
    move |i, found| {
        if let Some(slot) = occluded.get_mut(i) {
            *slot = found.is_some();
        }
    }
}
