//! glTF extensions: which required ones bvhc can convert, and `EXT_mesh_gpu_instancing`.

use glam::{DMat4, DVec3};
use gltf::json::Root;

use super::Located;
use super::buffers::Buffers;
use super::pose::unit_quaternion;
use crate::import::Problem;
use crate::import::limits::Meter;

/// Extensions that change geometry and that bvhc decodes.
const DECODED: &[&str] = &["KHR_mesh_quantization", "EXT_mesh_gpu_instancing"];

/// Extensions that do not change geometry (materials, textures, lights, metadata): never an obstacle.
fn is_geometry_neutral(name: &str) -> bool {
    name.starts_with("KHR_materials_")
        || name.starts_with("KHR_texture_")
        || name.starts_with("EXT_texture_")
        || matches!(
            name,
            "KHR_lights_punctual"
                | "EXT_lights_image_based"
                | "KHR_xmp_json_ld"
                | "KHR_xmp"
                | "KHR_animation_pointer"
                | "KHR_techniques_webgl"
                | "EXT_materials_bump"
                | "KHR_node_visibility"
        )
}

/// Fails on a required extension that bvhc cannot honour, naming it and saying what to do.
pub(super) fn check_required(root: &Root) -> Result<(), Located> {
    for name in &root.extensions_required {
        let name = name.as_str();
        if DECODED.contains(&name) || is_geometry_neutral(name) {
            continue;
        }
        let message = match name {
            "KHR_draco_mesh_compression" => format!(
                "requires {name}: its geometry is Draco-compressed, which bvhc does not decode. Decompress it first, \
                 for example by importing it into Blender and exporting glTF without Draco compression, or with \
                 glTF-Transform (`gltf-transform cp` with the Draco extension disposed of)"
            ),
            "EXT_meshopt_compression" | "KHR_meshopt_compression" => format!(
                "requires {name}: its buffers are meshopt-compressed, which bvhc does not decode. Decompress it \
                 first, for example with gltfpack (`gltfpack -i IN -o OUT` without -c) or glTF-Transform"
            ),
            _ => format!(
                "requires the extension {name}, which bvhc does not know; it may change the geometry, so the file \
                 cannot be converted faithfully"
            ),
        };
        return Err(Located::new("extensionsRequired", message));
    }
    Ok(())
}

/// The instance count a node's `EXT_mesh_gpu_instancing` declares (its first attribute accessor's count),
/// `None` without the extension or a readable count.
pub(super) fn declared_instances(root: &gltf::json::Root, node: &gltf::json::Node) -> Option<u64> {
    let extension = node.extensions.as_ref()?.others.get("EXT_mesh_gpu_instancing")?;
    let attributes = extension.get("attributes")?.as_object()?;
    let index = ["TRANSLATION", "ROTATION", "SCALE"].iter().find_map(|name| attributes.get(*name)?.as_u64())?;
    Some(root.accessors.get(usize::try_from(index).ok()?)?.count.0)
}

/// The per-instance transforms of a node with `EXT_mesh_gpu_instancing`, `None` without it.
/// The instance count (the first attribute's declared accessor count) is taken from `placements` before any
/// accessor is decoded.
pub(super) fn instance_transforms(
    node: &gltf::json::Node,
    buffers: &mut Buffers<'_>,
    placements: &mut Meter,
) -> Result<Option<Vec<DMat4>>, Problem> {
    let Some(extension) = node.extensions.as_ref().and_then(|e| e.others.get("EXT_mesh_gpu_instancing")) else {
        return Ok(None);
    };
    let attributes = extension.get("attributes").and_then(|a| a.as_object());
    let Some(attributes) = attributes else {
        return Err("EXT_mesh_gpu_instancing without an attributes object".to_string().into());
    };
    let declared = ["TRANSLATION", "ROTATION", "SCALE"]
        .iter()
        .find_map(|name| attributes.get(*name).and_then(|v| v.as_u64()))
        .and_then(|index| buffers.declared_count(index as usize));
    placements.take(declared.unwrap_or(1)).map_err(|e| Problem::limit(format!("EXT_mesh_gpu_instancing: {e}")))?;
    let mut read = |name: &str, components: usize| -> Result<Option<std::rc::Rc<super::buffers::Decoded>>, Problem> {
        let Some(value) = attributes.get(name) else { return Ok(None) };
        let index = value.as_u64().ok_or_else(|| format!("EXT_mesh_gpu_instancing {name} is not an accessor index"))?;
        let decoded =
            buffers.accessor(index as usize).map_err(|e| e.prefixed(&format!("EXT_mesh_gpu_instancing {name}: ")))?;
        if decoded.components != components {
            return Err(format!(
                "EXT_mesh_gpu_instancing {name}: accessor has {} components, not {components}",
                decoded.components
            )
            .into());
        }
        Ok(Some(decoded))
    };
    let translation = read("TRANSLATION", 3)?;
    let rotation = read("ROTATION", 4)?;
    let scale = read("SCALE", 3)?;
    let counts: Vec<usize> = [(&translation, 3), (&rotation, 4), (&scale, 3)]
        .iter()
        .filter_map(|(values, n)| values.as_ref().map(|v| v.values.len() / n))
        .collect();
    let Some(&count) = counts.first() else {
        return Err("EXT_mesh_gpu_instancing has none of TRANSLATION, ROTATION, SCALE".to_string().into());
    };
    if counts.iter().any(|&c| c != count) {
        return Err(format!("EXT_mesh_gpu_instancing attributes have different counts {counts:?}").into());
    }
    let vector = |values: &Option<std::rc::Rc<super::buffers::Decoded>>, i: usize, default: DVec3| {
        values.as_ref().map_or(default, |v| DVec3::new(v.values[3 * i], v.values[3 * i + 1], v.values[3 * i + 2]))
    };
    let mut transforms = Vec::with_capacity(count);
    for i in 0..count {
        let r = match &rotation {
            None => glam::DQuat::IDENTITY,
            Some(v) => {
                unit_quaternion([v.values[4 * i], v.values[4 * i + 1], v.values[4 * i + 2], v.values[4 * i + 3]])
                    .ok_or_else(|| {
                        format!(
                            "EXT_mesh_gpu_instancing ROTATION: instance {i}'s rotation has length 0 or is not finite"
                        )
                    })?
            }
        };
        let (t, s) = (vector(&translation, i, DVec3::ZERO), vector(&scale, i, DVec3::ONE));
        transforms.push(DMat4::from_scale_rotation_translation(s, r, t));
    }
    Ok(Some(transforms))
}
