//! One walk of a binary tree (`format-spec/bvh-1.md` 11.2 and, for the top tree, 11.3): depth first, nearer
//! child first, boxes culled beyond the reach of the closest hit so far (`crate::ray::reach`), with a fixed stack of
//! [`MAX_DEPTH`] entries (the depth rules V20 and V43 make it enough) and no heap allocation.
//!
//! What a leaf holds is the [`Leaves`] parameter: [`TriangleLeaves`] (a mesh's triangle records, the candidates
//! a filter accepts) or the instances of a two-level file (`crate::instances`). Each combination is
//! monomorphized; nothing on the walk goes through `dyn`.
//!
//! The walk is safe on any input: indices are bounds-checked, a child index must exceed its parent's (so paths
//! cannot cycle), and a ray visits at most `nodes.len()` nodes; on a file that fails verification it may return
//! wrong hits, never panic or hang.

use crate::format::{MAX_DEPTH, PackedNode, PackedTriangle};
use crate::ray::candidates::Candidates;
use crate::ray::hit::{TraversalCounter, TriangleHit};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::query::{Query, TieKey, TieOrder, precedes};
use crate::walk_stack::WalkStack;

/// What the walk does at a leaf.
pub(crate) trait Leaves<C: TraversalCounter> {
    /// What a hit in a leaf is.
    type Found;

    /// The tree's part in the walk's reach (`crate::ray::reach::tree_scale` of its root, for a top tree with
    /// its instances' largest stretch), computed once by the tracer.
    fn reach_scale(&self) -> f32;

    /// Tests leaf `node` for hits with `t <= *t_max` of `ray` (prepared as `prepared`): each hit that precedes
    /// `*found` ([`precedes`]: a smaller `t`, or the same and a lower key) replaces it and lowers `*t_max` to its
    /// `t`. For an any-hit query, returns `true` at the first hit taken, which
    /// ends the walk; `false` otherwise.
    fn test_leaf<Q: Query>(
        &mut self,
        node: &PackedNode,
        ray: &Ray,
        prepared: &PreparedRay,
        t_max: &mut f32,
        found: &mut Option<Self::Found>,
        counter: &mut C,
    ) -> bool;
}

/// The leaves of a mesh's tree: records `index .. index + count` of `triangles`, each tested by the watertight
/// test and taken when `candidates` accepts it.
pub(crate) struct TriangleLeaves<'t, 'c, F> {
    pub triangles: &'t [PackedTriangle],
    pub candidates: &'c F,
    /// Which [`TieKey`] orders hits at one `t`.
    pub tie: TieOrder<'t>,
    /// [`Leaves::reach_scale`].
    pub reach_scale: f32,
}

impl<F> TriangleLeaves<'_, '_, F> {
    /// The tie keys of records `record` and `best`.
    #[inline(never)]
    fn tie_keys(&self, record: u32, best: u32) -> (TieKey, TieKey) {
        let key = |r: u32| {
            self.tie.key(r, || self.triangles.get(r as usize).map_or([u32::MAX; 9], PackedTriangle::coordinate_bits))
        };
        (key(record), key(best))
    }
}

impl<C: TraversalCounter, F: Candidates> Leaves<C> for TriangleLeaves<'_, '_, F> {
    /// The record index and its hit.
    type Found = (u32, TriangleHit);

    fn reach_scale(&self) -> f32 {
        self.reach_scale
    }

    #[inline(always)]
    fn test_leaf<Q: Query>(
        &mut self,
        node: &PackedNode,
        _: &Ray,
        prepared: &PreparedRay,
        t_max: &mut f32,
        found: &mut Option<Self::Found>,
        counter: &mut C,
    ) -> bool {
        let end = (node.index as usize).saturating_add(node.count as usize);
        let leaf_triangles = self.triangles.get(node.index as usize..end).unwrap_or(&[]);
        for (offset, triangle) in leaf_triangles.iter().enumerate() {
            counter.triangle_tested();
            let record = node.index.wrapping_add(offset as u32);
            if let Some(hit) = prepared.intersect_triangle(triangle, *t_max)
                && (!F::ACTIVE || self.candidates.accept(record, &hit))
            {
                if Q::FIRST_HIT_ENDS {
                    *found = Some((record, hit));
                    return true;
                }
                if found.is_none_or(|(best, best_hit)| precedes(hit.t, best_hit.t, || self.tie_keys(record, best))) {
                    *found = Some((record, hit));
                    *t_max = hit.t;
                }
            }
        }
        false
    }
}

/// The closest hit of `ray` in the tree `nodes` (node 0 the root), or for an any-hit query the first hit found.
#[inline(always)]
pub(crate) fn walk<Q: Query, C: TraversalCounter, L: Leaves<C>>(
    nodes: &[PackedNode],
    ray: &Ray,
    counter: &mut C,
    mut leaves: L,
) -> Option<L::Found> {
    let root = nodes.first()?;
    let prepared = PreparedRay::new(ray).in_tree(leaves.reach_scale());
    let mut t_cull = prepared.cull_distance(ray.t_max);
    prepared.enter_box(root, t_cull)?;
    let mut t_max = ray.t_max;
    let mut found = None;
    let mut stack = WalkStack::<(u32, f32), MAX_DEPTH>::new();
    let mut current = 0u32;
    let mut visits_left = nodes.len();
    'walk: loop {
        // Visit `current`; `break` out of this block to pop the next node.
        'visit: {
            let Some(node) = nodes.get(current as usize).filter(|_| visits_left > 0) else {
                return found; // only on a file that breaks V14 (V43 in a top tree)
            };
            visits_left -= 1;
            counter.node_visited();
            if node.is_leaf() {
                if leaves.test_leaf::<Q>(node, ray, &prepared, &mut t_max, &mut found, counter) {
                    return found;
                }
                t_cull = prepared.cull_distance(t_max);
                break 'visit;
            }
            let first = node.index;
            let Some(second) = first.checked_add(1).filter(|_| first > current) else {
                break 'visit;
            };
            let (Some(left), Some(right)) = (nodes.get(first as usize), nodes.get(second as usize)) else {
                break 'visit;
            };
            match (prepared.enter_box(left, t_cull), prepared.enter_box(right, t_cull)) {
                (Some(t_left), Some(t_right)) => {
                    let (near, far, t_far) =
                        if t_left <= t_right { (first, second, t_right) } else { (second, first, t_left) };
                    stack.push((far, t_far));
                    current = near;
                    continue 'walk;
                }
                (Some(_), None) => {
                    current = first;
                    continue 'walk;
                }
                (None, Some(_)) => {
                    current = second;
                    continue 'walk;
                }
                (None, None) => {}
            }
        }
        // Pop the nearest pending node that may still hold a closer hit.
        loop {
            let Some((node, t_entry)) = stack.pop() else {
                return found;
            };
            if t_entry <= t_cull {
                current = node;
                break;
            }
        }
    }
}
