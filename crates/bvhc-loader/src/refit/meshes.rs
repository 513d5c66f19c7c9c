//! Refitting a two-level file: each mesh is a one-level tree of its own over its ranges of the sections, with
//! indices relative to them (`format-spec/bvh-1.md` 5.10), so each mesh's binary and wide trees are refit as a
//! one-level file's are, on the mesh's sub-arrays; then every instance takes the world box of its mesh's new root
//! (as the writer computes it, [`instance_world_box`]) and both top trees are refit bottom up
//! (`refit::instances`). The positions are the records', in each mesh's object space (a flattened mesh's records
//! are in world space, an instanced mesh's in the space its instances map).

use crate::binary::refit::{NewRecords, refit_binary};
use crate::error::Error;
use crate::format::{Bounds, MeshRecord, PackedTriangle, TriangleFold};
use crate::open::edit::SectionsMut;
use crate::open::view::BvhView;
use crate::parallel::Workers;
use crate::ray::transform::instance_world_box;
use crate::refit::instances::{refit_top_binary, refit_top_wide};
use crate::refit::positions::MovedRecords;
use crate::wide::refit::refit_wide;

/// The positions of one mesh's records: the file's, from the mesh's first record on.
struct MeshRecords<'a, N: ?Sized> {
    all: &'a N,
    first: usize,
}

impl<N: NewRecords + ?Sized> NewRecords for MeshRecords<'_, N> {
    #[inline(always)]
    fn write(&self, first: usize, records: &mut [PackedTriangle]) -> Bounds {
        self.all.write(self.first + first, records)
    }
}

/// Checks that every instance's world box fits f32 once its mesh is moved to `moved`: each mesh's new root box
/// (the box of its records as moved, which the refit gives its root) mapped by the instance. An error naming the
/// first instance whose box does not fit, before anything is written.
pub(super) fn check_world_boxes(view: &BvhView<'_>, moved: &MovedRecords<'_>) -> Result<(), Error> {
    let Some(sections) = view.two_level() else { return Ok(()) };
    let records = view.triangles();
    let mut last_range = 0;
    let roots: Vec<Bounds> = sections
        .meshes
        .iter()
        .map(|mesh| {
            let mut fold = TriangleFold::EMPTY;
            let range = mesh_range(mesh.first_triangle, mesh.triangle_count);
            for (record, kept) in range.clone().zip(records.get(range).unwrap_or(&[])) {
                // Checked before: every record has its vertices (or stays).
                let vertices = moved.record(record, &mut last_range).ok().flatten().unwrap_or(kept.vertices);
                fold.add(&vertices);
            }
            fold.bounds()
        })
        .collect();
    for (index, instance) in sections.instances.iter().enumerate() {
        let root = roots.get(instance.mesh_index as usize).copied();
        if root.and_then(|root| instance_world_box(&instance.object_to_world, root)).is_none() {
            return Err(Error::Refit(format!(
                "instance {index}: the world box of its moved mesh does not fit f32 (refit nothing)"
            )));
        }
    }
    Ok(())
}

/// Refits every mesh of `edit`'s two-level file to `new` (positions of all of the file's records, in record
/// order), each on up to `workers`' threads, then the instances' world boxes and the top trees. Ranges outside
/// their sections (a file that does not verify, V41) are passed over rather than panic.
pub(super) fn refit_meshes(edit: &mut SectionsMut<'_>, new: &(impl NewRecords + ?Sized), workers: Workers) {
    let Some(meshes) = edit.meshes else { return };
    for mesh in meshes {
        let nodes = edit.nodes.get_mut(mesh_range(mesh.first_node, mesh.node_count));
        let records = edit.triangles.get_mut(mesh_range(mesh.first_triangle, mesh.triangle_count));
        let (Some(nodes), Some(records)) = (nodes, records) else { continue };
        refit_binary(nodes, records, &MeshRecords { all: new, first: mesh.first_triangle as usize }, workers);
        let wide = edit
            .wide_nodes
            .as_deref_mut()
            .and_then(|n| n.get_mut(mesh_range(mesh.first_wide_node, mesh.wide_node_count)));
        let packets = edit
            .triangle_packets
            .as_deref_mut()
            .and_then(|p| p.get_mut(mesh_range(mesh.first_packet, mesh.packet_count)));
        if let (Some(wide), Some(packets)) = (wide, packets) {
            refit_wide(wide, packets, records, workers);
        }
    }
    let boxes: Vec<Option<Bounds>> = edit
        .instances
        .as_deref()
        .unwrap_or(&[])
        .iter()
        .map(|instance| {
            let mesh: &MeshRecord = meshes.get(instance.mesh_index as usize)?;
            let root = edit.nodes.get(mesh.first_node as usize)?;
            instance_world_box(&instance.object_to_world, (root.min, root.max))
        })
        .collect();
    if let Some(top_nodes) = edit.top_nodes.as_deref_mut() {
        refit_top_binary(top_nodes, &boxes);
    }
    if let Some(top_wide_nodes) = edit.top_wide_nodes.as_deref_mut() {
        refit_top_wide(top_wide_nodes, &boxes);
    }
}

/// The indices `first .. first + count` (empty where the sum overflows).
fn mesh_range(first: u32, count: u32) -> std::ops::Range<usize> {
    let first = first as usize;
    first..first.checked_add(count as usize).unwrap_or(first)
}
