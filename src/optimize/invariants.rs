//! The optimizer tree's invariants, checked in one pass: for tests, the property test that runs every preset
//! after every batch, and debugging.

use crate::aabb::Aabb;

use super::tree::{NONE, OptTree};

impl OptTree {
    /// Checks every invariant of an optimizer tree over `triangles`: the root has no parent; every inner node's
    /// children link back to it; every box is the exact union of its children's (a leaf's is its triangle's);
    /// every node is reachable from the root exactly once; every triangle is in exactly one leaf. Returns the
    /// first broken one, naming the node.
    pub fn check_invariants(&self, triangles: &[[[f32; 3]; 3]]) -> Result<(), String> {
        if self.nodes.is_empty() && triangles.is_empty() && self.root == NONE {
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
        let mut seen_triangle = vec![false; triangles.len()];
        let mut stack = vec![self.root];
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut seen_node[i as usize], true) {
                return Err(format!("node {i} reached twice"));
            }
            let node = self.nodes[i as usize];
            if node.left == NONE {
                let t = node.right as usize;
                let Some(triangle) = triangles.get(t) else {
                    return Err(format!("leaf {i}: triangle {t} out of range ({} triangles)", triangles.len()));
                };
                if std::mem::replace(&mut seen_triangle[t], true) {
                    return Err(format!("triangle {t} in two leaves"));
                }
                if node.aabb != Aabb::of_triangle(triangle) {
                    return Err(format!("leaf {i}: box is not its triangle's box"));
                }
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
        if let Some(t) = seen_triangle.iter().position(|&s| !s) {
            return Err(format!("triangle {t} is in no leaf"));
        }
        if let Some(i) = seen_node.iter().position(|&s| !s) {
            return Err(format!("node {i} is unreachable from the root"));
        }
        Ok(())
    }
}
