//! The peers' trees as build trees, so that one cost definition and one kernel measure them: obvhs 0.4's
//! presets, svenstaro's `bvh` 0.13 and, with `--features tinybvh`, tinybvh's SBVH.

use std::time::Duration;

use bvhc::build_tree::{BuildNode, BuildTree};
use bvhc::geometry::Aabb;
use obvhs::BvhBuildParams;

use crate::Triangle;
use crate::harness;
use crate::ours::{Method, timed};

/// obvhs's tree as a build tree (children at `first_index`, `first_index + 1`, as in the `.bvh` layout).
pub fn from_obvhs(bvh: &obvhs::bvh2::Bvh2) -> BuildTree {
    let mut tree = BuildTree::default();
    for node in &bvh.nodes {
        let aabb = Aabb { min: node.aabb.min.to_array(), max: node.aabb.max.to_array() };
        tree.nodes.push(if node.prim_count == 0 {
            BuildNode::Inner { aabb, left: node.first_index, right: node.first_index + 1 }
        } else {
            BuildNode::Leaf { aabb, first: node.first_index, count: node.prim_count }
        });
    }
    tree.triangle_order = bvh.primitive_indices.clone();
    tree
}

/// obvhs's presets, with `very_slow_build` also without pre-splits and at one primitive a leaf.
pub fn obvhs_methods(triangles: &[Triangle]) -> Vec<Method> {
    let tris = harness::obvhs_triangles(triangles);
    [
        ("fast_build", BvhBuildParams::fast_build()),
        ("medium_build", BvhBuildParams::medium_build()),
        ("very_slow_build", BvhBuildParams::very_slow_build()),
        ("very_slow_build, no pre-split", BvhBuildParams { pre_split: false, ..BvhBuildParams::very_slow_build() }),
        ("very_slow_build, 1 a leaf", BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::very_slow_build() }),
    ]
    .into_iter()
    .map(|(name, params)| {
        // With pre_split, a triangle's pieces are separate primitives that keep the triangle's index, so its
        // leaves may reference a triangle several times, as split references do in a .bvh file.
        let mut core = Duration::ZERO;
        let (bvh, build) = timed(|| obvhs::bvh2::builder::build_bvh2_from_tris(&tris, params, &mut core));
        Method { name: format!("obvhs {name}"), build, optimize: None, tree: from_obvhs(&bvh) }
    })
    .collect()
}

/// tinybvh's SBVH as it builds it (no reinsertion: the wrapper does not offer tinybvh's optimizer).
#[cfg(feature = "tinybvh")]
pub fn tinybvh_method(triangles: &[Triangle]) -> Method {
    let (tree, build) = timed(|| crate::tinybvh::sbvh(triangles));
    Method { name: crate::tinybvh::NAME.into(), build, optimize: None, tree }
}

struct Shape {
    aabb: bvh::aabb::Aabb<f32, 3>,
    node: usize,
}

impl bvh::aabb::Bounded<f32, 3> for Shape {
    fn aabb(&self) -> bvh::aabb::Aabb<f32, 3> {
        self.aabb
    }
}

impl bvh::bounding_hierarchy::BHShape<f32, 3> for Shape {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }
    fn bh_node_index(&self) -> usize {
        self.node
    }
}

/// svenstaro's `bvh` 0.13, one triangle a leaf.
pub fn svenstaro(triangles: &[Triangle]) -> Method {
    let mut shapes: Vec<Shape> = triangles
        .iter()
        .map(|t| {
            let b = Aabb::of_triangle(t);
            let p = |c: [f32; 3]| nalgebra::Point3::new(c[0], c[1], c[2]);
            Shape { aabb: bvh::aabb::Aabb::with_bounds(p(b.min), p(b.max)), node: 0 }
        })
        .collect();
    let (built, build) = timed(|| bvh::bvh::Bvh::build(&mut shapes));
    // Child boxes live in the parent; a node's own box is the union of its children's (a leaf: its shape's).
    let to_aabb =
        |b: &bvh::aabb::Aabb<f32, 3>| Aabb { min: [b.min.x, b.min.y, b.min.z], max: [b.max.x, b.max.y, b.max.z] };
    let mut tree = BuildTree::default();
    for node in &built.nodes {
        tree.nodes.push(match node {
            bvh::bvh::BvhNode::Node { child_l_index, child_l_aabb, child_r_index, child_r_aabb, .. } => {
                BuildNode::Inner {
                    aabb: to_aabb(child_l_aabb).union(&to_aabb(child_r_aabb)),
                    left: *child_l_index as u32,
                    right: *child_r_index as u32,
                }
            }
            bvh::bvh::BvhNode::Leaf { shape_index, .. } => {
                tree.triangle_order.push(*shape_index as u32);
                BuildNode::Leaf {
                    aabb: to_aabb(&shapes[*shape_index].aabb),
                    first: tree.triangle_order.len() as u32 - 1,
                    count: 1,
                }
            }
        });
    }
    Method { name: "svenstaro bvh 0.13".into(), build, optimize: None, tree }
}
