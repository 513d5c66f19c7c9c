//! The typed groups of sections a view hands out: the wide BVH's two sections, the GPU layout's two, and a
//! two-level file's three. Each group is present as a whole or not at all (rule V8).

use crate::error::{Rule, Violation, violation};
use crate::format::{
    GpuNode, GpuTriangle, InstanceRecord, MeshRecord, PackedNode, PackedTriangle, SECTION_FLAG_SPLIT_REFERENCES,
    SectionEntry, SectionKind, SourceRange, SourceVertexIndices, TrianglePacket4, WideNode8,
};

/// The two sections of the wide BVH (since 1.1), which a file has together or not at all (rule V8).
#[derive(Clone, Copy, Debug)]
pub struct WideSections<'a> {
    /// The `wide_nodes` section; node 0 is the root.
    pub nodes: &'a [WideNode8],
    /// The `triangle_packets` section.
    pub packets: &'a [TrianglePacket4],
}

/// The GPU sections of a file (format 1.4): the compressed 8-wide nodes and their leaf triangles, which the
/// WGSL kernel ([`crate::gpu::shader`]) traces; [`crate::gpu::GpuLayoutTracer`] traces them on the CPU the same way.
#[derive(Clone, Copy, Debug)]
pub struct GpuSections<'a> {
    /// The `gpu_nodes` section; node 0 is the root.
    pub nodes: &'a [GpuNode],
    /// The `gpu_triangles` section, in leaf order.
    pub triangles: &'a [GpuTriangle],
}

/// The three sections of a two-level file (1.3), which a file has together or not at all (rule V8).
#[derive(Clone, Copy, Debug)]
pub struct TwoLevelSections<'a> {
    /// The `meshes` section: each mesh's ranges of the one-level sections.
    pub meshes: &'a [MeshRecord],
    /// The `instances` section; an instance's index here is what hits report.
    pub instances: &'a [InstanceRecord],
    /// The `top_nodes` section: a binary tree over the instances in world space, node 0 the root, each leaf
    /// one instance (`index` the instance, `count` 1).
    pub top_nodes: &'a [PackedNode],
    /// The `top_wide_nodes` section: the same tree 8-wide, each leaf slot `LEAF_BIT | instance`; empty in a
    /// file without wide sections.
    pub top_wide_nodes: &'a [WideNode8],
}

impl<'a> TwoLevelSections<'a> {
    /// The instance at `instance_index` and the mesh it places, when both exist.
    pub fn placement(&self, instance_index: u32) -> Option<(&'a InstanceRecord, &'a MeshRecord)> {
        let instance = self.instances.get(instance_index as usize)?;
        Some((instance, self.meshes.get(instance.mesh_index as usize)?))
    }

    /// Triangle records placed in world space: each instance's mesh's records, summed (with split references a
    /// triangle has several records).
    pub fn placed_record_count(&self) -> u64 {
        self.instances
            .iter()
            .filter_map(|i| self.meshes.get(i.mesh_index as usize))
            .map(|m| u64::from(m.triangle_count))
            .sum()
    }
}

/// Every section of this version a file holds, typed: the one list that the view's openings assemble, the
/// writer lays out ([`SectionSet::present`], in [`SectionKind::ALL`]'s order) and the accessors read.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SectionSet<'a> {
    pub nodes: &'a [PackedNode],
    pub triangles: &'a [PackedTriangle],
    pub triangle_ids: Option<&'a [u32]>,
    pub source_table: Option<&'a [SourceRange]>,
    pub source_vertices: Option<&'a [SourceVertexIndices]>,
    pub triangle_flags: Option<&'a [u8]>,
    pub metadata: Option<&'a [u8]>,
    pub wide: Option<WideSections<'a>>,
    pub gpu: Option<GpuSections<'a>>,
    pub two_level: Option<TwoLevelSections<'a>>,
    /// The triangles section's `SECTION_FLAG_SPLIT_REFERENCES`.
    pub split_references: bool,
}

/// Typed slices of a file's sections from their table entries: checked ([`CheckedSlices`]) or, for bytes
/// known to pass the structural rules, not ([`UncheckedSlices`]).
pub(crate) trait Slices<'a> {
    /// Section `entry` as elements of `T` (whose size is the kind's element size).
    fn typed<T: bytemuck::Pod>(&self, entry: &SectionEntry) -> Result<&'a [T], Violation>;
}

impl<'a> SectionSet<'a> {
    /// No section at all (what no valid file is).
    pub(crate) const EMPTY: SectionSet<'static> = SectionSet {
        nodes: &[],
        triangles: &[],
        triangle_ids: None,
        source_table: None,
        source_vertices: None,
        triangle_flags: None,
        metadata: None,
        wide: None,
        gpu: None,
        two_level: None,
        split_references: false,
    };

    /// The sections `entry` finds in a file, typed by `slices`; the nodes and triangles sections must be there.
    #[inline]
    pub(crate) fn assemble(
        entry: impl Fn(SectionKind) -> Option<SectionEntry>,
        slices: &impl Slices<'a>,
    ) -> Result<SectionSet<'a>, Violation> {
        fn optional<'a, T: bytemuck::Pod>(
            entry: Option<SectionEntry>,
            slices: &impl Slices<'a>,
        ) -> Result<Option<&'a [T]>, Violation> {
            entry.map(|e| slices.typed(&e)).transpose()
        }
        let required = |kind: SectionKind| {
            entry(kind).ok_or_else(|| violation(Rule::SectionMultiplicity, format!("no {} section", kind.name())))
        };
        let triangles_entry = required(SectionKind::Triangles)?;
        Ok(SectionSet {
            nodes: slices.typed(&required(SectionKind::Nodes)?)?,
            triangles: slices.typed(&triangles_entry)?,
            triangle_ids: optional(entry(SectionKind::TriangleIds), slices)?,
            source_table: optional(entry(SectionKind::SourceTable), slices)?,
            source_vertices: optional(entry(SectionKind::SourceVertices), slices)?,
            triangle_flags: optional(entry(SectionKind::TriangleFlags), slices)?,
            metadata: optional(entry(SectionKind::Metadata), slices)?,
            wide: match (
                optional(entry(SectionKind::WideNodes), slices)?,
                optional(entry(SectionKind::TrianglePackets), slices)?,
            ) {
                (Some(nodes), Some(packets)) => Some(WideSections { nodes, packets }),
                _ => None,
            },
            gpu: match (
                optional(entry(SectionKind::GpuNodes), slices)?,
                optional(entry(SectionKind::GpuTriangles), slices)?,
            ) {
                (Some(nodes), Some(triangles)) => Some(GpuSections { nodes, triangles }),
                _ => None,
            },
            two_level: match (
                optional(entry(SectionKind::Meshes), slices)?,
                optional(entry(SectionKind::Instances), slices)?,
                optional(entry(SectionKind::TopNodes), slices)?,
            ) {
                (Some(meshes), Some(instances), Some(top_nodes)) => Some(TwoLevelSections {
                    meshes,
                    instances,
                    top_nodes,
                    top_wide_nodes: optional(entry(SectionKind::TopWideNodes), slices)?.unwrap_or(&[]),
                }),
                _ => None,
            },
            split_references: triangles_entry.section_flags & SECTION_FLAG_SPLIT_REFERENCES != 0,
        })
    }

    /// The bytes and element count of the section of `kind`, when the set has it (an empty top wide tree is
    /// no section).
    #[cfg(feature = "write")]
    pub(crate) fn get(&self, kind: SectionKind) -> Option<(&'a [u8], usize)> {
        fn raw<T: bytemuck::Pod>(slice: &[T]) -> (&[u8], usize) {
            (bytemuck::cast_slice(slice), slice.len())
        }
        match kind {
            SectionKind::Nodes => Some(raw(self.nodes)),
            SectionKind::Triangles => Some(raw(self.triangles)),
            SectionKind::TriangleIds => self.triangle_ids.map(raw),
            SectionKind::SourceTable => self.source_table.map(raw),
            SectionKind::SourceVertices => self.source_vertices.map(raw),
            SectionKind::TriangleFlags => self.triangle_flags.map(raw),
            SectionKind::Metadata => self.metadata.map(raw),
            SectionKind::WideNodes => self.wide.map(|w| raw(w.nodes)),
            SectionKind::TrianglePackets => self.wide.map(|w| raw(w.packets)),
            SectionKind::GpuNodes => self.gpu.map(|g| raw(g.nodes)),
            SectionKind::GpuTriangles => self.gpu.map(|g| raw(g.triangles)),
            SectionKind::Meshes => self.two_level.map(|t| raw(t.meshes)),
            SectionKind::Instances => self.two_level.map(|t| raw(t.instances)),
            SectionKind::TopNodes => self.two_level.map(|t| raw(t.top_nodes)),
            SectionKind::TopWideNodes => {
                self.two_level.filter(|t| !t.top_wide_nodes.is_empty()).map(|t| raw(t.top_wide_nodes))
            }
        }
    }

    /// Every section the set has, in [`SectionKind::ALL`]'s order (the order the writer stores them): kind,
    /// bytes, element count.
    #[cfg(feature = "write")]
    pub(crate) fn present(&self) -> impl Iterator<Item = (SectionKind, &'a [u8], usize)> + '_ {
        SectionKind::ALL.into_iter().filter_map(|kind| self.get(kind).map(|(bytes, count)| (kind, bytes, count)))
    }
}

/// Slices checked for size and alignment (`bytemuck`), for bytes being opened.
pub(crate) struct CheckedSlices<'a>(pub &'a [u8]);

impl<'a> Slices<'a> for CheckedSlices<'a> {
    fn typed<T: bytemuck::Pod>(&self, entry: &SectionEntry) -> Result<&'a [T], Violation> {
        let start = entry.section_byte_offset as usize;
        let bytes = self.0.get(start..start.saturating_add(entry.section_byte_len as usize)).unwrap_or(&[]);
        bytemuck::try_cast_slice(bytes).map_err(|e| {
            violation(
                Rule::SectionKindLayout,
                format!("section at byte {}: cannot be viewed ({e})", entry.section_byte_offset),
            )
        })
    }
}

/// Slices built without a check, for bytes that opening accepted before.
pub(crate) struct UncheckedSlices<'a>(&'a [u8]);

impl<'a> UncheckedSlices<'a> {
    /// # Safety
    ///
    /// `bytes` must be a buffer that [`crate::BvhView::open`] accepts, and the entries later given to
    /// [`Slices::typed`] must be its table's, each of the kind whose element type is asked for.
    #[allow(unsafe_code)]
    pub(crate) unsafe fn new(bytes: &'a [u8]) -> UncheckedSlices<'a> {
        UncheckedSlices(bytes)
    }
}

impl<'a> Slices<'a> for UncheckedSlices<'a> {
    #[allow(unsafe_code)]
    fn typed<T: bytemuck::Pod>(&self, entry: &SectionEntry) -> Result<&'a [T], Violation> {
        let (start, len) = (entry.section_byte_offset as usize, entry.element_count as usize);
        // SAFETY: by `new`'s contract, V5 and V6 place `len` elements of the kind's size, `T`'s size, at `start`,
        // inside `bytes`; `start` is a multiple of 64 and `bytes` is 4-byte aligned (checked by `open`), so the
        // pointer is aligned for `T`, which is Pod (any bit pattern is valid).
        Ok(unsafe { std::slice::from_raw_parts(self.0.as_ptr().add(start).cast::<T>(), len) })
    }
}
