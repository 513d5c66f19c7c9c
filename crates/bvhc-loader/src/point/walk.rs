//! The point walk of a binary tree: depth first, the nearer child (by box distance) first, a pending node popped
//! only while its box may still hold something as near as the closest point so far; the same bounds and checks as
//! the ray walk (`crate::binary::walk`): a fixed stack, child indices above their parent's, at most `nodes.len()`
//! visits, so any bytes give an answer, never a panic or a hang.
//!
//! What a leaf holds is the [`PointLeaves`] parameter: a mesh's triangle records ([`TriangleRecords`], in world
//! space or placed by an instance) or a top tree's instances (the tracer's, `crate::tracer::points`).

use crate::format::{InstanceRecord, MAX_DEPTH, PackedNode, PackedTriangle};
use crate::point::closest_on_triangle;
use crate::point::nearest::Nearest;
use crate::point::space::Space;
use crate::ray::query::{TieKey, TieOrder};
use crate::ray::transform::world_point;
use crate::walk_stack::WalkStack;

/// What the point walk does at a leaf.
pub(crate) trait PointLeaves {
    /// Offers what leaf `node` holds to `nearest`.
    fn test_leaf(&mut self, node: &PackedNode, nearest: &mut Nearest);
}

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

/// The triangle records of one mesh's tree: `triangles` (the mesh's range; leaf indices relative to it), the
/// first at absolute record `first_record`, placed in world space by `instance` (`None`: already in world space).
pub(crate) struct TriangleRecords<'a> {
    pub triangles: &'a [PackedTriangle],
    pub first_record: u32,
    pub instance: Option<(u32, &'a InstanceRecord)>,
    /// The mesh's tie order (its range of the source ids).
    pub tie: TieOrder<'a>,
}

impl TriangleRecords<'_> {
    /// The tie key of the mesh's record `local`: spec 11.1's key with the record made absolute.
    fn key(&self, local: u32) -> TieKey {
        match self.tie.key(local, || self.triangles.get(local as usize).map_or([u32::MAX; 9], |t| t.coordinate_bits()))
        {
            TieKey::Record(record) => TieKey::Record(record.wrapping_add(self.first_record)),
            key => key,
        }
    }
}

impl PointLeaves for TriangleRecords<'_> {
    #[inline(always)]
    fn test_leaf(&mut self, node: &PackedNode, nearest: &mut Nearest) {
        let end = (node.index as usize).saturating_add(node.count as usize);
        let records = self.triangles.get(node.index as usize..end).unwrap_or(&[]);
        for (offset, triangle) in records.iter().enumerate() {
            let local = node.index.wrapping_add(offset as u32);
            let vertices = match self.instance {
                None => triangle.vertices.map(|v| v.map(f64::from)),
                Some((_, instance)) => triangle.vertices.map(|v| world_point(instance, v)),
            };
            if !vertices.iter().flatten().all(|c| c.is_finite()) {
                continue; // only in a file that breaks V12
            }
            let found = closest_on_triangle(nearest.point, vertices);
            if nearest.admits(found.d2) {
                let instance = self.instance.map(|(index, _)| index);
                nearest.offer(found, self.first_record.wrapping_add(local), instance, || self.key(local));
            }
        }
    }
}
