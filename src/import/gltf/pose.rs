//! A glTF scene posed as glTF 2.0 says (sections 3.7.3 and 3.8): every node's local transform (its `matrix`, or
//! its translation, rotation and scale, the latter three possibly set by an animation clip sampled at a time,
//! `clip.rs`) and morph weights, world matrices down the hierarchy, and a primitive's positions as a viewer shows
//! them: first morphed (`POSITION + sum_k weight_k * target_k.POSITION`, the weights the node's, else the mesh's,
//! else zero), then, for a node with a skin, skinned by linear blending over every influence set
//! (`JOINTS_n`, `WEIGHTS_n`): `sum_i w_i * (world(joint_i) * inverseBind_i) * p`, where the skinned mesh node's
//! own transform is ignored as the spec requires; other nodes' primitives are placed by the node's world matrix.
//! All in f64; accessors through [`Buffers`], so sparse and quantized (normalized integer) ones decode too.

use glam::{DMat4, DQuat, DVec3};
use gltf::json::Root;
use gltf::json::animation::Property;
use gltf::json::mesh::Semantic;
use gltf::json::validation::Checked;

use super::buffers::{Buffers, Decoded};
use crate::import::Problem;

/// Every node's local transform, morph weights and world matrix at one pose.
pub(super) struct Pose {
    /// Per node: its local transform.
    pub(super) local: Vec<DMat4>,
    /// Per node: its morph weights where it sets them (its `weights`, or an animation's), else `None`.
    pub(super) weights: Vec<Option<Vec<f64>>>,
    /// Per node: its world matrix (its ancestors' local transforms and its own, root first); a node in a cycle
    /// keeps its local transform.
    world: Vec<DMat4>,
}

impl Pose {
    /// The default pose: each node's `matrix` or translation, rotation and scale, and its `weights`.
    pub(super) fn rest(root: &Root) -> Pose {
        let local = root.nodes.iter().map(local_transform).collect();
        let weights =
            root.nodes.iter().map(|n| n.weights.as_ref().map(|w| w.iter().map(|&x| f64::from(x)).collect())).collect();
        let mut pose = Pose { local, weights, world: Vec::new() };
        pose.update_world(root);
        pose
    }

    /// Recomputes the world matrices from the local transforms, down from each node that is no node's child.
    pub(super) fn update_world(&mut self, root: &Root) {
        let count = root.nodes.len();
        let mut is_child = vec![false; count];
        for child in root.nodes.iter().flat_map(|n| n.children.iter().flatten()) {
            if let Some(flag) = is_child.get_mut(child.value()) {
                *flag = true;
            }
        }
        self.world = self.local.clone();
        let mut visited = vec![false; count];
        let mut stack: Vec<(usize, DMat4)> =
            (0..count).filter(|&n| !is_child[n]).map(|n| (n, DMat4::IDENTITY)).collect();
        while let Some((node, parent)) = stack.pop() {
            if node >= count || std::mem::replace(&mut visited[node], true) {
                continue;
            }
            self.world[node] = parent * self.local[node];
            let world = self.world[node];
            stack.extend(root.nodes[node].children.iter().flatten().map(|c| (c.value(), world)));
        }
    }

    /// Node `node`'s world matrix (identity for a node that does not exist).
    pub(super) fn world(&self, node: usize) -> DMat4 {
        self.world.get(node).copied().unwrap_or(DMat4::IDENTITY)
    }

    /// The morph weights of mesh `mesh` placed by node `node` (`None`: an instanced mesh, in object space): the
    /// node's where it sets them, else the mesh's, else none (every target at weight 0).
    pub(super) fn morph_weights(&self, root: &Root, node: Option<usize>, mesh: usize) -> Vec<f64> {
        let of_node = node.and_then(|n| self.weights.get(n)).and_then(Option::clone);
        let of_mesh = || {
            root.meshes.get(mesh).and_then(|m| m.weights.as_ref()).map(|w| w.iter().map(|&x| f64::from(x)).collect())
        };
        of_node.or_else(of_mesh).unwrap_or_default()
    }
}

/// Per glTF mesh: whether some node poses it for itself (a skin, morph weights of its own, or morph weights that
/// one of `clips` animates), so that its placements cannot share one object-space copy. From the JSON alone.
pub(super) fn posed_per_node(root: &Root, clips: &[usize]) -> Vec<bool> {
    let mut posed = vec![false; root.meshes.len()];
    let animated = channel_targets(root, clips, |p| p == Property::MorphTargetWeights);
    for (index, node) in root.nodes.iter().enumerate() {
        let own = node.skin.is_some() || node.weights.is_some() || animated[index];
        if let Some(flag) = node.mesh.filter(|_| own).and_then(|m| posed.get_mut(m.value())) {
            *flag = true;
        }
    }
    posed
}

/// Per node: whether one of `clips` moves it: a translation, rotation or scale channel on it or an ancestor. From
/// the JSON alone (a channel whose keyframes never change counts).
pub(super) fn moved_nodes(root: &Root, clips: &[usize]) -> Vec<bool> {
    let count = root.nodes.len();
    let mut moved = channel_targets(root, clips, |p| p != Property::MorphTargetWeights);
    let mut stack: Vec<usize> = (0..count).filter(|&n| moved[n]).collect();
    while let Some(node) = stack.pop() {
        for child in root.nodes[node].children.iter().flatten().map(|c| c.value()) {
            if child < count && !std::mem::replace(&mut moved[child], true) {
                stack.push(child);
            }
        }
    }
    moved
}

/// Per glTF mesh: whether a node that `moved` flags places it.
pub(super) fn meshes_placed_by(root: &Root, moved: &[bool]) -> Vec<bool> {
    let mut meshes = vec![false; root.meshes.len()];
    for (node, json) in root.nodes.iter().enumerate() {
        if let Some(flag) = json.mesh.filter(|_| moved[node]).and_then(|m| meshes.get_mut(m.value())) {
            *flag = true;
        }
    }
    meshes
}

/// Per node: whether one of `clips` has a channel on it whose path `wanted` accepts (clips and nodes that do not
/// exist are skipped: the clip sampler reports them).
fn channel_targets(root: &Root, clips: &[usize], wanted: impl Fn(Property) -> bool) -> Vec<bool> {
    let mut targets = vec![false; root.nodes.len()];
    for animation in clips.iter().filter_map(|&c| root.animations.get(c)) {
        for channel in &animation.channels {
            if let (Checked::Valid(path), Some(flag)) =
                (channel.target.path, targets.get_mut(channel.target.node.value()))
                && wanted(path)
            {
                *flag = true;
            }
        }
    }
    targets
}

/// A node's local transform: `matrix` (column-major), or T * R * S.
pub(super) fn local_transform(node: &gltf::json::Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m.map(f64::from));
    }
    let (t, r, s) = node_trs(node);
    DMat4::from_scale_rotation_translation(s, r, t)
}

/// A node's translation, rotation and scale: its own (a rotation normalized), or its `matrix` taken apart (a
/// node with a matrix is not animated, by the spec, but a clip that names one still gets its parts).
pub(super) fn node_trs(node: &gltf::json::Node) -> (DVec3, DQuat, DVec3) {
    if let Some(m) = node.matrix {
        let (s, r, t) = DMat4::from_cols_array(&m.map(f64::from)).to_scale_rotation_translation();
        return (t, r, s);
    }
    let t = node.translation.map_or(DVec3::ZERO, |t| DVec3::from_array(t.map(f64::from)));
    let r = node.rotation.map_or(DQuat::IDENTITY, |r| quaternion(r.0.map(f64::from)));
    let s = node.scale.map_or(DVec3::ONE, |s| DVec3::from_array(s.map(f64::from)));
    (t, r, s)
}

/// A rotation from `[x, y, z, w]`, normalized (files often store slightly denormalized quaternions).
pub(super) fn quaternion(xyzw: [f64; 4]) -> DQuat {
    let q = DQuat::from_array(xyzw);
    let length = q.length();
    if length > 0.0 && length.is_finite() { q / length } else { DQuat::IDENTITY }
}

/// How one placement of a primitive is posed.
pub(super) struct Placing<'p> {
    /// The morph weights (empty: none).
    pub weights: &'p [f64],
    /// The skin of the placing node, with the pose, where the node has one: the node's own transform is then
    /// ignored.
    pub skin: Option<(usize, &'p Pose)>,
    /// The placement's world matrix, for a primitive that is not skinned.
    pub world: DMat4,
}

/// The positions of `primitive` (whose `POSITION` decoded to `base`) placed as `placing` says, and whether
/// skinning placed them. Errors name the accessor, joint or vertex at fault.
pub(super) fn posed_positions(
    root: &Root,
    buffers: &mut Buffers<'_>,
    primitive: &gltf::json::mesh::Primitive,
    base: &Decoded,
    placing: &Placing<'_>,
) -> Result<(Vec<DVec3>, bool), Problem> {
    let mut positions: Vec<DVec3> = base.values.chunks_exact(3).map(|v| DVec3::new(v[0], v[1], v[2])).collect();
    morph(buffers, primitive, placing.weights, &mut positions)?;
    let influences = influence_sets(buffers, primitive, positions.len())?;
    match placing.skin {
        Some((skin, pose)) if !influences.is_empty() => {
            let matrices = joint_matrices(root, buffers, skin, pose)?;
            skin_positions(&matrices, &influences, &mut positions)?;
            Ok((positions, true))
        }
        _ => {
            positions.iter_mut().for_each(|p| *p = placing.world.transform_point3(*p));
            Ok((positions, false))
        }
    }
}

/// Adds each morph target's `POSITION` displacements times its weight (targets without one, or at weight 0,
/// add nothing).
fn morph(
    buffers: &mut Buffers<'_>,
    primitive: &gltf::json::mesh::Primitive,
    weights: &[f64],
    positions: &mut [DVec3],
) -> Result<(), Problem> {
    let targets = primitive.targets.as_deref().unwrap_or(&[]);
    if weights.len() > targets.len() {
        return Err(format!("{} morph weights for {} morph targets", weights.len(), targets.len()).into());
    }
    for (k, (target, &weight)) in targets.iter().zip(weights).enumerate() {
        let Some(accessor) = target.positions.filter(|_| weight != 0.0) else { continue };
        let decoded = buffers.accessor(accessor.value()).map_err(|e| e.prefixed(&format!("morph target {k}: ")))?;
        if decoded.components != 3 || decoded.count() != positions.len() {
            return Err(format!(
                "morph target {k}: POSITION accessor {} has {} elements of {} components, not {} VEC3",
                accessor.value(),
                decoded.count(),
                decoded.components,
                positions.len()
            )
            .into());
        }
        for (p, d) in positions.iter_mut().zip(decoded.values.chunks_exact(3)) {
            *p += weight * DVec3::new(d[0], d[1], d[2]);
        }
    }
    Ok(())
}

/// One influence set: per vertex four joint indices (into the skin's joints) and four weights.
struct Influences {
    joints: std::rc::Rc<Decoded>,
    weights: std::rc::Rc<Decoded>,
}

/// The primitive's influence sets `JOINTS_n`, `WEIGHTS_n` for n = 0, 1, ... while both exist, each checked to
/// hold a VEC4 a vertex.
fn influence_sets(
    buffers: &mut Buffers<'_>,
    primitive: &gltf::json::mesh::Primitive,
    vertex_count: usize,
) -> Result<Vec<Influences>, Problem> {
    let mut sets = Vec::new();
    for n in 0u32.. {
        let joints = primitive.attributes.get(&Checked::Valid(Semantic::Joints(n)));
        let weights = primitive.attributes.get(&Checked::Valid(Semantic::Weights(n)));
        let (Some(joints), Some(weights)) = (joints, weights) else { break };
        let decode = |buffers: &mut Buffers<'_>, accessor: usize, name: &str| {
            let decoded = buffers.accessor(accessor).map_err(|e| e.prefixed(&format!("{name}_{n} ")))?;
            if decoded.components != 4 || decoded.count() != vertex_count {
                return Err(Problem::from(format!(
                    "{name}_{n} accessor {accessor}: {} elements of {} components, not {vertex_count} VEC4",
                    decoded.count(),
                    decoded.components
                )));
            }
            Ok(decoded)
        };
        sets.push(Influences {
            joints: decode(buffers, joints.value(), "JOINTS")?,
            weights: decode(buffers, weights.value(), "WEIGHTS")?,
        });
    }
    Ok(sets)
}

/// Each joint's skinning matrix, `world(joint) * inverseBind` (the inverse bind matrices identity where the skin
/// has none).
fn joint_matrices(root: &Root, buffers: &mut Buffers<'_>, skin: usize, pose: &Pose) -> Result<Vec<DMat4>, Problem> {
    let json = root.skins.get(skin).ok_or_else(|| format!("skin {skin} does not exist"))?;
    let inverse = match json.inverse_bind_matrices {
        Some(accessor) => {
            let decoded = buffers.accessor(accessor.value()).map_err(|e| e.prefixed("inverseBindMatrices "))?;
            if decoded.components != 16 || decoded.count() < json.joints.len() {
                return Err(format!(
                    "skin {skin}: inverseBindMatrices accessor {} has {} MAT4 for {} joints",
                    accessor.value(),
                    decoded.count(),
                    json.joints.len()
                )
                .into());
            }
            decoded.values.chunks_exact(16).map(|m| DMat4::from_cols_slice(m)).collect()
        }
        None => vec![DMat4::IDENTITY; json.joints.len()],
    };
    let mut matrices = Vec::with_capacity(json.joints.len());
    for (j, joint) in json.joints.iter().enumerate() {
        if joint.value() >= root.nodes.len() {
            return Err(format!("skin {skin}: joint {j} is node {}, which does not exist", joint.value()).into());
        }
        matrices.push(pose.world(joint.value()) * inverse[j]);
    }
    Ok(matrices)
}

/// Moves each vertex by the blend of its joints' matrices, its weights over every set normalized to sum 1 (a
/// vertex whose weights sum to 0 follows the first joint of its first set).
fn skin_positions(matrices: &[DMat4], sets: &[Influences], positions: &mut [DVec3]) -> Result<(), Problem> {
    for (v, p) in positions.iter_mut().enumerate() {
        let mut blended = DMat4::ZERO;
        let mut total = 0.0;
        for (n, set) in sets.iter().enumerate() {
            for i in 0..4 {
                let (joint, weight) = (set.joints.values[4 * v + i], set.weights.values[4 * v + i]);
                if weight == 0.0 {
                    continue;
                }
                let matrix = usize::try_from(joint as i64).ok().and_then(|j| matrices.get(j)).ok_or_else(|| {
                    format!("vertex {v}: JOINTS_{n} names joint {joint}, but the skin has {} joints", matrices.len())
                })?;
                blended += *matrix * weight;
                total += weight;
            }
        }
        let first = sets.first().map_or(0.0, |set| set.joints.values[4 * v]) as usize;
        let blended =
            if total > 0.0 { blended * (1.0 / total) } else { matrices.get(first).copied().unwrap_or_default() };
        *p = blended.transform_point3(*p);
    }
    Ok(())
}
