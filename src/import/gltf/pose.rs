//! A glTF scene posed as glTF 2.0 says (sections 3.7.3 and 3.8): every node's local transform (its `matrix`, or
//! its translation, rotation and scale, the latter three possibly set by an animation clip sampled at a time,
//! `clip.rs`), its morph weights, and world matrices down the hierarchy, in f64. How a primitive's vertices
//! follow a pose (morph targets, skins) is `skin.rs`.

use glam::{DMat4, DQuat, DVec3};
use gltf::json::Root;
use gltf::json::animation::Property;
use gltf::json::validation::Checked;

use crate::import::Located;

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

/// Checks that the nodes form disjoint strict trees, as glTF 2.0 requires (section 3.5.3): every child exists,
/// no node is the child of two nodes, and no node is its own ancestor, whether or not the scene reaches it (a
/// skin's joints are posed down their ancestors, which need not be in the scene). The error names the node.
pub(super) fn check_hierarchy(root: &Root) -> Result<(), Located> {
    let count = root.nodes.len();
    let mut parent = vec![usize::MAX; count];
    for (index, node) in root.nodes.iter().enumerate() {
        for child in node.children.iter().flatten().map(|c| c.value()) {
            let Some(slot) = parent.get_mut(child) else {
                let why = format!("child {child} does not exist (the file has {count} nodes)");
                return Err(Located::new(&format!("node {index}"), why));
            };
            if *slot != usize::MAX {
                let why = format!("is a child of node {} and of node {index}: the node hierarchy is not a tree", *slot);
                return Err(Located::new(&format!("node {child}"), why));
            }
            *slot = index;
        }
    }
    // With one parent at most, a node lies on a cycle or below one exactly when following its parents never
    // reaches a node without one. Each node is settled once: 1 on the path being followed, 2 settled.
    let mut state = vec![0u8; count];
    let mut path = Vec::new();
    for start in 0..count {
        let mut node = start;
        while node != usize::MAX && state[node] == 0 {
            state[node] = 1;
            path.push(node);
            node = parent[node];
        }
        if node != usize::MAX && state[node] == 1 {
            let why = "the node hierarchy has a cycle: the node is its own ancestor".to_string();
            return Err(Located::new(&format!("node {node}"), why));
        }
        for settled in path.drain(..) {
            state[settled] = 2;
        }
    }
    Ok(())
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

/// A rotation from `[x, y, z, w]`, normalized (files often store slightly denormalized quaternions); the
/// identity for a node's own rotation of length 0 or not finite (JSON cannot hold NaN; such a node is refused
/// later, its world transform not finite, or keeps no rotation).
pub(super) fn quaternion(xyzw: [f64; 4]) -> DQuat {
    unit_quaternion(xyzw).unwrap_or(DQuat::IDENTITY)
}

/// `[x, y, z, w]` normalized, or `None` when its length is 0 or not finite (it names no rotation).
pub(super) fn unit_quaternion(xyzw: [f64; 4]) -> Option<DQuat> {
    let q = DQuat::from_array(xyzw);
    let length = q.length();
    (length > 0.0 && length.is_finite()).then(|| q / length)
}
