//! Refitting an owned file to moved triangles ([`BvhFile::refit_triangles`]): the triangle records take the new
//! positions, and every layout the file has recomputes its boxes bottom up over the same tree (`binary::refit`,
//! `wide::refit`, `gpu::refit`), as skinned or morphed meshes need each frame: the tree's shape, its order and
//! every other section stay, so a refit to the file's own positions gives its bytes back (but for the sign of a
//! zero bound), and the hits of a refit file are those of its new triangles.

use crate::binary::refit::refit_binary;
use crate::error::Error;
use crate::format::PackedTriangle;
use crate::gpu::refit::refit_gpu;
use crate::open::file::BvhFile;
use crate::wide::refit::refit_wide;

impl BvhFile {
    /// Moves every triangle record to `positions` (one triangle a record, in record order: `v0`, `v1`, `v2`) and
    /// refits the file's layouts to them: the binary nodes' boxes, the wide slots' boxes and packet lanes, the GPU
    /// nodes' quantized boxes and triangles, each bottom up over the file's own tree, with the checksums
    /// recomputed ([`BvhFile::edit`]). The metadata's costs then describe the old positions: a file that must
    /// pass `verify` (one to ship) is `BvhFile::rewritten` (feature `write`), which recomputes them.
    ///
    /// Refused, with the file unchanged: a two-level file (its meshes are placed by instances, whose top tree a
    /// refit of the meshes would leave stale), a file with split references (its leaves hold clipped pieces of
    /// triangles, whose boxes are not the triangles' own; convert with `--no-splits` for meshes meant
    /// to deform), a count of positions other than the records', or a coordinate that is not finite (naming the
    /// record). An error from the GPU layout (a box too large for its grid) leaves the file partly refit: refit
    /// a copy where that may happen.
    pub fn refit_triangles(&mut self, positions: &[[[f32; 3]; 3]]) -> Result<(), Error> {
        let view = self.view();
        if view.two_level().is_some() {
            return Err(Error::Refit(
                "a two-level file's meshes are placed by instances; refit is for one-level files".into(),
            ));
        }
        if view.has_split_references() {
            return Err(Error::Refit(
                "the file has split references (leaves of clipped triangle pieces); convert with --no-splits".into(),
            ));
        }
        let count = view.triangles().len();
        if positions.len() != count {
            return Err(Error::Refit(format!("{} positions for {count} triangle records", positions.len())));
        }
        if let Some(record) = positions.iter().position(|t| t.iter().flatten().any(|c| !c.is_finite())) {
            return Err(Error::Refit(format!("triangle record {record}: a coordinate that is not finite")));
        }
        let mut edit = self.edit()?;
        for (record, vertices) in edit.triangles.iter_mut().zip(positions) {
            *record = PackedTriangle { vertices: *vertices };
        }
        let triangles: &[PackedTriangle] = edit.triangles;
        refit_binary(edit.nodes, triangles);
        if let (Some(nodes), Some(packets)) = (edit.wide_nodes.as_deref_mut(), edit.triangle_packets.as_deref_mut()) {
            refit_wide(nodes, packets, triangles);
        }
        if let (Some(nodes), Some(gpu_triangles)) = (edit.gpu_nodes.as_deref_mut(), edit.gpu_triangles.as_deref_mut()) {
            refit_gpu(nodes, gpu_triangles, triangles)?;
        }
        Ok(())
    }
}
