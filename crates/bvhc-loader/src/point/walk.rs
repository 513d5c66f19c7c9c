//! The point walk of a binary tree: depth first, the nearer child (by box distance) first, a pending node popped
//! only while its box may still hold something as near as the closest point so far; the same bounds and checks as
//! the ray walk (`crate::binary::walk`): a fixed stack, child indices above their parent's, at most `nodes.len()`
//! visits, so any bytes give an answer, never a panic or a hang.
//!
//! What a leaf holds is the [`PointLeaves`] parameter: a mesh's triangle records
//! (`crate::point::records::TriangleRecords`) or a top tree's instances (the tracer's, `crate::tracer::points`).

use crate::format::{MAX_DEPTH, PackedNode};
use crate::point::nearest::Nearest;
use crate::point::records::PointLeaves;
use crate::point::space::Space;
use crate::walk_stack::WalkStack;

/// Walks the tree `nodes` (node 0 the root, boxes in `space`), offering its leaves to `nearest`.
pub(crate) fn walk_points<L: PointLeaves>(nodes: &[PackedNode], space: &Space, nearest: &mut Nearest, leaves: &mut L) {
    let Some(root) = nodes.first() else { return };
    if space.box_d2(root) > nearest.cull_d2 {
        return;
    }
    let mut stack = WalkStack::<(u32, f64), MAX_DEPTH>::new();
    let mut current = 0u32;
    let mut visits_left = nodes.len();
    'walk: loop {
        'visit: {
            let Some(node) = nodes.get(current as usize).filter(|_| visits_left > 0) else {
                return; // only on a file that breaks V14 (V43 in a top tree)
            };
            visits_left -= 1;
            if node.is_leaf() {
                leaves.test_leaf(node, nearest);
                break 'visit;
            }
            let first = node.index;
            let Some(second) = first.checked_add(1).filter(|_| first > current) else { break 'visit };
            let (Some(left), Some(right)) = (nodes.get(first as usize), nodes.get(second as usize)) else {
                break 'visit;
            };
            let (d_left, d_right) = (space.box_d2(left), space.box_d2(right));
            let cull = nearest.cull_d2;
            match (d_left <= cull, d_right <= cull) {
                (true, true) => {
                    let (near, far, d_far) =
                        if d_left <= d_right { (first, second, d_right) } else { (second, first, d_left) };
                    stack.push((far, d_far));
                    current = near;
                    continue 'walk;
                }
                (true, false) => {
                    current = first;
                    continue 'walk;
                }
                (false, true) => {
                    current = second;
                    continue 'walk;
                }
                (false, false) => {}
            }
        }
        loop {
            let Some((node, d2)) = stack.pop() else { return };
            if d2 <= nearest.cull_d2 {
                current = node;
                break;
            }
        }
    }
}
