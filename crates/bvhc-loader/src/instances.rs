//! Traversal through instances (format 1.3, `format-spec/bvh-1.md` 11.3): the top-level tree over instance
//! boxes in world space, and for each instance whose box the ray enters, the ray mapped into the mesh's object
//! space ([`crate::ray::transform`]) and traced through the mesh's own tree by a one-level kernel, with the
//! closest hit so far as its `t_max`.
//!
//! The binary kernel walks the binary top tree with the walk it runs in a mesh ([`crate::binary::walk`], with
//! instance leaves); the wide kernel walks the 8-wide top tree with the walk it runs in a mesh
//! ([`crate::wide::walk`], with instance leaves: [`WideInstanceWalk`]). Both are safe on any input, and give
//! the same hits (the tests check it).

use crate::binary::walk::{Leaves, walk};
use crate::format::{LEAF_BIT, MeshRecord, PackedNode};
use crate::open::sections::TwoLevelSections;
use crate::ray::hit::{Hit, TraversalCounter};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::query::{Query, TieOrder, precedes};
use crate::ray::reach::tree_scale;
use crate::ray::transform::{object_ray, world_normal};
use crate::simd::{Isa, Kernel};
use crate::wide::walk::{Sections, Walk, WideLeaves, new_stack};
use std::marker::PhantomData;

/// The hit of `ray` (with `t_max`, the closest hit so far) in instance `index`'s mesh: the ray mapped into the
/// mesh's object space and traced by `trace_mesh`, whose hit (record index relative to the mesh) comes back with
/// the absolute record index, the instance and the world-space normal. `None` for no hit or no such instance.
#[inline(always)]
fn visit_instance<C: TraversalCounter>(
    sections: &TwoLevelSections<'_>,
    index: u32,
    ray: &Ray,
    t_max: f32,
    counter: &mut C,
    trace_mesh: &mut impl FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
) -> Option<Hit> {
    let (instance, mesh) = sections.placement(index)?;
    let mut hit = trace_mesh(index, mesh, &object_ray(instance, &Ray { t_max, ..*ray }), counter)?;
    hit.triangle_index = hit.triangle_index.wrapping_add(mesh.first_triangle);
    hit.instance_index = Some(index);
    hit.normal = world_normal(instance, hit.normal);
    Some(hit)
}

/// The tie keys of two hits in instances (spec 11.1): the instance index, then the record.
#[inline]
fn tie_keys(hit: &Hit, best: &Hit) -> ((Option<u32>, u32), (Option<u32>, u32)) {
    ((hit.instance_index, hit.triangle_index), (best.instance_index, best.triangle_index))
}

/// The closest hit (or for an any-hit query, the first hit found) of `ray` among the instances of `sections`, by the
/// binary walk over the top tree with instance leaves. `trace_mesh` traces an object-space ray through one mesh
/// and returns its hit with the triangle index relative to the mesh; this function makes the index absolute,
/// and adds the instance index and the world-space normal.
#[inline(always)]
pub(crate) fn walk_instances<C: TraversalCounter, Q: Query>(
    sections: &TwoLevelSections<'_>,
    reach_scale: f32,
    ray: &Ray,
    counter: &mut C,
    trace_mesh: impl FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
) -> Option<Hit> {
    walk::<Q, _, _>(sections.top_nodes, ray, counter, InstanceLeaves { sections, reach_scale, trace_mesh })
}

/// The top trees' part in their walks' reach: [`tree_scale`] of the binary top root with [`instance_stretch`]
/// (0 without a top tree), computed once for a tracer (`Tracer::with_instances`).
pub(crate) fn top_reach_scale(sections: &TwoLevelSections<'_>) -> f32 {
    sections.top_nodes.first().map_or(0.0, |root| tree_scale(root, instance_stretch(sections)))
}

/// How much an instance of `sections` can stretch a record's depth along a ray, relative to the world's: the
/// largest `||W||_inf ||L||_inf` of its instances (row sums of the linear parts of `world_to_object` and
/// `object_to_world`), which bounds a record's spread along the object-space ray's major axis over that axis's
/// direction component by the world extent over the world ray's largest component (`crate::ray::reach`: the
/// top trees' reach is scaled by it). At least 1; computed once for a tracer (`Tracer::with_instances`), in f64
/// and rounded up.
fn instance_stretch(sections: &TwoLevelSections<'_>) -> f32 {
    let norm = |m: &crate::format::Affine3x4| {
        m.iter().map(|row| row[..3].iter().map(|&c| f64::from(c).abs()).sum::<f64>()).fold(0.0, f64::max)
    };
    let largest =
        sections.instances.iter().map(|i| norm(&i.world_to_object) * norm(&i.object_to_world)).fold(1.0f64, f64::max);
    // Rounded up to f32 (a NaN map, which a verified file has not, gives NaN: the walk then culls nothing).
    let rounded = largest as f32;
    if f64::from(rounded) < largest { rounded.next_up() } else { rounded }
}

/// The leaves of a two-level file's binary top tree: one instance each (`index` the instance, `count` 1).
struct InstanceLeaves<'s, 'a, F> {
    sections: &'s TwoLevelSections<'a>,
    /// The top tree's part in the reach: [`top_reach_scale`] of `sections`.
    reach_scale: f32,
    trace_mesh: F,
}

impl<C, F> Leaves<C> for InstanceLeaves<'_, '_, F>
where
    C: TraversalCounter,
    F: FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
{
    type Found = Hit;

    fn reach_scale(&self) -> f32 {
        self.reach_scale
    }

    #[inline(always)]
    fn test_leaf<Q: Query>(
        &mut self,
        node: &PackedNode,
        ray: &Ray,
        _: &PreparedRay,
        t_max: &mut f32,
        found: &mut Option<Hit>,
        counter: &mut C,
    ) -> bool {
        let Some(hit) = visit_instance(self.sections, node.index, ray, *t_max, counter, &mut self.trace_mesh) else {
            return false;
        };
        if Q::FIRST_HIT_ENDS || found.as_ref().is_none_or(|best| precedes(hit.t, best.t, || tie_keys(&hit, best))) {
            *t_max = hit.t;
            *found = Some(hit);
        }
        Q::FIRST_HIT_ENDS
    }
}

/// The walk of [`walk_instances`] over the 8-wide top tree (`top_wide_nodes`): the wide kernel's walk
/// ([`crate::wide::walk`]) with instance leaves, its slots tested in the instruction set's lanes as the meshes'
/// wide nodes are (`Isa::box_test`: the same robust slab test per lane), hit slots nearest first for a closest
/// hit. The binary top root's box is tested first (a ray that misses it misses every instance).
pub(crate) struct WideInstanceWalk<'a, 'r, C, F, Q: Query> {
    pub sections: &'a TwoLevelSections<'a>,
    /// The top tree's part in the reach: [`top_reach_scale`] of `sections`.
    pub reach_scale: f32,
    pub ray: &'r Ray,
    pub counter: &'r mut C,
    pub trace_mesh: F,
    pub query: PhantomData<Q>,
}

impl<C, F, Q: Query> Kernel for WideInstanceWalk<'_, '_, C, F, Q>
where
    C: TraversalCounter,
    F: FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
{
    type Output = Option<Hit>;

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) -> Option<Hit> {
        let WideInstanceWalk { sections, reach_scale, ray, counter, trace_mesh, .. } = self;
        let root = *sections.top_nodes.first()?;
        let top =
            Sections { nodes: sections.top_wide_nodes, packets: &[], root, tie: TieOrder::default(), reach_scale };
        let mut stack = new_stack();
        let mut walk = Walk::start(&top, ray, &mut stack).filter(|walk| walk.enters(&root))?;
        let mut leaves = WideInstanceLeaves { sections, ray, trace_mesh };
        while walk.step::<Q, I, C, _>(isa, &top, &mut stack, counter, &mut leaves) {}
        walk.found()
    }
}

/// The leaf references of a two-level file's wide top tree: `LEAF_BIT | instance`.
struct WideInstanceLeaves<'s, 'a, 'r, F> {
    sections: &'s TwoLevelSections<'a>,
    /// The world-space ray.
    ray: &'r Ray,
    trace_mesh: F,
}

impl<C, F> WideLeaves<C> for WideInstanceLeaves<'_, '_, '_, F>
where
    C: TraversalCounter,
    F: FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
{
    type Found = Hit;
    const PREFETCH_LEAVES: bool = false;

    #[inline(always)]
    fn test_leaf<Q: Query, I: Isa>(
        &mut self,
        _: I,
        _: &Sections<'_>,
        reference: u32,
        _: &PreparedRay,
        t_max: f32,
        best: Option<Hit>,
        counter: &mut C,
    ) -> Option<Hit> {
        let hit = visit_instance(self.sections, reference & !LEAF_BIT, self.ray, t_max, counter, &mut self.trace_mesh)?;
        let first = best.is_none_or(|best| precedes(hit.t, best.t, || tie_keys(&hit, &best)));
        (Q::FIRST_HIT_ENDS || first).then_some(hit)
    }

    #[inline(always)]
    fn t(found: &Hit) -> f32 {
        found.t
    }
}
