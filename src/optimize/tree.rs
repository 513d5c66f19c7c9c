//! The optimizer's mutable tree: binary, one triangle per leaf, parent links, boxes kept exact by refitting.
//! With split references a triangle may be in several leaves, each leaf's box being its reference's.
//!
//! Kept apart from the packed on-disk layout: the optimizer rewires links in place, then
//! [`OptTree::to_build_tree_with_leaves`] hands a plain [`BuildTree`] to the packer.

use rayon::prelude::*;

use crate::build_tree::{BuildNode, BuildTree};
use crate::builders::build_binned_sah;
use crate::geometry::Aabb;

/// Nodes per chunk of the deterministic parallel area sums.
const AREA_SUM_CHUNK: usize = 16 * 1024;

/// Marks a missing link (the root's parent, a leaf's left child).
pub const NONE: u32 = u32::MAX;

/// A node: inner nodes have `left` and `right` children; a leaf has `left == NONE` and its triangle in `right`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OptNode {
    /// Exact box: the union of the children's boxes, or the triangle's box.
    pub aabb: Aabb,
    /// Parent, `NONE` for the root.
    pub parent: u32,
    /// First child, `NONE` for a leaf.
    pub left: u32,
    /// Second child, or the leaf's triangle index.
    pub right: u32,
}

impl OptNode {
    /// Build node `node` as an optimizer node (parent link unset), when every leaf holds one triangle of
    /// `triangle_order`.
    fn of_single_triangle_leaf(node: BuildNode, triangle_order: &[u32]) -> OptNode {
        match node {
            BuildNode::Inner { aabb, left, right } => OptNode { aabb, parent: NONE, left, right },
            BuildNode::Leaf { aabb, first, .. } => {
                OptNode { aabb, parent: NONE, left: NONE, right: triangle_order[first as usize] }
            }
        }
    }
}

/// Whether every leaf of `build` holds one triangle: a binary tree over `n` triangles with `2n - 1` nodes has
/// no other kind of leaf.
fn has_single_triangle_leaves(build: &BuildTree) -> bool {
    !build.nodes.is_empty() && build.nodes.len() + 1 == 2 * build.triangle_order.len()
}

const _: () = assert!(size_of::<OptNode>() == size_of::<BuildNode>(), "the in-place conversion needs equal sizes");

/// Receives the edits of an [`OptTree`] made by its `*_logged` methods: the optimizer's undo log
/// (`EditLog`) saves each node before its first write and sums the change of the inner nodes' areas; `()`
/// records nothing.
pub trait TreeEdits {
    /// Node `i` of `tree` is about to be written (`i` may be [`NONE`]).
    fn before_write(&mut self, tree: &OptTree, i: u32);
    /// An inner node's box changes from `old` to `new`.
    fn box_changed(&mut self, old: &Aabb, new: &Aabb);
}

impl TreeEdits for () {
    #[inline(always)]
    fn before_write(&mut self, _: &OptTree, _: u32) {}
    #[inline(always)]
    fn box_changed(&mut self, _: &Aabb, _: &Aabb) {}
}

/// A binary BVH with one triangle per leaf, as the optimizer needs.
#[derive(Clone, Debug, PartialEq)]
pub struct OptTree {
    /// All nodes; `2 * triangles - 1` of them.
    pub nodes: Vec<OptNode>,
    /// The root's index.
    pub root: u32,
}

/// Surface area in f32, the optimizer's working precision (reported costs are summed in f64 by
/// [`Aabb::surface_area`]). Saturates at `f32::MAX`: a box wider than about 1e19 would otherwise give infinity,
/// or NaN (infinity times a zero extent), and NaN gains would make the searches compare nothing. `f32::min`
/// returns the other operand for NaN, so one instruction covers both cases.
#[inline(always)]
pub fn area(aabb: &Aabb) -> f32 {
    let dx = aabb.max[0] - aabb.min[0];
    let dy = aabb.max[1] - aabb.min[1];
    let dz = aabb.max[2] - aabb.min[2];
    (2.0 * (dx * dy + dy * dz + dz * dx)).min(f32::MAX)
}

impl OptTree {
    /// [`OptTree::from_build_tree`], taking the build tree: where every leaf holds one triangle, its node array
    /// becomes the optimizer's in place (the two node types have the same size, and `Vec`'s `collect` reuses
    /// the allocation), so the two trees never coexist.
    pub fn from_build(build: BuildTree, triangles: &[[[f32; 3]; 3]]) -> OptTree {
        if !has_single_triangle_leaves(&build) {
            return OptTree::from_build_tree(&build, triangles);
        }
        let BuildTree { nodes, triangle_order } = build;
        let nodes = nodes.into_iter().map(|node| OptNode::of_single_triangle_leaf(node, &triangle_order)).collect();
        OptTree::with_parent_links(nodes)
    }

    /// The tree of `build`, with leaves of several triangles split (binned SAH) into one-triangle leaves.
    pub fn from_build_tree(build: &BuildTree, triangles: &[[[f32; 3]; 3]]) -> OptTree {
        if has_single_triangle_leaves(build) {
            return OptTree::from_single_triangle_leaves(build);
        }
        let mut tree = OptTree { nodes: Vec::with_capacity(2 * triangles.len()), root: NONE };
        if build.nodes.is_empty() {
            return tree;
        }
        tree.root = tree.add_build_subtree(build, 0, triangles, NONE);
        tree
    }

    /// The tree of `build` node for node (same indices, root 0), when every leaf holds one triangle.
    fn from_single_triangle_leaves(build: &BuildTree) -> OptTree {
        let triangle_order = &build.triangle_order;
        let nodes =
            build.nodes.par_iter().map(|&node| OptNode::of_single_triangle_leaf(node, triangle_order)).collect();
        OptTree::with_parent_links(nodes)
    }

    /// The tree over `nodes` (root 0, parent links still `NONE`), with the parent links set.
    fn with_parent_links(mut nodes: Vec<OptNode>) -> OptTree {
        for i in 0..nodes.len() {
            let OptNode { left, right, .. } = nodes[i];
            if left != NONE {
                nodes[left as usize].parent = i as u32;
                nodes[right as usize].parent = i as u32;
            }
        }
        OptTree { nodes, root: 0 }
    }

    fn add_build_subtree(&mut self, build: &BuildTree, index: usize, triangles: &[[[f32; 3]; 3]], parent: u32) -> u32 {
        // Iterative over the build tree: (build node, parent in self, link from the parent: None for the top).
        let mut stack: Vec<(usize, u32, Option<bool>)> = vec![(index, parent, None)];
        let mut top = NONE;
        while let Some((b, parent, link)) = stack.pop() {
            let at = match build.nodes[b] {
                BuildNode::Inner { aabb, left, right } => {
                    let at = self.push(OptNode { aabb, parent, left: NONE, right: NONE });
                    stack.push((right as usize, at, Some(false)));
                    stack.push((left as usize, at, Some(true)));
                    at
                }
                BuildNode::Leaf { first, count, .. } => {
                    let order = &build.triangle_order[first as usize..(first + count) as usize];
                    self.add_leaves(order, triangles, parent)
                }
            };
            match link {
                None => top = at,
                Some(true) => self.nodes[parent as usize].left = at,
                Some(false) => self.nodes[parent as usize].right = at,
            }
        }
        top
    }

    /// One leaf per triangle of `order`, under a binned SAH subtree when there are several.
    fn add_leaves(&mut self, order: &[u32], triangles: &[[[f32; 3]; 3]], parent: u32) -> u32 {
        if let [t] = order {
            let aabb = Aabb::of_triangle(&triangles[*t as usize]);
            return self.push(OptNode { aabb, parent, left: NONE, right: *t });
        }
        let local: Vec<[[f32; 3]; 3]> = order.iter().map(|&t| triangles[t as usize]).collect();
        let mut sub = build_binned_sah(&local, 1);
        for t in &mut sub.triangle_order {
            *t = order[*t as usize];
        }
        self.add_build_subtree(&sub, 0, triangles, parent)
    }

    fn push(&mut self, node: OptNode) -> u32 {
        self.nodes.push(node);
        (self.nodes.len() - 1) as u32
    }

    /// Whether node `i` is a leaf.
    #[inline(always)]
    pub fn is_leaf(&self, i: u32) -> bool {
        self.nodes[i as usize].left == NONE
    }

    /// Node `i`'s surface area.
    #[inline(always)]
    pub fn area(&self, i: u32) -> f32 {
        area(&self.nodes[i as usize].aabb)
    }

    /// The other child of `i`'s parent (`i` must not be the root).
    #[inline(always)]
    pub fn sibling(&self, i: u32) -> u32 {
        let p = &self.nodes[self.nodes[i as usize].parent as usize];
        if p.left == i { p.right } else { p.left }
    }

    /// Replaces `old` by `new` among the children of `parent` (or as the root when `parent` is `NONE`).
    pub fn replace_child(&mut self, parent: u32, old: u32, new: u32) {
        self.replace_child_logged(parent, old, new, &mut ());
    }

    /// [`OptTree::replace_child`], saving what it changes in `log`.
    pub fn replace_child_logged(&mut self, parent: u32, old: u32, new: u32, log: &mut impl TreeEdits) {
        log.before_write(self, parent);
        log.before_write(self, new);
        if parent == NONE {
            self.root = new;
        } else {
            let p = &mut self.nodes[parent as usize];
            if p.left == old {
                p.left = new;
            } else {
                p.right = new;
            }
        }
        self.nodes[new as usize].parent = parent;
    }

    /// Recomputes boxes from `i` up to the root, stopping where a box does not change.
    pub fn refit_from(&mut self, i: u32) {
        self.refit_from_logged(i, &mut ());
    }

    /// [`OptTree::refit_from`], saving what it changes in `log` and adding the area change.
    pub fn refit_from_logged(&mut self, mut i: u32, log: &mut impl TreeEdits) {
        while i != NONE {
            let node = self.nodes[i as usize];
            let aabb = self.nodes[node.left as usize].aabb.union(&self.nodes[node.right as usize].aabb);
            if aabb == node.aabb {
                return;
            }
            log.before_write(self, i);
            log.box_changed(&node.aabb, &aabb);
            self.nodes[i as usize].aabb = aabb;
            i = node.parent;
        }
    }

    /// Writes `node` into inner node `i` (inner before and after), saving it in `log` and adding the area change.
    pub fn set_inner_logged(&mut self, i: u32, node: OptNode, log: &mut impl TreeEdits) {
        log.before_write(self, i);
        log.box_changed(&self.nodes[i as usize].aabb, &node.aabb);
        self.nodes[i as usize] = node;
    }

    /// Sets the parent link of node `i`, saving it in `log`.
    pub fn set_parent_logged(&mut self, i: u32, parent: u32, log: &mut impl TreeEdits) {
        log.before_write(self, i);
        self.nodes[i as usize].parent = parent;
    }

    /// Whether `x` lies in the subtree of `c` (or is `c`). Boxes are exact, so a node of `c`'s subtree has a box
    /// inside `c`'s: most nodes are ruled out by that test, without the walk up from `x` (the parallel loop's
    /// check of every move: a third of its sequential apply time on the 7.8M grid).
    pub fn is_in_subtree(&self, mut x: u32, c: u32) -> bool {
        if !self.nodes[c as usize].aabb.contains(&self.nodes[x as usize].aabb) {
            return false;
        }
        while x != NONE {
            if x == c {
                return true;
            }
            x = self.nodes[x as usize].parent;
        }
        false
    }

    /// Moves `c` (not the root, with its subtree) to be the sibling of `x` (not `c`'s parent, not in `c`'s
    /// subtree), reusing `c`'s parent as their new parent; every change saved in `log`. The parallel loop's
    /// move.
    pub fn move_beside_logged(&mut self, c: u32, x: u32, log: &mut impl TreeEdits) {
        let p = self.nodes[c as usize].parent;
        let s = self.sibling(c);
        let g = self.nodes[p as usize].parent;
        self.replace_child_logged(g, p, s, log);
        self.refit_from_logged(g, log);
        let y = self.nodes[x as usize].parent;
        let aabb = self.nodes[x as usize].aabb.union(&self.nodes[c as usize].aabb);
        self.set_inner_logged(p, OptNode { aabb, parent: self.nodes[p as usize].parent, left: x, right: c }, log);
        self.replace_child_logged(y, x, p, log);
        self.set_parent_logged(x, p, log);
        self.refit_from_logged(y, log);
    }

    /// Sum of the inner nodes' areas and of the leaves' areas, each area in f64 as the cost module computes
    /// it. Summed in fixed chunks of node indices, chunk sums added in order: the same result for any number
    /// of threads.
    pub fn area_sums(&self) -> (f64, f64) {
        let partial: Vec<(f64, f64)> = self
            .nodes
            .par_chunks(AREA_SUM_CHUNK)
            .map(|chunk| {
                chunk.iter().fold((0.0, 0.0), |(inner, leaves), node| {
                    let a = node.aabb.surface_area();
                    if node.left == NONE { (inner, leaves + a) } else { (inner + a, leaves) }
                })
            })
            .collect();
        partial.into_iter().fold((0.0, 0.0), |(i, l), (pi, pl)| (i + pi, l + pl))
    }

    /// The root's area (0 for an empty tree).
    pub fn root_area(&self) -> f64 {
        if self.root == NONE { 0.0 } else { self.nodes[self.root as usize].aabb.surface_area() }
    }

    /// Depth-first order from the root (parents before children, left subtrees first).
    pub fn depth_first(&self) -> Vec<u32> {
        let mut order = Vec::with_capacity(self.nodes.len());
        if self.root == NONE {
            return order;
        }
        let mut stack = vec![self.root];
        while let Some(i) = stack.pop() {
            order.push(i);
            let node = &self.nodes[i as usize];
            if node.left != NONE {
                stack.push(node.right);
                stack.push(node.left);
            }
        }
        order
    }

    /// Every node after both of its subtrees, the right subtree's nodes before the left one's (the reverse of
    /// [`OptTree::depth_first`]), walked with an explicit stack of the tree's depth, not an array of its size.
    /// A pass that keeps each finished subtree's result on a stack finds, at an inner node, its left child's
    /// result on top and its right child's under it.
    pub fn children_first(&self) -> ChildrenFirst<'_> {
        let stack = if self.root == NONE { Vec::new() } else { vec![(self.root, false)] };
        ChildrenFirst { tree: self, stack }
    }

    /// Largest depth of a node (root 0), by a walk with an explicit stack (memory: the tree's depth).
    pub fn max_depth(&self) -> usize {
        if self.root == NONE {
            return 0;
        }
        let mut deepest = 0;
        let mut stack = vec![(self.root, 0usize)];
        while let Some((i, depth)) = stack.pop() {
            deepest = deepest.max(depth);
            let node = &self.nodes[i as usize];
            if node.left != NONE {
                stack.push((node.right, depth + 1));
                stack.push((node.left, depth + 1));
            }
        }
        deepest
    }

    /// Rebuilds (median splits) every subtree that reaches below `max_depth`, so that no node is deeper.
    pub fn limit_depth(&mut self, max_depth: usize) {
        // Subtrees rooted at depth `cut` are rebuilt balanced: their height becomes ceil(log2(leaves)) <= 32.
        let cut = max_depth.saturating_sub(33);
        if self.max_depth() <= max_depth {
            return;
        }
        let mut depth = vec![0usize; self.nodes.len()];
        let mut roots = Vec::new();
        for i in self.depth_first() {
            let node = self.nodes[i as usize];
            if depth[i as usize] == cut && node.left != NONE {
                roots.push(i);
            } else if node.left != NONE && depth[i as usize] < cut {
                depth[node.left as usize] = depth[i as usize] + 1;
                depth[node.right as usize] = depth[i as usize] + 1;
            }
        }
        for subtree in roots {
            self.rebuild_balanced(subtree);
        }
    }

    /// Replaces the subtree under `top` by a balanced one over the same triangles, reusing its nodes.
    fn rebuild_balanced(&mut self, top: u32) {
        let mut inner = Vec::new();
        let mut leaves = Vec::new();
        let mut stack = vec![top];
        while let Some(i) = stack.pop() {
            let node = self.nodes[i as usize];
            if node.left == NONE {
                leaves.push(i);
            } else {
                inner.push(i);
                stack.push(node.left);
                stack.push(node.right);
            }
        }
        leaves.sort_unstable();
        inner.sort_unstable();
        // A leaf's box is its triangle's (or, with split references, its reference's).
        let centroid = |leaf: &u32| self.nodes[*leaf as usize].aabb.center();
        let keys: Vec<([f32; 3], u32)> = leaves.iter().map(|l| (centroid(l), *l)).collect();
        let parent = self.nodes[top as usize].parent;
        let mut free = inner.into_iter();
        let new_top = self.balanced(keys, &mut free, 0);
        self.replace_child(parent, top, new_top);
        self.refit_from(parent);
    }

    fn balanced(&mut self, mut keys: Vec<([f32; 3], u32)>, free: &mut impl Iterator<Item = u32>, axis: usize) -> u32 {
        if let [(_, leaf)] = keys[..] {
            return leaf;
        }
        let mid = keys.len() / 2;
        keys.select_nth_unstable_by(mid, |a, b| a.0[axis].total_cmp(&b.0[axis]).then(a.1.cmp(&b.1)));
        let right_keys = keys.split_off(mid);
        let node = free.next().expect("a binary tree has leaves - 1 inner nodes");
        let left = self.balanced(keys, free, (axis + 1) % 3);
        let right = self.balanced(right_keys, free, (axis + 1) % 3);
        let aabb = self.nodes[left as usize].aabb.union(&self.nodes[right as usize].aabb);
        self.nodes[left as usize].parent = node;
        self.nodes[right as usize].parent = node;
        self.nodes[node as usize] = OptNode { aabb, parent: NONE, left, right };
        node
    }

    /// The tree as a build tree in depth-first order; nodes for which `collapse` holds become one leaf over all
    /// their triangles (the leaf merger's output; a triangle that several of its leaves hold as split
    /// references appears as often, see [`crate::builders::sbvh`]), other leaves keep their one triangle.
    pub fn to_build_tree_with_leaves(&self, collapse: &dyn Fn(u32) -> bool) -> BuildTree {
        let mut build = BuildTree::default();
        if self.root == NONE {
            return build;
        }
        build.nodes.push(BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 });
        let mut stack = vec![(self.root, 0usize)];
        while let Some((i, slot)) = stack.pop() {
            let node = self.nodes[i as usize];
            if node.left == NONE || collapse(i) {
                let first = build.triangle_order.len() as u32;
                self.collect_triangles(i, &mut build.triangle_order);
                let count = build.triangle_order.len() as u32 - first;
                build.nodes[slot] = BuildNode::Leaf { aabb: node.aabb, first, count };
            } else {
                let left = build.nodes.len();
                build.nodes.push(BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 });
                build.nodes.push(BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 });
                build.nodes[slot] = BuildNode::Inner { aabb: node.aabb, left: left as u32, right: left as u32 + 1 };
                stack.push((node.right, left + 1));
                stack.push((node.left, left));
            }
        }
        build
    }

    /// Appends the triangles under `i`, left to right.
    fn collect_triangles(&self, i: u32, out: &mut Vec<u32>) {
        let mut stack = vec![i];
        while let Some(j) = stack.pop() {
            let node = &self.nodes[j as usize];
            if node.left == NONE {
                out.push(node.right);
            } else {
                stack.push(node.right);
                stack.push(node.left);
            }
        }
    }
}

/// The iterator of [`OptTree::children_first`]: the stack holds nodes still to yield, each marked once its
/// subtrees are on the stack above it.
pub struct ChildrenFirst<'a> {
    tree: &'a OptTree,
    stack: Vec<(u32, bool)>,
}

impl Iterator for ChildrenFirst<'_> {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        loop {
            let (i, expanded) = self.stack.pop()?;
            let node = &self.tree.nodes[i as usize];
            if expanded || node.left == NONE {
                return Some(i);
            }
            self.stack.push((i, true));
            self.stack.push((node.left, false));
            self.stack.push((node.right, false));
        }
    }
}
