//! From a hit back to the source scene's own vertices: [`BvhView::source_corners`] gives the primitive a hit
//! lies on (its source range), the source vertex indices of the record's three corners (the `source_vertices`
//! section of format 1.2, `format-spec/bvh-1.md` 5.9) and the hit's weight of each, and
//! [`SourceCorners::interpolate`] blends a renderer's own per-vertex attribute (normals, texture coordinates,
//! colours) with them, as Embree's `rtcInterpolate` does for its geometries.
//!
//! ```
//! use bvhc_loader::{BvhFile, Ray, Trace};
//!
//! // The golden quad of the format spec, written with its source vertices (a glTF primitive of 4 vertices).
//! let file = BvhFile::from_bytes(include_bytes!("../../tests/data/quad-v1.2.bvh"))?;
//! let view = file.view();
//! let hit = view.tracer().closest_hit(&Ray::new([0.25, 0.75, 1.0], [0.0, 0.0, -1.0])).expect("a hit");
//! let corners = view.source_corners(&hit).expect("the file has source vertices");
//! assert_eq!(corners.range.mesh_index, 0); // the source range says whose vertex arrays these are
//! // The primitive's TEXCOORD_0, which the renderer read from the glTF itself.
//! let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
//! assert_eq!(corners.interpolate(&uv), Some([0.25, 0.75]));
//! # Ok::<(), bvhc_loader::Error>(())
//! ```

use crate::format::{InstanceRecord, NO_INDEX, SourceRange};
use crate::open::view::BvhView;
use crate::ray::hit::Hit;

/// Where a hit lies in the source scene: see [`BvhView::source_corners`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourceCorners<'a> {
    /// The source range of the hit triangle: file, node, mesh, primitive and instance, which say whose vertex
    /// arrays [`SourceCorners::vertices`] index.
    pub range: &'a SourceRange,
    /// The hit triangle's source id.
    pub source_triangle_id: u32,
    /// The source vertex indices of the record's `v0`, `v1`, `v2` in that primitive.
    pub vertices: [u32; 3],
    /// The hit's weight of each: `[1 - u - v, u, v]`; they sum to 1 (within rounding).
    pub weights: [f32; 3],
    /// In a two-level file, the instance the hit names: a mesh placed many times is stored once, so its
    /// source range names no glTF node (nor `EXT_mesh_gpu_instancing` instance); the placement does.
    pub placement: Option<&'a InstanceRecord>,
}

impl SourceCorners<'_> {
    /// The glTF node that placed the hit triangle: the source range's, or for a mesh placed by instances the
    /// hit instance's; [`NO_INDEX`] for OBJ and PLY sources.
    pub fn node_index(&self) -> u32 {
        match (self.range.node_index, self.placement) {
            (NO_INDEX, Some(instance)) => instance.node_index,
            (node, _) => node,
        }
    }

    /// The `EXT_mesh_gpu_instancing` instance that placed the hit triangle, found as [`SourceCorners::node_index`]
    /// is; [`NO_INDEX`] when the node places its mesh once.
    pub fn gpu_instance_index(&self) -> u32 {
        match (self.range.instance_index, self.placement) {
            (NO_INDEX, Some(instance)) => instance.gpu_instance_index,
            (index, _) => index,
        }
    }

    /// `attribute` (one value per vertex of the primitive, indexed as the source indexes it) at the hit:
    /// `weights[0] attribute[vertices[0]] + weights[1] attribute[vertices[1]] + weights[2] attribute[vertices[2]]`,
    /// summed in f64 and rounded once to f32. `None` when an index is not below `attribute.len()` (an array of
    /// another primitive). Normals come out unnormalized, as with any interpolation.
    pub fn interpolate<const N: usize>(&self, attribute: &[[f32; N]]) -> Option<[f32; N]> {
        let values = [0, 1, 2].map(|corner| attribute.get(self.vertices[corner] as usize));
        let [Some(a), Some(b), Some(c)] = values else {
            return None;
        };
        let [wa, wb, wc] = self.weights.map(f64::from);
        Some(std::array::from_fn(|k| (wa * f64::from(a[k]) + wb * f64::from(b[k]) + wc * f64::from(c[k])) as f32))
    }
}

impl<'a> BvhView<'a> {
    /// The source primitive, source vertices and weights of `hit`'s corners, when the file has the
    /// `source_vertices` section (1.2, which bvhc writes by default for files with ids) and the hit's record
    /// is in it (and, in a two-level file, the hit's instance). The weights already account for mirrored placements: the section lists the source vertices in
    /// the record's corner order, whatever the source order was. O(log ranges).
    pub fn source_corners(&self, hit: &Hit) -> Option<SourceCorners<'a>> {
        let record = hit.triangle_index as usize;
        let vertices = self.source_vertices()?.get(record)?.indices;
        let source_triangle_id = *self.triangle_ids()?.get(record)?;
        let range = self.source_range_of(source_triangle_id)?;
        let placement = match (hit.instance_index, self.two_level()) {
            (Some(index), Some(sections)) => Some(sections.placement(index)?.0),
            (None, None) => None,
            _ => return None,
        };
        let weights = [1.0 - hit.u - hit.v, hit.u, hit.v];
        Some(SourceCorners { range, source_triangle_id, vertices, weights, placement })
    }
}
