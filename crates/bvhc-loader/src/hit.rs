//! What every kernel returns and reports: the [`Hit`] record, the traversal counters, and the cull padding all
//! kernels share (so that they find the same closest hit).

use crate::intersect::TriangleHit;

/// Boxes are culled against the closest hit so far padded by this factor (`1 + 2^-18`). The triangle test's `t`
/// carries a rounding error of a few ulps (different triangles through the same point, such as the fan around
/// a shared vertex, report `t`s an ulp or two apart), so culling at the exact best `t` could skip a box whose
/// triangle reports a `t` an ulp smaller. With the pad, the closest hit equals a brute-force scan exactly.
pub(crate) const CULL_PADDING: f32 = 1.0 + 1.0 / 262_144.0;

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// Index of the triangle in the file's triangles section.
    pub triangle_index: u32,
    /// The triangle's source id from the triangle_ids section, when the file has one.
    pub source_triangle_id: Option<u32>,
    /// Barycentric weight of `v1`; the hit point is `(1 - u - v) v0 + u v1 + v v2`.
    pub u: f32,
    /// Barycentric weight of `v2`.
    pub v: f32,
}

impl Hit {
    /// The hit on triangle `triangle_index` (of the file's triangles), its source id looked up in `triangle_ids`.
    pub(crate) fn new(triangle_index: u32, hit: TriangleHit, triangle_ids: Option<&[u32]>) -> Hit {
        Hit {
            t: hit.t,
            triangle_index,
            source_triangle_id: triangle_ids.and_then(|ids| ids.get(triangle_index as usize).copied()),
            u: hit.u,
            v: hit.v,
        }
    }
}

/// Receives traversal events. The default path uses `()`, whose empty methods compile away.
pub trait TraversalCounter {
    /// A node was visited (its children's boxes tested, or its triangles).
    fn node_visited(&mut self) {}
    /// A ray-triangle test was run.
    fn triangle_tested(&mut self) {}
}

impl TraversalCounter for () {}

/// Counts of the opt-in statistics mode, summed over the rays traced with it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Nodes visited.
    pub node_visits: u64,
    /// Ray-triangle tests.
    pub triangle_tests: u64,
}

impl TraversalCounter for TraversalStats {
    #[inline(always)]
    fn node_visited(&mut self) {
        self.node_visits += 1;
    }
    #[inline(always)]
    fn triangle_tested(&mut self) {
        self.triangle_tests += 1;
    }
}
