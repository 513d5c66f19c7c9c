//! UsdSkel linear blend skinning: a mesh bound to a skeleton (`skel:skeleton`, on the mesh or an ancestor, with
//! `primvars:skel:jointIndices` and `jointWeights`) is drawn with its points skinned by the skeleton's joints at
//! the import's time: the skeleton's `restTransforms` with its animation source's (`skel:animationSource`)
//! translations, rotations and scales sampled over them (at the default time, which reads no time samples, the
//! rest pose), composed into skeleton space and multiplied by the inverse `bindTransforms`; each point moved by
//! its `geomBindTransform` and the weighted sum of its joints' transforms, as `UsdSkelSkinningQuery` computes
//! it. The skinned points are in the skeleton's space, which the skeleton's own transform places in the world
//! (the mesh's transform no longer applies), as UsdSkel's imaging draws them. The arithmetic is the `openusd`
//! crate's UsdSkel (`schemas::skel`).

use glam::DMat4;
use openusd::gf;
use openusd::schemas::skel::{AnimMapper, SkelAnimQuery, SkelBindingAPI, Skeleton, SkeletonResolver, SkinningResolver};
use openusd::usd::{Stage, TimeCode};

use super::xform::world_transform;

/// A skinned mesh's points in its skeleton's space and that space's transform to the world.
pub(super) struct Skinned {
    pub points: Vec<[f64; 3]>,
    pub skeleton_to_world: DMat4,
}

/// The skinned points of the mesh at `path` at `time`; `None` for a mesh that is not skinned.
pub(super) fn skin(
    stage: &Stage,
    path: &str,
    points: &[[f64; 3]],
    time: Option<TimeCode>,
) -> Result<Option<Skinned>, String> {
    let Some(binding) = SkelBindingAPI::get(stage, path).map_err(error)? else { return Ok(None) };
    let Some(skeleton_path) = binding.inherited_skeleton().map_err(error)? else { return Ok(None) };
    if binding.joint_indices().map_err(error)?.is_empty() {
        return Ok(None);
    }
    let skeleton = Skeleton::get(stage, skeleton_path.clone())
        .map_err(error)?
        .ok_or_else(|| format!("skel:skeleton names {}, which is no Skeleton", skeleton_path.as_str()))?;
    let resolver = SkeletonResolver::from_skeleton(&skeleton).map_err(error)?;
    let joints = resolver.joint_order().len();
    if resolver.rest_pose_local().len() != joints {
        return Err(format!(
            "skeleton {}: {joints} joints but {} restTransforms",
            skeleton_path.as_str(),
            resolver.rest_pose_local().len()
        ));
    }
    let mut local = resolver.rest_pose_local().to_vec();
    if let Some(time) = time {
        let source = match SkelBindingAPI::get(stage, skeleton_path.clone()).map_err(error)? {
            Some(skeleton_binding) => skeleton_binding.inherited_animation_source().map_err(error)?,
            None => None,
        };
        if let Some(animation) = source.map(|s| SkelAnimQuery::new(stage, s)).transpose().map_err(error)?.flatten() {
            let animated = animation.compute_joint_local_transforms(stage, time).map_err(error)?;
            // Each joint the animation names takes its sampled transform; the others keep their rest transform.
            let mapper = AnimMapper::new(animation.joint_order(), resolver.joint_order());
            if animated.len() == animation.joint_order().len() {
                for (joint, transform) in mapper.remap(&animated, gf::Matrix4d::IDENTITY).into_iter().enumerate() {
                    if let Some(name) = resolver.joint_order().get(joint)
                        && animation.joint_order().contains(name)
                    {
                        local[joint] = transform;
                    }
                }
            }
        }
    }
    let skel_space = resolver.joint_local_to_skel_space(&local);
    let skinning = resolver.compute_skinning_transforms_from_world(&skel_space);
    let query = SkinningResolver::from_binding(&binding, resolver.joint_order()).map_err(error)?;
    let skeleton_to_world = world_transform(stage, &skeleton_path, time)?;
    if query.is_rigidly_deformed() {
        let rigid = to_glam(&query.compute_rigid_transform(&skinning));
        return Ok(Some(Skinned { points: points.to_vec(), skeleton_to_world: skeleton_to_world * rigid }));
    }
    let influences = query.num_influences_per_component();
    let weights_needed = points.len().saturating_mul(influences);
    if binding.joint_indices().map_err(error)?.len() != weights_needed
        || binding.joint_weights().map_err(error)?.len() != weights_needed
    {
        return Err(format!(
            "jointIndices and jointWeights do not hold {influences} influences for each of {} points",
            points.len()
        ));
    }
    let single: Vec<gf::Vec3f> = points.iter().map(|p| gf::vec3f(p[0] as f32, p[1] as f32, p[2] as f32)).collect();
    let skinned = query.compute_skinned_points(&single, &skinning);
    let points = skinned.iter().map(|p| [p.x, p.y, p.z].map(f64::from)).collect();
    Ok(Some(Skinned { points, skeleton_to_world }))
}

/// A UsdSkel error as this import's message.
fn error(e: impl std::fmt::Display) -> String {
    format!("UsdSkel binding: {e:#}")
}

/// A USD matrix (rows for row vectors) as glam's (columns for column vectors): the same numbers.
fn to_glam(m: &gf::Matrix4d) -> DMat4 {
    DMat4::from_cols_array(&m.0)
}
