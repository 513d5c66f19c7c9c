//! Rules V14-V20 of `format-spec/bvh-1.md`: a binary tree over a triangles array (a one-level file's sections,
//! or a mesh's ranges of a two-level file's), its shape, boxes, leaves and depth.

use crate::error::{Rule, Violation, violation};
use crate::format::{MAX_DEPTH, PackedNode, PackedTriangle};

/// V14-V20 over the node and triangle arrays.
///
/// First pass (index order): boxes (V16), child indices and single parents (V14), leaf ranges in bounds (V15).
/// Since every child comes after its parent and every non-root node has exactly one parent, the nodes form one
/// tree rooted at node 0. Second pass (depth first, left child first): depth (V20), child boxes (V17), leaves
/// consecutive over the triangles (V15), and each triangle checked once against its leaf (V18, V19).
pub fn verify_tree(
    nodes: &[PackedNode],
    triangles: &[PackedTriangle],
    split_references: bool,
) -> Result<(), Violation> {
    if nodes.is_empty() {
        return match triangles.len() {
            0 => Ok(()),
            n => Err(violation(Rule::LeafPartition, format!("no nodes for {n} triangles"))),
        };
    }
    let node_count = nodes.len();
    let mut has_parent = vec![0u64; node_count.div_ceil(64)];
    for (i, node) in nodes.iter().enumerate() {
        check_box(i, node)?;
        if node.is_leaf() {
            let end = u64::from(node.index) + u64::from(node.count);
            if end > triangles.len() as u64 {
                return Err(violation(
                    Rule::LeafPartition,
                    format!(
                        "node {i}: leaf triangles {}..{end} out of range (triangle_count {})",
                        node.index,
                        triangles.len()
                    ),
                ));
            }
            continue;
        }
        let first = node.index as usize;
        if first <= i || first + 1 >= node_count {
            return Err(violation(
                Rule::TreeShape,
                format!(
                    "node {i}: children {first} and {} must come after it and be < node_count {node_count}",
                    first + 1
                ),
            ));
        }
        for child in [first, first + 1] {
            let (word, bit) = (child / 64, 1u64 << (child % 64));
            if has_parent[word] & bit != 0 {
                return Err(violation(Rule::TreeShape, format!("node {child}: second parent {i}")));
            }
            has_parent[word] |= bit;
        }
    }
    if let Some(orphan) = (1..node_count).find(|&j| has_parent[j / 64] & (1 << (j % 64)) == 0) {
        return Err(violation(Rule::TreeShape, format!("node {orphan}: no parent (unreachable from the root)")));
    }
    drop(has_parent);
    walk_depth_first(nodes, triangles, split_references)
}

fn check_box(i: usize, node: &PackedNode) -> Result<(), Violation> {
    let finite = node.min.iter().chain(&node.max).all(|v| v.is_finite());
    if !finite || (0..3).any(|a| node.min[a] > node.max[a]) {
        return Err(violation(
            Rule::NodeBox,
            format!("node {i}: box {:?}..{:?} must be finite with min <= max", node.min, node.max),
        ));
    }
    Ok(())
}

fn walk_depth_first(
    nodes: &[PackedNode],
    triangles: &[PackedTriangle],
    split_references: bool,
) -> Result<(), Violation> {
    let mut next_triangle = 0usize;
    let mut stack: Vec<(usize, usize)> = vec![(0, 0)];
    while let Some((i, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return Err(violation(Rule::Depth, format!("node {i}: depth {depth} exceeds {MAX_DEPTH}")));
        }
        let node = &nodes[i];
        if node.is_leaf() {
            let first = node.index as usize;
            if first != next_triangle {
                return Err(violation(
                    Rule::LeafPartition,
                    format!(
                        "node {i}: leaf starts at triangle {first}, expected {next_triangle} (leaves in depth-first order must be consecutive)"
                    ),
                ));
            }
            next_triangle = first + node.count as usize;
            for (t, triangle) in triangles[first..next_triangle].iter().enumerate() {
                check_triangle(first + t, triangle, i, node, split_references)?;
            }
            continue;
        }
        let first = node.index as usize;
        for child in [first, first + 1] {
            let c = &nodes[child];
            if (0..3).any(|a| c.min[a] < node.min[a] || c.max[a] > node.max[a]) {
                return Err(violation(
                    Rule::ChildInParent,
                    format!(
                        "node {child}: box {:?}..{:?} not inside parent {i} {:?}..{:?}",
                        c.min, c.max, node.min, node.max
                    ),
                ));
            }
        }
        // Right child pushed first so the left one is visited first.
        stack.push((first + 1, depth + 1));
        stack.push((first, depth + 1));
    }
    if next_triangle != triangles.len() {
        return Err(violation(
            Rule::LeafPartition,
            format!("leaves cover triangles 0..{next_triangle} of {}", triangles.len()),
        ));
    }
    Ok(())
}

fn check_triangle(
    t: usize,
    triangle: &PackedTriangle,
    leaf_index: usize,
    leaf: &PackedNode,
    split_references: bool,
) -> Result<(), Violation> {
    let v = &triangle.vertices;
    if !v.iter().flatten().all(|c| c.is_finite()) {
        return Err(violation(Rule::TriangleFinite, format!("triangle {t}: vertex {v:?} is not finite")));
    }
    let inside = |p: &[f32; 3]| (0..3).all(|a| leaf.min[a] <= p[a] && p[a] <= leaf.max[a]);
    let ok = if split_references {
        (0..3).all(|a| {
            let lo = v[0][a].min(v[1][a]).min(v[2][a]);
            let hi = v[0][a].max(v[1][a]).max(v[2][a]);
            lo <= leaf.max[a] && hi >= leaf.min[a]
        })
    } else {
        v.iter().all(inside)
    };
    if !ok {
        return Err(violation(
            Rule::TriangleInLeaf,
            format!("triangle {t}: {v:?} not inside leaf node {leaf_index} box {:?}..{:?}", leaf.min, leaf.max),
        ));
    }
    Ok(())
}
