//! The triangle soup every importer produces, and the builder that fills it.
//!
//! Importers hand the builder one *primitive instance* at a time (a glTF primitive placed by one node and
//! instance, an OBJ model, a PLY file): its triangles as local vertex indices and a function that gives a
//! vertex's world-space position. The builder
//! * numbers the primitive's triangles with consecutive **source ids**, dropped ones included, so that a
//!   triangle's index within its primitive is `source_id - first_source_triangle` of its [`SourceRange`];
//! * drops degenerate triangles (a repeated vertex index, or zero area in world space) unless told to keep
//!   them, and counts them either way;
//! * copies only the vertices that kept triangles use, so unreferenced vertices cost nothing downstream;
//! * records each kept triangle's source vertex indices (the primitive's own numbering, in the stored corner
//!   order), which the writer stores as the `source_vertices` section.

use crate::import::limits::Meter;
use crate::import::memory::{MemoryLimit, usable_memory};
use crate::import::{ErrorKind, ImportLimits};
use bvhc_loader::format::NO_INDEX;
use bvhc_loader::format::SourceRange;

use super::report::{Degenerate, ImportReport};

/// World-space triangles with provenance: the input of the builders and of the writer's id sections.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleSoup {
    /// Vertex positions in world space.
    pub positions: Vec<[f32; 3]>,
    /// Vertex indices of each triangle, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Each triangle's source id (see the module documentation).
    pub source_ids: Vec<u32>,
    /// Each triangle's vertex indices in its source primitive, in the order of `triangles` (so swapped with
    /// them in a mirrored placement): `format-spec/bvh-1.md` 5.9.
    pub source_vertices: Vec<[u32; 3]>,
    /// The source ranges, ascending and disjoint; every source id lies in one of them.
    pub sources: Vec<SourceRange>,
    /// For each source range, whether its material may cut its triangles out (a glTF primitive whose material's
    /// `alphaMode` is `MASK` or `BLEND`); the converter marks them in the `triangle_flags` section (format 1.5).
    pub cut_out: Vec<bool>,
    /// For each source range, whether its geometry is meant to deform (a glTF primitive of a skinned node, or
    /// with morph targets): `--no-splits-deforming` keeps its triangles whole, for a tight refit.
    pub deforming: Vec<bool>,
}

impl TriangleSoup {
    /// The three vertex positions of triangle `i`.
    pub fn vertices(&self, i: usize) -> [[f32; 3]; 3] {
        self.triangles[i].map(|v| self.positions[v as usize])
    }

    /// Every triangle's vertex positions, in order.
    pub fn triangle_vertices(&self) -> Vec<[[f32; 3]; 3]> {
        (0..self.triangles.len()).map(|i| self.vertices(i)).collect()
    }

    /// The source range that a source id belongs to.
    pub fn source_of(&self, source_id: u32) -> Option<&SourceRange> {
        self.sources.get(self.source_index_of(source_id)?)
    }

    /// The index in [`TriangleSoup::sources`] of the range a source id belongs to.
    pub fn source_index_of(&self, source_id: u32) -> Option<usize> {
        let after = self.sources.partition_point(|r| r.first_source_triangle <= source_id);
        let index = after.checked_sub(1)?;
        let range = self.sources.get(index)?;
        (source_id - range.first_source_triangle < range.source_triangle_count).then_some(index)
    }

    /// Whether the triangle of `source_id` comes from a primitive meant to deform.
    pub fn is_deforming(&self, source_id: u32) -> bool {
        self.source_index_of(source_id).and_then(|i| self.deforming.get(i).copied()).unwrap_or(false)
    }

    /// Whether the triangle of `source_id` comes from a material that may cut it out.
    pub fn is_cut_out(&self, source_id: u32) -> bool {
        self.source_index_of(source_id).and_then(|i| self.cut_out.get(i).copied()).unwrap_or(false)
    }
}

/// Where a primitive instance came from; `NO_INDEX` where a field does not apply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Provenance {
    /// glTF node.
    pub node_index: u32,
    /// glTF mesh, or OBJ model.
    pub mesh_index: u32,
    /// glTF primitive within the mesh.
    pub primitive_index: u32,
    /// `EXT_mesh_gpu_instancing` instance.
    pub instance_index: u32,
}

impl Provenance {
    /// No node, mesh, primitive or instance (a PLY file).
    pub const NONE: Provenance =
        Provenance { node_index: NO_INDEX, mesh_index: NO_INDEX, primitive_index: NO_INDEX, instance_index: NO_INDEX };
}

/// One primitive instance handed to [`SoupBuilder::add`].
pub struct PrimitiveInstance<'a, S: Fn(u32) -> [f64; 3], P: Fn(u32) -> [f32; 3]> {
    /// Where it came from.
    pub provenance: Provenance,
    /// Number of vertices the local indices refer to; every index must be below it.
    pub vertex_count: usize,
    /// Position of a local vertex in the source's own coordinates and precision (for the zero-area test that
    /// the source's authors would make).
    pub source_position: S,
    /// World-space position of a local vertex.
    pub position: P,
    /// Triangles as local vertex indices, in the primitive's order.
    pub triangles: &'a [[u32; 3]],
    /// The source's number of each local vertex (an OBJ model's vertex -> the file's `v` record), where it
    /// differs from the local index; `None`: the local indices are the source's (glTF, PLY).
    pub source_vertex_index: Option<&'a [u32]>,
    /// Reverse the winding (the placement has a negative determinant).
    pub flip_winding: bool,
    /// Whether this is the first placement of this mesh data (counted in the "unique" figures).
    pub first_use: bool,
    /// Whether the primitive's material may cut its triangles out (glTF `alphaMode` `MASK` or `BLEND`).
    pub cut_out: bool,
    /// Whether the primitive is meant to deform (a skinned node's, or one with morph targets).
    pub deforming: bool,
}

/// Fills a [`TriangleSoup`] and the counts of an [`ImportReport`].
pub struct SoupBuilder {
    soup: TriangleSoup,
    keep_degenerate: bool,
    next_source_id: u64,
    /// Local vertex -> soup vertex for the current primitive (`u32::MAX`: not copied yet); reused.
    remap: Vec<u32>,
    /// The figures for the report.
    pub report: ImportReport,
    /// Triangles placed so far against [`ImportLimits::max_triangles`].
    triangle_budget: Meter,
    /// Mesh placements so far against [`ImportLimits::max_placements`].
    pub(crate) placement_budget: Meter,
    /// The conversion's memory budget, resolved once ([`MemoryLimit::Detect`] read at the start).
    memory: MemoryLimit,
    /// The conversion's estimated peak bytes a placed triangle.
    peak_bytes_per_triangle: u64,
}

impl SoupBuilder {
    /// An empty builder.
    pub fn new(keep_degenerate: bool, limits: &ImportLimits, peak_bytes_per_triangle: u64) -> SoupBuilder {
        SoupBuilder {
            soup: TriangleSoup::default(),
            keep_degenerate,
            next_source_id: 0,
            remap: Vec::new(),
            report: ImportReport::default(),
            triangle_budget: Meter::new(limits.max_triangles, "triangles", "--max-triangles"),
            placement_budget: Meter::new(limits.max_placements, "mesh placements", "--max-placements"),
            memory: match limits.max_memory {
                MemoryLimit::Detect => usable_memory().map_or(MemoryLimit::Unlimited, MemoryLimit::Detected),
                other => other,
            },
            peak_bytes_per_triangle,
        }
    }

    /// Refuses a scene of `triangles` placed triangles whose conversion would need more memory than the budget.
    pub fn check_memory(&self, triangles: u64) -> Result<(), String> {
        self.memory.check(triangles, self.peak_bytes_per_triangle)
    }

    /// [`SoupBuilder::check_memory`] for an import that also holds `decoded_bytes` of decoded input (a glTF's
    /// accessors, kept while its meshes are placed).
    pub fn check_memory_with(&self, triangles: u64, decoded_bytes: u64) -> Result<(), String> {
        self.memory.check_with(triangles, self.peak_bytes_per_triangle, decoded_bytes)
    }

    /// Adds one primitive instance. Fails when the scene outgrows the triangle budget or u32 ids or indices,
    /// or memory for it cannot be had; the budget is checked before anything is allocated.
    pub fn add<S, P>(&mut self, primitive: PrimitiveInstance<'_, S, P>) -> Result<(), (ErrorKind, String)>
    where
        S: Fn(u32) -> [f64; 3],
        P: Fn(u32) -> [f32; 3],
    {
        let count = primitive.triangles.len();
        if count == 0 {
            return Ok(());
        }
        if let Some(t) =
            primitive.triangles.iter().position(|t| t.iter().any(|&v| v as usize >= primitive.vertex_count))
        {
            let message = format!("triangle {t}: vertex index out of range ({} vertices)", primitive.vertex_count);
            return Err((ErrorKind::Invalid, message));
        }
        if primitive.source_vertex_index.is_some_and(|numbers| numbers.len() < primitive.vertex_count) {
            return Err((ErrorKind::Invalid, "a vertex has no source number".to_string()));
        }
        self.triangle_budget.take(count as u64).map_err(|e| (ErrorKind::Limit, e))?;
        self.check_memory(self.report.source_triangles.saturating_add(count as u64))
            .map_err(|e| (ErrorKind::Limit, e))?;
        let soup = &mut self.soup;
        let reserved = soup
            .triangles
            .try_reserve(count)
            .and_then(|()| soup.source_ids.try_reserve(count))
            .and_then(|()| soup.source_vertices.try_reserve(count));
        reserved.map_err(|_| (ErrorKind::Limit, format!("out of memory adding {count} triangles")))?;
        let first = self.next_source_id;
        self.next_source_id += count as u64;
        if self.next_source_id > u64::from(u32::MAX) {
            return Err((ErrorKind::Limit, "the scene has more than 2^32 - 1 triangles".to_string()));
        }
        let p = primitive.provenance;
        self.soup.sources.push(SourceRange {
            first_source_triangle: first as u32,
            source_triangle_count: count as u32,
            file_index: 0,
            node_index: p.node_index,
            mesh_index: p.mesh_index,
            primitive_index: p.primitive_index,
            instance_index: p.instance_index,
            reserved: 0,
        });
        self.soup.cut_out.push(primitive.cut_out);
        self.soup.deforming.push(primitive.deforming);
        self.remap.clear();
        self.remap.resize(primitive.vertex_count, u32::MAX);
        let report = &mut self.report;
        report.source_triangles += count as u64;
        if primitive.first_use {
            report.unique_source_triangles += count as u64;
        }
        let mut referenced = 0usize;
        for (k, &[a, b, c]) in primitive.triangles.iter().enumerate() {
            if primitive.first_use {
                for v in [a, b, c] {
                    // Counted before dropping: a vertex used only by degenerate triangles is still referenced.
                    if self.remap[v as usize] == u32::MAX {
                        self.remap[v as usize] = u32::MAX - 1;
                        referenced += 1;
                    }
                }
            }
            let repeated = a == b || b == c || a == c;
            let positions = [a, b, c].map(&primitive.position);
            let kind = if repeated {
                Some(Degenerate::RepeatedIndex)
            } else if is_zero_area_f64(&[a, b, c].map(&primitive.source_position)) {
                Some(Degenerate::ZeroArea)
            } else if is_zero_area(&positions) {
                Some(Degenerate::ZeroAreaAfterPlacement)
            } else {
                None
            };
            if let Some(kind) = kind {
                report.count_degenerate(kind, primitive.first_use);
                if !self.keep_degenerate {
                    continue;
                }
            }
            let mut triangle = [0u32; 3];
            for (slot, (v, position)) in triangle.iter_mut().zip([a, b, c].into_iter().zip(positions)) {
                let mapped = &mut self.remap[v as usize];
                if *mapped >= u32::MAX - 1 {
                    *mapped = u32::try_from(self.soup.positions.len())
                        .ok()
                        .filter(|&index| index < u32::MAX - 1)
                        .ok_or_else(|| (ErrorKind::Limit, "the scene has more than 2^32 - 2 vertices".to_string()))?;
                    self.soup.positions.push(position);
                }
                *slot = *mapped;
            }
            let mut source_vertices = [a, b, c];
            if let Some(numbers) = primitive.source_vertex_index {
                source_vertices = source_vertices.map(|v| numbers[v as usize]);
            }
            if primitive.flip_winding {
                triangle.swap(1, 2);
                source_vertices.swap(1, 2);
            }
            self.soup.triangles.push(triangle);
            self.soup.source_vertices.push(source_vertices);
            self.soup.source_ids.push(first as u32 + k as u32);
        }
        if primitive.first_use {
            report.unreferenced_vertices += (primitive.vertex_count - referenced) as u64;
        }
        Ok(())
    }

    /// Adds a mesh that is placed once, as it is (OBJ models, PLY files): its source positions, the same
    /// rounded to f32, its triangles, and the source's number of each vertex where it differs from its index;
    /// counts the placement and the file's triangles.
    pub fn add_mesh_in_place(
        &mut self,
        provenance: Provenance,
        source: &[[f64; 3]],
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
        source_vertex_index: Option<&[u32]>,
    ) -> Result<(), (ErrorKind, String)> {
        self.add(PrimitiveInstance {
            provenance,
            vertex_count: positions.len(),
            source_position: |v| source[v as usize],
            position: |v| positions[v as usize],
            triangles,
            source_vertex_index,
            flip_winding: false,
            first_use: true,
            cut_out: false,
            deforming: false,
        })?;
        self.report.mesh_placements += 1;
        self.report.file_mesh_triangles += triangles.len() as u64;
        Ok(())
    }

    /// Triangles in the soup so far.
    pub fn triangle_count(&self) -> usize {
        self.soup.triangles.len()
    }

    /// The finished soup and report.
    pub fn finish(self) -> (TriangleSoup, ImportReport) {
        let mut report = self.report;
        report.triangles = self.soup.triangles.len() as u64;
        report.vertices = self.soup.positions.len() as u64;
        (self.soup, report)
    }
}

/// Whether an f32 triangle's area is exactly zero, with the cross product taken in f64 (so no non-degenerate
/// f32 triangle is misjudged through underflow). Such a triangle can never be hit by a watertight ray test.
pub fn is_zero_area(v: &[[f32; 3]; 3]) -> bool {
    is_zero_area_f64(&v.map(|p| p.map(f64::from)))
}

/// Whether the triangle's three vertices are exactly collinear (or coincide): its cross product is zero in
/// exact arithmetic. Decided by Shewchuk's adaptive exact orientation predicate (the `robust` crate) on the
/// three axis-aligned projections, so the verdict does not depend on the order of the vertices, unlike an f64
/// cross product, whose edge differences round (a vertex at 1e17 next to one at 1 once made a real triangle
/// look flat). Exact for coordinates within the f32 range, which every importer checks.
pub fn is_zero_area_f64(v: &[[f64; 3]; 3]) -> bool {
    let projected = |a: usize, b: usize| {
        let p = |i: usize| robust::Coord { x: v[i][a], y: v[i][b] };
        robust::orient2d(p(0), p(1), p(2)) == 0.0
    };
    projected(0, 1) && projected(1, 2) && projected(2, 0)
}
