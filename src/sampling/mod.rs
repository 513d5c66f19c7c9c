//! Trees tuned to the rays users trace: sample rays traced through the optimized binary tree give each node the
//! measured probability that a ray reaches it, which replaces the surface-area estimate in the wide and GPU
//! collapses (Gu, He, Blelloch, "Ray Specialized Contraction on Bounding Volume Hierarchies", Computer Graphics
//! Forum 34(7), 2015; Bittner and Havran, "RDH: Ray Distribution Heuristics", SCCG 2009). Where few sample rays
//! reach a node, its estimate leans on the surface-area one, as RSC blends them.
//!
//! [`RaySample`] holds a conversion's rays: training rays of the built-in distribution ([`training_rays`], made
//! from the scene and a seed) or of a user's ray file ([`TrainingRays`]), and held-out rays that no collapse was
//! trained on, which judge the candidate trees by the work a wide kernel does for them ([`sampled_wide_work`]).
//! Tiny scenes are not sampled. [`node_visits`] counts, per node, the rays that reached it (in parallel, with
//! the same counts for any thread count: counts are integer sums); [`ray_weights`] turns counts into the
//! collapse's weights.

mod ray_file;
mod rays;
mod sample;
mod trace;
mod wide_cost;

pub use ray_file::{RAY_RECORD_BYTE_LEN, TrainingRays, parse_rays, read_ray_file};
pub use rays::training_rays;
pub use sample::{
    MAX_RAYS_PER_TRIANGLE, MIN_SAMPLED_TRIANGLES, RaySample, SamplingSummary, held_out_seed, scene_is_sampled,
};
pub use trace::{SampleHit, trace_counting};
pub use wide_cost::{WideWork, sampled_wide_work};

use bvhc_loader::Ray;
use rayon::prelude::*;

use crate::optimize::{NONE, OptTree};

/// How a conversion samples rays to tune its wide and GPU collapses (`build.ray_tuning` in the metadata).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RayTuning {
    /// Training rays of the built-in distribution ([`training_rays`]).
    pub rays: usize,
    /// Their seed.
    pub seed: u64,
    /// The surface-area estimate's weight, in sample rays, in each node's blended probability ([`ray_weights`]).
    pub prior: f64,
    /// With a user's ray file (`--train-rays`) instead of the built-in rays: the XXH3-64 of its bytes, recorded
    /// as `xxh3-64:<16 hex digits>` (`rays` is then the file's count and `seed` 0).
    #[serde(skip_serializing_if = "Option::is_none", serialize_with = "content_hash")]
    pub training_file: Option<u64>,
}

/// `xxh3-64:<16 hex digits>`, as the metadata's input hashes are written.
fn content_hash<S: serde::Serializer>(hash: &Option<u64>, serializer: S) -> Result<S::Ok, S::Error> {
    match hash {
        Some(h) => serializer.serialize_str(&format!("xxh3-64:{h:016x}")),
        None => serializer.serialize_none(),
    }
}

impl Default for RayTuning {
    /// 2^16 rays, seed 1, a prior worth 32 rays.
    fn default() -> Self {
        RayTuning { rays: 1 << 16, seed: 1, prior: 32.0, training_file: None }
    }
}

/// Rays traced a chunk at a time, each chunk's counts summed into the total.
const CHUNK: usize = 4096;

/// Per node of `tree`, how many of `rays` entered its box on the way to their closest hit.
pub fn node_visits(tree: &OptTree, triangles: &[[[f32; 3]; 3]], rays: &[Ray]) -> Vec<u32> {
    let zero = || vec![0u32; tree.nodes.len()];
    rays.par_chunks(CHUNK)
        .fold(zero, |mut visits, chunk| {
            for ray in chunk {
                trace_counting(tree, triangles, ray, &mut visits);
            }
            visits
        })
        .reduce(zero, |mut a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                *x = x.saturating_add(y);
            }
            a
        })
}

/// The collapse's weight of each node: `(visits(n) + prior * SA(n) / SA(root)) / (visits(root) + prior)`, the
/// sampled probability that a ray through the scene reaches `n`, blended with the surface-area estimate by a
/// prior worth `prior` rays (RSC's smoothing). With no sample rays it is `SA(n) / SA(root)`: the SAH collapse.
pub fn ray_weights(tree: &OptTree, visits: &[u32], prior: f64) -> Vec<f64> {
    if tree.root == NONE {
        return Vec::new();
    }
    let root_area = tree.nodes[tree.root as usize].aabb.surface_area();
    let root_visits = f64::from(visits.get(tree.root as usize).copied().unwrap_or(0));
    let share = |area: f64| if root_area > 0.0 { area / root_area } else { 1.0 };
    tree.nodes
        .iter()
        .zip(visits)
        .map(|(node, &v)| (f64::from(v) + prior * share(node.aabb.surface_area())) / (root_visits + prior))
        .collect()
}

/// The collapse weights of `tree`: the visits of `sample`'s training rays ([`node_visits`]) blended with the
/// surface areas by `tuning.prior` ([`ray_weights`]).
pub fn tuned_weights(tree: &OptTree, triangles: &[[[f32; 3]; 3]], tuning: &RayTuning, sample: &RaySample) -> Vec<f64> {
    ray_weights(tree, &node_visits(tree, triangles, &sample.training), tuning.prior)
}
