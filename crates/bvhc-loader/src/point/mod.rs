//! Point queries (`format-spec/point-queries.md`): the closest point of a file's surface to a position, within
//! an optional distance, and the distance alone. The answer is defined by the normative f64 arithmetic of one
//! triangle ([`closest_on_triangle`]) and a tie rule, so the walks and an outside reader that follows the
//! spec return the same triangle, point and distance bit for bit.
//!
//! The walks are the ray walks' shape with another node test: a box is culled when its distance from the query
//! point (in f64, from the stored f32 bounds) exceeds the closest distance so far by more than a slack that covers
//! rounding (`nearest::Nearest`); the nearer child goes first. Through a two-level file the point is mapped into
//! each instance's object space, and an object-space box's distance becomes a lower bound on the world distance
//! through the smallest stretch of the instance's map (`space::Space`).

pub(crate) mod caps;
pub(crate) mod nearest;
pub(crate) mod order;
pub(crate) mod records;
pub(crate) mod space;
pub(crate) mod triangle;
pub(crate) mod walk;
pub(crate) mod wide;
pub(crate) mod winding;

pub use triangle::{Point3, TrianglePoint, closest_on_triangle};
pub use winding::{BETA, solid_angle};

/// A triangle record a filtered point query may answer with ([`PointFilter`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointCandidate {
    /// The triangle record (absolute in a two-level file).
    pub triangle_index: u32,
    /// Its source id (`triangle_ids`), when the file has them.
    pub source_triangle_id: Option<u32>,
    /// The instance placing it, in a two-level file.
    pub instance_index: Option<u32>,
}

/// Which triangles a point query may answer with: a filtered query's answer is the closest point of the
/// triangles the filter keeps, by the same arithmetic and tie rule (`format-spec/point-queries.md`), as if the
/// others were absent. Asked about each record within the query's bound that could be the answer; with split
/// references each reference of a triangle is asked on its own, so a filter should keep all of a triangle's or
/// none (one by source id does). Closures `Fn(&PointCandidate) -> bool` are filters.
pub trait PointFilter: Sync {
    /// Whether `candidate` may be the answer.
    fn keep(&self, candidate: &PointCandidate) -> bool;
}

impl<F: Fn(&PointCandidate) -> bool + Sync> PointFilter for F {
    fn keep(&self, candidate: &PointCandidate) -> bool {
        self(candidate)
    }
}

/// The closest point of a file's surface to a query point (`format-spec/point-queries.md`).
///
/// Of all triangle records within the query's distance, the one at the smallest squared distance, computed as
/// the spec's arithmetic says; at equal squared distance the lowest instance, then the lowest record (with split
/// references the triangle's coordinates and source id, as for ray hits; the record named is then one of that
/// triangle's). `point` and `distance` are the f64 results rounded to f32 once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The point on the surface, in world space.
    pub point: [f32; 3],
    /// Its distance from the query point.
    pub distance: f32,
    /// The triangle record it lies on (an index into the triangles section, absolute in a two-level file).
    pub triangle_index: u32,
    /// The record's source id (`triangle_ids`), when the file has them.
    pub source_triangle_id: Option<u32>,
    /// Barycentric weight of the record's `v1` at the point.
    pub u: f32,
    /// Barycentric weight of the record's `v2` at the point.
    pub v: f32,
    /// The instance whose placement of the mesh it lies on, in a two-level file.
    pub instance_index: Option<u32>,
}
