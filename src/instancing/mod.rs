//! Two-level scenes (format 1.3): meshes built once in their object space, placed by instances under a
//! top-level tree, built over the instances' world boxes by the loader's builder
//! ([`bvhc_loader::top_tree`], which also rebuilds a moved file's top trees); [`TwoLevelScene::assemble`] lays the
//! meshes' packed trees out as the file's sections (each mesh's indices relative to its own ranges,
//! `format-spec/bvh-1.md` 5.10) beside the mesh table, the instances and the top trees.

use bvhc_loader::{
    TwoLevelSections, format::Affine3x4, format::InstanceRecord, format::MeshRecord, format::PackedNode,
    format::PackedTriangle, format::SourceVertexIndices, format::TrianglePacket4, format::WideNode8,
    ray::instance_world_box,
};

use bvhc_loader::top_tree::{build_top_tree, collapse_top_tree};

/// One mesh's packed trees in its object space, in the one-level layout (root first, indices from 0).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PackedMesh {
    /// Binary nodes, the root first.
    pub nodes: Vec<PackedNode>,
    /// Triangle records in leaf order.
    pub triangles: Vec<PackedTriangle>,
    /// Each record's source triangle id (empty when the file stores none).
    pub triangle_ids: Vec<u32>,
    /// Each record's source vertex indices (empty when the file stores none).
    pub source_vertices: Vec<SourceVertexIndices>,
    /// The wide nodes and packets over `triangles` (both empty when the file has no wide sections).
    pub wide_nodes: Vec<WideNode8>,
    /// See `wide_nodes`.
    pub packets: Vec<TrianglePacket4>,
}

/// A placement of mesh `mesh_index` by `object_to_world`, with its provenance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The placed mesh.
    pub mesh_index: u32,
    /// Object space to world space.
    pub object_to_world: Affine3x4,
    /// The glTF node, or `NO_INDEX`.
    pub node_index: u32,
    /// The `EXT_mesh_gpu_instancing` instance, or `NO_INDEX`.
    pub gpu_instance_index: u32,
}

/// Every section of a two-level file but the metadata and source table, owned.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TwoLevelScene {
    /// The meshes' binary nodes, concatenated.
    pub nodes: Vec<PackedNode>,
    /// The meshes' triangle records, concatenated.
    pub triangles: Vec<PackedTriangle>,
    /// The records' source ids (empty without ids).
    pub triangle_ids: Vec<u32>,
    /// The records' source vertices (empty without them).
    pub source_vertices: Vec<SourceVertexIndices>,
    /// The meshes' wide nodes, concatenated (empty without wide sections).
    pub wide_nodes: Vec<WideNode8>,
    /// The meshes' packets, concatenated.
    pub packets: Vec<TrianglePacket4>,
    /// The mesh table.
    pub meshes: Vec<MeshRecord>,
    /// The instances, in the order of the placements.
    pub instances: Vec<InstanceRecord>,
    /// The top-level tree.
    pub top_nodes: Vec<PackedNode>,
    /// The top-level tree 8-wide (empty without wide sections).
    pub top_wide_nodes: Vec<WideNode8>,
}

impl TwoLevelScene {
    /// Lays `meshes` out one after the other and places them by `placements` (instance `i` is placement `i`).
    /// Fails, naming the placement, when a transform is not finite or not invertible (rule V42) or its world
    /// box overflows f32, or names no mesh; and when a mesh is empty or placed by no placement.
    pub fn assemble(meshes: Vec<PackedMesh>, placements: &[Placement]) -> Result<TwoLevelScene, String> {
        let mut scene = TwoLevelScene::default();
        let mut placed = vec![false; meshes.len()];
        let mut root_boxes = Vec::with_capacity(meshes.len());
        for (m, mesh) in meshes.into_iter().enumerate() {
            let root = mesh.nodes.first().ok_or_else(|| format!("mesh {m} has no triangles"))?;
            root_boxes.push((root.min, root.max));
            let count = |n: usize| u32::try_from(n).map_err(|_| "more than 2^32 - 1 elements in a section".to_string());
            scene.meshes.push(MeshRecord {
                first_node: count(scene.nodes.len())?,
                node_count: count(mesh.nodes.len())?,
                first_triangle: count(scene.triangles.len())?,
                triangle_count: count(mesh.triangles.len())?,
                first_wide_node: count(scene.wide_nodes.len())?,
                wide_node_count: count(mesh.wide_nodes.len())?,
                first_packet: count(scene.packets.len())?,
                packet_count: count(mesh.packets.len())?,
            });
            scene.nodes.extend(mesh.nodes);
            scene.triangles.extend(mesh.triangles);
            scene.triangle_ids.extend(mesh.triangle_ids);
            scene.source_vertices.extend(mesh.source_vertices);
            scene.wide_nodes.extend(mesh.wide_nodes);
            scene.packets.extend(mesh.packets);
        }
        let mut boxes = Vec::with_capacity(placements.len());
        for (i, placement) in placements.iter().enumerate() {
            let m = placement.mesh_index as usize;
            let root_box =
                *root_boxes.get(m).ok_or_else(|| format!("placement {i} names mesh {m}, which is not there"))?;
            placed[m] = true;
            let instance =
                InstanceRecord::placing(placement.mesh_index, placement.object_to_world).ok_or_else(|| {
                    format!(
                        "placement {i}: its transform is not finite or not invertible: {:?}",
                        placement.object_to_world
                    )
                })?;
            let world_box = instance_world_box(&placement.object_to_world, root_box)
                .ok_or_else(|| format!("placement {i}: its world box overflows f32"))?;
            boxes.push(world_box);
            scene.instances.push(InstanceRecord {
                node_index: placement.node_index,
                gpu_instance_index: placement.gpu_instance_index,
                ..instance
            });
        }
        if let Some(m) = placed.iter().position(|&p| !p) {
            return Err(format!("mesh {m} is placed by no placement"));
        }
        scene.top_nodes = build_top_tree(&boxes);
        if !scene.wide_nodes.is_empty() {
            if scene.instances.len() > 1 << 28 {
                return Err(format!("{} instances: a wide top tree names at most 2^28", scene.instances.len()));
            }
            scene.top_wide_nodes = collapse_top_tree(&scene.top_nodes);
        }
        Ok(scene)
    }

    /// The two-level sections, borrowed (for `BvhWriter::two_level`).
    pub fn sections(&self) -> TwoLevelSections<'_> {
        TwoLevelSections {
            meshes: &self.meshes,
            instances: &self.instances,
            top_nodes: &self.top_nodes,
            top_wide_nodes: &self.top_wide_nodes,
        }
    }
}
