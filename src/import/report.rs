//! What an import read, skipped and dropped.

use serde::Serialize;

/// Counts of an import. "Unique" figures count each mesh's data once (a glTF mesh placed by several nodes or
/// instances counts once); the others count every placement.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ImportReport {
    /// Triangles in the soup (an instanced mesh's once).
    pub triangles: u64,
    /// Triangles in the scene as placed: those of the soup, with an instanced mesh's counted once a placement.
    pub placed_triangles: u64,
    /// glTF meshes kept instanced (format 1.3); 0 for a flattened scene.
    pub instanced_meshes: u64,
    /// Vertices in the soup (only those that kept triangles use).
    pub vertices: u64,
    /// Triangles of every placed primitive, before dropping degenerate ones.
    pub source_triangles: u64,
    /// Triangles counting each mesh's data once, before dropping.
    pub unique_source_triangles: u64,
    /// Triangles with a repeated vertex index (dropped unless kept), over all placements.
    pub degenerate_repeated_index: u64,
    /// Triangles with distinct indices but zero area in the source's own coordinates and precision (dropped
    /// unless kept), over all placements.
    pub degenerate_zero_area: u64,
    /// Triangles with non-zero source area whose area becomes exactly zero after the transform to world space
    /// and the rounding to f32 (dropped unless kept: no ray can hit them), over all placements.
    pub degenerate_zero_area_after_placement: u64,
    /// `degenerate_repeated_index` counting each mesh's data once.
    pub unique_degenerate_repeated_index: u64,
    /// `degenerate_zero_area` counting each mesh's data once.
    pub unique_degenerate_zero_area: u64,
    /// Triangles of every mesh in the file, placed or not, counted once each (from counts alone, without
    /// decoding unplaced meshes); for OBJ and PLY the same as `unique_source_triangles`.
    pub file_mesh_triangles: u64,
    /// Vertices no triangle refers to, counting each mesh's data once.
    pub unreferenced_vertices: u64,
    /// Primitives skipped because they are points or lines (glTF modes 0-3).
    pub skipped_point_and_line_primitives: u64,
    /// glTF primitives without a POSITION attribute (skipped).
    pub skipped_primitives_without_positions: u64,
    /// Placements of meshes (glTF node uses and instances; OBJ models; 1 for PLY).
    pub mesh_placements: u64,
    /// Placements by skinned nodes (their primitives posed by their joints, the node's own transform ignored).
    pub skinned_placements: u64,
}

impl ImportReport {
    /// Degenerate triangles over all placements.
    pub fn degenerate(&self) -> u64 {
        self.degenerate_repeated_index + self.degenerate_zero_area + self.degenerate_zero_area_after_placement
    }

    pub(super) fn count_degenerate(&mut self, kind: Degenerate, first_use: bool) {
        let (all, unique) = match kind {
            Degenerate::RepeatedIndex => {
                (&mut self.degenerate_repeated_index, Some(&mut self.unique_degenerate_repeated_index))
            }
            Degenerate::ZeroArea => (&mut self.degenerate_zero_area, Some(&mut self.unique_degenerate_zero_area)),
            Degenerate::ZeroAreaAfterPlacement => (&mut self.degenerate_zero_area_after_placement, None),
        };
        *all += 1;
        if let Some(unique) = unique.filter(|_| first_use) {
            *unique += 1;
        }
    }
}

/// Why a triangle is degenerate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Degenerate {
    /// Two of its vertex indices are equal.
    RepeatedIndex,
    /// Zero area in the source's coordinates.
    ZeroArea,
    /// Zero area only after placement in world space and rounding to f32.
    ZeroAreaAfterPlacement,
}
