//! Closest-hit traversal of the optimizer's binary tree ([`OptTree`], one triangle or split reference a leaf)
//! that counts, per node, the sample rays that reached it: the statistics of Gu, He, Blelloch, "Ray Specialized
//! Contraction on Bounding Volume Hierarchies" (Computer Graphics Forum 34(7), 2015), section 4. The walk is the
//! loader's reference walk (robust slab test, watertight triangle test, nearer child first, boxes culled at the
//! closest hit), so a node counts as reached exactly when a kernel over this tree would test its box and enter
//! it.

use bvhc_loader::{Ray, format::PackedNode, format::PackedTriangle, ray::PreparedRay};

use crate::geometry::Aabb;
use crate::optimize::{NONE, OptTree};

/// A closest hit: distance and the triangle (index into the tree's triangles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleHit {
    /// Distance along the ray.
    pub t: f32,
    /// The triangle's index in the soup the tree was built over.
    pub triangle: u32,
}

/// The closest hit of `ray` in `tree` over `triangles`, adding one to `visits[n]` for every node whose box the
/// ray entered (`visits` has one counter per node of `tree`). The root counts when the ray enters the scene's box.
pub fn trace_counting(tree: &OptTree, triangles: &[[[f32; 3]; 3]], ray: &Ray, visits: &mut [u32]) -> Option<SampleHit> {
    if tree.root == NONE {
        return None;
    }
    let prepared = PreparedRay::new(ray);
    let enters = |n: u32, t_max: f32| prepared.enter_box(&packed(&tree.nodes[n as usize].aabb), t_max);
    let mut best: Option<SampleHit> = None;
    let mut t_max = ray.t_max;
    let mut stack: Vec<(u32, f32)> = Vec::with_capacity(64);
    if let Some(t) = enters(tree.root, t_max) {
        stack.push((tree.root, t));
    }
    while let Some((n, t_entry)) = stack.pop() {
        if t_entry > t_max {
            continue;
        }
        visits[n as usize] = visits[n as usize].saturating_add(1);
        let node = tree.nodes[n as usize];
        if node.left == NONE {
            let triangle = PackedTriangle { vertices: triangles[node.right as usize] };
            if let Some(hit) = prepared.intersect_triangle(&triangle, t_max) {
                t_max = hit.t;
                best = Some(SampleHit { t: hit.t, triangle: node.right });
            }
            continue;
        }
        let near = enters(node.left, t_max).map(|t| (node.left, t));
        let far = enters(node.right, t_max).map(|t| (node.right, t));
        match (near, far) {
            (Some(a), Some(b)) => {
                let (first, second) = if a.1 <= b.1 { (a, b) } else { (b, a) };
                stack.push(second);
                stack.push(first);
            }
            (Some(only), None) | (None, Some(only)) => stack.push(only),
            (None, None) => {}
        }
    }
    best
}

/// An [`Aabb`] as the loader's box type (the slab test's input).
pub(super) fn packed(aabb: &Aabb) -> PackedNode {
    PackedNode { min: aabb.min, max: aabb.max, index: 0, count: 0 }
}
