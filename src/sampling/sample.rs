//! A conversion's ray sample: the training rays that weigh the collapses and the held-out rays that judge the
//! candidate trees, made once per conversion, or skipped where the scene is too small to gain from it.

use bvhc_loader::Ray;
use serde::Serialize;

use super::{RayTuning, TrainingRays, training_rays};
use crate::optimize::OptTree;

/// Scenes with fewer triangles are not sampled: their wide tree has a few dozen nodes at most, too few for the
/// weights to change it, and at most as many rays as triangles ([`MAX_RAYS_PER_TRIANGLE`]) would weigh little
/// against the prior of 32 rays (`docs/ray-tuning.md`).
pub const MIN_SAMPLED_TRIANGLES: usize = 1024;

/// Built-in training rays a triangle at most: scenes of fewer triangles than the budget get fewer rays, so that
/// sampling stays a small part of their conversion: a ray costs about 1.3 us on the fandisk (made, and traced
/// through each of the balanced preset's two candidates), and at one ray a triangle scenes of 4k-13k triangles
/// convert in 1.13-1.3x their time, at two 1.17-1.5x, at sixteen 1.9-2.3x (`docs/ray-tuning.md`).
pub const MAX_RAYS_PER_TRIANGLE: usize = 1;

/// Whether a conversion with ray tuning samples a scene of `triangle_count` triangles (at least
/// [`MIN_SAMPLED_TRIANGLES`]); the others are converted as without tuning.
pub fn scene_is_sampled(triangle_count: usize) -> bool {
    triangle_count >= MIN_SAMPLED_TRIANGLES
}

/// The held-out rays' seed for built-in training rays of seed `seed`: the next one.
pub fn held_out_seed(seed: u64) -> u64 {
    seed.wrapping_add(1)
}

/// What a conversion's sampling did (`sampling` in the metadata).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SamplingSummary {
    /// Why no rays were sampled, when none were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// Rays the collapses were weighed by.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub training_rays: Option<usize>,
    /// Rays the candidate trees were judged on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_rays: Option<usize>,
    /// The held-out rays' seed (built-in rays; a user's file gives its odd-numbered rays instead).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_seed: Option<u64>,
}

/// The rays of one conversion's sampling.
#[derive(Clone, Debug)]
pub struct RaySample {
    /// Rays whose visits weigh the collapses ([`super::node_visits`], [`super::ray_weights`]).
    pub training: Vec<Ray>,
    /// Rays the candidates are judged on ([`super::sampled_wide_work`]); none were trained on.
    pub held_out: Vec<Ray>,
    /// What was done, for the metadata.
    pub summary: SamplingSummary,
}

impl RaySample {
    /// Whether the conversion sampled rays (else the collapses and the choice use surface areas).
    pub fn is_sampled(&self) -> bool {
        self.summary.skipped.is_none()
    }

    /// The sample of a conversion with `tuning`, made over `tree` (any tree of the scene: the built-in rays use
    /// it only to find the camera rays' hits): none for a scene of fewer than [`MIN_SAMPLED_TRIANGLES`]
    /// triangles; else with the user's `rays`, their even-numbered rays (counted from 0) for training and the
    /// odd-numbered ones held out; else `min(tuning.rays, triangles)` built-in rays from `tuning.seed` and as
    /// many from [`held_out_seed`].
    pub fn new(tree: &OptTree, triangles: &[[[f32; 3]; 3]], tuning: &RayTuning, rays: Option<&TrainingRays>) -> Self {
        if !scene_is_sampled(triangles.len()) {
            let skipped = format!(
                "{} triangles, fewer than {MIN_SAMPLED_TRIANGLES}: too few for sampled rays to change the tree",
                triangles.len()
            );
            let summary = SamplingSummary { skipped: Some(skipped), ..SamplingSummary::default() };
            return RaySample { training: Vec::new(), held_out: Vec::new(), summary };
        }
        let (training, held_out, held_out_seed) = match rays {
            Some(user) => {
                let every_other = |first: usize| user.rays.iter().skip(first).step_by(2).copied().collect::<Vec<Ray>>();
                (every_other(0), every_other(1), None)
            }
            None => {
                let count = tuning.rays.min(MAX_RAYS_PER_TRIANGLE.saturating_mul(triangles.len()));
                let seed = held_out_seed(tuning.seed);
                let training = training_rays(tree, triangles, count, tuning.seed);
                (training, training_rays(tree, triangles, count, seed), Some(seed))
            }
        };
        let summary = SamplingSummary {
            skipped: None,
            training_rays: Some(training.len()),
            held_out_rays: Some(held_out.len()),
            held_out_seed,
        };
        RaySample { training, held_out, summary }
    }
}
