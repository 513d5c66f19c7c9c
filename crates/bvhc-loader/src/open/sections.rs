//! The typed groups of sections a view hands out: the wide BVH's two sections, the GPU layout's two, and a
//! two-level file's three. Each group is present as a whole or not at all (rule V8).

use crate::format::{GpuNode, GpuTriangle, InstanceRecord, MeshRecord, PackedNode, TrianglePacket4, WideNode8};

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
