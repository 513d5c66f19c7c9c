//! The glTF scene posed at a time of one of its animation clips, done here (not by bvhc): node TRS channels
//! sampled (LINEAR with quaternions by shortest-arc spherical interpolation, STEP, CUBICSPLINE as Hermite
//! splines over the keyframe interval, glTF 2.0 section 3.11), node world matrices down the hierarchy, and each
//! skinned primitive's vertices by linear-blend skinning: `sum_i w_i (world(joint_i) * inverseBind_i) p`, the
//! skinned mesh node's own transform ignored as the spec requires. Primitives of unskinned nodes follow their
//! node's animated world matrix. Morph targets are not read (a note says so when the scene has any).

use std::path::Path;

use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::animation::{Interpolation, Property, util::ReadOutputs};

/// One animation channel of a node's translation, rotation or scale.
struct Channel {
    node: usize,
    property: Property,
    interpolation: Interpolation,
    times: Vec<f32>,
    /// Per keyframe one value (LINEAR, STEP) or three (CUBICSPLINE: in-tangent, value, out-tangent), as `Vec4`s
    /// (translations and scales in `xyz`).
    values: Vec<Vec4>,
}

/// A primitive's vertex data for skinning.
struct Primitive {
    positions: Vec<Vec3>,
    joints: Vec<[u16; 4]>,
    weights: Vec<Vec4>,
}

/// A glTF scene read for posing.
pub struct Scene {
    /// Each node's default translation, rotation and scale.
    rest: Vec<(Vec3, Quat, Vec3)>,
    children: Vec<Vec<usize>>,
    roots: Vec<usize>,
    /// Per node: its skin's joints and inverse bind matrices, when skinned.
    skins: Vec<Option<(Vec<usize>, Vec<Mat4>)>>,
    /// Per mesh, per primitive.
    meshes: Vec<Vec<Primitive>>,
    channels: Vec<Channel>,
    /// The clip's length in seconds.
    pub duration: f32,
    /// A note on what this posing leaves out, if anything.
    pub note: Option<String>,
}

fn vec4s(outputs: ReadOutputs<'_>) -> Vec<Vec4> {
    match outputs {
        ReadOutputs::Translations(t) => t.map(|v| Vec3::from(v).extend(0.0)).collect(),
        ReadOutputs::Scales(s) => s.map(|v| Vec3::from(v).extend(0.0)).collect(),
        ReadOutputs::Rotations(r) => r.into_f32().map(Vec4::from).collect(),
        ReadOutputs::MorphTargetWeights(_) => Vec::new(),
    }
}

impl Scene {
    /// Reads `path` (a `.gltf` with its buffers beside it, or a `.glb`) and animation clip `clip`.
    pub fn read(path: &Path, clip: usize) -> Result<Scene, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut buffers = Vec::new();
        for buffer in gltf.buffers() {
            buffers.push(match buffer.source() {
                gltf::buffer::Source::Bin => gltf.blob.clone().ok_or("a GLB without its binary chunk")?,
                gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => {
                    std::fs::read(dir.join(uri)).map_err(|e| format!("buffer {uri}: {e}"))?
                }
                gltf::buffer::Source::Uri(_) => return Err("data: URIs are not read by this example".into()),
            });
        }
        let data = |buffer: gltf::Buffer<'_>| buffers.get(buffer.index()).map(Vec::as_slice);
        let rest = gltf
            .nodes()
            .map(|n| {
                let (t, r, s) = n.transform().decomposed();
                (Vec3::from(t), Quat::from_array(r), Vec3::from(s))
            })
            .collect();
        let children = gltf.nodes().map(|n| n.children().map(|c| c.index()).collect()).collect();
        let scene = gltf.default_scene().or_else(|| gltf.scenes().next()).ok_or("no scene")?;
        let roots = scene.nodes().map(|n| n.index()).collect();
        let skins = gltf
            .nodes()
            .map(|n| {
                n.skin().map(|skin| {
                    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
                    let inverse: Vec<Mat4> = skin.reader(data).read_inverse_bind_matrices().map_or_else(
                        || vec![Mat4::IDENTITY; joints.len()],
                        |m| m.map(|c| Mat4::from_cols_array_2d(&c)).collect(),
                    );
                    (joints, inverse)
                })
            })
            .collect();
        let mut morphs = false;
        let meshes = gltf
            .meshes()
            .map(|mesh| {
                mesh.primitives()
                    .map(|primitive| {
                        morphs |= primitive.morph_targets().next().is_some();
                        let reader = primitive.reader(data);
                        let positions: Vec<Vec3> =
                            reader.read_positions().map_or(Vec::new(), |p| p.map(Vec3::from).collect());
                        let joints = reader.read_joints(0).map_or(Vec::new(), |j| j.into_u16().collect());
                        let weights =
                            reader.read_weights(0).map_or(Vec::new(), |w| w.into_f32().map(Vec4::from).collect());
                        Primitive { positions, joints, weights }
                    })
                    .collect()
            })
            .collect();
        let animation = gltf.animations().nth(clip);
        let mut channels = Vec::new();
        for channel in animation.iter().flat_map(|a| a.channels()) {
            let property = channel.target().property();
            if property == Property::MorphTargetWeights {
                morphs = true;
                continue;
            }
            let reader = channel.reader(data);
            let times: Vec<f32> = reader.read_inputs().map_or(Vec::new(), |t| t.collect());
            let values = reader.read_outputs().map_or(Vec::new(), vec4s);
            let interpolation = channel.sampler().interpolation();
            channels.push(Channel { node: channel.target().node().index(), property, interpolation, times, values });
        }
        let duration = channels.iter().filter_map(|c| c.times.last().copied()).fold(0.0, f32::max);
        let note = morphs.then(|| "the scene has morph targets, which this example does not apply".to_string());
        Ok(Scene { rest, children, roots, skins, meshes, channels, duration, note })
    }

    /// Every node's world matrix at `time` seconds into the clip.
    fn world_matrices(&self, time: f32) -> Vec<Mat4> {
        let mut local = self.rest.clone();
        for channel in &self.channels {
            let Some(value) = channel.sample(time) else { continue };
            let Some(trs) = local.get_mut(channel.node) else { continue };
            match channel.property {
                Property::Translation => trs.0 = value.truncate(),
                Property::Rotation => trs.1 = Quat::from_vec4(value).normalize(),
                Property::Scale => trs.2 = value.truncate(),
                Property::MorphTargetWeights => {}
            }
        }
        let mut world = vec![Mat4::IDENTITY; self.rest.len()];
        let mut stack: Vec<(usize, Mat4)> = self.roots.iter().map(|&r| (r, Mat4::IDENTITY)).collect();
        while let Some((node, parent)) = stack.pop() {
            let (t, r, s) = local[node];
            world[node] = parent * Mat4::from_scale_rotation_translation(s, r, t);
            stack.extend(self.children[node].iter().map(|&c| (c, world[node])));
        }
        world
    }

    /// The world-space positions of primitive `primitive` of mesh `mesh` placed by node `node`, at `time`:
    /// skinned where the node has a skin, else moved by the node's world matrix. `None` for an unknown node,
    /// mesh or primitive.
    pub fn positions(&self, node: usize, mesh: usize, primitive: usize, world: &[Mat4]) -> Option<Vec<[f32; 3]>> {
        let data = self.meshes.get(mesh)?.get(primitive)?;
        let skinned = self.skins.get(node)?.as_ref().filter(|_| !data.joints.is_empty() && !data.weights.is_empty());
        Some(match skinned {
            Some((joints, inverse)) => {
                let matrices: Vec<Mat4> = joints.iter().zip(inverse).map(|(&j, m)| world[j] * *m).collect();
                let skin = |k: usize| {
                    let (j, w) = (data.joints[k], data.weights[k]);
                    let total = w.x + w.y + w.z + w.w;
                    let w = if total > 0.0 { w / total } else { Vec4::X };
                    (0..4).fold(Mat4::ZERO, |m, i| {
                        m + matrices.get(usize::from(j[i])).copied().unwrap_or(Mat4::IDENTITY) * w[i]
                    })
                };
                data.positions.iter().enumerate().map(|(k, p)| skin(k).transform_point3(*p).to_array()).collect()
            }
            None => data.positions.iter().map(|p| world[node].transform_point3(*p).to_array()).collect(),
        })
    }

    /// The world matrices at `time` (see [`Scene::positions`]).
    pub fn pose(&self, time: f32) -> Vec<Mat4> {
        self.world_matrices(time)
    }
}

impl Channel {
    /// The channel's value at `time` (clamped to its keyframes).
    fn sample(&self, time: f32) -> Option<Vec4> {
        let (first, last) = (*self.times.first()?, *self.times.last()?);
        let time = time.clamp(first, last);
        // The last keyframe at or before the time, and the one after it (itself at the last keyframe).
        let previous = self.times.partition_point(|&t| t <= time).saturating_sub(1);
        let next = (previous + 1).min(self.times.len() - 1);
        let (t0, t1) = (self.times[previous], self.times[next]);
        let span = t1 - t0;
        let s = if span > 0.0 { (time - t0) / span } else { 0.0 };
        let rotation = self.property == Property::Rotation;
        match self.interpolation {
            Interpolation::Step => self.values.get(previous).copied(),
            Interpolation::Linear => {
                let (a, b) = (*self.values.get(previous)?, *self.values.get(next)?);
                Some(if rotation {
                    Vec4::from(Quat::from_vec4(a).normalize().slerp(Quat::from_vec4(b).normalize(), s))
                } else {
                    a.lerp(b, s)
                })
            }
            Interpolation::CubicSpline => {
                // Keyframe k's triple is (in-tangent, value, out-tangent) at 3k, 3k + 1, 3k + 2.
                let (v0, out0) = (*self.values.get(3 * previous + 1)?, *self.values.get(3 * previous + 2)?);
                let (in1, v1) = (*self.values.get(3 * next)?, *self.values.get(3 * next + 1)?);
                let (s2, s3) = (s * s, s * s * s);
                let value = v0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + out0 * span * (s3 - 2.0 * s2 + s)
                    + v1 * (-2.0 * s3 + 3.0 * s2)
                    + in1 * span * (s3 - s2);
                Some(if rotation { Vec4::from(Quat::from_vec4(value).normalize()) } else { value })
            }
        }
    }
}
