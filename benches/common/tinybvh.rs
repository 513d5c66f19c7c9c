//! tinybvh 1.6.8's SBVH (`BVH::BuildHQ`: spatial splits with unsplitting, Stich et al. 2009) as a peer in the
//! evaluate benchmark, through the `tinybvh-rs` wrapper pinned to 0.1.0-beta.3 (which vendors that header and
//! compiles it with the system's C++ compiler). Compiled only with `--features tinybvh`, so the default build,
//! the tests and CI never compile C++.
//!
//! The tree is read back in tinybvh's own layout (32-byte Wald nodes: root at 0, node 1 unused, an inner node's
//! children at `left_first` and `left_first + 1`, a leaf's references at `left_first..left_first + tri_count`
//! of the index array) and rewritten depth first as a [`BuildTree`], keeping tinybvh's boxes, leaves and split
//! references as they are, so that bvhc's cost, EPO and kernel measure it like every other tree.
#![allow(unsafe_code)] // One read past the wrapper's index slice; its bound is proved beside it.

use bvhc::build_tree::{BuildNode, BuildTree};
use bvhc::geometry::Aabb;

/// The name of the method in the tables.
pub const NAME: &str = "tinybvh 1.6.8 BuildHQ (SBVH)";

/// tinybvh's SBVH over `triangles`, with its default constants (8 bins, `C_INT` = `C_TRAV` = 1).
pub fn sbvh(triangles: &[[[f32; 3]; 3]]) -> BuildTree {
    let vertices: Vec<[f32; 4]> = triangles.iter().flat_map(|t| t.map(|v| [v[0], v[1], v[2], 0.0])).collect();
    let bvh = tinybvh_rs::bvh::BVH::new_hq(vertices.as_slice().into()).expect("three vertices a triangle");
    let nodes = bvh.nodes();
    let stored = bvh.indices();
    let leaf_end = |n: &tinybvh_rs::bvh::Node| if n.is_leaf() { (n.left_first + n.tri_count) as usize } else { 0 };
    let used = nodes.iter().map(leaf_end).max().unwrap_or(0);
    // The wrapper's slice stops at the triangle count, but an SBVH's leaves also index the slack that
    // `PrepareHQBuild` allocates for split references: `primIdx` holds `n + n / 2` entries, all written
    // (zeroed, then filled by the build).
    let capacity = triangles.len() + triangles.len() / 2;
    assert!(used <= capacity, "a leaf indexes past tinybvh's reference array ({used} > {capacity})");
    // SAFETY: `stored` starts the `primIdx` allocation of `capacity` initialized u32 (tinybvh 1.6.8,
    // `PrepareHQBuild`: `AlignedAlloc((primCount + slack) * 4)` then `memset` of the slack), `used <= capacity`
    // was checked above, and `bvh` owns the allocation for as long as `indices` is read below.
    let indices = unsafe { std::slice::from_raw_parts(stored.as_ptr(), used.max(stored.len())) };
    let mut tree = BuildTree::default();
    if triangles.is_empty() {
        return tree;
    }
    tree.nodes.push(placeholder());
    // (tinybvh node, our slot)
    let mut stack = vec![(0usize, 0usize)];
    while let Some((source, slot)) = stack.pop() {
        let node = &nodes[source];
        let aabb = Aabb { min: node.min, max: node.max };
        tree.nodes[slot] = if node.is_leaf() {
            let first = tree.triangle_order.len() as u32;
            let range = node.left_first as usize..(node.left_first + node.tri_count) as usize;
            tree.triangle_order.extend_from_slice(&indices[range]);
            BuildNode::Leaf { aabb, first, count: node.tri_count }
        } else {
            let left = tree.nodes.len();
            tree.nodes.extend([placeholder(), placeholder()]);
            stack.push((node.left_first as usize + 1, left + 1));
            stack.push((node.left_first as usize, left));
            BuildNode::Inner { aabb, left: left as u32, right: left as u32 + 1 }
        };
    }
    tree
}

fn placeholder() -> BuildNode {
    BuildNode::Leaf { aabb: Aabb { min: [0.0; 3], max: [0.0; 3] }, first: 0, count: 0 }
}
