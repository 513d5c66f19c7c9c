//! A glTF animation clip sampled at a time (glTF 2.0 section 3.11): each channel's sampler evaluated at the time
//! (clamped to its keyframes) with STEP, LINEAR (quaternions by shortest-arc spherical interpolation) or
//! CUBICSPLINE (Hermite splines over the keyframe interval, tangents scaled by its length) interpolation,
//! rotations normalized, and the value set on its node's translation, rotation, scale or morph weights. The
//! pose's world matrices are then recomputed. In f64, the keyframes read through [`Buffers`] (so normalized
//! integer outputs, as KHR_mesh_quantization allows for rotations and weights, decode too).

use glam::{DMat4, DQuat, DVec3};
use gltf::json::Root;
use gltf::json::animation::{Interpolation, Property};
use gltf::json::validation::Checked;

use super::buffers::{Buffers, Decoded};
use super::pose::{Pose, node_trs, unit_quaternion};
use crate::import::Problem;

/// Which clip a pose samples: by index in the file's `animations`, or by name.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ClipSelector {
    /// The clip at this index.
    Index(usize),
    /// The clip with this name.
    Name(String),
}

/// The index of the clip `selector` names; an error listing the clips where none matches.
pub(super) fn clip_index(root: &Root, selector: &ClipSelector) -> Result<usize, Problem> {
    let count = root.animations.len();
    match selector {
        ClipSelector::Index(i) if *i < count => Ok(*i),
        ClipSelector::Index(i) => Err(format!("animation {i} does not exist (the file has {count})").into()),
        ClipSelector::Name(name) => {
            root.animations.iter().position(|a| a.name.as_deref() == Some(name)).ok_or_else(|| {
                let names: Vec<_> = root.animations.iter().map(|a| a.name.clone().unwrap_or_default()).collect();
                format!("no animation is named '{name}' (names: {names:?})").into()
            })
        }
    }
}

/// `pose` (every node's TRS and weights at rest, from [`Pose::rest`]) with clip `clip` applied at `seconds`.
pub(super) fn apply_clip(
    root: &Root,
    buffers: &mut Buffers<'_>,
    clip: usize,
    seconds: f64,
    pose: &mut Pose,
) -> Result<(), Problem> {
    let animation = root.animations.get(clip).ok_or_else(|| format!("animation {clip} does not exist"))?;
    // Each node's translation, rotation and scale, as animated so far.
    let mut trs: Vec<Option<(DVec3, DQuat, DVec3)>> = vec![None; root.nodes.len()];
    for (c, channel) in animation.channels.iter().enumerate() {
        let at = |why: String| Problem::from(format!("animation {clip} channel {c}: {why}"));
        let node = channel.target.node.value();
        let Some(json_node) = root.nodes.get(node) else { return Err(at(format!("node {node} does not exist"))) };
        let Checked::Valid(property) = channel.target.path else { return Err(at("invalid target path".into())) };
        let sampler = animation.samplers.get(channel.sampler.value()).ok_or_else(|| at("no such sampler".into()))?;
        let Checked::Valid(interpolation) = sampler.interpolation else {
            return Err(at("invalid interpolation".into()));
        };
        let s = channel.sampler.value();
        let times = keyframe_times(buffers, clip, s, sampler.input.value())?;
        let outputs = keyframe_values(buffers, clip, s, sampler.output.value())?;
        let width = match property {
            Property::Translation | Property::Scale => 3,
            Property::Rotation => 4,
            Property::MorphTargetWeights => {
                let targets = root.meshes.get(json_node.mesh.map_or(usize::MAX, |m| m.value()));
                targets.and_then(|m| m.primitives.first()).and_then(|p| p.targets.as_ref()).map_or(0, Vec::len)
            }
        };
        let keys = times.values.len();
        let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
        if width == 0 || outputs.values.len() != keys * per_key {
            return Err(at(format!(
                "{} output values for {keys} keyframes of {width} values ({interpolation:?})",
                outputs.values.len()
            )));
        }
        let rotation = property == Property::Rotation;
        let value = sample(&times.values, &outputs.values, width, interpolation, rotation, seconds)
            .map_err(|why| at(format!("sampler {s} output accessor {}: {why}", sampler.output.value())))?;
        let Some(value) = value else { continue };
        if property == Property::MorphTargetWeights {
            pose.weights[node] = Some(value);
            continue;
        }
        let entry = trs[node].get_or_insert_with(|| node_trs(json_node));
        match property {
            Property::Translation => entry.0 = DVec3::new(value[0], value[1], value[2]),
            Property::Rotation => entry.1 = DQuat::from_array([value[0], value[1], value[2], value[3]]),
            _ => entry.2 = DVec3::new(value[0], value[1], value[2]),
        }
    }
    for (node, trs) in trs.into_iter().enumerate() {
        if let Some((t, r, s)) = trs {
            pose.local[node] = DMat4::from_scale_rotation_translation(s, r, t);
        }
    }
    pose.update_world(root);
    Ok(())
}

/// Sampler `sampler`'s keyframe times (its `input`, accessor `accessor`) of animation `clip`: finite and in
/// order, as glTF 2.0 requires (section 3.11: strictly increasing; equal neighbours are let through, the later
/// one winning), or an error naming the sampler, the accessor and the first time that breaks the rule.
pub(super) fn keyframe_times(
    buffers: &mut Buffers<'_>,
    clip: usize,
    sampler: usize,
    accessor: usize,
) -> Result<std::rc::Rc<Decoded>, Problem> {
    let at =
        |why: String| Problem::from(format!("animation {clip} sampler {sampler} input accessor {accessor}: {why}"));
    let times =
        buffers.accessor(accessor).map_err(|e| e.prefixed(&format!("animation {clip} sampler {sampler} input ")))?;
    if times.components != 1 {
        return Err(at(format!("{} components a keyframe time, not SCALAR", times.components)));
    }
    for (k, &time) in times.values.iter().enumerate() {
        if !time.is_finite() {
            return Err(at(format!("keyframe time {k} is {time}, not a finite number of seconds")));
        }
        if let Some(&previous) = k.checked_sub(1).and_then(|p| times.values.get(p))
            && time < previous
        {
            return Err(at(format!("keyframe time {k} ({time} s) is before keyframe {}'s ({previous} s)", k - 1)));
        }
    }
    Ok(times)
}

/// Sampler `sampler`'s keyframe values (its `output`, accessor `accessor`) of animation `clip`, every one finite,
/// or an error naming the sampler, the accessor and the first value that is not.
fn keyframe_values(
    buffers: &mut Buffers<'_>,
    clip: usize,
    sampler: usize,
    accessor: usize,
) -> Result<std::rc::Rc<Decoded>, Problem> {
    let values =
        buffers.accessor(accessor).map_err(|e| e.prefixed(&format!("animation {clip} sampler {sampler} output ")))?;
    if let Some(i) = values.values.iter().position(|v| !v.is_finite()) {
        return Err(Problem::from(format!(
            "animation {clip} sampler {sampler} output accessor {accessor}: value {i} (element {}, component {}) is {}, not finite",
            i / values.components.max(1),
            i % values.components.max(1),
            values.values[i]
        )));
    }
    Ok(values)
}

/// The sampler's value at `time` (clamped to its keyframes), `width` values, or `None` without keyframes; an
/// error for a rotation keyframe of length 0, which names no rotation. The times are finite and in order
/// ([`keyframe_times`]), the outputs finite.
fn sample(
    times: &[f64],
    outputs: &[f64],
    width: usize,
    interpolation: Interpolation,
    rotation: bool,
    time: f64,
) -> Result<Option<Vec<f64>>, String> {
    let (Some(&first), Some(&last)) = (times.first(), times.last()) else { return Ok(None) };
    let time = time.max(first).min(last);
    // The last keyframe at or before the time, and the one after it (itself at the last keyframe).
    let previous = times.partition_point(|&t| t <= time).saturating_sub(1);
    let next = (previous + 1).min(times.len() - 1);
    let (t0, t1) = (times[previous], times[next]);
    let span = t1 - t0;
    let s = if span > 0.0 { (time - t0) / span } else { 0.0 };
    let key = |k: usize, part: usize| {
        let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
        &outputs[k * per_key + part * width..k * per_key + (part + 1) * width]
    };
    let unit = |k: usize, part: usize| {
        let v = key(k, part);
        unit_quaternion([v[0], v[1], v[2], v[3]]).ok_or_else(|| format!("rotation keyframe {k} has length 0"))
    };
    let value: Vec<f64> = match interpolation {
        Interpolation::Step if rotation => unit(previous, 0)?.to_array().to_vec(),
        Interpolation::Step => key(previous, 0).to_vec(),
        Interpolation::Linear if rotation => unit(previous, 0)?.slerp(unit(next, 0)?, s).to_array().to_vec(),
        Interpolation::Linear => key(previous, 0).iter().zip(key(next, 0)).map(|(a, b)| a + (b - a) * s).collect(),
        Interpolation::CubicSpline => {
            // Keyframe k's parts: in-tangent 0, value 1, out-tangent 2.
            let (v0, out0, in1, v1) = (key(previous, 1), key(previous, 2), key(next, 0), key(next, 1));
            let (s2, s3) = (s * s, s * s * s);
            (0..width)
                .map(|i| {
                    (2.0 * s3 - 3.0 * s2 + 1.0) * v0[i]
                        + span * (s3 - 2.0 * s2 + s) * out0[i]
                        + (-2.0 * s3 + 3.0 * s2) * v1[i]
                        + span * (s3 - s2) * in1[i]
                })
                .collect()
        }
    };
    if !rotation {
        return Ok(Some(value));
    }
    // A cubic spline's rotation is normalized after the blend (glTF 2.0, appendix C); one that blends to length 0
    // names no rotation.
    let blended = unit_quaternion([value[0], value[1], value[2], value[3]])
        .ok_or_else(|| format!("the rotation between keyframes {previous} and {next} has length 0"))?;
    Ok(Some(blended.to_array().to_vec()))
}

/// One animation clip of a glTF file: its index, name and the span of its keyframes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ClipSpan {
    /// Its index in the file's `animations`.
    pub index: usize,
    /// Its name, where the file gives one (absent from JSON where it gives none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The earliest keyframe of any of its samplers, in seconds.
    pub start: f64,
    /// The latest keyframe of any of its samplers, in seconds.
    pub end: f64,
}

/// Every clip's span, from its samplers' input keyframes (decoded, so a file whose accessors lack the `min` and
/// `max` glTF requires still gets its spans). A clip without keyframes is refused.
pub(super) fn clip_spans(root: &Root, buffers: &mut Buffers<'_>) -> Result<Vec<ClipSpan>, Problem> {
    let mut spans = Vec::with_capacity(root.animations.len());
    for (index, animation) in root.animations.iter().enumerate() {
        let (mut start, mut end) = (f64::INFINITY, f64::NEG_INFINITY);
        for (s, sampler) in animation.samplers.iter().enumerate() {
            let times = keyframe_times(buffers, index, s, sampler.input.value())?;
            if let (Some(&first), Some(&last)) = (times.values.first(), times.values.last()) {
                (start, end) = (start.min(first), end.max(last));
            }
        }
        if !(start.is_finite() && end.is_finite()) {
            return Err(format!("animation {index} has no keyframes").into());
        }
        spans.push(ClipSpan { index, name: animation.name.clone(), start, end });
    }
    Ok(spans)
}
