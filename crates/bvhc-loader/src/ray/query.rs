//! What a walk looks for along a ray (`format-spec/bvh-1.md` 11.1): the query is a type parameter of every walk
//! (binary, wide, coherent packets, the GPU model), so each query is its own monomorphized kernel and nothing on
//! the walk asks at run time which one it runs.
//!
//! Both queries bound the walk by the closest hit taken so far: a hit shrinks `t_max` to its `t`, and boxes
//! entered beyond it (padded, 11.2) are culled. They differ in whether the first hit taken ends the walk. A query
//! that bounds by another measure (the closest point to a position: the distance to a box instead of the slab
//! test) would bring its own node and leaf tests as well.

/// A query of the walks: [`ClosestHit`] or [`AnyHit`].
pub(crate) trait Query {
    /// Whether the first hit taken ends the walk (an any-hit query needs no order among hits, so its walks skip
    /// the ordering of children and, in a packet of four triangles, the search for the nearest lane).
    const FIRST_HIT_ENDS: bool;
}

/// The closest hit: the walk goes on until no box nearer than the closest hit so far is left.
pub(crate) enum ClosestHit {}

/// Any hit (occlusion): the first hit found ends the walk.
pub(crate) enum AnyHit {}

impl Query for ClosestHit {
    const FIRST_HIT_ENDS: bool = false;
}

impl Query for AnyHit {
    const FIRST_HIT_ENDS: bool = true;
}
