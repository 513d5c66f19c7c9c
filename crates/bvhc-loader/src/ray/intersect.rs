//! Robust ray-box and watertight ray-triangle tests.
//!
//! * Box: the slab test of T. Ize, "Robust BVH Ray Traversal", JCGT 2(2), 2013. Every slab's exit distance is
//!   padded by `1 + 2 gamma(3)` (gamma(n) = n eps / (1 - n eps), eps = 2^-24), which bounds the rounding of
//!   `(plane - origin) * (1 / direction)`, so a box that the exact ray touches is never missed. The padding is
//!   folded into the exit reciprocal once per ray (`exit_inverse = (1 / direction) * (1 + 2 gamma(3))`): the exit
//!   distance `(plane - origin) * exit_inverse` then carries four roundings, as Ize's `((plane - origin) *
//!   (1 / direction)) * (1 + 2 gamma(3))` does, each at most a factor `1 - eps` away, and `(1 - eps)^4 (1 + 6
//!   eps) > 1`, so it is still never below the exact distance; one multiplication a slab fewer.
//! * Triangle: S. Woop, C. Benthin, I. Wald, "Watertight Ray/Triangle Intersection", JCGT 2(1), 2013
//!   ([`crate::ray::watertight`], written once for every lane width; here its one-lane form). The 2D edge functions
//!   U, V, W are recomputed in f64 when any is exactly 0, so a ray through a shared edge or vertex hits at
//!   least one of the triangles that share it. An ill-conditioned hit (a needle, a sliver, a ray nearly in the
//!   plane: `format-spec/bvh-1.md` 11.1 step 5) takes the exact `t`, `u`, `v` ([`crate::ray::exact_hit`]).
//!
//! Direction components of +0 and -0 give infinite reciprocals. The slab distances are then `+-inf`, or NaN
//! when the origin lies exactly on a slab plane (`0 * inf`); the slab bounds are accumulated with comparisons
//! that ignore a NaN operand, which treats the origin on the plane as inside the closed slab, as the exact test
//! would.

use crate::format::{PackedNode, PackedTriangle, WIDE};
use crate::ray::exact_hit::exact_hit;
use crate::ray::hit::TriangleHit;
use crate::ray::reach::{BoxRay, cull};
use crate::ray::slab::{EXIT_PADDING, slab};
use crate::ray::watertight::{
    EXACT_SIGNS, ILL_CONDITIONED, RelativeTriangle, TINY_EXTENT, barycentrics, conditioning, determinant, distance,
    edge_functions, edge_functions_f64, has_zero_edge, outside, sheared, zero_edges_exact,
};
use crate::simd::SlabRay;

/// A ray: points `origin + t * direction` for `t` in `[t_min, t_max]`.
///
/// `direction` need not be normalized; `t` is measured in its units. `t_min` should be `>= 0`: boxes are tested
/// conservatively only for non-negative distances. Plain data in the layout of the 32-byte ray records of
/// `bvhc trace` and of the C API's `bvhc_ray` (`bytemuck::Pod`), so arrays of them can be viewed in place.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: [f32; 3],
    /// Direction; must not be the zero vector.
    pub direction: [f32; 3],
    /// Smallest distance that counts as a hit.
    pub t_min: f32,
    /// Largest distance that counts as a hit.
    pub t_max: f32,
}

crate::format::plain_data::plain_data! { Ray { [f32; 3], [f32; 3], f32, f32 } }

impl Ray {
    /// A ray over `[0, +inf]`.
    pub fn new(origin: [f32; 3], direction: [f32; 3]) -> Ray {
        Ray { origin, direction, t_min: 0.0, t_max: f32::INFINITY }
    }
}

/// Per-ray constants of both tests, computed once per ray.
#[derive(Clone, Copy, Debug)]
pub struct PreparedRay {
    pub(crate) origin: [f32; 3],
    /// The ray's direction, for the exact values of ill-conditioned hits.
    direction: [f32; 3],
    pub(crate) inverse_direction: [f32; 3],
    /// `inverse_direction * EXIT_PADDING`: exit distances through it are Ize's padded ones.
    pub(crate) exit_inverse: [f32; 3],
    /// Per axis: whether the direction's sign bit is set, so the slab is entered through `max`.
    pub(crate) negative: [bool; 3],
    /// Per axis: where a wide node's entry and exit planes of the axis start, in `f32`s from the start of the
    /// node (its three `min` rows, then its three `max` rows, `WIDE` lanes a row): `axis * WIDE`, plus
    /// `3 * WIDE` for the `max` row. Only [`PreparedRay::new`] writes them, so they are always such offsets.
    wide_plane_offsets: ([usize; 3], [usize; 3]),
    pub(crate) t_min: f32,
    /// The walk's reach offset `2^-11 D` over its tree (`crate::ray::reach`), set by [`PreparedRay::in_tree`];
    /// 0 before.
    pub(crate) reach_offset: f32,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

/// The permuted axes `[kx, ky, kz]` of Woop et al.'s shear for `direction` (spec 11.1): `kz` the axis of the
/// largest magnitude (the first of equal ones), `kx`, `ky` the next two in cyclic order, swapped when the
/// direction along `kz` is negative (so the triangle's winding is kept).
#[inline(always)]
pub(crate) fn shear_axes(direction: [f32; 3]) -> [usize; 3] {
    let abs = direction.map(f32::abs);
    let kz = if abs[0] >= abs[1] && abs[0] >= abs[2] {
        0
    } else if abs[1] >= abs[2] {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if direction[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    [kx, ky, kz]
}

impl PreparedRay {
    /// Precomputes the reciprocal direction and the shear of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> PreparedRay {
        let d = ray.direction;
        // `shear_axes`, written out: calling it (array or tuple) cost 1.7% more instructions a ray through the
        // wide kernel (callgrind, kitchen, 852.7 -> 866.8).
        let abs = d.map(f32::abs);
        let kz = if abs[0] >= abs[1] && abs[0] >= abs[2] {
            0
        } else if abs[1] >= abs[2] {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let inverse_direction = d.map(|c| 1.0 / c);
        let row = |axis: usize, max: bool| axis * WIDE + if max { 3 * WIDE } else { 0 };
        PreparedRay {
            origin: ray.origin,
            direction: d,
            inverse_direction,
            exit_inverse: inverse_direction.map(|i| i * EXIT_PADDING),
            negative: d.map(f32::is_sign_negative),
            wide_plane_offsets: (
                std::array::from_fn(|axis| row(axis, d[axis].is_sign_negative())),
                std::array::from_fn(|axis| row(axis, !d[axis].is_sign_negative())),
            ),
            t_min: ray.t_min,
            reach_offset: 0.0,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// This ray as a walk over a tree of `crate::ray::reach::tree_scale` `tree` prepares it: its reach offset
    /// `tree |sz|` set.
    #[inline(always)]
    pub(crate) fn in_tree(self, tree: f32) -> PreparedRay {
        PreparedRay { reach_offset: tree * self.sz.abs(), ..self }
    }

    /// The distance beyond which a walk culls boxes when its closest hit so far (or its `t_max`) is `t`, for a
    /// ray prepared for its tree ([`PreparedRay::in_tree`]): `crate::ray::reach::cull` with the ray's `2^-11 D`.
    #[inline(always)]
    pub(crate) fn cull_distance(&self, t: f32) -> f32 {
        cull(t, self.reach_offset)
    }

    /// The box condition of a hit at `t` on `triangle` (`crate::ray::reach`, "The box condition").
    #[inline]
    pub(crate) fn meets_record_box(&self, triangle: &PackedTriangle, t: f32) -> bool {
        let ([_, _, kz], [_, _, sz]) = self.shear();
        self.box_ray().meets_record_box(triangle, t, (self.t_min, kz, sz))
    }

    /// What the box tests need of this ray.
    #[inline(always)]
    pub(crate) fn box_ray(&self) -> BoxRay {
        BoxRay {
            origin: self.origin,
            inverse: self.inverse_direction,
            exit_inverse: self.exit_inverse,
            negative: self.negative,
        }
    }

    /// What the slab test of a wide node's eight boxes needs of this ray.
    #[inline(always)]
    pub(crate) fn slab_ray(&self) -> SlabRay<'_> {
        SlabRay {
            origin: &self.origin,
            inverse_direction: &self.inverse_direction,
            exit_inverse: &self.exit_inverse,
            plane_offsets: &self.wide_plane_offsets,
            t_min: self.t_min,
        }
    }

    /// The permuted axes `[kx, ky, kz]` and the shear `[sx, sy, sz]` of Woop et al.'s test.
    pub(crate) fn shear(&self) -> ([usize; 3], [f32; 3]) {
        ([self.kx, self.ky, self.kz], [self.sx, self.sy, self.sz])
    }

    /// The distance at which the ray enters `node`'s box, if it overlaps the box within `[t_min, t_max]`.
    #[inline(always)]
    pub fn enter_box(&self, node: &PackedNode, t_max: f32) -> Option<f32> {
        let mut t_near = self.t_min;
        let mut t_far = t_max;
        for axis in 0..3 {
            let (entry_plane, exit_plane) =
                if self.negative[axis] { (node.max[axis], node.min[axis]) } else { (node.min[axis], node.max[axis]) };
            let inverses = (self.inverse_direction[axis], self.exit_inverse[axis]);
            (t_near, t_far) = slab(entry_plane, exit_plane, self.origin[axis], inverses, t_near, t_far);
        }
        (t_near <= t_far).then_some(t_near)
    }

    /// The exact `t`, `u`, `v` of a hit on `triangle` that the watertight test found ill-conditioned
    /// ([`exact_hit`]), as the hit within `[t_min, t_max]` that meets the box condition or `Some(None)` when it
    /// is not one; `None` when there are none (the weights sum to zero), so that the test's own values stand.
    pub(crate) fn exact_hit(&self, triangle: &PackedTriangle, t_max: f32) -> Option<Option<TriangleHit>> {
        let hit = exact_hit(&self.origin, &self.direction, self.kz, &triangle.vertices)?;
        let counts = hit.t >= self.t_min && hit.t <= t_max && self.meets_record_box(triangle, hit.t);
        Some(counts.then_some(hit))
    }

    /// The triangle's vertices relative to the origin, in the ray's permuted axes.
    #[inline(always)]
    pub(crate) fn relative(&self, triangle: &PackedTriangle) -> RelativeTriangle<f32> {
        let o = &self.origin;
        let [v0, v1, v2] = &triangle.vertices;
        let a = [v0[0] - o[0], v0[1] - o[1], v0[2] - o[2]];
        let b = [v1[0] - o[0], v1[1] - o[1], v1[2] - o[2]];
        let c = [v2[0] - o[0], v2[1] - o[1], v2[2] - o[2]];
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        RelativeTriangle { a: [a[kx], a[ky], a[kz]], b: [b[kx], b[ky], b[kz]], c: [c[kx], c[ky], c[kz]] }
    }

    /// The watertight test: a hit with `t_min <= t <= t_max`, from either side of the triangle, that meets the box
    /// condition (`format-spec/bvh-1.md` 11.1: the ray meets the record's bounding box near `t`).
    #[inline(always)]
    pub fn intersect_triangle(&self, triangle: &PackedTriangle, t_max: f32) -> Option<TriangleHit> {
        self.intersect_triangle_with::<true>(triangle, t_max)
    }

    /// The GPU kernel's form of [`PreparedRay::intersect_triangle`]: without f64, an edge function of exactly 0
    /// becomes its exact value ([`zero_edges_exact`]: what the f64 recomputation gives that edge) while the other
    /// two keep their f32 values (`crate::gpu::model` says what that changes).
    #[inline(always)]
    pub(crate) fn intersect_triangle_f32(&self, triangle: &PackedTriangle, t_max: f32) -> Option<TriangleHit> {
        self.intersect_triangle_with::<false>(triangle, t_max)
    }

    #[inline(always)]
    fn intersect_triangle_with<const F64_EDGES: bool>(
        &self,
        triangle: &PackedTriangle,
        t_max: f32,
    ) -> Option<TriangleHit> {
        let r = self.relative(triangle);
        let p = sheared(&r, self.sx, self.sy);
        let mut e = edge_functions(p);
        if has_zero_edge(e, 0.0) {
            e = if F64_EDGES { edge_functions_f64(p) } else { zero_edges_exact(p, e) };
        }
        if outside(e, 0.0) {
            return None;
        }
        let det = determinant(e);
        if det == 0.0 {
            return None;
        }
        let (ill, exact_signs) = conditioning(e, p, &r, det, (ILL_CONDITIONED, TINY_EXTENT, EXACT_SIGNS));
        if ill && let Some(hit) = self.exact_hit(triangle, t_max) {
            return hit;
        }
        let t = distance(e, &r, self.sz, det);
        if !(t >= self.t_min && t <= t_max) {
            return None;
        }
        // The box condition, which a well-conditioned hit of the exact ray inside the triangle meets.
        let inside = !ill && t < f32::INFINITY && exact_signs;
        if !inside && !self.meets_record_box(triangle, t) {
            return None;
        }
        let (u, v) = barycentrics(e, det, 1.0);
        Some(TriangleHit { t, u, v })
    }
}

#[cfg(test)]
mod tests {
    use super::{PreparedRay, Ray, cull, shear_axes};
    use crate::format::{PackedNode, PackedTriangle};

    /// `shear_axes` (the coherent packets' set-up) and `PreparedRay::new` (which writes the same choice out)
    /// choose the same axes: every direction whose components are drawn from values with equal magnitudes,
    /// signed zeros and both signs, so every tie and swap is met.
    #[test]
    fn shear_axes_match_the_prepared_ray() {
        let values = [0.0f32, -0.0, 1.0, -1.0, 2.0, -2.0, 0.5, -0.5];
        for &x in &values {
            for &y in &values {
                for &z in &values {
                    let direction = [x, y, z];
                    let prepared = PreparedRay::new(&Ray::new([0.0; 3], direction));
                    assert_eq!(shear_axes(direction), prepared.shear().0, "{direction:?}");
                }
            }
        }
    }

    #[test]
    fn the_box_condition_takes_hits_of_the_exact_ray_and_drops_records_the_ray_passes_by() {
        let triangle = PackedTriangle { vertices: [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] };
        let down = PreparedRay::new(&Ray::new([0.25, 0.25, 5.0], [0.0, 0.0, -1.0]));
        assert!(down.meets_record_box(&triangle, 5.0));
        // A `t` far outside the window (as no hit of this ray has) is refused, and a ray that passes beside the
        // record's box never meets it.
        assert!(!down.meets_record_box(&triangle, 4.0));
        let beside = PreparedRay::new(&Ray::new([2.0, 0.25, 5.0], [0.0, 0.0, -1.0]));
        assert!(!beside.meets_record_box(&triangle, 5.0));
    }

    #[test]
    fn a_prepared_ray_reaches_past_its_tree_along_its_major_axis() {
        let root = PackedNode { min: [-1.0, -2.0, -3.0], max: [1.0, 2.0, 3.0], index: 0, count: 0 };
        let tree = crate::ray::reach::tree_scale(&root, 1.0);
        // D = 6 * 0.25: a record spread over the root's longest side, along a ray of |d|_inf = 4.
        let ray = PreparedRay::new(&Ray::new([0.0; 3], [1.0, 2.0, -4.0])).in_tree(tree);
        assert_eq!(ray.cull_distance(1.0), cull(1.0, 1.5 * crate::ray::reach::REACH));
        assert_eq!(ray.cull_distance(f32::INFINITY), f32::INFINITY);
    }
}
