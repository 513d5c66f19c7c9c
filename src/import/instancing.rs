//! Which glTF meshes stay instanced, and what the import hands the pipeline for them.
//!
//! A mesh placed more than once (by several nodes, or by `EXT_mesh_gpu_instancing`) can be stored once in its
//! object space and placed by instances (format 1.3), or flattened into world-space triangles for every
//! placement. Flattened is faster to trace (no transform per ray, a better tree where the placements overlap);
//! instanced costs a fraction of the memory and build time. [`Instancing::Auto`] keeps a mesh instanced when its
//! extra placements add at least [`AUTO_MIN_SAVED_TRIANGLES`] triangles, or when the flattened scene would not
//! fit the memory budget; everything else is flattened.

use std::ops::Range;

use bvhc_loader::format::{Affine3x4, InstanceRecord};
use glam::DMat4;

/// Whether a conversion keeps meshes placed more than once as instances (glTF inputs; OBJ and PLY files place
/// each model once).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Instancing {
    /// Instance a mesh whose extra placements add at least 2^20 (1,048,576) triangles, or every repeated mesh
    /// when the flattened scene would not fit the memory budget; flatten the rest.
    #[default]
    Auto,
    /// Instance every mesh placed more than once, and with `--animation` every mesh its clips move rigidly (see
    /// `ImportOptions::moving_clips`).
    Always,
    /// Flatten every placement (a one-level file).
    Never,
}

impl Instancing {
    /// The name used in options.
    pub fn name(self) -> &'static str {
        match self {
            Instancing::Auto => "auto",
            Instancing::Always => "always",
            Instancing::Never => "never",
        }
    }
}

/// [`Instancing::Auto`] instances a mesh when flattening its extra placements would add at least this many
/// triangles: 2^20, about 5 s of conversion on 2 cores and 280 MB at the peak at the rates `docs/scale.md`
/// measures, against a trace slowdown of the instanced scene that `docs/instancing.md` measures.
pub const AUTO_MIN_SAVED_TRIANGLES: u64 = 1 << 20;

/// A glTF mesh kept instanced: its triangles in the soup (object space, stored once) and its placements.
#[derive(Clone, Debug, PartialEq)]
pub struct InstancedMesh {
    /// The glTF mesh.
    pub mesh_index: u32,
    /// Its triangles: `soup.triangles[range]` (and the parallel arrays), in object space.
    pub triangles: Range<usize>,
    /// Its placements, in the order the scene places them.
    pub placements: Vec<MeshPlacement>,
}

/// One placement of an instanced mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshPlacement {
    /// Object space to world space, rounded to f32 (a valid instance transform, rule V42).
    pub object_to_world: Affine3x4,
    /// The glTF node.
    pub node_index: u32,
    /// The node's `EXT_mesh_gpu_instancing` instance, or `NO_INDEX`.
    pub gpu_instance_index: u32,
    /// Whether the import's moving clips ([`super::ImportOptions::moving_clips`]) move the node.
    pub moving: bool,
}

/// Which meshes to instance, given each mesh's placements and triangles (declared counts), and whether a scene
/// of a given number of stored triangles fits the memory budget.
pub(crate) fn choose_instanced(
    mode: Instancing,
    placements: &[u64],
    triangles: &[u64],
    fits: impl Fn(u64) -> bool,
) -> Vec<bool> {
    let repeated = |m: usize| placements[m] >= 2 && triangles[m] > 0;
    let count = placements.len();
    let mut chosen: Vec<bool> = match mode {
        Instancing::Never => vec![false; count],
        Instancing::Always => (0..count).map(repeated).collect(),
        Instancing::Auto => (0..count)
            .map(|m| repeated(m) && triangles[m].saturating_mul(placements[m] - 1) >= AUTO_MIN_SAVED_TRIANGLES)
            .collect(),
    };
    if mode == Instancing::Auto && !fits(stored_triangles(placements, triangles, &chosen)) {
        chosen = (0..count).map(repeated).collect();
    }
    chosen
}

/// Triangles a scene stores: an instanced mesh's once, a flattened mesh's once a placement.
pub(crate) fn stored_triangles(placements: &[u64], triangles: &[u64], instanced: &[bool]) -> u64 {
    (0..placements.len())
        .map(|m| if instanced[m] { triangles[m] } else { triangles[m].saturating_mul(placements[m]) })
        .fold(0, u64::saturating_add)
}

/// `world` as the rows of a 3x4 map rounded to f32, when that is a valid instance transform (rule V42).
pub(crate) fn affine(world: &DMat4) -> Option<Affine3x4> {
    let m: Affine3x4 = std::array::from_fn(|i| std::array::from_fn(|j| world.col(j)[i] as f32));
    InstanceRecord::placing(0, m).map(|_| m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_instances_what_saves_a_million_triangles_or_what_memory_needs() {
        // Mesh 0: 4,000 triangles placed 10,000 times; 1: 871k placed 9 times; 2: 5k placed 4 times; 3: once.
        let placements = [10_000, 9, 4, 1];
        let triangles = [4_000, 871_414, 5_000, 1_000_000];
        let roomy = |_| true;
        assert_eq!(choose_instanced(Instancing::Auto, &placements, &triangles, roomy), [true, true, false, false]);
        assert_eq!(choose_instanced(Instancing::Always, &placements, &triangles, roomy), [true, true, true, false]);
        assert_eq!(choose_instanced(Instancing::Never, &placements, &triangles, roomy), [false; 4]);
        // Memory for 702,000 triangles: the base choice stores 703,000, so every repeated mesh is instanced.
        let tight = |stored| stored < 702_000;
        assert_eq!(choose_instanced(Instancing::Auto, &[3, 3], &[1_000, 700_000], tight), [true, true]);
        assert_eq!(stored_triangles(&[3, 3], &[1_000, 700_000], &[false, true]), 703_000);
    }
}
