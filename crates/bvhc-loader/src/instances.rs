//! Traversal through instances (format 1.3, `format-spec/bvh-1.md` 11.3): the top-level tree over instance
//! boxes in world space, and for each instance whose box the ray enters, the ray mapped into the mesh's object
//! space ([`crate::ray::transform`]) and traced through the mesh's own tree by a one-level kernel, with the
//! closest hit so far as its `t_max`.
//!
//! The binary kernel walks the binary top tree with the walk it runs in a mesh ([`crate::binary::walk`], with
//! instance leaves); the wide kernel walks the 8-wide top tree ([`WideInstanceWalk`]) as it walks a
//! mesh's wide tree. Both are safe on any input, and give the same hits (the tests check it).

use crate::binary::walk::{Leaves, walk};
use crate::format::{LEAF_BIT, MeshRecord, PackedNode, WIDE};
use crate::open::sections::TwoLevelSections;
use crate::ray::hit::{CULL_PADDING, Hit, TraversalCounter};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::transform::{object_ray, world_normal};
use crate::simd::{Isa, Kernel};
use crate::wide::walk::new_stack;

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

/// The closest hit (or with `ANY_HIT`, the first hit found) of `ray` among the instances of `sections`, by the
/// binary walk over the top tree with instance leaves. `trace_mesh` traces an object-space ray through one mesh
/// and returns its hit with the triangle index relative to the mesh; this function makes the index absolute,
/// and adds the instance index and the world-space normal.
#[inline(always)]
pub(crate) fn walk_instances<C: TraversalCounter, const ANY_HIT: bool>(
    sections: &TwoLevelSections<'_>,
    ray: &Ray,
    counter: &mut C,
    trace_mesh: impl FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
) -> Option<Hit> {
    walk::<ANY_HIT, _, _>(sections.top_nodes, ray, counter, InstanceLeaves { sections, trace_mesh })
}

/// The leaves of a two-level file's binary top tree: one instance each (`index` the instance, `count` 1).
struct InstanceLeaves<'s, 'a, F> {
    sections: &'s TwoLevelSections<'a>,
    trace_mesh: F,
}

impl<C, F> Leaves<C> for InstanceLeaves<'_, '_, F>
where
    C: TraversalCounter,
    F: FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
{
    type Found = Hit;

    #[inline(always)]
    fn test_leaf<const ANY_HIT: bool>(
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
        *t_max = hit.t;
        *found = Some(hit);
        ANY_HIT
    }
}

/// The walk of [`walk_instances`] over the 8-wide top tree (`top_wide_nodes`), its slots tested in the
/// instruction set's lanes as the meshes' wide nodes are (`Isa::box_test`: the same robust slab test per lane):
/// hit slots nearest first for a closest hit, in slot order for any hit. The same hits as the binary walk.
pub(crate) struct WideInstanceWalk<'a, 'r, C, F, const ANY_HIT: bool> {
    pub sections: &'a TwoLevelSections<'a>,
    pub ray: &'r Ray,
    pub counter: &'r mut C,
    pub trace_mesh: F,
}

impl<C, F, const ANY_HIT: bool> Kernel for WideInstanceWalk<'_, '_, C, F, ANY_HIT>
where
    C: TraversalCounter,
    F: FnMut(u32, &MeshRecord, &Ray, &mut C) -> Option<Hit>,
{
    type Output = Option<Hit>;

    #[inline(always)]
    #[allow(unsafe_code)] // reading the uninitialized-by-default stack, see the SAFETY note
    fn run<I: Isa>(mut self, isa: I) -> Option<Hit> {
        let (sections, ray) = (self.sections, self.ray);
        let nodes = sections.top_wide_nodes;
        let prepared = PreparedRay::new(ray);
        prepared.enter_box(sections.top_nodes.first()?, ray.t_max * CULL_PADDING)?;
        let mut t_max = ray.t_max;
        let mut found: Option<Hit> = None;
        let mut stack = new_stack();
        let mut stack_len = 0usize;
        let mut current = 0u32;
        let mut visits_left = nodes.len();
        'walk: loop {
            'visit: {
                if current & LEAF_BIT != 0 {
                    let index = current & !LEAF_BIT;
                    if let Some(hit) = visit_instance(sections, index, ray, t_max, self.counter, &mut self.trace_mesh) {
                        if ANY_HIT {
                            return Some(hit);
                        }
                        t_max = hit.t;
                        found = Some(hit);
                    }
                    break 'visit;
                }
                let Some(node) = nodes.get(current as usize).filter(|_| visits_left > 0) else { break 'visit };
                visits_left -= 1;
                self.counter.node_visited();
                let (mask, t_near) = isa.box_test(node, &prepared.slab_ray(), t_max * CULL_PADDING);
                // The hit slots sorted farthest first (for any hit: in reverse slot order); all but the nearest
                // onto the stack (at most 7 a level, so `STACK_LEN` entries suffice), the walk going on with it.
                let mut order = [(0u32, 0f32); WIDE];
                let mut count = 0;
                for (slot, (&t_slot, &child)) in t_near.iter().zip(&node.child).enumerate() {
                    if mask & (1 << slot) != 0 {
                        let t = if ANY_HIT { slot as f32 } else { t_slot };
                        let mut k = count;
                        while k > 0 && order[k - 1].1 < t {
                            order[k] = order[k - 1];
                            k -= 1;
                        }
                        order[k] = (child, t);
                        count += 1;
                    }
                }
                let Some(&(nearest, _)) = order[..count].last() else { break 'visit };
                for &(child, t) in &order[..count - 1] {
                    let t = if ANY_HIT { f32::NEG_INFINITY } else { t };
                    if let Some(entry) = stack.get_mut(stack_len) {
                        entry.write((child, t));
                        stack_len += 1;
                    }
                }
                current = nearest;
                continue 'walk;
            }
            // Pop the nearest pending entry that may still hold a closer hit.
            loop {
                if stack_len == 0 {
                    return found;
                }
                stack_len -= 1;
                // SAFETY: every index below `stack_len` was written by the push above before `stack_len` passed it,
                // and `stack_len` only moves down by one here, so entry `stack_len` is initialized.
                let (child, t_entry) = unsafe { stack[stack_len].assume_init() };
                if t_entry <= t_max * CULL_PADDING {
                    current = child;
                    break;
                }
            }
        }
    }
}
