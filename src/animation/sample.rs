//! The poses an animation's tree is chosen for: times spread over the chosen clips, and the scene imported as it
//! stands at each, its triangles in the order of the stored pose's.

use std::path::Path;

use super::{Animation, MAX_POSES, TimeWindow};
use bvhc_loader::format::SourceRange;

use crate::import::{ClipSelector, ClipSpan, ErrorKind, ImportError, ImportOptions, PoseSelector};

/// A sampled time of one clip.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SampledPose {
    /// The clip's index in the file.
    pub clip: usize,
    /// The time, in seconds.
    pub seconds: f64,
}

/// Every sampled pose and the scene's triangles in each.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseSet {
    /// The clips sampled.
    pub clips: Vec<ClipSpan>,
    /// The poses, clip by clip, in time order.
    pub poses: Vec<SampledPose>,
    /// `triangles[k][t]`: triangle `t` of the stored pose (the conversion's order) as it stands in pose `k`.
    pub triangles: Vec<Vec<[[f32; 3]; 3]>>,
}

/// The times `animation` samples in `spans` (the file's clips): `poses_per_clip` in each chosen clip, at the
/// middles of equal parts of its span cut to the animation's window (one at its start when that is one time).
/// Refused: a file without clips, a clip that does not exist, a window that leaves no time of a chosen clip, no
/// pose or more than [`MAX_POSES`].
pub fn sample_times(spans: &[ClipSpan], animation: &Animation) -> Result<(Vec<ClipSpan>, Vec<SampledPose>), String> {
    if spans.is_empty() {
        return Err("the file has no animation clips to sample".into());
    }
    let names = || spans.iter().map(|s| s.name.clone().unwrap_or_default()).collect::<Vec<_>>();
    let chosen: Vec<ClipSpan> = if animation.clips.is_empty() {
        spans.to_vec()
    } else {
        let mut chosen: Vec<ClipSpan> = Vec::new();
        for selector in &animation.clips {
            let span = match selector {
                ClipSelector::Index(i) => spans
                    .get(*i)
                    .ok_or_else(|| format!("animation {i} does not exist (the file has {})", spans.len()))?,
                ClipSelector::Name(name) => spans
                    .iter()
                    .find(|s| s.name.as_deref() == Some(name))
                    .ok_or_else(|| format!("no animation is named '{name}' (names: {:?})", names()))?,
            };
            if !chosen.iter().any(|c| c.index == span.index) {
                chosen.push(span.clone());
            }
        }
        chosen
    };
    let per_clip = animation.poses_per_clip as usize;
    if per_clip == 0 {
        return Err("--animation-poses: at least 1 pose a clip".into());
    }
    let mut poses = Vec::new();
    for span in &chosen {
        let (start, end) = sampled_part(span, animation.window)?;
        let length = end - start;
        let count = if length > 0.0 { per_clip } else { 1 };
        for j in 0..count {
            let seconds = start + length * (j as f64 + 0.5) / count as f64;
            poses.push(SampledPose { clip: span.index, seconds: if length > 0.0 { seconds } else { start } });
        }
    }
    if poses.len() > MAX_POSES {
        return Err(format!(
            "{} poses ({} clips at {per_clip} a clip) are more than {MAX_POSES}: choose fewer clips or lower \
             --animation-poses",
            poses.len(),
            chosen.len()
        ));
    }
    Ok((chosen, poses))
}

/// The times of `span` that are sampled: its keyframes' span, cut to `window` where there is one. Refused: a
/// window that leaves no time of the clip.
fn sampled_part(span: &ClipSpan, window: Option<TimeWindow>) -> Result<(f64, f64), String> {
    let Some(window) = window else {
        return Ok((span.start, span.end));
    };
    let (start, end) = (span.start.max(window.start), span.end.min(window.end));
    if start > end {
        return Err(format!(
            "--animation-window {}..{} leaves no time of clip {} (its keyframes span {}..{} s)",
            window.start, window.end, span.index, span.start, span.end
        ));
    }
    Ok((start, end))
}

/// The clips `animation` samples in the glTF file at `input` and its times in them ([`sample_times`] on the
/// file's clips), an error naming the file where it cannot.
pub fn sampled_times(
    input: &Path,
    import: &ImportOptions,
    animation: &Animation,
) -> Result<(Vec<ClipSpan>, Vec<SampledPose>), ImportError> {
    let spans = crate::import::animation_clips(input, import)?;
    sample_times(&spans, animation).map_err(|message| refused(input, message))
}

fn refused(input: &Path, message: String) -> ImportError {
    ImportError { path: input.to_path_buf(), location: "animations".into(), message, kind: ErrorKind::Invalid }
}

/// The scene's triangles in each of `poses` of the glTF file at `input`: the triangles with source ids `ids` (the
/// stored pose's, in its order) found by their ids in each pose's import (`import`'s scene, limits, instancing
/// and moving clips, degenerate triangles kept so that one a pose flattens keeps its place). Each pose's import
/// must place the primitives the stored one did (`sources`, its source ranges): a placement that a pose would
/// flatten instead of instancing (a moving node's transform singular at that time) is refused naming it.
pub fn import_poses(
    input: &Path,
    import: &ImportOptions,
    poses: (Vec<ClipSpan>, Vec<SampledPose>),
    sources: &[SourceRange],
    ids: &[u32],
) -> Result<PoseSet, ImportError> {
    let (clips, poses) = poses;
    let mut triangles = Vec::with_capacity(poses.len());
    for pose in &poses {
        let options = ImportOptions {
            pose: Some(PoseSelector { clip: ClipSelector::Index(pose.clip), seconds: pose.seconds }),
            keep_degenerate: true,
            ..import.clone()
        };
        let soup = crate::import::import(input, &options)?.soup;
        if let Err(why) = crate::posed::same_ranges(sources, &soup.sources, ("the default pose", "the pose")) {
            let why = format!(
                "clip {} at {} s places the scene's primitives otherwise ({why}): a moving \
                 node's transform may be singular there; convert with --instancing never",
                pose.clip, pose.seconds
            );
            return Err(refused(input, why));
        }
        let mut triangle_of_id = vec![u32::MAX; soup.source_ids.iter().map(|&id| id as usize + 1).max().unwrap_or(0)];
        for (t, &id) in soup.source_ids.iter().enumerate() {
            triangle_of_id[id as usize] = t as u32;
        }
        let mut posed = Vec::with_capacity(ids.len());
        for &id in ids {
            let t = triangle_of_id.get(id as usize).copied().filter(|&t| t != u32::MAX).ok_or_else(|| {
                let why =
                    format!("triangle {id} of the stored pose is not in clip {} at {} s", pose.clip, pose.seconds);
                refused(input, why)
            })?;
            posed.push(soup.vertices(t as usize));
        }
        triangles.push(posed);
    }
    Ok(PoseSet { clips, poses, triangles })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(index: usize, name: &str, start: f64, end: f64) -> ClipSpan {
        ClipSpan { index, name: Some(name.into()), start, end }
    }

    #[test]
    fn times_are_the_middles_of_equal_parts_of_each_chosen_clip() {
        let spans = [span(0, "Walk", 0.0, 2.0), span(1, "Run", 1.0, 1.0), span(2, "Jump", 0.5, 1.5)];
        let animation =
            Animation { clips: Animation::parse_clips("Jump, 1,2").unwrap(), poses_per_clip: 4, window: None };
        let (clips, poses) = sample_times(&spans, &animation).unwrap();
        assert_eq!(clips.iter().map(|c| c.index).collect::<Vec<_>>(), [2, 1]);
        let times: Vec<(usize, f64)> = poses.iter().map(|p| (p.clip, p.seconds)).collect();
        assert_eq!(times, [(2, 0.625), (2, 0.875), (2, 1.125), (2, 1.375), (1, 1.0)]);
        let every = sample_times(&spans, &Animation { poses_per_clip: 1, ..Animation::default() }).unwrap().1;
        assert_eq!(every.iter().map(|p| p.seconds).collect::<Vec<_>>(), [1.0, 1.0, 1.0]);
    }

    #[test]
    fn a_window_cuts_each_clip_to_its_times() {
        let spans = [span(0, "Walk", 0.0, 2.0), span(1, "Wave", 1.0, 3.0)];
        let window = Some("0.5..1.5".parse().unwrap());
        let (_, poses) =
            sample_times(&spans, &Animation { poses_per_clip: 2, window, ..Animation::default() }).unwrap();
        let times: Vec<(usize, f64)> = poses.iter().map(|p| (p.clip, p.seconds)).collect();
        assert_eq!(times, [(0, 0.75), (0, 1.25), (1, 1.125), (1, 1.375)]);
        // A window of one time samples it once; one past a clip's keyframes is refused, naming the clip.
        let at =
            |text: &str| Animation { poses_per_clip: 4, window: Some(text.parse().unwrap()), ..Animation::default() };
        let (_, once) = sample_times(&spans[..1], &at("2..2")).unwrap();
        assert_eq!(once, [SampledPose { clip: 0, seconds: 2.0 }]);
        let why = sample_times(&spans, &at("2.5..4")).unwrap_err();
        assert!(why.contains("leaves no time of clip 0") && why.contains("0..2 s"), "{why}");
        for (text, expected) in
            [("1..0.5", "ends before"), ("1", "START..END"), ("a..2", "'a' is not"), ("0..inf", "'inf'")]
        {
            let why = text.parse::<TimeWindow>().unwrap_err();
            assert!(why.contains(expected), "{text}: {why}");
        }
    }

    #[test]
    fn refusals_name_the_problem() {
        let spans = [span(0, "Walk", 0.0, 2.0)];
        let ask = |clips: &str, poses: u32| {
            let clips = Animation::parse_clips(clips).unwrap();
            sample_times(&spans, &Animation { clips, poses_per_clip: poses, window: None }).unwrap_err()
        };
        assert!(ask("3", 8).contains("animation 3 does not exist"));
        assert!(ask("Fly", 8).contains("no animation is named 'Fly'"));
        assert!(ask("", 0).contains("at least 1"));
        assert!(ask("", 65).contains("more than 64"));
        assert!(sample_times(&[], &Animation::default()).unwrap_err().contains("no animation clips"));
        assert!(Animation::parse_clips("Walk,,Run").is_err());
    }
}
