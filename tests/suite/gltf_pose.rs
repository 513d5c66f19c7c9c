//! An independent posing of glTF scenes for the import tests, in f64 over the `gltf` crate's reader (not the
//! importer's raw-JSON decoder): node world matrices from each node's TRS or matrix, animation clips sampled at a
//! time (STEP, LINEAR with shortest-arc slerp, CUBICSPLINE Hermite), morph targets by weights, linear-blend
//! skinning by every influence set with the inverse bind matrices (the skinned node's own transform ignored).

use std::path::Path;

use glam::{DMat4, DQuat, DVec3, DVec4};
use gltf::animation::util::ReadOutputs;
use gltf::animation::{Interpolation, Property};

/// Every node's local translation, rotation and scale (or matrix) and morph weights.
pub struct TestPose {
    pub local: Vec<DMat4>,
    pub weights: Vec<Option<Vec<f64>>>,
}

fn trs(t: DVec3, r: DQuat, s: DVec3) -> DMat4 {
    DMat4::from_scale_rotation_translation(s, r / r.length(), t)
}

fn decomposed(node: &gltf::Node<'_>) -> Option<(DVec3, DQuat, DVec3)> {
    match node.transform() {
        gltf::scene::Transform::Matrix { .. } => None,
        gltf::scene::Transform::Decomposed { translation, rotation, scale } => Some((
            DVec3::from_array(translation.map(f64::from)),
            DQuat::from_array(rotation.map(f64::from)),
            DVec3::from_array(scale.map(f64::from)),
        )),
    }
}

impl TestPose {
    /// The default pose.
    pub fn rest(document: &gltf::Document) -> TestPose {
        let local = document
            .nodes()
            .map(|n| match (decomposed(&n), n.transform()) {
                (Some((t, r, s)), _) => trs(t, r, s),
                (None, transform) => DMat4::from_cols_array_2d(&transform.matrix().map(|c| c.map(f64::from))),
            })
            .collect();
        let weights =
            document.nodes().map(|n| n.weights().map(|w| w.iter().map(|&x| f64::from(x)).collect())).collect();
        TestPose { local, weights }
    }

    /// The pose `seconds` into clip `clip`.
    pub fn at(document: &gltf::Document, buffers: &[Vec<u8>], clip: usize, seconds: f64) -> TestPose {
        let mut pose = TestPose::rest(document);
        let mut parts: Vec<Option<(DVec3, DQuat, DVec3)>> = vec![None; pose.local.len()];
        let animation = document.animations().nth(clip).unwrap();
        for channel in animation.channels() {
            let reader = channel.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let times: Vec<f64> = reader.read_inputs().unwrap().map(f64::from).collect();
            let values: Vec<Vec<f64>> = match reader.read_outputs().unwrap() {
                ReadOutputs::Translations(v) => v.map(|x| x.map(f64::from).to_vec()).collect(),
                ReadOutputs::Scales(v) => v.map(|x| x.map(f64::from).to_vec()).collect(),
                ReadOutputs::Rotations(v) => v.into_f32().map(|x| x.map(f64::from).to_vec()).collect(),
                ReadOutputs::MorphTargetWeights(v) => {
                    let flat: Vec<f64> = v.into_f32().map(f64::from).collect();
                    let cubic = channel.sampler().interpolation() == Interpolation::CubicSpline;
                    let width = flat.len() / (times.len() * if cubic { 3 } else { 1 });
                    flat.chunks(width).map(<[f64]>::to_vec).collect()
                }
            };
            let property = channel.target().property();
            let node = channel.target().node();
            let value =
                sample(&times, &values, channel.sampler().interpolation(), property == Property::Rotation, seconds);
            let entry = || decomposed(&node).unwrap();
            match property {
                Property::MorphTargetWeights => pose.weights[node.index()] = Some(value),
                Property::Translation => parts[node.index()].get_or_insert_with(entry).0 = DVec3::from_slice(&value),
                Property::Rotation => parts[node.index()].get_or_insert_with(entry).1 = DQuat::from_slice(&value),
                Property::Scale => parts[node.index()].get_or_insert_with(entry).2 = DVec3::from_slice(&value),
            }
        }
        for (n, part) in parts.into_iter().enumerate() {
            if let Some((t, r, s)) = part {
                pose.local[n] = trs(t, r, s);
            }
        }
        pose
    }

    /// Every node's world matrix.
    pub fn world(&self, document: &gltf::Document) -> Vec<DMat4> {
        let mut parent_of = vec![None; self.local.len()];
        for node in document.nodes() {
            for child in node.children() {
                parent_of[child.index()] = Some(node.index());
            }
        }
        (0..self.local.len())
            .map(|n| {
                let (mut matrix, mut at) = (self.local[n], parent_of[n]);
                while let Some(p) = at {
                    matrix = self.local[p] * matrix;
                    at = parent_of[p];
                }
                matrix
            })
            .collect()
    }
}

/// The sampler's value at `time` (keyframes `times`, one value or, for CUBICSPLINE, three a keyframe).
fn sample(times: &[f64], values: &[Vec<f64>], interpolation: Interpolation, rotation: bool, time: f64) -> Vec<f64> {
    let time = time.clamp(times[0], times[times.len() - 1]);
    let previous = times.partition_point(|&t| t <= time).saturating_sub(1);
    let next = (previous + 1).min(times.len() - 1);
    let span = times[next] - times[previous];
    let s = if span > 0.0 { (time - times[previous]) / span } else { 0.0 };
    let normalized = |v: Vec<f64>| {
        if rotation {
            let q = DQuat::from_slice(&v);
            (q / q.length()).to_array().to_vec()
        } else {
            v
        }
    };
    match interpolation {
        Interpolation::Step => normalized(values[previous].clone()),
        Interpolation::Linear if rotation => {
            let q = |v: &[f64]| {
                let q = DQuat::from_slice(v);
                q / q.length()
            };
            q(&values[previous]).slerp(q(&values[next]), s).to_array().to_vec()
        }
        Interpolation::Linear => values[previous].iter().zip(&values[next]).map(|(a, b)| a + (b - a) * s).collect(),
        Interpolation::CubicSpline => {
            let (v0, out0, in1, v1) =
                (&values[3 * previous + 1], &values[3 * previous + 2], &values[3 * next], &values[3 * next + 1]);
            let (s2, s3) = (s * s, s * s * s);
            normalized(
                (0..v0.len())
                    .map(|i| {
                        (2.0 * s3 - 3.0 * s2 + 1.0) * v0[i]
                            + span * (s3 - 2.0 * s2 + s) * out0[i]
                            + (-2.0 * s3 + 3.0 * s2) * v1[i]
                            + span * (s3 - s2) * in1[i]
                    })
                    .collect(),
            )
        }
    }
}

/// The positions glTF gives primitive `primitive` of `node`'s mesh, in f64.
pub fn expected_positions(
    node: &gltf::Node<'_>,
    primitive: &gltf::Primitive<'_>,
    buffers: &[Vec<u8>],
    world: &[DMat4],
    pose: &TestPose,
) -> Vec<DVec3> {
    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let mut positions: Vec<DVec3> =
        reader.read_positions().unwrap().map(|p| DVec3::from_array(p.map(f64::from))).collect();
    let mesh = node.mesh().unwrap();
    let weights: Vec<f64> = pose.weights[node.index()]
        .clone()
        .unwrap_or_else(|| mesh.weights().map_or(Vec::new(), |w| w.iter().map(|&x| f64::from(x)).collect()));
    for (target, weight) in reader.read_morph_targets().zip(weights.iter().chain(std::iter::repeat(&0.0))) {
        if let Some(displacements) = target.0 {
            for (p, d) in positions.iter_mut().zip(displacements) {
                *p += *weight * DVec3::from_array(d.map(f64::from));
            }
        }
    }
    let Some(skin) = node.skin().filter(|_| reader.read_joints(0).is_some()) else {
        return positions.iter().map(|&p| world[node.index()].transform_point3(p)).collect();
    };
    let skin_reader = skin.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let inverse: Vec<DMat4> = skin_reader.read_inverse_bind_matrices().map_or_else(
        || vec![DMat4::IDENTITY; skin.joints().count()],
        |m| m.map(|c| DMat4::from_cols_array_2d(&c.map(|col| col.map(f64::from)))).collect(),
    );
    let joints: Vec<DMat4> = skin.joints().zip(&inverse).map(|(j, m)| world[j.index()] * *m).collect();
    let mut sets = Vec::new();
    for n in 0.. {
        let (Some(j), Some(w)) = (reader.read_joints(n), reader.read_weights(n)) else { break };
        let j: Vec<[u16; 4]> = j.into_u16().collect();
        let w: Vec<DVec4> = w.into_f32().map(|w| DVec4::from_array(w.map(f64::from))).collect();
        sets.push((j, w));
    }
    positions
        .iter()
        .enumerate()
        .map(|(v, &p)| {
            let (mut sum, mut total) = (DVec3::ZERO, 0.0);
            for (j, w) in &sets {
                for i in 0..4 {
                    if w[v][i] != 0.0 {
                        sum += w[v][i] * joints[usize::from(j[v][i])].transform_point3(p);
                        total += w[v][i];
                    }
                }
            }
            if total > 0.0 { sum / total } else { joints[usize::from(sets[0].0[v][0])].transform_point3(p) }
        })
        .collect()
}

/// The document and its buffers (a `.gltf` with external buffers, or a `.glb`), read by the `gltf` crate.
pub fn read_gltf(path: &Path) -> (gltf::Document, Vec<Vec<u8>>) {
    let gltf = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let dir = path.parent().unwrap();
    let buffers = gltf
        .buffers()
        .map(|buffer| match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().unwrap(),
            gltf::buffer::Source::Uri(uri) => std::fs::read(dir.join(uri)).unwrap(),
        })
        .collect();
    (gltf.document, buffers)
}
