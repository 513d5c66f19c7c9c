//! The optimizer tree's invariants, checked in one pass: for tests, the property test that runs every preset
//! after every batch, and debugging.

use crate::builders::References;
use crate::geometry::Aabb;

use super::tree::{NONE, OptTree};

impl OptTree {
    /// Checks every invariant of an optimizer tree over `triangles`: the root has no parent; every inner node's
    /// children link back to it; every box is the exact union of its children's (a leaf's is its triangle's);
    /// every node is reachable from the root exactly once; every triangle is in exactly one leaf. Returns the
    /// first broken one, naming the node.
    pub fn check_invariants(&self, triangles: &[[[f32; 3]; 3]]) -> Result<(), String> {
        let mut seen_triangle = vec![false; triangles.len()];
        self.check_links_and_boxes(triangles.is_empty(), &mut |i, t, aabb| {
            let Some(triangle) = triangles.get(t) else {
                return Err(format!("leaf {i}: triangle {t} out of range ({} triangles)", triangles.len()));
            };
            if std::mem::replace(&mut seen_triangle[t], true) {
                return Err(format!("triangle {t} in two leaves"));
            }
            if *aabb != Aabb::of_triangle(triangle) {
                return Err(format!("leaf {i}: box is not its triangle's box"));
            }
            Ok(())
        })?;
        if let Some(t) = seen_triangle.iter().position(|&s| !s) {
            return Err(format!("triangle {t} is in no leaf"));
        }
        Ok(())
    }

    /// [`OptTree::check_invariants`] for a tree over split references: the leaves, as (triangle, box) pairs,
    /// are exactly the references, each once.
    pub fn check_reference_invariants(&self, references: &References) -> Result<(), String> {
        let key = |t: u32, aabb: &Aabb| (t, aabb.min.map(f32::to_bits), aabb.max.map(f32::to_bits));
        let mut leaves = Vec::with_capacity(references.len());
        self.check_links_and_boxes(references.is_empty(), &mut |_, t, aabb| {
            leaves.push(key(t as u32, aabb));
            Ok(())
        })?;
        let mut expected: Vec<_> = references.triangle.iter().zip(&references.aabb).map(|(&t, b)| key(t, b)).collect();
        leaves.sort_unstable();
        expected.sort_unstable();
        if leaves != expected {
            let first =
                leaves.iter().zip(&expected).position(|(a, b)| a != b).unwrap_or(leaves.len().min(expected.len()));
            return Err(format!(
                "the leaves ({}) are not the references ({}): first difference at sorted position {first}",
                leaves.len(),
                expected.len()
            ));
        }
        Ok(())
    }

    /// The structural invariants, calling `leaf(node, triangle, box)` for every leaf reached.
    fn check_links_and_boxes(
        &self,
        no_leaves_expected: bool,
        leaf: &mut dyn FnMut(u32, usize, &Aabb) -> Result<(), String>,
    ) -> Result<(), String> {
        if self.nodes.is_empty() && no_leaves_expected && self.root == NONE {
            return Ok(());
        }
        let node_count = self.nodes.len();
        if self.root as usize >= node_count {
            return Err(format!("root {} out of range ({node_count} nodes)", self.root));
        }
        if self.nodes[self.root as usize].parent != NONE {
            return Err(format!("root {} has parent {}", self.root, self.nodes[self.root as usize].parent));
        }
        let mut seen_node = vec![false; node_count];
        let mut stack = vec![self.root];
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut seen_node[i as usize], true) {
                return Err(format!("node {i} reached twice"));
            }
            let node = self.nodes[i as usize];
            if node.left == NONE {
                leaf(i, node.right as usize, &node.aabb)?;
                continue;
            }
            for child in [node.left, node.right] {
                if child as usize >= node_count {
                    return Err(format!("node {i}: child {child} out of range ({node_count} nodes)"));
                }
                if self.nodes[child as usize].parent != i {
                    return Err(format!(
                        "node {child}: parent link {} but a child of {i}",
                        self.nodes[child as usize].parent
                    ));
                }
                stack.push(child);
            }
            let union = self.nodes[node.left as usize].aabb.union(&self.nodes[node.right as usize].aabb);
            if node.aabb != union {
                return Err(format!("node {i}: box is not the union of its children's"));
            }
        }
        if let Some(i) = seen_node.iter().position(|&s| !s) {
            return Err(format!("node {i} is unreachable from the root"));
        }
        Ok(())
    }
}
