//! What a refit tells its caller: the refit tree's costs against the costs the file was optimized to
//! ([`RefitReport`]), and when to convert again ([`RebuildPolicy`]). A refit keeps the tree's shape, so as the
//! triangles move away from the pose the tree was built for, its boxes grow and overlap and rays visit more of
//! them; the usual test of that decay compares the refit tree's SAH cost with the original's and rebuilds past a
//! ratio (Lauterbach, Yoon, Tuft, Manocha, "RT-DEFORM: Interactive Ray Tracing of Dynamic Scenes using BVHs",
//! IEEE Symposium on Interactive Ray Tracing 2006, section 4.2). The costs are the format's (5.6 for the binary
//! tree, 6.1 for the wide tree), each normalized by its root's area, so a scene that only grows or moves keeps its
//! ratio at 1.

use crate::format::cost::{AreaSums, BinaryCost};
use crate::open::view::BvhView;
use crate::verify::costs::{CostsOf, stated_costs};
use crate::verify::json::Map;
use crate::verify::metadata::parsed_metadata;

/// A refit tree's costs beside the costs the file's metadata states (those of the tree at the pose it was
/// converted at, which a refit leaves in the metadata). A cost the file does not state (no metadata, or no wide
/// sections) is `None` on both sides.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefitReport {
    /// The binary tree's SAH cost now (section 5.6, under the metadata's `c_t` and `c_i`).
    pub cost: Option<f64>,
    /// The binary tree's SAH cost the metadata states (`cost.sah_cost`).
    pub file_cost: Option<f64>,
    /// The wide tree's cost now (section 6.1, under the metadata's `node_visit` and `packet_test`): the cost of
    /// the tree the CPU kernel walks.
    pub wide_cost: Option<f64>,
    /// The wide tree's cost the metadata states (`wide.cost`).
    pub file_wide_cost: Option<f64>,
    /// For a tree chosen for an animation (`bvhc --animation`): the largest [`RefitReport::cost_ratio`] that a
    /// refit to one of the poses it was chosen for reaches: the largest of the costs the metadata's `animation`
    /// object states for its poses (format spec 5.5; wide where both the poses and the file state wide costs),
    /// over the cost the file states. Computed from the poses, not read from `worst_cost_ratio`, so that it stays
    /// true after a refit restated the file's costs (the poses' costs are the tree's, whichever pose the records
    /// hold). `None` for other files.
    pub planned_cost_ratio: Option<f64>,
}

impl RefitReport {
    /// The costs of `view` (just refit), from the area sums its refits made, beside its metadata's.
    pub(crate) fn of(view: &BvhView<'_>, sums: &RefitSums) -> RefitReport {
        let mut report = RefitReport::default();
        let Ok(Some(metadata)) = parsed_metadata(view) else { return report };
        for stated in stated_costs(view, &metadata, sums) {
            match stated.name {
                "cost.sah_cost" => {
                    (report.cost, report.file_cost) = (Some(stated.computed), Some(stated.stated.value()))
                }
                "wide.cost" => {
                    (report.wide_cost, report.file_wide_cost) = (Some(stated.computed), Some(stated.stated.value()))
                }
                _ => {}
            }
        }
        report.planned_cost_ratio = planned_ratio(&metadata, report.file_cost, report.file_wide_cost);
        report
    }

    /// How much costlier the refit tree is than the file's own: the wide tree's cost over the stated one where
    /// the file has both (the tree the CPU kernel walks), else the binary tree's; 1 when neither is stated (no
    /// metadata to compare with) or the stated cost is 0.
    pub fn cost_ratio(&self) -> f64 {
        let ratio = |now: Option<f64>, then: Option<f64>| match (now, then) {
            (Some(now), Some(then)) if then > 0.0 => Some(now / then),
            _ => None,
        };
        ratio(self.wide_cost, self.file_wide_cost).or(ratio(self.cost, self.file_cost)).unwrap_or(1.0)
    }
}

/// The largest cost the metadata's `animation.poses` state over the cost the file states (`stated_sah`, and
/// `stated_wide` where it has wide sections): wide costs where the file states one and every pose has one, else
/// binary costs. `None` without poses.
fn planned_ratio(metadata: &Map, stated_sah: Option<f64>, stated_wide: Option<f64>) -> Option<f64> {
    let poses = metadata.object("animation")?.get("poses")?.as_array()?;
    let largest =
        |key: &str| poses.iter().try_fold(0.0f64, |most, pose| Some(most.max(pose.as_object()?.number(key)?)));
    let (most, stated) = match (stated_wide, largest("wide_cost")) {
        (Some(stated), Some(most)) => (most, stated),
        _ => (largest("sah_cost")?, stated_sah?),
    };
    let ratio = most / stated;
    (!poses.is_empty() && ratio.is_finite() && ratio > 0.0).then_some(ratio)
}

impl BvhView<'_> {
    /// For a tree chosen for an animation (`bvhc --animation`): the largest [`RefitReport::cost_ratio`] a refit to
    /// one of the poses it was chosen for reaches, [`RefitReport::planned_cost_ratio`] before any refit: the
    /// largest of the costs the metadata's `animation.poses` state over the cost the file states. `None` for other
    /// files.
    pub fn planned_cost_ratio(&self) -> Option<f64> {
        let metadata = parsed_metadata(self).ok()??;
        let stated_sah = metadata.object("cost").and_then(|cost| cost.number("sah_cost"));
        let stated_wide = metadata.object("wide").and_then(|wide| wide.number("cost"));
        planned_ratio(&metadata, stated_sah, stated_wide)
    }
}

/// A refit file's box areas, summed by the refits as they make the boxes, for the costs the metadata's rule
/// compares (sections 5.6 and 6.1): the same sums in another order than the spec's running sums, so equal to them
/// within rounding (far inside V37's tolerance), not bit for bit.
#[derive(Default)]
pub(crate) struct RefitSums {
    /// The binary root's area.
    pub(crate) root_area: f64,
    /// The binary tree's sums.
    pub(crate) binary: AreaSums,
    /// The wide tree's sums (zero without the wide sections).
    pub(crate) wide: AreaSums,
}

impl CostsOf for RefitSums {
    fn binary(&self, c_t: f64, c_i: f64) -> BinaryCost {
        self.binary.binary_cost(self.root_area, c_t, c_i)
    }

    fn wide(&self, node_visit: f64, packet_test: f64) -> f64 {
        self.wide.wide_cost(self.root_area, node_visit, packet_test)
    }
}

/// When a refit tree has decayed enough that converting the posed geometry again pays: past a cost ratio
/// ([`RefitReport::cost_ratio`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RebuildPolicy {
    /// Rebuild when the refit tree's cost exceeds the file's by this factor.
    pub max_cost_ratio: f64,
}

impl RebuildPolicy {
    /// Rebuild past a cost ratio of 1.2. On the bend benchmark (`cargo bench --bench refit`, `docs/loader.md`)
    /// the refit trees past 1.2 traced 13-33% slower than fresh conversions of the same geometry (one of five,
    /// BrainStem's, 3%), those below it 0-20% slower: the ratio compares the refit tree with the converted
    /// pose's tree, not with the best tree for the new pose, so it misses decay where the new pose's best tree
    /// is cheaper than the old one (the bent dragon), and a threshold is a compromise. Measure your own
    /// animation's curve with the benchmark's method where the choice matters.
    pub const DEFAULT: RebuildPolicy = RebuildPolicy { max_cost_ratio: 1.2 };

    /// The policy of `max_cost_ratio`, checked: a finite ratio of at least 1 (a smaller one would call every
    /// refit tree, even an unchanged one, worth rebuilding). The command line's `--max-cost-ratio` and the
    /// bindings refuse the same values with this message.
    pub fn new(max_cost_ratio: f64) -> Result<RebuildPolicy, String> {
        match max_cost_ratio >= 1.0 && max_cost_ratio.is_finite() {
            true => Ok(RebuildPolicy { max_cost_ratio }),
            false => Err(format!("max_cost_ratio {max_cost_ratio}: a finite ratio of at least 1")),
        }
    }

    /// Whether the tree `report` describes should be rebuilt: its cost ratio exceeds `max_cost_ratio`, or for a
    /// tree chosen for an animation, `max_cost_ratio` times the ratio its poses were planned to reach
    /// ([`RefitReport::planned_cost_ratio`], when above 1). Such a file stores one pose and measured the others:
    /// a pose of BrainStem's clip reads a ratio up to 2.2 to the stored pose while its refit tree stays within 1.05
    /// of a fresh conversion's cost (`docs/animation.md`), so the plain threshold would rebuild at every frame for
    /// nothing; a pose beyond the plan still crosses the threshold.
    pub fn should_rebuild(&self, report: &RefitReport) -> bool {
        report.cost_ratio() > self.max_cost_ratio * report.planned_cost_ratio.unwrap_or(1.0).max(1.0)
    }
}

impl Default for RebuildPolicy {
    fn default() -> RebuildPolicy {
        RebuildPolicy::DEFAULT
    }
}
