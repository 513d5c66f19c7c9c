//! The public tracer: closest-hit and any-hit calls over a file's trees, run by the wide kernel where the file
//! has wide sections and by the binary walk (`crate::binary::walk`) otherwise, through the instances of a
//! two-level file (`crate::instances`); its batch calls, filters, crossings and traced files beside it.

pub(crate) mod batch;
pub(crate) mod crossings;
pub mod filter;
mod of_view;
mod points;
pub(crate) mod winding;
pub(crate) mod traced;

pub use batch::CHECKED_CHUNK;
pub use crossings::Crossings;
pub use traced::TracedFile;

use crate::binary::walk::{TriangleLeaves, walk};
use crate::format::{MeshRecord, PackedNode, PackedTriangle};
use crate::instances::{WideInstanceWalk, top_reach_scale, walk_instances};
use crate::open::sections::TwoLevelSections;
use crate::ray::candidates::{Candidates, Unfiltered};
use crate::ray::check::BatchRayError;
use crate::ray::hit::{ForeignHit, Hit, HitCore, TraversalCounter};
use crate::ray::intersect::Ray;
use crate::ray::query::{AnyHit, ClosestHit, Query, TieOrder};
use crate::ray::reach::tree_scale;
use crate::ray::spawn::SurfacePoint;
use crate::simd::KernelPath;
use crate::trace::{BatchResult, Order, Trace, refused};
use crate::wide::WideTracer;
use std::marker::PhantomData;

/// The traversal kernel over borrowed node and triangle arrays (a `BvhView`'s, or in-memory ones),
/// and, when it was given one ([`Tracer::with_wide`]), the wide kernel over the same triangles, which it then
/// runs instead: both give the same closest `t` and any-hit answers. Over a two-level file
/// ([`Tracer::with_instances`]) it walks the top-level tree and runs that kernel in each instance's mesh.
///
/// **Rays are checked**: every tracing call tests its rays against the ray contract ([`Ray::check`]: finite
/// origin and direction, a direction not below `2^-64`, `0 <= t_min <= t_max`) and panics, naming the rule and
/// the ray, on one that breaks it, since such a ray has no specified answer. The check costs about 30
/// instructions for a single ray (SSE2) and about 7 a ray in the batch calls (AVX2, 8 rays at a time): 1-2% of
/// a batch's instructions, 3-6% of a single ray's (`cargo bench --bench peer`, `BVHC_PEER_ONLY=ray-check`). A
/// caller that validates its rays itself (or wants a ray it cannot vouch for answered anyway, safely but
/// unspecified) uses [`Tracer::trusting_rays`].
#[derive(Clone, Copy, Debug)]
pub struct Tracer<'a> {
    nodes: &'a [PackedNode],
    triangles: &'a [PackedTriangle],
    triangle_ids: Option<&'a [u32]>,
    /// The `triangle_flags` section, for filtered tracing ([`crate::tracer::filter`]).
    triangle_flags: Option<&'a [u8]>,
    wide: Option<WideTracer<'a>>,
    instances: Option<TwoLevelSections<'a>>,
    /// The binary tree's part in its walks' reach (`crate::ray::reach::tree_scale` of `nodes[0]`).
    reach_scale: f32,
    /// The top trees' part in their walks' reach (`crate::instances::top_reach_scale`); 0 without instances.
    top_reach_scale: f32,
    /// Whether the tracing calls skip the ray check ([`Tracer::trusting_rays`]).
    trusts_rays: bool,
    /// The triangles section's `SPLIT_REFERENCES` flag ([`Tracer::with_split_references`]).
    split_references: bool,
}

/// Which kernel a [`Tracer`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// The binary kernel over the nodes section (the reference).
    Binary,
    /// The 8-wide kernel over the wide sections, on this path.
    Wide(KernelPath),
}

/// What the traversal loop found: triangle index and hit.
type Found = Option<(u32, crate::ray::hit::TriangleHit)>;

impl<'a> Tracer<'a> {
    /// A tracer over a tree in the layout of the nodes section (node 0 is the root).
    pub fn new(nodes: &'a [PackedNode], triangles: &'a [PackedTriangle], triangle_ids: Option<&'a [u32]>) -> Self {
        Tracer {
            nodes,
            triangles,
            triangle_ids,
            triangle_flags: None,
            wide: None,
            instances: None,
            reach_scale: nodes.first().map_or(0.0, |root| tree_scale(root, 1.0)),
            top_reach_scale: 0.0,
            trusts_rays: false,
            split_references: false,
        }
    }

    /// This tracer over a triangles section with the `SPLIT_REFERENCES` flag (`split`), as
    /// [`crate::BvhView::tracer`] makes it for such a file: a triangle then has several records, a ray may meet
    /// any of them, and of hits at one `t` the closest is decided by the triangles' coordinates rather than by
    /// the records' indices (`format-spec/bvh-1.md` 11.1). Its wide kernel, given before or after, follows.
    pub fn with_split_references(self, split: bool) -> Self {
        Tracer { split_references: split, wide: self.wide.map(|w| w.with_split_references(split)), ..self }
    }

    /// This tracer with the file's `triangle_flags` section (1.5), which filtered tracing reads ([`crate::tracer::filter`]).
    pub fn with_triangle_flags(self, flags: Option<&'a [u8]>) -> Self {
        Tracer { triangle_flags: flags, ..self }
    }

    /// The triangle flags this tracer's filtered calls read.
    pub(crate) fn triangle_flags(&self) -> Option<&'a [u8]> {
        self.triangle_flags
    }

    /// The source ids of this tracer's triangles.
    pub(crate) fn triangle_ids(&self) -> Option<&'a [u32]> {
        self.triangle_ids
    }

    /// The two-level sections this tracer walks, if the file is two-level.
    pub(crate) fn instance_sections(&self) -> Option<TwoLevelSections<'a>> {
        self.instances
    }

    /// The largest side of the scene's box in world space (the top tree's root, or the tree's), 0 when empty.
    pub(crate) fn scene_extent(&self) -> f32 {
        let root = match &self.instances {
            Some(sections) => sections.top_nodes.first(),
            None => self.nodes.first(),
        };
        root.map_or(0.0, PackedNode::largest_extent)
    }

    /// This tracer without the ray check: a ray that breaks the contract gets an unspecified answer (never a
    /// panic, a hang or a memory error). For callers that check their rays themselves ([`Ray::check`],
    /// [`crate::check_rays`]) or make them valid by construction.
    pub fn trusting_rays(self) -> Self {
        Tracer { trusts_rays: true, ..self }
    }

    /// Whether this tracer checks its rays (see [`Tracer::trusting_rays`]).
    pub fn checks_rays(&self) -> bool {
        !self.trusts_rays
    }

    /// Panics with `call`'s name when `ray` breaks the contract and this tracer checks rays.
    #[inline(always)]
    #[track_caller]
    pub(crate) fn check(&self, call: &str, ray: &Ray) {
        if !self.trusts_rays
            && let Err(error) = ray.check()
        {
            refused(call, &error);
        }
    }

    /// The first ray of `rays` that breaks the contract, as an error, when this tracer checks rays (the whole
    /// batch checked before any ray is traced).
    pub(crate) fn check_all(&self, rays: &[Ray]) -> Result<(), BatchRayError> {
        match self.trusts_rays {
            true => Ok(()),
            false => crate::ray::check::check_rays(rays),
        }
    }

    /// This tracer over a two-level file (1.3): its arrays (and wide sections) are the meshes' trees, which
    /// `sections` place; rays walk the top-level tree and are traced through each mesh they reach in its object
    /// space (`format-spec/bvh-1.md` 11.3).
    pub fn with_instances(self, sections: TwoLevelSections<'a>) -> Self {
        Tracer { instances: Some(sections), top_reach_scale: top_reach_scale(&sections), ..self }
    }

    /// The two-level sections this tracer walks, if any.
    pub fn instances(&self) -> Option<&TwoLevelSections<'a>> {
        self.instances.as_ref()
    }

    /// The one-level tracer over `mesh`'s ranges of this tracer's arrays (indices relative to the mesh, as the
    /// two-level layout stores them), with the wide kernel when this tracer has it. `None` when the ranges lie
    /// outside the arrays (a file that breaks V41).
    fn mesh_tracer(&self, mesh: &MeshRecord) -> Option<Tracer<'a>> {
        let range = |first: u32, count: u32| first as usize..(first as usize).saturating_add(count as usize);
        let nodes = self.nodes.get(range(mesh.first_node, mesh.node_count))?;
        let triangle_range = range(mesh.first_triangle, mesh.triangle_count);
        let triangles = self.triangles.get(triangle_range.clone())?;
        let ids = self.triangle_ids.and_then(|ids| ids.get(triangle_range));
        // The object-space ray comes from a checked world-space one; it is not checked again.
        let bottom = Tracer::new(nodes, triangles, ids).trusting_rays().with_split_references(self.split_references);
        let root = nodes.first()?;
        Some(match self.wide.and_then(|wide| wide.mesh(mesh, (root.min, root.max), ids)) {
            Some(wide) => bottom.with_wide(wide),
            None => bottom,
        })
    }

    /// This tracer running `wide` (built over the same triangles) instead of the binary kernel.
    pub fn with_wide(self, wide: WideTracer<'a>) -> Self {
        Tracer { wide: Some(wide.with_split_references(self.split_references)), ..self }
    }

    /// The binary kernel alone: the reference traversal.
    pub fn binary(&self) -> Tracer<'a> {
        Tracer { wide: None, ..*self }
    }

    /// The wide kernel the batch calls stream rays through: this tracer's, for a one-level file.
    pub(crate) fn one_level_wide(&self) -> Option<&WideTracer<'a>> {
        self.wide.as_ref().filter(|_| self.instances.is_none())
    }

    /// The kernel that [`Tracer::closest_hit`] and [`Tracer::any_hit`] run.
    pub fn kernel(&self) -> Kernel {
        self.wide.map_or(Kernel::Binary, |wide| Kernel::Wide(wide.path()))
    }

    /// The point of `hit` (a hit this tracer returned) on its triangle, for spawning secondary rays without an
    /// epsilon: `tracer.surface(&hit)?.spawn(direction)` is a ray with `t_min = 0` that does not meet the
    /// triangle it starts on ([`SurfacePoint`]). Refuses a hit that cannot be this file's ([`ForeignHit`]: a
    /// record or instance out of range, an instance in a one-level file or none in a two-level one, a record
    /// outside the instance's mesh, `u`, `v` NaN or off the triangle), rather than make a ray from nothing.
    pub fn surface(&self, hit: &Hit) -> Result<SurfacePoint, ForeignHit> {
        let triangle = self.triangles.get(hit.triangle_index as usize);
        let triangle =
            triangle.ok_or(ForeignHit::Triangle { index: hit.triangle_index, count: self.triangles.len() })?;
        match (hit.instance_index, self.instances) {
            (None, None) => SurfacePoint::new(hit, triangle),
            (Some(index), Some(sections)) => {
                let count = sections.instances.len();
                let (instance, mesh) = sections.placement(index).ok_or(ForeignHit::Instance { index, count })?;
                let first = u64::from(mesh.first_triangle);
                if !(first..first + u64::from(mesh.triangle_count)).contains(&u64::from(hit.triangle_index)) {
                    return Err(ForeignHit::NotInMesh { triangle: hit.triangle_index, instance: index });
                }
                SurfacePoint::placed(hit, triangle, instance)
            }
            (_, sections) => Err(ForeignHit::Levels { two_level: sections.is_some() }),
        }
    }

    /// The closest hit of a ray taken as valid.
    #[inline(always)]
    pub(crate) fn closest_hit_trusted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        self.closest_hit_inner(ray, counter, &Unfiltered)
    }

    /// The closest hit of a ray taken as valid among the candidates `candidates` accepts.
    #[inline(always)]
    pub(crate) fn closest_hit_inner<C: Candidates>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> Option<Hit> {
        if let Some(sections) = &self.instances {
            return self.closest_hit_through(sections, ray, counter, candidates);
        }
        let (triangle_index, hit) = match &self.wide {
            None => self.traverse::<ClosestHit, C>(ray, counter, candidates)?,
            Some(wide) => return wide.closest_hit_filtered(ray, counter, candidates),
        };
        Some(Hit::new(triangle_index, hit, self.triangles, self.triangle_ids, &ray.direction))
    }

    /// [`Trace::closest_hit`] of a ray taken as valid with the binary kernel: out of line, so that the wide
    /// kernel's call inlines into callers without the binary walk (the batch calls keep it inlined).
    #[inline(never)]
    fn closest_hit_binary(&self, ray: &Ray) -> Option<Hit> {
        let (triangle_index, hit) = self.traverse::<ClosestHit, Unfiltered>(ray, &mut (), &Unfiltered)?;
        Some(Hit::new(triangle_index, hit, self.triangles, self.triangle_ids, &ray.direction))
    }

    /// [`Trace::any_hit`] of a ray taken as valid with the binary kernel, out of line as
    /// [`Tracer::closest_hit_binary`].
    #[inline(never)]
    fn any_hit_binary(&self, ray: &Ray) -> bool {
        self.traverse::<AnyHit, Unfiltered>(ray, &mut (), &Unfiltered).is_some()
    }

    /// Whether a ray taken as valid hits anything.
    #[inline(always)]
    pub(crate) fn any_hit_trusted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool {
        self.any_hit_inner(ray, counter, &Unfiltered)
    }

    /// Whether a ray taken as valid hits anything `candidates` accepts.
    #[inline(always)]
    pub(crate) fn any_hit_inner<C: Candidates>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> bool {
        if let Some(sections) = &self.instances {
            return self.any_hit_through(sections, ray, counter, candidates);
        }
        match &self.wide {
            None => self.traverse::<AnyHit, C>(ray, counter, candidates).is_some(),
            Some(wide) => wide.any_hit_filtered(ray, counter, candidates),
        }
    }

    /// [`Tracer::closest_hit_counted`] in a two-level file: the wide top tree with the wide kernel, else the binary
    /// one. Out of line, so that the one-level kernel inlines as before.
    #[inline(never)]
    fn closest_hit_through<C: Candidates>(
        &self,
        sections: &TwoLevelSections<'a>,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> Option<Hit> {
        let trace_mesh = |instance: u32, mesh: &MeshRecord, object_ray: &Ray, counter: &mut _| {
            let in_mesh = candidates.in_mesh(mesh.first_triangle, instance);
            self.mesh_tracer(mesh)?.closest_hit_inner(object_ray, counter, &in_mesh)
        };
        match self.wide.filter(|_| !sections.top_wide_nodes.is_empty()) {
            Some(wide) => {
                let walk = WideInstanceWalk::<_, _, ClosestHit> {
                    sections,
                    reach_scale: self.top_reach_scale,
                    ray,
                    counter,
                    trace_mesh,
                    query: PhantomData,
                };
                crate::simd::run(wide.avx2(), walk)
            }
            None => walk_instances::<_, ClosestHit>(sections, self.top_reach_scale, ray, counter, trace_mesh),
        }
    }

    /// [`Tracer::any_hit_counted`] in a two-level file, as [`Tracer::closest_hit_through`].
    #[inline(never)]
    fn any_hit_through<C: Candidates>(
        &self,
        sections: &TwoLevelSections<'a>,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> bool {
        let occluding = |instance: u32, mesh: &MeshRecord, object_ray: &Ray, counter: &mut _| {
            let in_mesh = candidates.in_mesh(mesh.first_triangle, instance);
            self.mesh_tracer(mesh)?.any_hit_inner(object_ray, counter, &in_mesh).then_some(Hit::OCCLUSION)
        };
        match self.wide.filter(|_| !sections.top_wide_nodes.is_empty()) {
            Some(wide) => {
                let walk = WideInstanceWalk::<_, _, AnyHit> {
                    sections,
                    reach_scale: self.top_reach_scale,
                    ray,
                    counter,
                    trace_mesh: occluding,
                    query: PhantomData,
                };
                crate::simd::run(wide.avx2(), walk).is_some()
            }
            None => walk_instances::<_, AnyHit>(sections, self.top_reach_scale, ray, counter, occluding).is_some(),
        }
    }

    /// The binary kernel: the binary walk over this tracer's triangle leaves.
    #[inline(always)]
    fn traverse<Q: Query, C: Candidates>(
        &self,
        ray: &Ray,
        counter: &mut impl TraversalCounter,
        candidates: &C,
    ) -> Found {
        walk::<Q, _, _>(
            self.nodes,
            ray,
            counter,
            TriangleLeaves {
                triangles: self.triangles,
                candidates,
                tie: TieOrder::new(self.split_references, self.triangle_ids),
                reach_scale: self.reach_scale,
            },
        )
    }
}

/// The checked single-ray calls (the ray contract checked, the call named in a panic) and the batch calls of
/// `tracer/batch.rs`.
impl Trace for Tracer<'_> {
    /// The closest hit with `t_min <= t <= t_max`.
    ///
    /// # Panics
    ///
    /// When the ray breaks the contract and the tracer checks rays (see [`Tracer`]).
    ///
    /// Inlined into the caller with the wide kernel of a one-level file, whose call it then makes itself (so
    /// no call in between and no hit copied through it: 1.7-7% fewer instructions a ray, up to 6% more rays a
    /// second, `docs/kernel-peer.md`); the other kernels out of line.
    #[track_caller]
    #[inline(always)]
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.check("closest_hit", ray);
        if let Some(sections) = &self.instances {
            return self.closest_hit_through(sections, ray, &mut (), &Unfiltered);
        }
        match &self.wide {
            None => self.closest_hit_binary(ray),
            Some(wide) => wide.closest_hit_filtered(ray, &mut (), &Unfiltered),
        }
    }

    /// [`Trace::closest_hit`], counting node visits and triangle tests into `counter` (with the wide kernel:
    /// wide node visits and packet tests).
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hit`].
    #[track_caller]
    fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        self.check("closest_hit_counted", ray);
        self.closest_hit_trusted(ray, counter)
    }

    /// Whether anything is hit with `t_min <= t <= t_max` (occlusion); stops at the first hit found.
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hit`].
    ///
    /// Inlined as [`Trace::closest_hit`] is.
    #[track_caller]
    #[inline(always)]
    fn any_hit(&self, ray: &Ray) -> bool {
        self.check("any_hit", ray);
        if let Some(sections) = &self.instances {
            return self.any_hit_through(sections, ray, &mut (), &Unfiltered);
        }
        match &self.wide {
            Some(wide) => wide.any_hit_filtered(ray, &mut (), &Unfiltered),
            None => self.any_hit_binary(ray),
        }
    }

    /// [`Trace::any_hit`], counting as [`Trace::closest_hit_counted`] does.
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hit`].
    #[track_caller]
    fn any_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool {
        self.check("any_hit_counted", ray);
        self.any_hit_trusted(ray, counter)
    }

    /// Each ray's closest hit to `each`, with the wide kernel's stream (rays interleaved over large files,
    /// [`crate::WideTracer`]) or coherent packets in a one-level file, ray after ray otherwise; the rays checked
    /// chunk by chunk ([`CHECKED_CHUNK`]), each chunk just before it is traced.
    fn closest_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, Option<Hit>)) -> BatchResult {
        self.closest_hits_each(rays, order, &mut each)
    }

    /// [`Trace::closest_hits_with`] handing off each hit's core: in a one-level file the wide kernel computes no
    /// normal, side or source id.
    fn closest_hit_cores_with(
        &self,
        rays: &[Ray],
        order: Order,
        mut each: impl FnMut(usize, Option<HitCore>),
    ) -> BatchResult {
        self.closest_hit_cores_each(rays, order, &mut each)
    }

    /// Each ray's any-hit answer to `each`, as [`Trace::closest_hits_with`] for this tracer.
    fn any_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, bool)) -> BatchResult {
        self.any_hits_each(rays, order, &mut each)
    }
}
