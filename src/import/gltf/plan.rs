//! What a glTF import will decode, counted from the JSON alone before any accessor is read: every accessor that
//! one of the import's readers takes (a placed primitive's `POSITION` and indices, its morph targets' `POSITION`,
//! a skinned placement's `JOINTS_n` and `WEIGHTS_n` and its skin's inverse bind matrices, the
//! `EXT_mesh_gpu_instancing` attributes of a placing node, the samplers of the animation clips it samples, and
//! the sparse substitutions of each), once each. A few hundred bytes of JSON can declare accessors of billions of
//! elements; their sum is held to the decoded-values limit here, the values the accessors without a
//! `bufferView` fill with zeros (which no buffer bounds) to an eighth of it, and the memory the decoded values
//! take counts in the conversion's memory estimate, all before the first allocation.

use std::collections::BTreeSet;

use gltf::json::Root;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::buffers::components_of;
use crate::import::limits::limit_message;
use crate::import::{ErrorKind, Located};

/// Bytes an accessor value takes once decoded (the importer decodes to f64 and keeps each accessor once).
pub(super) const BYTES_PER_DECODED_VALUE: u64 = 8;

/// The accessors an import reads and what they declare.
#[derive(Debug, Default)]
pub(super) struct DecodePlan {
    /// Accessor indices, each once, in increasing order.
    accessors: BTreeSet<usize>,
}

impl DecodePlan {
    /// The accessors that the scene under `roots` makes the import read (the nodes that `reached` flags place
    /// meshes), with the samplers of the animation clips `clips`.
    pub(super) fn of_scene(root: &Root, reached: &[bool], clips: &[usize]) -> DecodePlan {
        let mut plan = DecodePlan::default();
        for (index, node) in root.nodes.iter().enumerate() {
            if !reached.get(index).copied().unwrap_or(false) {
                continue;
            }
            let skinned = node.skin.is_some();
            if let Some(mesh) = node.mesh.and_then(|m| root.meshes.get(m.value())) {
                for primitive in &mesh.primitives {
                    plan.add_primitive(primitive, skinned);
                }
            }
            if let Some(skin) = node.skin.and_then(|s| root.skins.get(s.value())) {
                plan.accessors.extend(skin.inverse_bind_matrices.map(|a| a.value()));
            }
            let instancing = node.extensions.as_ref().and_then(|e| e.others.get("EXT_mesh_gpu_instancing"));
            if let Some(attributes) = instancing.and_then(|e| e.get("attributes")).and_then(|a| a.as_object()) {
                let indices = attributes.values().filter_map(|v| v.as_u64()).filter_map(|i| usize::try_from(i).ok());
                plan.accessors.extend(indices);
            }
        }
        plan.add_clips(root, clips);
        plan
    }

    /// The accessors of the samplers of the animation clips `clips` (those that exist).
    pub(super) fn of_clips(root: &Root, clips: &[usize]) -> DecodePlan {
        let mut plan = DecodePlan::default();
        plan.add_clips(root, clips);
        plan
    }

    fn add_clips(&mut self, root: &Root, clips: &[usize]) {
        for animation in clips.iter().filter_map(|&c| root.animations.get(c)) {
            for sampler in &animation.samplers {
                self.accessors.extend([sampler.input.value(), sampler.output.value()]);
            }
        }
    }

    /// A primitive of a placed mesh: nothing for points and lines (never decoded), else its `POSITION`, indices
    /// and morph targets' `POSITION`, and with a skin its influence sets.
    fn add_primitive(&mut self, primitive: &gltf::json::mesh::Primitive, skinned: bool) {
        if matches!(primitive.mode, Checked::Valid(Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip)) {
            return;
        }
        let Some(position) = primitive.attributes.get(&Checked::Valid(Semantic::Positions)) else { return };
        self.accessors.insert(position.value());
        self.accessors.extend(primitive.indices.map(|i| i.value()));
        for target in primitive.targets.iter().flatten() {
            self.accessors.extend(target.positions.map(|p| p.value()));
        }
        if skinned {
            for n in 0u32.. {
                let joints = primitive.attributes.get(&Checked::Valid(Semantic::Joints(n)));
                let weights = primitive.attributes.get(&Checked::Valid(Semantic::Weights(n)));
                let (Some(joints), Some(weights)) = (joints, weights) else { break };
                self.accessors.extend([joints.value(), weights.value()]);
            }
        }
    }

    /// The values the planned accessors declare: their elements times components, plus their sparse
    /// substitutions (an index and the components each). Accessors that do not exist or have no valid type count
    /// nothing here (decoding them reports them).
    fn values<'a>(&'a self, root: &'a Root) -> impl Iterator<Item = (usize, u64, bool)> + 'a {
        self.accessors.iter().filter_map(move |&index| {
            let accessor = root.accessors.get(index)?;
            let Checked::Valid(kind) = accessor.type_ else { return None };
            let components = components_of(kind) as u64;
            let sparse = accessor.sparse.as_ref().map_or(0, |s| s.count.0.saturating_mul(components + 1));
            let values = accessor.count.0.saturating_mul(components).saturating_add(sparse);
            Some((index, values, accessor.buffer_view.is_none()))
        })
    }

    /// Checks the planned accessors against `max_decoded_values` (their sum) and an eighth of it (the values of
    /// those without a `bufferView`, zero-filled); returns the sum. Errors name the accessor that crosses the
    /// limit, the total and the option that raises it.
    pub(super) fn check(&self, root: &Root, max_decoded_values: u64) -> Result<u64, Located> {
        let zero_limit = max_decoded_values / 8;
        let (mut total, mut zero_filled) = (0u64, 0u64);
        for (index, values, zeros) in self.values(root) {
            total = total.saturating_add(values);
            let at = format!("accessor {index}");
            if total > max_decoded_values {
                let message = format!(
                    "declares {values} values; with the other accessors the scene reads, {}",
                    limit_message(total, max_decoded_values, "accessor values", "--max-decoded-values")
                );
                return Err(Located::of_kind(ErrorKind::Limit, &at, message));
            }
            if zeros {
                zero_filled = zero_filled.saturating_add(values);
                if zero_filled > zero_limit {
                    let message = format!(
                        "declares {values} values without a bufferView, zeros that no buffer bounds: {zero_filled} such \
                         values in the accessors the scene reads exceed the import limit of {zero_limit}, an eighth of \
                         the decoded values (raise it with --max-decoded-values)"
                    );
                    return Err(Located::of_kind(ErrorKind::Limit, &at, message));
                }
            }
        }
        Ok(total)
    }
}
