//! Secondary rays without a scene epsilon: the point a hit describes, a bound on its rounding error, and ray
//! origins pushed off the surface by just that bound, so that a ray leaving the surface with `t_min = 0` never
//! meets the triangle it starts on, whatever the scene's scale or distance from the origin.
//!
//! The approach is pbrt's (Pharr, Jakob, Humphreys, "Physically Based Rendering", 3rd ed., section 3.9): compute
//! the hit point with a bound on its error, move the origin along the geometric normal by that bound projected on
//! the normal, to the side the new ray leaves by, and round each coordinate one more ulp away. Here:
//!
//! * the point is `p = v0 + (u e1 + v e2)` with `e1 = v1 - v0`, `e2 = v2 - v0`, whose error per axis is at most
//!   `gamma(1) |p| + gamma(4) (|u e1| + |v e2|)` (`gamma(n) = n eps / (1 - n eps)`, `eps = 2^-24`): one rounding
//!   of the point's own size plus terms of the triangle's size, so a triangle far from the origin costs one ulp
//!   of its position, not seven as `b0 v0 + u v1 + v v2` would;
//! * pbrt's triangle test rejects hits whose `t` is within its error bound of 0; the test of this crate
//!   (`format-spec/bvh-1.md` 11.1, which every kernel runs bit for bit) does not, so the offset adds a first
//!   estimate of that bound, `RESOLUTION * eps * sqrt(3) * R` (`R` the largest coordinate difference between `p`
//!   and a vertex), and [`SurfacePoint::spawn`] then runs that very test on the triangle the point lies on and
//!   doubles the offset until the new ray does not meet it (slivers seen at a grazing angle need a few
//!   doublings). Because every kernel computes the same hits as that test, no kernel reports the triangle the
//!   ray starts on.
//!
//! Wächter and Binder ("A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems, chapter 6,
//! 2019) offset by a fixed number of ulps instead, with an absolute offset near the origin that is too large for
//! scenes scaled far below 1. Neither needs an epsilon from the user. The tests spawn rays from hit points on
//! real scenes scaled from `1e-3` to `1e4` and moved up to `1e6` from the origin and count the rays that meet
//! their own triangle: none.

use crate::format::{InstanceRecord, PackedTriangle};
use crate::ray::check::RayError;
use crate::ray::hit::{ForeignHit, Hit, geometric_normal, on_triangle};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::transform::{object_ray, world_point};

/// The unit roundoff of f32, `2^-24`.
const EPS: f32 = f32::EPSILON * 0.5;

/// `gamma(n)` for f32, rounded up.
const fn gamma(n: f32) -> f32 {
    n * EPS / (1.0 - n * EPS) * 1.0001
}

/// Most doublings of the offset before [`SurfacePoint::spawn`] gives up on a record the test cannot separate
/// from an origin near it (a degenerate record); 2^40 times the first offset is far beyond any sliver's need.
const MAX_DOUBLINGS: u32 = 40;

/// The hit test's resolution in units of `eps * R` (see the module doc), the first estimate: its depth for an
/// origin on the triangle carries about six roundings of terms up to `R`; 16 leaves a margin (the offset stays
/// below `2^-20` of the triangle's size), and [`SurfacePoint::spawn`] doubles it where the test still meets the
/// triangle.
const RESOLUTION: f32 = 16.0;

/// `n` scaled to length 1; zero when it has no finite, non-zero length (a degenerate record).
fn unit(n: [f32; 3]) -> [f32; 3] {
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if length > 0.0 && length.is_finite() { n.map(|c| c / length) } else { [0.0; 3] }
}

/// Where a ray met a surface, for spawning the next rays from it: see the module doc.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// The hit point `(1 - u - v) v0 + u v1 + v v2`, in f32.
    pub position: [f32; 3],
    /// A bound on `position`'s rounding error, per axis (absolute).
    pub error: [f32; 3],
    /// How far the hit test cannot tell which side of the triangle an origin at `position` lies on:
    /// `RESOLUTION * eps * sqrt(3) * R`, `R` the largest coordinate difference between `position` and a vertex.
    pub resolution: f32,
    /// The unit geometric normal, on the front side (the winding the file stores); zero for a degenerate record.
    pub normal: [f32; 3],
    /// Whether the ray that found the point arrived at the front side.
    pub front_face: bool,
    /// The triangle record the point lies on (in its mesh's object space when `instance` is set).
    pub triangle: PackedTriangle,
    /// In a two-level file, the instance that places `triangle` in world space; `position`, `error`,
    /// `resolution` and `normal` are then in world space, and the offset is confirmed on the ray as the
    /// kernel maps it into the mesh's object space.
    pub instance: Option<InstanceRecord>,
}

impl SurfacePoint {
    /// The point of `hit` on `triangle`, the record `hit.triangle_index` names (`view.triangles()[i]`).
    /// Refuses `u`, `v` that are NaN or off the triangle ([`ForeignHit::OffTriangle`]): no kernel returns them.
    pub fn new(hit: &Hit, triangle: &PackedTriangle) -> Result<SurfacePoint, ForeignHit> {
        if !on_triangle(hit.u, hit.v) {
            return Err(ForeignHit::OffTriangle { u: hit.u, v: hit.v });
        }
        let [v0, v1, v2] = &triangle.vertices;
        let (u, v) = (hit.u, hit.v);
        let e1: [f32; 3] = std::array::from_fn(|a| v1[a] - v0[a]);
        let e2: [f32; 3] = std::array::from_fn(|a| v2[a] - v0[a]);
        let position: [f32; 3] = std::array::from_fn(|a| v0[a] + (u * e1[a] + v * e2[a]));
        let error = std::array::from_fn(|a| {
            gamma(1.0) * position[a].abs() + gamma(4.0) * ((u * e1[a]).abs() + (v * e2[a]).abs())
        });
        let reach = [v0, v1, v2]
            .iter()
            .flat_map(|vertex| (0..3).map(move |a| (vertex[a] - position[a]).abs()))
            .fold(0.0f32, f32::max);
        let resolution = RESOLUTION * EPS * 3f32.sqrt() * reach;
        let normal = unit(hit.normal);
        Ok(SurfacePoint {
            position,
            error,
            resolution,
            normal,
            front_face: hit.front_face,
            triangle: *triangle,
            instance: None,
        })
    }

    /// The point of `hit` on `triangle` (a mesh's record, in object space) placed by `instance`: the object-space
    /// point mapped to world space in f64 and rounded, its error bound carried through the map (`sum_j |L_ij|
    /// error_j`, plus the final rounding, `gamma(1) |p_i|`), the resolution scaled by the map's largest stretch
    /// (the Frobenius norm of `L` bounds it), and the unit normal of `hit.normal` (world space already).
    /// Refuses `u`, `v` off the triangle as [`SurfacePoint::new`] does.
    pub fn placed(hit: &Hit, triangle: &PackedTriangle, instance: &InstanceRecord) -> Result<SurfacePoint, ForeignHit> {
        let object_hit = Hit { normal: geometric_normal(triangle), ..*hit };
        let object = SurfacePoint::new(&object_hit, triangle)?;
        let l = &instance.object_to_world;
        let exact = world_point(instance, object.position);
        let position = exact.map(|c| c as f32);
        let error = std::array::from_fn(|i| {
            let carried: f64 = (0..3).map(|j| f64::from(l[i][j].abs()) * f64::from(object.error[j])).sum();
            (carried as f32) * (1.0 + 4.0 * EPS) + gamma(1.0) * position[i].abs()
        });
        let frobenius: f64 = l.iter().flat_map(|row| &row[..3]).map(|&c| f64::from(c) * f64::from(c)).sum::<f64>();
        let resolution = (f64::from(object.resolution) * frobenius.sqrt()) as f32 * (1.0 + 4.0 * EPS);
        Ok(SurfacePoint { position, error, resolution, normal: unit(hit.normal), instance: Some(*instance), ..object })
    }

    /// The origin for a ray leaving the surface along `direction` (to either side): [`SurfacePoint::position`]
    /// moved off the surface to `direction`'s side by the error bound and the test's resolution, so that the
    /// triangle the point lies on is behind it; the hit test then confirms it, doubling the offset until it does
    /// (see the module doc). Refuses a direction the ray contract refuses (NaN, infinite, zero, or below
    /// `2^-64` in every component), which has no side to leave by.
    pub fn offset_origin(&self, direction: [f32; 3]) -> Result<[f32; 3], RayError> {
        Ray::new(self.position, direction).check()?;
        let n = self.normal;
        let mut d =
            n[0].abs() * self.error[0] + n[1].abs() * self.error[1] + n[2].abs() * self.error[2] + self.resolution;
        let mut origin = self.moved_by(d, direction);
        for _ in 0..MAX_DOUBLINGS {
            let ray = Ray { origin, direction, t_min: 0.0, t_max: f32::INFINITY };
            let ray = match &self.instance {
                Some(instance) => object_ray(instance, &ray),
                None => ray,
            };
            if PreparedRay::new(&ray).intersect_triangle(&self.triangle, f32::INFINITY).is_none() {
                break;
            }
            d *= 2.0;
            origin = self.moved_by(d, direction);
        }
        Ok(origin)
    }

    /// [`SurfacePoint::position`] moved by `d` along the normal to `direction`'s side, each coordinate rounded
    /// one more ulp away.
    fn moved_by(&self, d: f32, direction: [f32; 3]) -> [f32; 3] {
        // A degenerate record has no normal: move along the ray instead.
        let n = if self.normal == [0.0; 3] {
            let length =
                (direction[0] * direction[0] + direction[1] * direction[1] + direction[2] * direction[2]).sqrt();
            direction.map(|c| c / length)
        } else {
            self.normal
        };
        let side = direction[0] * n[0] + direction[1] * n[1] + direction[2] * n[2];
        let d = if side < 0.0 { -d } else { d };
        std::array::from_fn(|a| {
            let offset = d * n[a];
            let moved = self.position[a] + offset;
            // One more ulp away from the surface, against the rounding of the addition.
            if offset > 0.0 {
                moved.next_up()
            } else if offset < 0.0 {
                moved.next_down()
            } else {
                moved
            }
        })
    }

    /// The unit geometric normal on the side the ray that found the point came from (the normal for a front-face
    /// hit, its opposite for a back-face one): the hemisphere a reflection or an occlusion ray leaves into.
    pub fn facing_normal(&self) -> [f32; 3] {
        if self.front_face { self.normal } else { self.normal.map(|c| -c) }
    }

    /// A cosine-weighted unit direction in the hemisphere of [`SurfacePoint::facing_normal`] from two uniform
    /// numbers `xi` in `[0, 1)`: Malley's method (a uniform point of the unit disk, `(sqrt(xi0) cos(2 pi xi1),
    /// sqrt(xi0) sin(2 pi xi1))`, lifted onto the hemisphere) in the orthonormal basis of Duff et al. ("Building
    /// an Orthonormal Basis, Revisited", JCGT 6(1), 2017), which is continuous and has no division by a small
    /// number. Its probability density is `cos(theta) / pi`, the weight of ambient occlusion and of a diffuse
    /// bounce, so an estimator averages the rays' results unweighted. For a degenerate record (no normal) the
    /// hemisphere is that of `+z`.
    pub fn cosine_direction(&self, xi: [f32; 2]) -> [f32; 3] {
        let n = if self.normal == [0.0; 3] { [0.0, 0.0, 1.0] } else { self.facing_normal() };
        let sign = 1.0f32.copysign(n[2]);
        let a = -1.0 / (sign + n[2]);
        let b = n[0] * n[1] * a;
        let tangent = [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
        let bitangent = [b, sign + n[1] * n[1] * a, -n[1]];
        let radius = xi[0].clamp(0.0, 1.0).sqrt();
        let (sin, cos) = (std::f32::consts::TAU * xi[1]).sin_cos();
        let (x, y, z) = (radius * cos, radius * sin, (1.0 - xi[0].clamp(0.0, 1.0)).sqrt());
        let d: [f32; 3] = std::array::from_fn(|k| x * tangent[k] + y * bitangent[k] + z * n[k]);
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        d.map(|c| c / length)
    }

    /// A ray leaving the surface along `direction` (ambient occlusion, bounces), over `[0, +inf]`. Refuses a
    /// direction the ray contract refuses (NaN, infinite, zero, or below `2^-64` in every component), naming
    /// the rule, rather than make a ray no tracer answers.
    pub fn spawn(&self, direction: [f32; 3]) -> Result<Ray, RayError> {
        let ray = Ray { origin: self.offset_origin(direction)?, direction, t_min: 0.0, t_max: f32::INFINITY };
        ray.check().map(|()| ray)
    }

    /// A shadow ray from the surface to `target` (a light's position): direction `target - origin`, so `t = 1`
    /// at the target, and `t_max` just below 1 so that a surface at the target itself does not occlude.
    /// Refuses a target that is not finite or lies at the surface point (no direction), as [`SurfacePoint::spawn`]
    /// refuses such directions.
    pub fn spawn_to(&self, target: [f32; 3]) -> Result<Ray, RayError> {
        if !target.iter().all(|c| c.is_finite()) {
            return Err(RayError::DirectionNotFinite);
        }
        let toward = std::array::from_fn(|a| target[a] - self.position[a]);
        let origin = self.offset_origin(toward)?;
        let direction = std::array::from_fn(|a| target[a] - origin[a]);
        let ray = Ray { origin, direction, t_min: 0.0, t_max: 1.0 - f32::EPSILON };
        ray.check().map(|()| ray)
    }
}
