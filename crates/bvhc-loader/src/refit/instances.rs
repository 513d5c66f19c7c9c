//! Moving instances of a two-level file in place ([`BvhViewMut::move_instances`]): each moved instance takes its new
//! transform and the inverse the writer would store, its world box is recomputed as the writer computes it
//! ([`instance_world_box`]: the mesh's root box mapped and padded, `format-spec/bvh-1.md` 5.12 and 11.3), and the
//! top trees (binary and 8-wide) are refit bottom up over their own shape. The meshes and their trees do not
//! change, so this costs O(moved instances + top nodes), whatever the meshes hold.
//!
//! A refit keeps the top tree's shape: after large moves its boxes overlap more than a tree built for the new
//! placements would (the converter builds it by binned SAH); converting again restores it.

use crate::error::Error;
use crate::format::{
    Affine3x4, Bounds, EMPTY_BOUNDS, EMPTY_SLOT, InstanceRecord, LEAF_BIT, PackedNode, WIDE, WideNode8, union_bounds,
};
use crate::open::view_mut::BvhViewMut;
use crate::ray::transform::instance_world_box;
use crate::wide::refit::node_box;

impl BvhViewMut<'_> {
    /// Places the instances `moves` names anew: `(instance index, object_to_world)` pairs (one, some or all of
    /// the file's instances, in any order; a later pair for the same instance wins). Each moved instance keeps
    /// its mesh and provenance and takes the map, its inverse (computed in f64 as the writer computes it) and
    /// its world box; the top trees' boxes are refit bottom up; the checksums recomputed. The file then traces
    /// the instances where they now stand and verifies (two-level files state no cost for the metadata to
    /// disagree with).
    ///
    /// Refused, with the file unchanged: a one-level file (it has no instances), an instance index out of range,
    /// and a map that breaks rule V42 (not finite, singular, or an inverse that does not fit f32) or whose world
    /// box does not fit f32, each naming the instance.
    pub fn move_instances(&mut self, moves: &[(u32, Affine3x4)]) -> Result<(), Error> {
        self.place_instances(moves, true)
    }

    /// [`BvhViewMut::move_instances`] leaving the checksums as they were, as [`BvhViewMut::refit`] does: for a
    /// file moved every frame (hashing a large file's sections costs more than moving its instances), which
    /// verifies again once `BvhFile::rewritten` (feature `write`) has recomputed them. The same refusals.
    pub fn move_instances_in_frame(&mut self, moves: &[(u32, Affine3x4)]) -> Result<(), Error> {
        self.place_instances(moves, false)
    }

    /// The instances moved, the top trees refit, and the checksums recomputed when `checksums`.
    fn place_instances(&mut self, moves: &[(u32, Affine3x4)], checksums: bool) -> Result<(), Error> {
        let view = self.view();
        let Some(sections) = view.two_level() else {
            return Err(Error::Refit("a one-level file has no instances to move".into()));
        };
        let instance_count = sections.instances.len();
        // The moved instances' records and their world boxes (by instance), checked before anything is written.
        let mut records: Vec<(usize, InstanceRecord)> = Vec::with_capacity(moves.len());
        let mut boxes: Vec<Option<Bounds>> = vec![None; instance_count];
        for &(index, object_to_world) in moves {
            let Some((instance, mesh)) = sections.placement(index) else {
                return Err(Error::Refit(format!("instance {index}: the file has {instance_count} instances")));
            };
            let refused = |why: &str| Error::Refit(format!("instance {index}: {why}"));
            let record = InstanceRecord::placing(instance.mesh_index, object_to_world).ok_or_else(|| {
                refused("the transform is not finite and invertible with an inverse that fits f32 (rule V42)")
            })?;
            let root = view.nodes().get(mesh.first_node as usize).ok_or_else(|| refused("its mesh has no root"))?;
            let world_box = instance_world_box(&object_to_world, (root.min, root.max))
                .ok_or_else(|| refused("its world box does not fit f32"))?;
            let record = InstanceRecord {
                node_index: instance.node_index,
                gpu_instance_index: instance.gpu_instance_index,
                ..record
            };
            records.push((index as usize, record));
            boxes[index as usize] = Some(world_box);
        }
        let mut edit = self.edit()?;
        if let Some(instances) = edit.instances.as_deref_mut() {
            // In order, so that a later pair for the same instance wins, as its box does.
            for (index, record) in records {
                if let Some(instance) = instances.get_mut(index) {
                    *instance = record;
                }
            }
        }
        if let Some(top_nodes) = edit.top_nodes.as_deref_mut() {
            refit_top_binary(top_nodes, &boxes);
        }
        if let Some(top_wide_nodes) = edit.top_wide_nodes.as_deref_mut() {
            refit_top_wide(top_wide_nodes, &boxes);
        }
        if !checksums {
            edit.end_without_checksums();
        }
        Ok(())
    }
}

/// The binary top tree (children after parents, V43) refit: a leaf of a moved instance takes its new box
/// (`boxes[instance]`), another leaf keeps its own, an inner node the union of its children's.
pub(super) fn refit_top_binary(nodes: &mut [PackedNode], boxes: &[Option<Bounds>]) {
    for i in (0..nodes.len()).rev() {
        let node = nodes[i];
        let bounds = if node.is_leaf() {
            match boxes.get(node.index as usize).copied().flatten() {
                Some(world_box) => world_box,
                None => continue,
            }
        } else {
            let child = |c: usize| nodes.get(c).map_or(EMPTY_BOUNDS, |n| (n.min, n.max));
            union_bounds(child(node.index as usize), child((node.index as usize).saturating_add(1)))
        };
        (nodes[i].min, nodes[i].max) = bounds;
    }
}

/// The 8-wide top tree (children after parents) refit: a leaf slot of a moved instance takes its new box, another
/// keeps its own, an inner slot the union of its child's slots.
pub(super) fn refit_top_wide(nodes: &mut [WideNode8], boxes: &[Option<Bounds>]) {
    for i in (0..nodes.len()).rev() {
        for slot in 0..WIDE {
            let child = nodes[i].child[slot];
            if child == EMPTY_SLOT {
                continue;
            }
            let bounds = if child & LEAF_BIT != 0 {
                match boxes.get((child & !LEAF_BIT) as usize).copied().flatten() {
                    Some(world_box) => world_box,
                    None => continue,
                }
            } else {
                nodes.get(child as usize).map_or(EMPTY_BOUNDS, node_box)
            };
            nodes[i].set_slot_box(slot, bounds);
        }
    }
}
