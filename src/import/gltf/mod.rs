//! glTF 2.0 (`.gltf` and `.glb`): the selected scene's node hierarchy, placed in world space.
//!
//! Works on the raw JSON (gltf-json) rather than the gltf crate's wrapper, whose accessors assume a validated
//! document; every index, enum and length is checked here, so a malformed file gives an error, never a panic.
//! Transforms (`matrix` or T * R * S, and `EXT_mesh_gpu_instancing`'s per-instance T * R * S, applied before
//! the node's) are accumulated in f64 with glam; a negative determinant reverses the winding. Images are never
//! read or decoded. Meshes that [`choose_instanced`] keeps instanced are added once, in object space, at their
//! first placement, and every placement of them becomes a [`MeshPlacement`].

mod buffers;
mod clip;
mod extensions;
mod plan;
mod pose;
mod primitive;
mod skin;

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use glam::DMat4;
use gltf::json::Root;

use bvhc_loader::format::NO_INDEX;

use self::buffers::Buffers;
pub use self::clip::{ClipSelector, ClipSpan};
use self::pose::Pose;
use self::skin::{Placing, posed_positions};
use super::instancing::{InstancedMesh, MeshPlacement, affine, choose_instanced, stored_triangles};
use super::soup::{PrimitiveInstance, Provenance, SoupBuilder};
use super::{ErrorKind, ImportOptions, Instancing, Located, SceneSelector};

/// Reads a `.gltf` (JSON) or `.glb` file's scene into `builder`; returns the external files it read and the
/// meshes kept instanced.
pub(super) fn read(
    path: &Path,
    bytes: &[u8],
    options: &ImportOptions,
    builder: &mut SoupBuilder,
) -> Result<(Vec<PathBuf>, Vec<InstancedMesh>), Located> {
    let scene = options.scene.as_ref();
    let (root, bin) = parse(bytes)?;
    pose::check_hierarchy(&root)?;
    let roots = scene_roots(&root, scene)?;
    builder.report.file_mesh_triangles = primitive::file_mesh_triangles(&root);
    // The triangles the scene will store, counted from the JSON before any accessor is decoded, against the
    // memory budget: a small file that places a large mesh many times (and does not instance it) is refused
    // here, in a moment.
    let reached = reached_nodes(&root, &roots);
    check_placements(&root, &reached, options.limits.max_placements)?;
    let placements = mesh_placements(&root, &reached);
    let triangles: Vec<u64> = root.meshes.iter().map(|mesh| primitive::mesh_triangles(&root, mesh)).collect();
    let clip =
        options.pose.as_ref().map(|p| clip::clip_index(&root, &p.clip)).transpose().map_err(|e| e.at("animations"))?;
    let mut instanced =
        choose_instanced(options.instancing, &placements, &triangles, |stored| builder.check_memory(stored).is_ok());
    if let Some(&missing) = options.moving_clips.iter().find(|&&c| c >= root.animations.len()) {
        let count = root.animations.len();
        return Err(Located::new("animations", format!("animation {missing} does not exist (the file has {count})")));
    }
    // With --instancing always, a mesh that the animation moves rigidly is stored once and placed by instances
    // that a refit can move.
    let moving_nodes = pose::moved_nodes(&root, &options.moving_clips);
    if options.instancing == Instancing::Always {
        for (mesh, moved) in pose::meshes_placed_by(&root, &moving_nodes).into_iter().enumerate() {
            if let Some(flag) = instanced.get_mut(mesh) {
                *flag |= moved && triangles[mesh] > 0;
            }
        }
    }
    // A mesh that some node poses for itself (a skin, or morph weights of its own or animated) is not shared.
    let posing_clips: Vec<usize> = options.moving_clips.iter().copied().chain(clip).collect();
    for (mesh, posed) in pose::posed_per_node(&root, &posing_clips).into_iter().enumerate() {
        if posed && let Some(flag) = instanced.get_mut(mesh) {
            *flag = false;
        }
    }
    // Every accessor the import will decode, summed and held to the limits before the first is read, and their
    // decoded values counted in the memory estimate beside the triangles.
    let decoded_values = plan::DecodePlan::of_scene(&root, &reached, &clip.into_iter().collect::<Vec<_>>())
        .check(&root, options.limits.max_decoded_values)?;
    let stored = stored_triangles(&placements, &triangles, &instanced);
    builder
        .check_memory_with(stored, decoded_values.saturating_mul(plan::BYTES_PER_DECODED_VALUE))
        .map_err(|e| Located::of_kind(ErrorKind::Limit, "scene", e))?;
    let mut buffers = Buffers::new(&root, path, bin.as_deref(), options);
    let mut pose = Pose::rest(&root);
    if let (Some(selector), Some(clip)) = (&options.pose, clip) {
        clip::apply_clip(&root, &mut buffers, clip, selector.seconds, &mut pose).map_err(|e| e.at("animations"))?;
    }
    let mut walker = Walker {
        root: &root,
        pose: &pose,
        buffers: &mut buffers,
        builder,
        placed: HashSet::new(),
        instanced,
        moving_nodes,
        slot_of_mesh: vec![None; root.meshes.len()],
        meshes: Vec::new(),
    };
    walker.walk(&roots)?;
    let meshes = walker.meshes;
    Ok((buffers.files_read, meshes))
}

/// The JSON document and the GLB's binary chunk of a `.gltf` or `.glb` file's bytes, its required extensions
/// checked.
fn parse(bytes: &[u8]) -> Result<(Root, Option<Vec<u8>>), Located> {
    let (json, bin) = if bytes.starts_with(b"glTF") {
        let glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| Located::new("GLB container", e.to_string()))?;
        (glb.json.into_owned(), glb.bin.map(|b| b.into_owned()))
    } else {
        (bytes.to_vec(), None)
    };
    let root = Root::from_slice(&json).map_err(|e| Located::new("JSON", format!("malformed glTF JSON: {e}")))?;
    extensions::check_required(&root)?;
    Ok((root, bin))
}

/// Every animation clip of a `.gltf` or `.glb` file's bytes, with the span of its keyframes.
pub(super) fn clips(path: &Path, bytes: &[u8], options: &ImportOptions) -> Result<Vec<ClipSpan>, Located> {
    let (root, bin) = parse(bytes)?;
    pose::check_hierarchy(&root)?;
    let every_clip: Vec<usize> = (0..root.animations.len()).collect();
    plan::DecodePlan::of_clips(&root, &every_clip).check(&root, options.limits.max_decoded_values)?;
    let mut buffers = Buffers::new(&root, path, bin.as_deref(), options);
    clip::clip_spans(&root, &mut buffers).map_err(|e| e.at("animations"))
}

/// The root nodes of the selected scene: the one asked for, else the default scene, else scene 0, else (a file
/// without scenes) every node that is no node's child.
fn scene_roots(root: &Root, selector: Option<&SceneSelector>) -> Result<Vec<usize>, Located> {
    let count = root.scenes.len();
    let chosen = match selector {
        Some(SceneSelector::Index(i)) if *i < count => Some(*i),
        Some(SceneSelector::Index(i)) => {
            return Err(Located::new("scenes", format!("scene {i} does not exist (the file has {count} scenes)")));
        }
        Some(SceneSelector::Name(name)) => {
            let found = root.scenes.iter().position(|s| s.name.as_deref() == Some(name.as_str()));
            let names: Vec<_> = root.scenes.iter().map(|s| s.name.clone().unwrap_or_default()).collect();
            Some(
                found
                    .ok_or_else(|| Located::new("scenes", format!("no scene is named '{name}' (names: {names:?})")))?,
            )
        }
        None => root.scene.map(|s| s.value()).or((count > 0).then_some(0)),
    };
    match chosen {
        Some(i) => {
            let scene =
                root.scenes.get(i).ok_or_else(|| Located::new("scene", format!("default scene {i} does not exist")))?;
            Ok(scene.nodes.iter().map(|n| n.value()).collect())
        }
        None => {
            let children: HashSet<usize> =
                root.nodes.iter().flat_map(|n| n.children.iter().flatten().map(|c| c.value())).collect();
            Ok((0..root.nodes.len()).filter(|i| !children.contains(i)).collect())
        }
    }
}

/// Per node: whether the scene's walk from `roots` reaches it (nodes reached twice, or missing, the walk
/// reports).
fn reached_nodes(root: &Root, roots: &[usize]) -> Vec<bool> {
    let mut reached = vec![false; root.nodes.len()];
    let mut stack = roots.to_vec();
    while let Some(index) = stack.pop() {
        let Some(node) = root.nodes.get(index) else { continue };
        if !std::mem::replace(&mut reached[index], true) {
            stack.extend(node.children.iter().flatten().map(|c| c.value()));
        }
    }
    reached
}

/// The mesh placements the reached nodes declare (a node with a mesh one, or its `EXT_mesh_gpu_instancing`
/// instances), held to `max_placements` before anything is decoded, as the walk holds them (same message).
fn check_placements(root: &Root, reached: &[bool], max_placements: u64) -> Result<(), Located> {
    let mut meter = crate::import::limits::Meter::new(max_placements, "mesh placements", "--max-placements");
    for (index, node) in root.nodes.iter().enumerate().filter(|&(i, _)| reached.get(i).copied().unwrap_or(false)) {
        if node.mesh.is_none() {
            continue;
        }
        let declared = extensions::declared_instances(root, node);
        meter.take(declared.unwrap_or(1)).map_err(|e| {
            let e = if declared.is_some() { format!("EXT_mesh_gpu_instancing: {e}") } else { e };
            Located::of_kind(ErrorKind::Limit, &format!("node {index}"), e)
        })?;
    }
    Ok(())
}

/// How many times the scene places each mesh: each node that `reached` flags places its mesh once, or its
/// instances (`EXT_mesh_gpu_instancing`'s declared count), from declared counts only.
fn mesh_placements(root: &Root, reached: &[bool]) -> Vec<u64> {
    let mut placements = vec![0u64; root.meshes.len()];
    for (node, _) in root.nodes.iter().zip(reached).filter(|(_, reached)| **reached) {
        if let Some(count) = node.mesh.and_then(|m| placements.get_mut(m.value())) {
            *count = count.saturating_add(extensions::declared_instances(root, node).unwrap_or(1));
        }
    }
    placements
}

struct Walker<'r, 'b> {
    root: &'r Root,
    /// The pose the scene is placed in: every node's local transform, morph weights and world matrix.
    pose: &'b Pose,
    buffers: &'b mut Buffers<'r>,
    builder: &'b mut SoupBuilder,
    /// (mesh, primitive) pairs placed so far, for the report's unique figures.
    placed: HashSet<(usize, usize)>,
    /// Per glTF mesh: whether it stays instanced.
    instanced: Vec<bool>,
    /// Per node: whether the import's moving clips move it.
    moving_nodes: Vec<bool>,
    /// Per glTF mesh: its index in `meshes` once its object-space triangles are in the soup.
    slot_of_mesh: Vec<Option<usize>>,
    /// The instanced meshes, in the order of their first placement.
    meshes: Vec<InstancedMesh>,
}

impl Walker<'_, '_> {
    /// Depth first from `roots`, children in file order.
    fn walk(&mut self, roots: &[usize]) -> Result<(), Located> {
        let mut visited = vec![false; self.root.nodes.len()];
        let mut stack: Vec<(usize, DMat4)> = roots.iter().rev().map(|&n| (n, DMat4::IDENTITY)).collect();
        while let Some((index, parent)) = stack.pop() {
            let at = format!("node {index}");
            let node = self.root.nodes.get(index).ok_or_else(|| Located::new(&at, "does not exist".to_string()))?;
            if std::mem::replace(&mut visited[index], true) {
                return Err(Located::new(&at, "is reached twice: the node hierarchy is not a tree".to_string()));
            }
            let world = parent * self.pose.local.get(index).copied().unwrap_or(DMat4::IDENTITY);
            if !world.is_finite() {
                return Err(Located::new(&at, "its world transform is not finite".to_string()));
            }
            if let Some(mesh) = node.mesh {
                let placements = &mut self.builder.placement_budget;
                let instances =
                    extensions::instance_transforms(node, self.buffers, placements).map_err(|e| e.at(&at))?;
                if instances.is_none() {
                    placements.take(1).map_err(|e| Located::of_kind(ErrorKind::Limit, &at, e))?;
                }
                if node.skin.is_some() {
                    self.builder.report.skinned_placements += instances.as_ref().map_or(1, Vec::len) as u64;
                }
                match instances {
                    None => self.place(index, mesh.value(), None, world)?,
                    Some(instances) => {
                        for (i, instance) in instances.into_iter().enumerate() {
                            self.place(index, mesh.value(), Some(i), world * instance)?;
                        }
                    }
                }
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world));
            }
        }
        Ok(())
    }

    /// One placement of mesh `mesh_index` by node `node` (and its instance): flattened into world space, or,
    /// for a mesh kept instanced, as an instance of the mesh's object-space triangles (added at its first
    /// placement). A placement whose transform is no valid instance (singular or not finite once rounded to
    /// f32, rule V42) is flattened, where its triangles are dropped as zero-area after placement.
    fn place(&mut self, node: usize, mesh_index: usize, instance: Option<usize>, world: DMat4) -> Result<(), Located> {
        // (A mesh some node poses for itself is never instanced: see `pose::posed_per_node`.)
        let placement = self.instanced.get(mesh_index).copied().unwrap_or(false).then(|| affine(&world)).flatten();
        let Some(object_to_world) = placement else {
            self.builder.report.mesh_placements += 1;
            return self.place_mesh(node, mesh_index, Some(node), instance, world);
        };
        let slot = match self.slot_of_mesh[mesh_index] {
            Some(slot) => slot,
            None => {
                let start = self.builder.triangle_count();
                self.place_mesh(node, mesh_index, None, None, DMat4::IDENTITY)?;
                let triangles = start..self.builder.triangle_count();
                self.meshes.push(InstancedMesh { mesh_index: mesh_index as u32, triangles, placements: Vec::new() });
                self.slot_of_mesh[mesh_index] = Some(self.meshes.len() - 1);
                self.meshes.len() - 1
            }
        };
        self.builder.report.mesh_placements += 1;
        self.meshes[slot].placements.push(MeshPlacement {
            object_to_world,
            node_index: node as u32,
            gpu_instance_index: instance.map_or(NO_INDEX, |i| i as u32),
            moving: self.moving_nodes.get(node).copied().unwrap_or(false),
        });
        Ok(())
    }

    /// Adds mesh `mesh_index`'s primitives placed by `world`, with provenance `provenance_node` (and
    /// `instance`); `node` is the placing node, for messages.
    fn place_mesh(
        &mut self,
        node: usize,
        mesh_index: usize,
        provenance_node: Option<usize>,
        instance: Option<usize>,
        world: DMat4,
    ) -> Result<(), Located> {
        let mesh = self
            .root
            .meshes
            .get(mesh_index)
            .ok_or_else(|| Located::new(&format!("node {node}"), format!("mesh {mesh_index} does not exist")))?;
        let weights = self.pose.morph_weights(self.root, provenance_node, mesh_index);
        let skin =
            provenance_node.and_then(|n| self.root.nodes.get(n)).and_then(|n| n.skin).map(|s| (s.value(), self.pose));
        let placing = Placing { node, weights: &weights, skin, world };
        let mut world_positions: Vec<[f32; 3]> = Vec::new();
        for (p, json_primitive) in mesh.primitives.iter().enumerate() {
            let at = format!("mesh {mesh_index} primitive {p}");
            let Some(geometry) =
                primitive::geometry(json_primitive, self.buffers, &mut self.builder.report).map_err(|e| e.at(&at))?
            else {
                continue;
            };
            let skinned = posed_positions(
                self.root,
                self.buffers,
                json_primitive,
                &geometry.positions,
                &placing,
                &mut world_positions,
            )
            .map_err(|e| e.at(&at))?;
            // A skinned primitive's winding is its own (its node's transform is ignored).
            let flip_winding = !skinned && world.determinant() < 0.0;
            let provenance = Provenance {
                node_index: provenance_node.map_or(NO_INDEX, |n| n as u32),
                mesh_index: mesh_index as u32,
                primitive_index: p as u32,
                instance_index: instance.map_or(NO_INDEX, |i| i as u32),
            };
            let positions = &world_positions;
            let source = &geometry.positions.values;
            self.builder
                .add(PrimitiveInstance {
                    provenance,
                    vertex_count: positions.len(),
                    source_position: |v| {
                        let at = 3 * v as usize;
                        [source[at], source[at + 1], source[at + 2]]
                    },
                    position: |v| positions[v as usize],
                    triangles: &geometry.triangles,
                    source_vertex_index: None,
                    flip_winding,
                    first_use: self.placed.insert((mesh_index, p)),
                    cut_out: primitive::cuts_out(self.root, json_primitive).map_err(|e| Located::new(&at, e))?,
                    deforming: self.root.nodes.get(node).is_some_and(|n| n.skin.is_some())
                        || json_primitive.targets.as_ref().is_some_and(|targets| !targets.is_empty()),
                })
                .map_err(|(kind, e)| Located::of_kind(kind, &at, e))?;
        }
        Ok(())
    }
}
