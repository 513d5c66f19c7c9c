//! Trees for an animation (`--animation`): a glTF scene's clips sampled at evenly spaced times, and the tree the
//! file stores (in the scene's default pose) chosen for the average of its costs when refit to each sampled pose,
//! not for the stored pose alone. A renderer that refits the file every frame of the animation then walks trees
//! that stay near a fresh build's cost across the clip (measured: `docs/animation.md`).
//!
//! The conversion: every sampled pose imported as the scene stands then ([`import_poses`], the records matched
//! by source id); the tree built and optimized in the stored pose as usual, without split references (a refit
//! boxes each record by its whole moved triangle, so a split reference would be worth nothing after it); then
//! reinsertion for the pose-averaged cost ([`optimize_for_poses`]); then the leaf merging and the wide and GPU
//! collapses weigh each node by its pose-averaged ray probability ([`node_weights`]) instead of its area in the
//! stored pose. The metadata's `animation` object records the poses, each one's cost and the worst
//! ([`AnimationRecord`]).
//!
//! With `--instancing always`, meshes that the clips only carry along (placed by a node a translation, rotation
//! or scale channel moves, and not deformed) stay instanced ([`crate::import::ImportOptions::moving_clips`]): the
//! file is two-level, each such placement an instance whose transform follows its node
//! ([`crate::posed::placed_pose`]), and the tree chosen for the poses is the flattened mesh 0's.

mod costs;
mod pose_boxes;
mod reinsert;
mod sample;

pub use costs::{
    AnimationRecord, MovingInstance, PoseCost, PoseCosts, ReinsertionRecord, animation_record, binary_cost_at,
    node_weights, wide_cost_at,
};
pub use pose_boxes::{MAX_POSES, PoseBoxes};
pub use reinsert::{PoseReinsertion, PoseReinsertionReport, average_cost, optimize_for_poses, pose_boxes_of};
pub use sample::{PoseSet, SampledPose, import_poses, sample_times, sampled_times};

use crate::import::ClipSelector;

/// Poses sampled in each clip unless told otherwise (`--animation-poses`): the measured point where more poses
/// stopped lowering the cost between samples (`docs/animation.md`).
pub const DEFAULT_POSES_PER_CLIP: u32 = 8;

/// Which clips a conversion samples, and how densely.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Animation {
    /// The clips by index or name; empty: every clip of the file.
    pub clips: Vec<ClipSelector>,
    /// Poses sampled in each clip, at the middles of equal parts of its keyframes' span (1 to
    /// [`MAX_POSES`] in all).
    pub poses_per_clip: u32,
    /// The part of each clip sampled (`--animation-window`): its span cut to these times; `None`, the whole span.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window: Option<TimeWindow>,
}

impl Default for Animation {
    fn default() -> Self {
        Animation { clips: Vec::new(), poses_per_clip: DEFAULT_POSES_PER_CLIP, window: None }
    }
}

/// A part of a clip, in seconds from the clip's time 0: for a tree chosen for the part an application plays (or
/// for one tree per part of a long clip, switched as it plays).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TimeWindow {
    /// Its first time.
    pub start: f64,
    /// Its last time, not before `start`.
    pub end: f64,
}

impl std::str::FromStr for TimeWindow {
    type Err = String;

    /// `START..END` in seconds (`2.5..5`), finite, `START <= END`.
    fn from_str(text: &str) -> Result<Self, String> {
        let (start, end) = text.split_once("..").ok_or_else(|| format!("'{text}': not START..END (seconds)"))?;
        let seconds = |part: &str| {
            part.trim()
                .parse::<f64>()
                .ok()
                .filter(|s| s.is_finite())
                .ok_or_else(|| format!("'{text}': '{}' is not a finite number of seconds", part.trim()))
        };
        let (start, end) = (seconds(start)?, seconds(end)?);
        if start > end {
            return Err(format!("'{text}': the window ends before it starts"));
        }
        Ok(TimeWindow { start, end })
    }
}

impl Animation {
    /// The clips of a comma-separated list of indices and names (`0,Run`); an empty text names every clip.
    pub fn parse_clips(text: &str) -> Result<Vec<ClipSelector>, String> {
        if text.trim().is_empty() {
            return Ok(Vec::new());
        }
        text.split(',')
            .map(|part| match part.trim() {
                "" => Err(format!("'{text}': an empty clip name")),
                name => Ok(name.parse::<usize>().map_or(ClipSelector::Name(name.to_string()), ClipSelector::Index)),
            })
            .collect()
    }
}
