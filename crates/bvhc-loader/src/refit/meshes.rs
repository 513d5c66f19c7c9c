//! Refitting a two-level file: each mesh is a one-level tree of its own over its ranges of the sections, with
//! indices relative to them (`format-spec/bvh-1.md` 5.10), so each mesh's binary and wide trees are refit as a
//! one-level file's are, on the mesh's sub-arrays; then every instance takes the world box of its mesh's new root
//! (as the writer computes it, [`instance_world_box`]) and both top trees are refit bottom up
//! (`refit::instances`). The positions are the records', in each mesh's object space (a flattened mesh's records
//! are in world space, an instanced mesh's in the space its instances map).

use crate::binary::refit::{NewRecords, refit_binary};
use crate::error::Error;
use crate::format::{Bounds, EMPTY_BOUNDS, MeshRecord, PackedTriangle, TriangleFold};
use crate::open::edit::SectionsMut;
use crate::open::view::BvhView;
use crate::open::view_mut::BvhViewMut;
use crate::parallel::Workers;
use crate::ray::transform::instance_world_box;
use crate::refit::instances::{refit_top_binary, refit_top_wide};
use crate::refit::positions::MovedRecords;
use crate::refit::report::{RefitReport, RefitSums};
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

/// Per mesh of a two-level file, whether any of its records moves to `moved` (empty for a one-level file).
pub(super) fn moving_meshes(view: &BvhView<'_>, moved: &MovedRecords<'_>) -> Vec<bool> {
    let Some(sections) = view.two_level() else { return Vec::new() };
    sections.meshes.iter().map(|mesh| moved.moves_any(mesh_range(mesh.first_triangle, mesh.triangle_count))).collect()
}

/// Checks that every instance's world box fits f32 once its mesh is moved to `moved`: each moving mesh's new root
/// box (the box of its records as moved, which the refit gives its root; `moves` flags the moving meshes) mapped
/// by the instance. An error naming the first instance whose box does not fit, before anything is written.
pub(super) fn check_world_boxes(view: &BvhView<'_>, moved: &MovedRecords<'_>, moves: &[bool]) -> Result<(), Error> {
    let Some(sections) = view.two_level() else { return Ok(()) };
    let records = view.triangles();
    let mut last_range = 0;
    let roots: Vec<Bounds> = sections
        .meshes
        .iter()
        .zip(moves)
        .map(|(mesh, &moves)| {
            let range = mesh_range(mesh.first_triangle, mesh.triangle_count);
            if !moves {
                // Its root and its instances' world boxes stay as the file holds them.
                return view.nodes().get(mesh.first_node as usize).map_or(EMPTY_BOUNDS, |root| (root.min, root.max));
            }
            let mut fold = TriangleFold::EMPTY;
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

/// Refits every mesh of `edit`'s two-level file that `moves` (per mesh) to `new` (positions of all of the file's
/// records, in record order), each on up to `workers`' threads, then the instances' world boxes and the top
/// trees; a mesh none of whose records moves keeps its trees untouched, so a frame that moves instances and a
/// small deforming mesh costs that mesh's refit, not the scene's. Ranges outside their sections (a file that does
/// not verify, V41) are passed over rather than panic.
pub(super) fn refit_meshes(
    edit: &mut SectionsMut<'_>,
    new: &(impl NewRecords + ?Sized),
    moves: &[bool],
    workers: Workers,
) {
    let Some(meshes) = edit.meshes else { return };
    for (mesh, _) in meshes.iter().zip(moves).filter(|(_, moves)| **moves) {
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

/// One mesh's new positions, read by the file's record index (the mesh's records start at `first`).
struct OneMesh<'a> {
    positions: &'a [[[f32; 3]; 3]],
    first: usize,
}

impl NewRecords for OneMesh<'_> {
    #[inline(always)]
    fn write(&self, first: usize, records: &mut [PackedTriangle]) -> Bounds {
        self.positions[first.saturating_sub(self.first).min(self.positions.len())..].write(0, records)
    }
}

impl BvhViewMut<'_> {
    /// Moves the records of mesh `mesh` of a two-level file to `positions` (one triangle a record of that mesh,
    /// in its record order and its object space) and refits that mesh's binary and wide trees, its instances'
    /// world boxes and both top trees, on up to `threads` threads (0 counts as 1); every other mesh is left
    /// untouched, so the work is the mesh's whatever the rest of the file holds (a deforming mesh beside large
    /// rigid ones that instances move: [`BvhViewMut::move_instances_in_frame`]). The checksums are left as
    /// [`BvhViewMut::refit`] leaves them. Returns the report of a two-level file (no costs, rule V37).
    ///
    /// Refused, with the file unchanged: a one-level file, a mesh that does not exist, a count other than the
    /// mesh's records, a coordinate that is not finite, references of one triangle (split references) given
    /// different positions, and an instance whose world box would not fit f32, each naming it.
    pub fn refit_mesh(&mut self, mesh: u32, positions: &[[[f32; 3]; 3]], threads: usize) -> Result<RefitReport, Error> {
        let view = self.view();
        let Some(sections) = view.two_level() else {
            return Err(Error::Refit("a one-level file has no meshes: refit it whole (BvhViewMut::refit)".into()));
        };
        let count = sections.meshes.len();
        let record = sections
            .meshes
            .get(mesh as usize)
            .ok_or_else(|| Error::Refit(format!("mesh {mesh}: the file has {count} meshes")))?;
        let range = mesh_range(record.first_triangle, record.triangle_count);
        let moved = MovedRecords::Triangles(positions);
        moved.check(range.len()).map_err(|e| match e {
            Error::Refit(why) => Error::Refit(format!("mesh {mesh}: {why}")),
            other => other,
        })?;
        if let (true, Some(ids)) = (view.has_split_references(), view.triangle_ids()) {
            moved.check_references_agree(ids.get(range.clone()).unwrap_or(&[]))?;
        }
        let mut fold = TriangleFold::EMPTY;
        for vertices in positions {
            fold.add(vertices);
        }
        for (index, instance) in sections.instances.iter().enumerate().filter(|(_, i)| i.mesh_index == mesh) {
            if instance_world_box(&instance.object_to_world, fold.bounds()).is_none() {
                return Err(Error::Refit(format!(
                    "instance {index}: the world box of its moved mesh {mesh} does not fit f32 (refit nothing)"
                )));
            }
        }
        let mut moves = vec![false; count];
        moves[mesh as usize] = true;
        let workers = Workers::new(threads);
        let mut edit = self.edit()?;
        refit_meshes(&mut edit, &OneMesh { positions, first: range.start }, &moves, workers);
        edit.end_without_checksums();
        Ok(RefitReport::of(&self.view(), &RefitSums::default()))
    }
}
