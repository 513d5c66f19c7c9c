//! The wide kernel's public face: [`WideBvh`] (wide sections in memory, checked by V29-V35) and [`WideTracer`]
//! (closest hit, any hit, one ray, a stream of rays or packets of coherent rays). The traversal itself is
//! `walk` (wide nodes, box tests, one ray's walk), `packets` (triangle packets), `coherent` (ray packets) and
//! `batch` (the batch calls: which rays go as packets, streams);
//! layout: `format::WideNode8`, `format::TrianglePacket4`.
//!
//! Each entry point is a `Kernel` written once over an instruction set and run by `crate::simd::run`: on
//! AVX2 (box tests in AVX2, triangle packets in SSE2) inside one `target_feature` function, so everything
//! inlines into it, or on the portable path, which gives the same hits bit for bit.

pub(crate) mod batch;
pub(crate) mod coherent;
pub(crate) mod encode;
pub(crate) mod packets;
pub(crate) mod refit;
pub(crate) mod walk;

use crate::error::Violation;
use crate::format::{PackedNode, PackedTriangle, TrianglePacket4, WideNode8};
use crate::ray::candidates::{Candidates, Unfiltered};
use crate::ray::hit::{Hit, HitCore, TraversalCounter, TriangleHit};
use crate::ray::intersect::Ray;
use crate::ray::query::{AnyHit, ClosestHit, Query, TieOrder};
use crate::ray::reach::tree_scale;
use crate::simd::{Avx2, KernelPath};
use crate::trace::{BatchResult, Order, Trace};
use crate::verify::wide::{WideContext, verify_wide};
use crate::wide::batch::{Batch, Packets};
use crate::wide::walk::{Sections, SingleRay};
use std::marker::PhantomData;

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

    /// The nodes and packets, moved out (to lay several trees out in one file).
    pub fn into_parts(self) -> (Vec<WideNode8>, Vec<TrianglePacket4>) {
        (self.nodes, self.packets)
    }
}

/// Closest-hit and any-hit queries over wide sections (a file's, or a [`WideBvh`]): the kernel itself, which
/// takes its rays as valid (it does not check the ray contract; a [`crate::Tracer`] does before running it).
#[derive(Clone, Copy, Debug)]
pub struct WideTracer<'a> {
    sections: Sections<'a>,
    triangle_ids: Option<&'a [u32]>,
    /// The AVX2 token when the tracer runs the AVX2 path.
    avx2: Option<Avx2>,
    interleave: bool,
}

/// Streams interleave rays only over wide sections larger than this; over smaller ones, which stay in the
/// caches, the bookkeeping of interleaving costs more than it hides, and rays run one after the other (measured
/// in `docs/evaluation.md`, traversal).
const INTERLEAVE_ABOVE_BYTES: usize = 32 << 20;

impl<'a> WideTracer<'a> {
    /// A tracer over `bvh` on `path` (the portable one when `path` is not supported here). `triangle_ids` are
    /// indexed by the packets' triangle indices; hits take their normals from the packets' vertices.
    pub fn new(bvh: &'a WideBvh, triangle_ids: Option<&'a [u32]>, path: KernelPath) -> WideTracer<'a> {
        WideTracer::over(&bvh.nodes, &bvh.packets, (bvh.root.min, bvh.root.max), triangle_ids, path)
    }

    /// A tracer over borrowed wide sections (a `BvhView`'s) inside `root_box`, the binary root's box.
    /// Safe on any contents; the hits are those of the binary kernel when the sections pass V29-V35.
    pub fn over(
        nodes: &'a [WideNode8],
        packets: &'a [TrianglePacket4],
        root_box: ([f32; 3], [f32; 3]),
        triangle_ids: Option<&'a [u32]>,
        path: KernelPath,
    ) -> WideTracer<'a> {
        let avx2 = match path {
            KernelPath::Avx2 => Avx2::detect(),
            KernelPath::Portable => None,
        };
        let root = PackedNode { min: root_box.0, max: root_box.1, index: 0, count: 0 };
        let interleave = size_of_val(nodes) + size_of_val(packets) > INTERLEAVE_ABOVE_BYTES;
        let reach_scale = tree_scale(&root, 1.0);
        let sections = Sections { nodes, packets, root, tie: TieOrder::default(), reach_scale };
        WideTracer { sections, triangle_ids, avx2, interleave }
    }

    /// The tracer over mesh `mesh`'s ranges of these sections (a two-level file's, whose indices inside a mesh
    /// are relative to its ranges), inside `root_box` (the mesh's binary root box), its lanes' source ids in
    /// `triangle_ids` (the mesh's range of them). `None` when the ranges lie outside the sections (a file that
    /// breaks V41).
    pub(crate) fn mesh(
        &self,
        mesh: &crate::format::MeshRecord,
        root_box: ([f32; 3], [f32; 3]),
        triangle_ids: Option<&'a [u32]>,
    ) -> Option<WideTracer<'a>> {
        let range = |first: u32, count: u32| first as usize..(first as usize).saturating_add(count as usize);
        let nodes = self.sections.nodes.get(range(mesh.first_wide_node, mesh.wide_node_count))?;
        let packets = self.sections.packets.get(range(mesh.first_packet, mesh.packet_count))?;
        let tracer = WideTracer::over(nodes, packets, root_box, triangle_ids, self.path());
        Some(tracer.with_split_references(self.sections.tie.by_coordinates()))
    }

    /// This tracer over packets whose triangles section has the `SPLIT_REFERENCES` flag (`split`): hits at one
    /// `t` are then ordered by their triangles' coordinates and source ids, not by record
    /// (`format-spec/bvh-1.md` 11.1).
    pub fn with_split_references(self, split: bool) -> WideTracer<'a> {
        let tie = TieOrder::new(split, self.triangle_ids);
        WideTracer { sections: Sections { tie, ..self.sections }, ..self }
    }

    /// The wide sections this tracer walks (for the point walk, `crate::point::wide`).
    pub(crate) fn sections(&self) -> &Sections<'a> {
        &self.sections
    }

    /// The AVX2 token when the tracer runs the AVX2 path (for walks of other wide trees on the same path).
    pub(crate) fn avx2(&self) -> Option<Avx2> {
        self.avx2
    }

    /// The path this tracer runs.
    pub fn path(&self) -> KernelPath {
        if self.avx2.is_some() { KernelPath::Avx2 } else { KernelPath::Portable }
    }

    /// [`WideTracer::closest_hit_counted`] among the candidates `candidates` accepts.
    #[inline(always)]
    pub(crate) fn closest_hit_filtered<C: Candidates>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> Option<Hit> {
        let (address, hit) = self.dispatch::<ClosestHit, C>(ray, counter, candidates)?;
        Some(Hit::in_lane(address, hit, self.sections.packets, self.triangle_ids, &ray.direction))
    }

    /// [`WideTracer::any_hit_counted`] among the candidates `candidates` accepts.
    #[inline(always)]
    pub(crate) fn any_hit_filtered<C: Candidates>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> bool {
        self.dispatch::<AnyHit, C>(ray, counter, candidates).is_some()
    }

    /// Each ray's closest hit to `each(i, hit)`, once per ray: as a stream ([`WideTracer::closest_hits`]) or, when
    /// `coherent`, in packets of 8 ([`WideTracer::closest_hits_coherent`]).
    pub(crate) fn closest_hits_each(&self, rays: &[Ray], order: Order, each: &mut impl FnMut(usize, Option<Hit>)) {
        let (packets, ids) = (self.sections.packets, self.triangle_ids);
        let mut done = |i: usize, found: Option<(u32, TriangleHit)>| {
            if let Some(ray) = rays.get(i) {
                each(i, found.map(|(address, hit)| Hit::in_lane(address, hit, packets, ids, &ray.direction)));
            }
        };
        match order == Order::Coherent {
            true => self.packets::<ClosestHit>(rays, &mut done),
            false => self.stream::<ClosestHit>(rays, &mut done),
        }
    }

    /// Each ray's closest hit to `each(i, core)`, once per ray, handed off lean (no normal, side or source id
    /// computed), as [`WideTracer::closest_hits_each`].
    pub(crate) fn closest_hit_cores_each(
        &self,
        rays: &[Ray],
        order: Order,
        each: &mut impl FnMut(usize, Option<HitCore>),
    ) {
        let packets = self.sections.packets;
        let mut done = |i: usize, found: Option<(u32, TriangleHit)>| {
            each(i, found.map(|(address, hit)| HitCore::in_lane(address, hit, packets)));
        };
        match order == Order::Coherent {
            true => self.packets::<ClosestHit>(rays, &mut done),
            false => self.stream::<ClosestHit>(rays, &mut done),
        }
    }

    /// Whether each ray hits anything to `each(i, occluded)`, once per ray, as [`WideTracer::closest_hits_with`].
    pub(crate) fn any_hits_each(&self, rays: &[Ray], order: Order, each: &mut impl FnMut(usize, bool)) {
        let mut done = |i: usize, found: Option<(u32, TriangleHit)>| each(i, found.is_some());
        match order == Order::Coherent {
            true => self.packets::<AnyHit>(rays, &mut done),
            false => self.stream::<AnyHit>(rays, &mut done),
        }
    }

    /// Packets of consecutive rays on the tracer's path; `done(i, found)` receives ray `i`'s result.
    fn packets<Q: Query>(&self, rays: &[Ray], done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>)) {
        crate::simd::run(self.avx2, Packets::<_, Q> { sections: &self.sections, rays, done, query: PhantomData });
    }

    /// One ray's walk to its end on the tracer's path.
    #[inline(always)]
    fn dispatch<Q: Query, C: Candidates>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> Option<(u32, TriangleHit)> {
        crate::simd::run(
            self.avx2,
            SingleRay::<_, _, Q> { sections: &self.sections, ray, counter, candidates, query: PhantomData },
        )
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

    /// The stream call ([`Order::Stream`]) on the tracer's path; `done(i, found)` receives ray `i`'s result.
    /// Each group of 8 consecutive rays (counted from the first) whose origins are equal bit for bit (a pinhole
    /// camera's rays, a point light's shadow rays, one hit's ambient-occlusion rays), or whose directions lie in
    /// one octant and origins within a sixteenth of the scene's size (shadow rays from neighbouring hits toward
    /// a light), is traced as a coherent packet, the other rays one by one or interleaved
    /// ([`WideTracer::interleaves_streams`]): the same hits either way (`docs/batches-peer.md`).
    fn stream<Q: Query>(&self, rays: &[Ray], done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>)) {
        let (sections, interleave) = (&self.sections, self.interleave);
        crate::simd::run(self.avx2, Batch::<_, Q> { sections, rays, done, interleave, query: PhantomData });
    }
}

/// The single-ray calls, and the batch calls as a stream of interleaved rays ([`WideTracer::interleaves_streams`])
/// or in coherent packets of 8 consecutive rays: the same hit for each ray either way, ties decided as spec 11.1
/// says (with split references, possibly another record of the same triangle).
impl Trace for WideTracer<'_> {
    /// [`Trace::closest_hit`], counting wide node visits and triangle tests (packets of
    /// four count as one test each) into `counter`.
    fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        self.closest_hit_filtered(ray, counter, &Unfiltered)
    }

    /// [`Trace::any_hit`], counting as [`Trace::closest_hit_counted`] does.
    fn any_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool {
        self.any_hit_filtered(ray, counter, &Unfiltered)
    }

    /// Each ray's closest hit to `each(i, hit)`: a stream, over large sections several rays in flight at once
    /// so that one ray's cache misses overlap with the others' work, or packets of 8 ([`Order::Coherent`]).
    fn closest_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, Option<Hit>)) -> BatchResult {
        self.closest_hits_each(rays, order, &mut each);
        Ok(())
    }

    /// [`Trace::closest_hits_with`] handing off each hit's core: no normal, side or source id computed.
    fn closest_hit_cores_with(
        &self,
        rays: &[Ray],
        order: Order,
        mut each: impl FnMut(usize, Option<HitCore>),
    ) -> BatchResult {
        self.closest_hit_cores_each(rays, order, &mut each);
        Ok(())
    }

    /// Whether each ray hits anything to `each(i, occluded)`, as [`Trace::closest_hits_with`] for this tracer.
    fn any_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, bool)) -> BatchResult {
        self.any_hits_each(rays, order, &mut each);
        Ok(())
    }
}
