//! One ray against one primitive: the ray and its contract, the robust box test and the watertight triangle
//! test (with the exact values of ill-conditioned hits), the hit records, secondary rays, instance transforms,
//! the queries a walk answers (closest hit, any hit), and the candidate tests that filters plug in. Every
//! layout's walk is built from these.

pub(crate) mod candidates;
pub(crate) mod check;
pub(crate) mod exact_hit;
pub(crate) mod exact_int;
pub(crate) mod hit;
pub(crate) mod intersect;
pub(crate) mod moved;
pub(crate) mod query;
pub(crate) mod reach;
pub(crate) mod slab;
pub(crate) mod spawn;
pub(crate) mod transform;
pub(crate) mod watertight;

pub use check::{BatchRayError, MIN_DIRECTION_COMPONENT, RayError, check_rays};
pub use hit::{
    BARYCENTRIC_SLACK, ForeignHit, Hit, HitCore, TraversalCounter, TraversalStats, TriangleHit, geometric_normal,
};
pub use intersect::{PreparedRay, Ray};
pub use spawn::SurfacePoint;
pub use transform::{instance_world_box, transformed_box};
