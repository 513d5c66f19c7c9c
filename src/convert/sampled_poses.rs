//! An animation's sampled poses in a conversion: the times chosen before the import (so that the memory budget
//! counts their triangles and boxes), and each pose imported as the stored one was, for the part of the scene
//! the poses deform.

use std::path::Path;
use std::time::Instant;

use bvhc_loader::format::SourceRange;

use super::candidates::lap;
use super::report::{ConvertError, Timings};
use crate::animation::{PoseSet, SampledPose, import_poses};
use crate::import::{ClipSpan, ImportOptions};

/// What `poses` sampled poses add to a conversion's peak, a triangle: its corners in each pose (36 bytes) and two
/// nodes' boxes in each of the pose lanes (the count rounded up to 8: `crate::animation::PoseBoxes`).
pub(super) fn pose_bytes_per_triangle(poses: usize) -> u64 {
    let lanes = poses.next_multiple_of(8).max(8) as u64;
    36 * poses as u64 + 2 * 24 * lanes
}

/// An animation's sampled times, and the import options that imported its stored pose (each pose is imported
/// alike).
pub(super) struct SampledAnimation {
    pub sampled: (Vec<ClipSpan>, Vec<SampledPose>),
    pub import: ImportOptions,
}

impl SampledAnimation {
    /// The stored pose's triangles `ids` (of the import with source ranges `sources`) at each sampled time, after a
    /// probe that they and the optimizer's boxes can be allocated (their time added to the import's).
    pub(super) fn import_poses(
        self,
        input: &Path,
        sources: &[SourceRange],
        ids: &[u32],
        timings: &mut Timings,
    ) -> Result<PoseSet, ConvertError> {
        let clock = Instant::now();
        let bytes = (ids.len() as u64).saturating_mul(pose_bytes_per_triangle(self.sampled.1.len()));
        crate::fallible::probe(usize::try_from(bytes).unwrap_or(usize::MAX), "sampling the animation's poses")
            .map_err(|e| super::part::out_of_memory(input, "sampling the animation's poses", e))?;
        let poses = import_poses(input, &self.import, self.sampled, sources, ids)?;
        timings.import += lap(clock);
        Ok(poses)
    }
}
