//! A primitive's vertices as a viewer shows them in a pose (glTF 2.0 sections 3.7.2.2, 3.7.3 and 3.8): first
//! morphed (`POSITION + sum_k weight_k * target_k.POSITION`, the weights the node's, else the mesh's, else zero),
//! then, for a node with a skin, skinned by linear blending over every influence set (`JOINTS_n`, `WEIGHTS_n`):
//! `sum_i w_i * (world(joint_i) * inverseBind_i) * p`, the skinned mesh node's own transform ignored as the
//! spec requires; other nodes' primitives are placed by the node's world matrix. Each vertex is computed in f64
//! from the decoded accessors and written once, rounded to f32: no f64 copy of a primitive is held.
//!
//! What glTF allows of a skin is checked here, naming the accessor and the vertex: `JOINTS_n` of unsigned bytes
//! or shorts naming joints of the skin; `WEIGHTS_n` of floats or normalized unsigned bytes or shorts, each
//! weight finite and not negative, and every vertex weighed by some joint (its weights summing above 0). glTF
//! asks that the weights sum to 1; a sum that is positive but not 1 (rounding, or an exporter that does not
//! normalize) is normalized, as viewers do.

use glam::{DMat4, DVec3};
use gltf::json::Root;
use gltf::json::accessor::{ComponentType, GenericComponentType};
use gltf::json::mesh::Semantic;
use gltf::json::validation::Checked;

use super::buffers::{Buffers, Decoded};
use super::pose::Pose;
use crate::import::Problem;

/// How one placement of a primitive is posed.
pub(super) struct Placing<'p> {
    /// The placing node (for messages).
    pub node: usize,
    /// The morph weights (empty: none).
    pub weights: &'p [f64],
    /// The skin of the placing node, with the pose, where the node has one: the node's own transform is then
    /// ignored.
    pub skin: Option<(usize, &'p Pose)>,
    /// The placement's world matrix, for a primitive that is not skinned.
    pub world: DMat4,
}

/// Writes the positions of `primitive` (whose `POSITION` decoded to `base`) placed as `placing` says into
/// `positions` (cleared first), rounded to f32; returns whether skinning placed them. Errors name the accessor,
/// joint or vertex at fault, and a vertex whose position is not finite once placed.
pub(super) fn posed_positions(
    root: &Root,
    buffers: &mut Buffers<'_>,
    primitive: &gltf::json::mesh::Primitive,
    base: &Decoded,
    placing: &Placing<'_>,
    positions: &mut Vec<[f32; 3]>,
) -> Result<bool, Problem> {
    let vertex_count = base.count();
    let targets = morph_targets(buffers, primitive, placing.weights, vertex_count)?;
    // A placement without a skin reads no influences; a skinned one without `JOINTS_0` is placed as the others.
    let influences = match placing.skin {
        Some(_) => influence_sets(root, buffers, primitive, vertex_count)?,
        None => Vec::new(),
    };
    let skin = match placing.skin {
        Some((skin, pose)) if !influences.is_empty() => Some(joint_matrices(root, buffers, skin, pose)?),
        _ => None,
    };
    positions.clear();
    positions
        .try_reserve_exact(vertex_count)
        .map_err(|_| Problem::limit(format!("out of memory placing {vertex_count} vertices")))?;
    for v in 0..vertex_count {
        let at = |values: &[f64]| DVec3::new(values[3 * v], values[3 * v + 1], values[3 * v + 2]);
        let mut p = at(&base.values);
        for (weight, target) in &targets {
            p += *weight * at(&target.values);
        }
        let placed = match &skin {
            Some(matrices) => blend(matrices, &influences, v)?.transform_point3(p),
            None => placing.world.transform_point3(p),
        };
        let placed = placed.as_vec3().to_array();
        if !placed.iter().all(|c| c.is_finite()) {
            return Err(format!("vertex {v}: world position {placed:?} is not finite (node {})", placing.node).into());
        }
        positions.push(placed);
    }
    Ok(skin.is_some())
}

/// Each morph target with a `POSITION` and a weight other than 0, with that weight, its displacements checked to
/// be one VEC3 a vertex.
fn morph_targets(
    buffers: &mut Buffers<'_>,
    primitive: &gltf::json::mesh::Primitive,
    weights: &[f64],
    vertex_count: usize,
) -> Result<Vec<(f64, std::rc::Rc<Decoded>)>, Problem> {
    let targets = primitive.targets.as_deref().unwrap_or(&[]);
    if weights.len() > targets.len() {
        return Err(format!("{} morph weights for {} morph targets", weights.len(), targets.len()).into());
    }
    let mut used = Vec::new();
    for (k, (target, &weight)) in targets.iter().zip(weights).enumerate() {
        let Some(accessor) = target.positions.filter(|_| weight != 0.0) else { continue };
        let decoded = buffers.accessor(accessor.value()).map_err(|e| e.prefixed(&format!("morph target {k}: ")))?;
        if decoded.components != 3 || decoded.count() != vertex_count {
            return Err(format!(
                "morph target {k}: POSITION accessor {} has {} elements of {} components, not {vertex_count} VEC3",
                accessor.value(),
                decoded.count(),
                decoded.components
            )
            .into());
        }
        if let Some(i) = decoded.values.iter().position(|d| !d.is_finite()) {
            return Err(format!(
                "morph target {k}: POSITION accessor {}: vertex {} is not finite",
                accessor.value(),
                i / 3
            )
            .into());
        }
        used.push((weight, decoded));
    }
    Ok(used)
}

/// One influence set: per vertex four joint indices (into the skin's joints) and four weights, and the
/// accessors they came from (for messages).
struct Influences {
    set: u32,
    joints: (usize, std::rc::Rc<Decoded>),
    weights: (usize, std::rc::Rc<Decoded>),
}

/// The primitive's influence sets `JOINTS_n`, `WEIGHTS_n` for n = 0, 1, ... while both exist, each checked to
/// hold a VEC4 a vertex of the component types glTF allows (2.0, 3.7.3.3), and each weight finite and not
/// negative.
fn influence_sets(
    root: &Root,
    buffers: &mut Buffers<'_>,
    primitive: &gltf::json::mesh::Primitive,
    vertex_count: usize,
) -> Result<Vec<Influences>, Problem> {
    let mut sets = Vec::new();
    for n in 0u32.. {
        let joints = primitive.attributes.get(&Checked::Valid(Semantic::Joints(n)));
        let weights = primitive.attributes.get(&Checked::Valid(Semantic::Weights(n)));
        let (Some(joints), Some(weights)) = (joints, weights) else { break };
        let (joints, weights) = (joints.value(), weights.value());
        let component = |accessor: usize| {
            root.accessors.get(accessor).and_then(|a| match a.component_type {
                Checked::Valid(GenericComponentType(c)) => Some((c, a.normalized)),
                Checked::Invalid => None,
            })
        };
        if let Some((c, normalized)) = component(joints)
            && (normalized || !matches!(c, ComponentType::U8 | ComponentType::U16))
        {
            return Err(format!(
                "JOINTS_{n} accessor {joints}: componentType {c:?}{}; glTF allows unsigned bytes or shorts, not normalized",
                if normalized { ", normalized" } else { "" }
            )
            .into());
        }
        if let Some((c, normalized)) = component(weights)
            && !(c == ComponentType::F32 && !normalized
                || matches!(c, ComponentType::U8 | ComponentType::U16) && normalized)
        {
            return Err(format!(
                "WEIGHTS_{n} accessor {weights}: componentType {c:?}{}; glTF allows floats or normalized unsigned bytes or shorts",
                if normalized { ", normalized" } else { "" }
            )
            .into());
        }
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
        let joint_values = decode(buffers, joints, "JOINTS")?;
        let weight_values = decode(buffers, weights, "WEIGHTS")?;
        if let Some(i) = weight_values.values.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(format!(
                "WEIGHTS_{n} accessor {weights}: vertex {} weight {} is {}; glTF weights are finite and not negative",
                i / 4,
                i % 4,
                weight_values.values[i]
            )
            .into());
        }
        sets.push(Influences { set: n, joints: (joints, joint_values), weights: (weights, weight_values) });
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
            decoded.values.chunks_exact(16).map(DMat4::from_cols_slice).collect()
        }
        None => vec![DMat4::IDENTITY; json.joints.len()],
    };
    let mut matrices = Vec::with_capacity(json.joints.len());
    for (j, joint) in json.joints.iter().enumerate() {
        if joint.value() >= root.nodes.len() {
            return Err(format!("skin {skin}: joint {j} is node {}, which does not exist", joint.value()).into());
        }
        let matrix = pose.world(joint.value()) * inverse[j];
        if !matrix.is_finite() {
            return Err(
                format!("skin {skin}: joint {j} (node {})'s skinning matrix is not finite", joint.value()).into()
            );
        }
        matrices.push(matrix);
    }
    Ok(matrices)
}

/// Vertex `v`'s blend of its joints' matrices over every influence set, its weights normalized to sum 1; an
/// error naming the vertex when a weighed joint is not one of the skin's or no joint weighs it.
fn blend(matrices: &[DMat4], sets: &[Influences], v: usize) -> Result<DMat4, Problem> {
    let mut blended = DMat4::ZERO;
    let mut total = 0.0;
    for set in sets {
        let (accessor, joints) = (set.joints.0, &set.joints.1.values);
        for i in 0..4 {
            let (joint, weight) = (joints[4 * v + i], set.weights.1.values[4 * v + i]);
            if weight == 0.0 {
                continue;
            }
            let matrix = usize::try_from(joint as i64).ok().and_then(|j| matrices.get(j)).ok_or_else(|| {
                format!(
                    "JOINTS_{} accessor {accessor}: vertex {v} names joint {joint}, but the skin has {} joints",
                    set.set,
                    matrices.len()
                )
            })?;
            blended += *matrix * weight;
            total += weight;
        }
    }
    if total <= 0.0 {
        let accessors: Vec<String> =
            sets.iter().map(|s| format!("WEIGHTS_{} accessor {}", s.set, s.weights.0)).collect();
        return Err(format!(
            "vertex {v}: its weights ({}) sum to 0, so no joint moves it; glTF weights sum to 1",
            accessors.join(", ")
        )
        .into());
    }
    Ok(blended * (1.0 / total))
}
