//! End-point overlap (EPO): how much of the scene's surface lies inside boxes of nodes that do not hold it.
//!
//! T. Aila, T. Karras, S. Laine, "On Quality Metrics of Bounding Volume Hierarchies", High Performance Graphics
//! 2013: a ray's end point on a surface must be found by every node whose box contains that point, whether or
//! not the surface is in the node's subtree; SAH charges only the box area, EPO the surface area that makes a
//! node visited in vain. Their definition:
//!
//! `EPO = sum_n C(n) * A((S \ Q(n)) ∩ box(n)) / A(S)`
//!
//! with `S` all triangles, `Q(n)` the triangles of `n`'s subtree, `A(X ∩ box)` the area of the parts of `X`
//! inside the box, and `C(n)` the node's cost: `c_T` for an inner node, `c_I` times its triangle count for a
//! leaf (the constants of [`crate::cost`], so EPO and SAH weigh nodes alike). Areas are computed in f64 by
//! clipping each triangle to each box it meets.
//!
//! Split references: a subtree holds the parts of a split triangle that lie inside the boxes of its leaves that
//! reference it (a ray ending there is found in those leaves), so the area charged to `n` is that of
//! `t ∩ box(n)` outside those leaf boxes. Without repeats this is the definition above; a triangle in one leaf
//! is held whole by every subtree that holds the leaf.

use rayon::prelude::*;

use crate::build_tree::{BuildNode, BuildTree};
use crate::cost::SahConstants;
use crate::geometry::Aabb;
use crate::geometry::clip::{clip_to_box, polygon_area, split_polygon};

/// The end-point overlap of `tree` over `triangles` (0 for an empty tree or a scene without area).
pub fn end_point_overlap(tree: &BuildTree, triangles: &[[[f32; 3]; 3]], constants: SahConstants) -> f64 {
    if tree.nodes.is_empty() {
        return 0.0;
    }
    let spans = Spans::of(tree, triangles.len());
    let total_area: f64 = triangles.iter().map(|t| polygon_area(&t.map(|v| v.map(f64::from)))).sum();
    if total_area <= 0.0 {
        return 0.0;
    }
    let overlap: f64 = triangles
        .par_iter()
        .enumerate()
        .map(|(t, vertices)| triangle_overlap(tree, &spans, t, vertices, constants))
        // Summed in triangle order after the parallel part, so the figure does not depend on the threads.
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    overlap / total_area
}

/// `sum_n C(n) * A(t ∩ box(n))` over the nodes `n` whose subtree does not hold triangle `t`.
fn triangle_overlap(
    tree: &BuildTree,
    spans: &Spans,
    t: usize,
    vertices: &[[f32; 3]; 3],
    constants: SahConstants,
) -> f64 {
    let corners: Vec<[f64; 3]> = vertices.iter().map(|v| v.map(f64::from)).collect();
    let own = Aabb::of_triangle(vertices);
    let mut sum = 0.0;
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        let node = &tree.nodes[n as usize];
        let aabb = node.aabb();
        if !boxes_meet(aabb, &own) {
            continue;
        }
        let held = spans.held_boxes(n, t);
        let whole_held = spans.leaf_count(t) == 1 && held.len() == 1;
        if !whole_held {
            let inside = clip_to_box(corners.clone(), aabb);
            if polygon_area(&inside) <= 0.0 {
                // Every descendant's box lies inside this one: none meets the triangle either.
                continue;
            }
            let area = area_outside(inside, &held);
            sum += match node {
                BuildNode::Inner { .. } => constants.traversal * area,
                BuildNode::Leaf { count, .. } => constants.intersection * f64::from(*count) * area,
            };
        }
        if let BuildNode::Inner { left, right, .. } = node {
            stack.push(*left);
            stack.push(*right);
        }
    }
    sum
}

/// Which subtrees hold which triangles: nodes numbered in depth-first order, so a subtree is a range of
/// numbers, and for each triangle the numbers and boxes of the leaves that hold it.
struct Spans {
    /// Node `n`'s subtree is numbers `enter[n]..exit[n]`.
    enter: Vec<u32>,
    exit: Vec<u32>,
    /// Triangle `t`'s leaves are `holders[first[t]..first[t + 1]]`: (number, box), by number.
    first: Vec<u32>,
    holders: Vec<(u32, Aabb)>,
}

impl Spans {
    fn of(tree: &BuildTree, triangle_count: usize) -> Spans {
        let n = tree.nodes.len();
        let (mut enter, mut exit) = (vec![0u32; n], vec![0u32; n]);
        let mut next = 0u32;
        let mut holders: Vec<(u32, u32, Aabb)> = Vec::with_capacity(tree.triangle_order.len());
        // (node, children done): a node's exit is set when it is popped the second time.
        let mut stack = vec![(0u32, false)];
        while let Some((node, done)) = stack.pop() {
            if done {
                exit[node as usize] = next;
                continue;
            }
            enter[node as usize] = next;
            next += 1;
            stack.push((node, true));
            match tree.nodes[node as usize] {
                BuildNode::Inner { left, right, .. } => {
                    stack.push((right, false));
                    stack.push((left, false));
                }
                BuildNode::Leaf { aabb, first, count } => {
                    for &t in &tree.triangle_order[first as usize..(first + count) as usize] {
                        holders.push((t, enter[node as usize], aabb));
                    }
                }
            }
        }
        holders.sort_unstable_by_key(|&(t, number, _)| (t, number));
        // A leaf holding a triangle twice is one holder.
        holders.dedup_by_key(|&mut (t, number, _)| (t, number));
        let mut first = vec![0u32; triangle_count + 1];
        for &(t, _, _) in &holders {
            first[t as usize + 1] += 1;
        }
        for t in 0..triangle_count {
            first[t + 1] += first[t];
        }
        Spans { enter, exit, first, holders: holders.into_iter().map(|(_, number, aabb)| (number, aabb)).collect() }
    }

    /// How many leaves hold triangle `t`.
    fn leaf_count(&self, t: usize) -> usize {
        (self.first[t + 1] - self.first[t]) as usize
    }

    /// The boxes of the leaves in node `n`'s subtree that hold triangle `t`.
    fn held_boxes(&self, n: u32, t: usize) -> Vec<Aabb> {
        let (low, high) = (self.enter[n as usize], self.exit[n as usize]);
        self.holders[self.first[t] as usize..self.first[t + 1] as usize]
            .iter()
            .filter(|&&(number, _)| low <= number && number < high)
            .map(|&(_, aabb)| aabb)
            .collect()
    }
}

/// The area of the convex polygon `corners` outside every box of `boxes`: the parts outside the first box (cut
/// off one box side at a time, each a convex polygon) measured against the other boxes in turn.
fn area_outside(corners: Vec<[f64; 3]>, boxes: &[Aabb]) -> f64 {
    // Only boxes that meet the polygon's bounds can take area from it: the pieces of a split triangle each meet
    // a few of its boxes, so this keeps the recursion narrow.
    let (low, high) = corners.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(low, high), p| {
        (std::array::from_fn(|a| low[a].min(p[a])), std::array::from_fn(|a| high[a].max(p[a])))
    });
    // Strictly: a box that only touches the polygon (as the boxes of neighbouring pieces do along their cut)
    // takes no area from it; along an axis the polygon is flat on, the box must reach its plane.
    let meets = |b: &&Aabb| {
        (0..3).all(|a| {
            let (min, max) = (f64::from(b.min[a]), f64::from(b.max[a]));
            if low[a] == high[a] { min <= low[a] && low[a] <= max } else { min < high[a] && low[a] < max }
        })
    };
    let boxes: Vec<Aabb> = boxes.iter().filter(meets).copied().collect();
    let Some((aabb, rest)) = boxes.split_first() else { return polygon_area(&corners) };
    let mut remaining = corners;
    let mut sum = 0.0;
    for axis in 0..3 {
        for (bound, outside_below) in [(f64::from(aabb.min[axis]), true), (f64::from(aabb.max[axis]), false)] {
            if polygon_area(&remaining) <= 0.0 {
                return sum;
            }
            // Outside is strictly beyond the side: a polygon lying in the side's plane is inside.
            let beyond = |p: &[f64; 3]| if outside_below { p[axis] < bound } else { p[axis] > bound };
            if !remaining.iter().any(beyond) {
                continue;
            }
            let (below, above) = split_polygon(&remaining, axis, bound);
            let (outside, inside) = if outside_below { (below, above) } else { (above, below) };
            if polygon_area(&outside) > 0.0 {
                sum += area_outside(outside, rest);
            }
            remaining = inside;
        }
    }
    sum
}

fn boxes_meet(a: &Aabb, b: &Aabb) -> bool {
    (0..3).all(|i| a.min[i] <= b.max[i] && b.min[i] <= a.max[i])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::Builder;

    /// The definition summed over every node and every triangle, no pruning: each triangle's area inside the
    /// node's box outside the boxes of the subtree's leaves that hold it.
    fn brute_force(tree: &BuildTree, triangles: &[[[f32; 3]; 3]], constants: SahConstants) -> f64 {
        let total: f64 = triangles.iter().map(|t| polygon_area(&t.map(|v| v.map(f64::from)))).sum();
        let mut sum = 0.0;
        for (n, node) in tree.nodes.iter().enumerate() {
            let leaves = subtree_leaves(tree, n as u32);
            let weight = match node {
                BuildNode::Inner { .. } => constants.traversal,
                BuildNode::Leaf { count, .. } => constants.intersection * f64::from(*count),
            };
            for (t, vertices) in triangles.iter().enumerate() {
                let held: Vec<Aabb> = leaves
                    .iter()
                    .filter(|&&(_, first, count)| {
                        tree.triangle_order[first as usize..(first + count) as usize].contains(&(t as u32))
                    })
                    .map(|&(aabb, _, _)| aabb)
                    .collect();
                let corners = vertices.iter().map(|v| v.map(f64::from)).collect();
                sum += weight * area_outside(clip_to_box(corners, node.aabb()), &held);
            }
        }
        sum / total
    }

    /// (box, first, count) of every leaf under node `n`.
    fn subtree_leaves(tree: &BuildTree, n: u32) -> Vec<(Aabb, u32, u32)> {
        match tree.nodes[n as usize] {
            BuildNode::Inner { left, right, .. } => {
                let mut leaves = subtree_leaves(tree, left);
                leaves.extend(subtree_leaves(tree, right));
                leaves
            }
            BuildNode::Leaf { aabb, first, count } => vec![(aabb, first, count)],
        }
    }

    fn random_triangles(count: usize, seed: u64) -> Vec<[[f32; 3]; 3]> {
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..count)
            .map(|_| {
                let c = [next() * 10.0, next() * 10.0, next() * 10.0];
                std::array::from_fn(|_| std::array::from_fn(|a| c[a] + 3.0 * (next() - 0.5)))
            })
            .collect()
    }

    #[test]
    fn the_pruned_walk_equals_the_definition_summed_over_every_node() {
        let constants = SahConstants::default();
        for seed in 1..4 {
            let triangles = random_triangles(200, seed);
            for builder in [Builder::BinnedSah, Builder::SpatialMedian] {
                for leaf_size in [1, 4] {
                    let tree = builder.build(&triangles, leaf_size);
                    let fast = end_point_overlap(&tree, &triangles, constants);
                    let slow = brute_force(&tree, &triangles, constants);
                    assert!(fast > 0.0);
                    assert!((fast - slow).abs() <= 1e-9 * slow, "{fast} against {slow}");
                }
            }
        }
    }

    #[test]
    fn over_split_references_the_pruned_walk_equals_the_definition_too() {
        let constants = SahConstants::default();
        let triangles = random_triangles(150, 9);
        let references = crate::builders::split_triangles(&triangles, 1.0);
        assert!(references.len() > 200);
        let tree = Builder::BinnedSah.build_references(&references);
        let fast = end_point_overlap(&tree, &triangles, constants);
        let slow = brute_force(&tree, &triangles, constants);
        assert!((fast - slow).abs() <= 1e-9 * slow, "{fast} against {slow}");
    }

    #[test]
    fn the_area_outside_overlapping_boxes_counts_their_union_once() {
        // The triangle x + y <= 4 (area 8) minus [0, 1] x [0, 1] and [0.5, 2] x [0, 1]: their union, area 2, lies
        // inside it.
        let triangle = vec![[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        let a = Aabb { min: [0.0, 0.0, -1.0], max: [1.0, 1.0, 1.0] };
        let b = Aabb { min: [0.5, 0.0, -1.0], max: [2.0, 1.0, 1.0] };
        assert!((area_outside(triangle.clone(), &[a, b]) - 6.0).abs() < 1e-12);
        assert!((area_outside(triangle.clone(), &[b, a]) - 6.0).abs() < 1e-12);
        assert!((area_outside(triangle.clone(), &[]) - 8.0).abs() < 1e-12);
        // Flat boxes in the triangle's own plane (as the boxes of an axis-aligned triangle's pieces are).
        let flat_a = Aabb { min: [0.0, 0.0, 0.0], max: [1.0, 1.0, 0.0] };
        let flat_b = Aabb { min: [0.5, 0.0, 0.0], max: [2.0, 1.0, 0.0] };
        assert!((area_outside(triangle, &[flat_a, flat_b]) - 6.0).abs() < 1e-12);
    }

    #[test]
    fn triangles_in_separate_boxes_overlap_nothing() {
        let triangles =
            [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 1.0, 0.0]]];
        let tree = Builder::BinnedSah.build(&triangles, 1);
        assert_eq!(end_point_overlap(&tree, &triangles, SahConstants::default()), 0.0);
    }

    #[test]
    fn a_triangle_inside_a_sibling_leaf_box_is_charged_that_leaf() {
        // A large triangle whose box holds a small one: the small one lies inside the large one's leaf box
        // but (in the plane z = 0.5, off the large triangle's plane z = 0) the large one's area inside the
        // small one's box is zero; only the small triangle's area counts, once, at the large leaf's cost.
        let large = [[0.0, 0.0, 0.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0]];
        let small = [[1.0, 1.0, 0.5], [2.0, 1.0, 0.5], [1.0, 2.0, 0.5]];
        let triangles = [large, small];
        let tree = Builder::BinnedSah.build(&triangles, 1);
        let constants = SahConstants::default();
        let epo = end_point_overlap(&tree, &triangles, constants);
        let total = polygon_area(&large.map(|v| v.map(f64::from))) + 0.5;
        let expected = constants.intersection * 0.5 / total;
        assert!((epo - expected).abs() <= 1e-12, "{epo} against {expected}");
    }

    #[test]
    fn clipping_keeps_the_part_inside_the_box() {
        let square_half = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let unit = Aabb { min: [0.0, 0.0, -1.0], max: [1.0, 1.0, 1.0] };
        assert!((polygon_area(&clip_to_box(square_half, &unit)) - 1.0).abs() < 1e-12);
    }
}
