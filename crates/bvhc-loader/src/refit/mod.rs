//! Refitting a file to moved triangles in place ([`BvhViewMut::refit`], [`BvhFile::refit`] for an owned one): the triangle records take the new positions
//! (per record, or per source vertex of each primitive, [`RefitPositions`]), and every layout the file has
//! recomputes its boxes bottom up over the same tree (`binary::refit`, `wide::refit`, `gpu::refit`), as skinned or
//! morphed meshes need each frame: the tree's shape, its order and every other section stay, so a refit to the
//! file's own positions gives its bytes back (but for the sign of a zero bound), and the hits of a refit file are
//! those of its new triangles. The refit tree's costs come back beside the file's own ([`RefitReport`]), for a
//! [`RebuildPolicy`] to decide when to convert again.

mod instances;
mod meshes;
mod positions;
mod report;

pub use positions::RefitPositions;
pub use report::{RebuildPolicy, RefitReport};

use report::RefitSums;

use crate::binary::refit::refit_binary;
use crate::error::Error;
use crate::format::Affine3x4;
use crate::format::cost::{AreaSums, box_area};
use crate::gpu::refit::refit_gpu;
use crate::open::file::BvhFile;
use crate::open::view_mut::BvhViewMut;
use crate::parallel::Workers;
use crate::wide::refit::refit_wide;
use positions::MovedRecords;

impl BvhViewMut<'_> {
    /// Moves the triangle records to `positions` and refits the file's layouts to them, on up to `threads`
    /// threads (the caller's included; 0 counts as 1): the binary nodes' boxes, the wide slots' boxes and packet
    /// lanes, the GPU nodes' quantized boxes and triangles, each bottom up over the file's own tree. The result
    /// is the same for any thread count. Returns the refit tree's costs beside those the file was converted with
    /// ([`RefitReport`]). The metadata's costs then still describe the converted pose, and the checksums the bytes
    /// before the refit (hashing the file each frame would buy nothing a tracer reads): a file that must pass
    /// `verify` (one to ship) is `BvhFile::rewritten` (feature `write`), which recomputes both.
    ///
    /// A file with split references (its leaves hold clipped pieces of triangles) refits each reference to its
    /// whole moved triangle: correct (every rule on split references asks a leaf's box to meet or cover its
    /// pieces, and a box of the whole triangle does), but the pieces' tighter boxes are lost, so its cost ratio
    /// starts above 1 even at the file's own positions (`docs/loader.md` measures it); convert meshes meant to
    /// deform with `--no-splits` or `--no-splits-deforming`. The references of one triangle (one id) must move
    /// alike.
    ///
    /// In a two-level file the records are each mesh's, in the mesh's object space (a flattened mesh's records in
    /// world space, an instanced mesh's in the space its instances map): each mesh's trees are refit over its own
    /// ranges, then every instance takes its moved mesh's world box and both top trees are refit; a mesh none of
    /// whose records moves (positions per source vertex that leave each of its ranges `None`, as for the rigid
    /// meshes of an animation, whose instances move instead) keeps its trees untouched, at no cost. A two-level
    /// file states no costs (rule V37), so its report has none.
    ///
    /// Refused, with the file unchanged: a file with split references but no ids, references of one triangle
    /// given different positions (naming both records), positions that do not fit the file (a count other than
    /// the records' or the source ranges', a source vertex index past its range's positions, a file without
    /// source vertices for [`RefitPositions::SourceVertices`]), a coordinate that is not finite, each naming the
    /// record, range or vertex, and an instance whose moved mesh's world box does not fit f32. An error from the
    /// GPU layout (a box too large for its grid) leaves the file partly refit: refit a copy where that may
    /// happen.
    pub fn refit(&mut self, positions: RefitPositions<'_>, threads: usize) -> Result<RefitReport, Error> {
        let view = self.view();
        let split = view.has_split_references();
        if split && view.triangle_ids().is_none() {
            return Err(Error::Refit(
                "the file has split references but no triangle ids, so a moved triangle's references cannot be \
                 told apart from other triangles'; convert with --no-splits (or without --no-ids)"
                    .into(),
            ));
        }
        let moved = MovedRecords::new(positions, view.source_table(), view.triangle_ids(), view.source_vertices())?;
        moved.check(view.triangles().len())?;
        if let (true, Some(ids)) = (split, view.triangle_ids()) {
            moved.check_references_agree(ids)?;
        }
        let moves = meshes::moving_meshes(&view, &moved);
        meshes::check_world_boxes(&view, &moved, &moves)?;
        let workers = Workers::new(threads);
        let mut edit = self.edit()?;
        let moved = MovedRecords::new(positions, edit.source_table, edit.triangle_ids, edit.source_vertices)?;
        if edit.meshes.is_some() {
            match moved {
                MovedRecords::Triangles(triangles) => meshes::refit_meshes(&mut edit, triangles, &moves, workers),
                _ => meshes::refit_meshes(&mut edit, &moved, &moves, workers),
            }
            edit.end_without_checksums();
            return Ok(RefitReport::of(&self.view(), &RefitSums::default()));
        }
        let binary = match moved {
            // The common case compiled on its own, its records' copies inlined into the tree's walk.
            MovedRecords::Triangles(triangles) => refit_binary(edit.nodes, edit.triangles, triangles, workers),
            _ => refit_binary(edit.nodes, edit.triangles, &moved, workers),
        };
        let root_area = edit.nodes.first().map_or(0.0, |root| box_area(&root.min, &root.max));
        let triangles = &*edit.triangles;
        let wide = match (edit.wide_nodes.as_deref_mut(), edit.triangle_packets.as_deref_mut()) {
            (Some(nodes), Some(packets)) => refit_wide(nodes, packets, triangles, workers),
            _ => AreaSums::default(),
        };
        if let (Some(nodes), Some(gpu_triangles)) = (edit.gpu_nodes.as_deref_mut(), edit.gpu_triangles.as_deref_mut()) {
            refit_gpu(nodes, gpu_triangles, triangles, workers)?;
        }
        edit.end_without_checksums();
        Ok(RefitReport::of(&self.view(), &RefitSums { root_area, binary, wide }))
    }
}

impl BvhFile {
    /// [`BvhViewMut::refit`] of the file's bytes.
    pub fn refit(&mut self, positions: RefitPositions<'_>, threads: usize) -> Result<RefitReport, Error> {
        self.view_mut().refit(positions, threads)
    }

    /// [`BvhViewMut::refit`] to one triangle a record (`v0`, `v1`, `v2` in record order), on one thread.
    pub fn refit_triangles(&mut self, positions: &[[[f32; 3]; 3]]) -> Result<RefitReport, Error> {
        self.refit(RefitPositions::Triangles(positions), 1)
    }

    /// [`BvhViewMut::move_instances`] of the file's bytes.
    pub fn move_instances(&mut self, moves: &[(u32, Affine3x4)]) -> Result<(), Error> {
        self.view_mut().move_instances(moves)
    }

    /// [`BvhViewMut::refit_mesh`] of the file's bytes.
    pub fn refit_mesh(&mut self, mesh: u32, positions: &[[[f32; 3]; 3]], threads: usize) -> Result<RefitReport, Error> {
        self.view_mut().refit_mesh(mesh, positions, threads)
    }

    /// [`BvhViewMut::move_instances_in_frame`] of the file's bytes.
    pub fn move_instances_in_frame(&mut self, moves: &[(u32, Affine3x4)]) -> Result<(), Error> {
        self.view_mut().move_instances_in_frame(moves)
    }
}
