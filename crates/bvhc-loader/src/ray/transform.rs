//! The arithmetic of instances (`format-spec/bvh-1.md` 5.11 and 11.3): mapping a ray into a mesh's object
//! space, a hit's normal back to world space, a mesh's box to world space, and the checks of rule V42.
//!
//! Everything is computed in f64 from the stored f32 entries and rounded to f32 once, so the object-space ray
//! is the exact image of the world ray rounded to nearest per coordinate (at most 2^-24 relative error each,
//! plus the f64 sums' far smaller error). Every kernel path runs this same scalar code, so they see the same
//! object-space ray bit for bit.

use crate::format::{Affine3x4, INSTANCE_BOX_PADDING, INVERSE_TOLERANCE, InstanceRecord, MIN_ORTHOGONALITY, NO_INDEX};
use crate::ray::intersect::Ray;

/// `m` applied to the point `p` (f64).
pub(crate) fn apply_point(m: &Affine3x4, p: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| {
        let row = m[i].map(f64::from);
        row[0] * p[0] + row[1] * p[1] + row[2] * p[2] + row[3]
    })
}

/// The linear part of `m` applied to the direction `d` (f64).
fn apply_direction(m: &Affine3x4, d: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| {
        let row = m[i].map(f64::from);
        row[0] * d[0] + row[1] * d[1] + row[2] * d[2]
    })
}

/// The determinant of the 3x3 part of `m` (f64).
fn determinant(m: &Affine3x4) -> f64 {
    let a = |i: usize, j: usize| f64::from(m[i][j]);
    a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
        + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0))
}

/// Whether `instance`'s map mirrors (its linear part has a negative determinant), which turns its mesh's
/// front sides to the back in world space.
pub(crate) fn mirrors(instance: &InstanceRecord) -> bool {
    determinant(&instance.object_to_world) < 0.0
}

/// `ray` in the object space of `instance`: origin `W (o - t)`, direction `W d`, for the 3x3 part `W` of
/// `world_to_object` and the translation `t` of `object_to_world` (not renormalized, so a point at parameter
/// `t` is the image of the world ray's point at `t`), each coordinate computed in f64 and rounded to nearest
/// f32; `t_min` and `t_max` unchanged. Subtracting the placement's own translation first (exact in f64) rather
/// than adding `world_to_object`'s keeps the origin's error relative to its distance from the instance, not
/// to the instance's distance from the world origin: far from the origin, `world_to_object`'s translation is
/// rounded to a step as large as the mesh's details.
#[inline]
pub(crate) fn object_ray(instance: &InstanceRecord, ray: &Ray) -> Ray {
    let m = &instance.world_to_object;
    let translation = instance.object_to_world.map(|row| f64::from(row[3]));
    let relative: [f64; 3] = std::array::from_fn(|k| f64::from(ray.origin[k]) - translation[k]);
    let origin = apply_direction(m, relative).map(|c| c as f32);
    let direction = apply_direction(m, ray.direction.map(f64::from)).map(|c| c as f32);
    Ray { origin, direction, t_min: ray.t_min, t_max: ray.t_max }
}

/// The world-space geometric normal of a hit whose object-space normal is `normal`: `|det L| W^T n` for the
/// linear parts `L` of `object_to_world` and `W` of `world_to_object` (`det(L) L^-T` is the cofactor matrix,
/// which maps a cross product of object edges to the cross product of their images; the absolute value keeps
/// the normal on the front side under a mirroring map). For the identity map it is `normal` bit for bit.
pub(crate) fn world_normal(instance: &InstanceRecord, normal: [f32; 3]) -> [f32; 3] {
    let scale = determinant(&instance.object_to_world).abs();
    let w = &instance.world_to_object;
    let n = normal.map(f64::from);
    std::array::from_fn(|i| {
        let column = [0, 1, 2].map(|j| f64::from(w[j][i]));
        ((column[0] * n[0] + column[1] * n[1] + column[2] * n[2]) * scale) as f32
    })
}

/// `point` (object space) in world space, in f64.
pub(crate) fn world_point(instance: &InstanceRecord, point: [f32; 3]) -> [f64; 3] {
    apply_point(&instance.object_to_world, point.map(f64::from))
}

/// The exact (f64) axis-aligned box of the image of the box `min..max` under `object_to_world`: the bounds of
/// its eight transformed corners.
pub fn transformed_box(object_to_world: &Affine3x4, (min, max): ([f32; 3], [f32; 3])) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for corner in 0..8 {
        let p = std::array::from_fn(|a| f64::from(if corner >> a & 1 == 0 { min[a] } else { max[a] }));
        let q = apply_point(object_to_world, p);
        for a in 0..3 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
        }
    }
    (lo, hi)
}

/// The world box a writer stores for an instance of a mesh whose root box is `mesh_box`: the exact image box
/// ([`transformed_box`]) grown on every side by [`INSTANCE_BOX_PADDING`] times its magnitude (its largest
/// absolute coordinate) and rounded outward to f32. `None` when it is not finite in f32.
pub fn instance_world_box(object_to_world: &Affine3x4, mesh_box: ([f32; 3], [f32; 3])) -> Option<([f32; 3], [f32; 3])> {
    let (lo, hi) = transformed_box(object_to_world, mesh_box);
    let magnitude = lo.iter().chain(&hi).map(|c| c.abs()).fold(0.0, f64::max);
    let pad = magnitude * INSTANCE_BOX_PADDING;
    let min = lo.map(|c| round_down(c - pad));
    let max = hi.map(|c| round_up(c + pad));
    min.iter().chain(&max).all(|c| c.is_finite()).then_some((min, max))
}

/// The largest f32 at most `x`.
fn round_down(x: f64) -> f32 {
    let r = x as f32;
    if f64::from(r) > x { r.next_down() } else { r }
}

/// The smallest f32 at least `x`.
fn round_up(x: f64) -> f32 {
    let r = x as f32;
    if f64::from(r) < x { r.next_up() } else { r }
}

impl InstanceRecord {
    /// The record placing mesh `mesh_index` by `object_to_world`, with its inverse computed in f64 and rounded
    /// to f32; provenance fields [`NO_INDEX`]. `None` when the map breaks rule V42 (not finite, singular, or an
    /// inverse that does not fit f32 within the tolerance).
    pub fn placing(mesh_index: u32, object_to_world: Affine3x4) -> Option<InstanceRecord> {
        let a = |i: usize, j: usize| f64::from(object_to_world[i][j]);
        let det = determinant(&object_to_world);
        if !det.is_finite() || det == 0.0 {
            return None;
        }
        // The inverse of the 3x3 part by cofactors, then the translation `-L^-1 t`.
        let cofactor = |i: usize, j: usize| {
            let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
            let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
            a(r0, c0) * a(r1, c1) - a(r0, c1) * a(r1, c0)
        };
        let inverse: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| cofactor(j, i) / det));
        let mut world_to_object = [[0.0f32; 4]; 3];
        for i in 0..3 {
            let translation = -(0..3).map(|j| inverse[i][j] * a(j, 3)).sum::<f64>();
            world_to_object[i] = [inverse[i][0], inverse[i][1], inverse[i][2], translation].map(|c| c as f32);
        }
        let record = InstanceRecord {
            object_to_world,
            world_to_object,
            mesh_index,
            node_index: NO_INDEX,
            gpu_instance_index: NO_INDEX,
            reserved: 0,
        };
        check_transform(&record).is_ok().then_some(record)
    }
}

/// Rule V42 for one instance: both maps finite, the 3x3 part of `object_to_world` invertible
/// ([`MIN_ORTHOGONALITY`]), and `world_to_object . object_to_world` the identity within [`INVERSE_TOLERANCE`]:
/// per entry of the 3x3 part `|P_ij - delta_ij| <= tol * sum_k |W_ik| |L_kj|`, per translation entry
/// `|p_i| <= tol * (sum_k |W_ik| |t_k| + |w_i|)` (each product's own scale, so the test does not depend on
/// units or on the distance from the origin). Returns what is wrong.
pub(crate) fn check_transform(instance: &InstanceRecord) -> Result<(), String> {
    let (l, w) = (&instance.object_to_world, &instance.world_to_object);
    if !l.iter().chain(w).flatten().all(|c| c.is_finite()) {
        return Err("object_to_world and world_to_object must be finite".to_string());
    }
    let row_norm = |i: usize| l[i][..3].iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>().sqrt();
    let det = determinant(l);
    let hadamard = row_norm(0) * row_norm(1) * row_norm(2);
    if det == 0.0 || det.abs() < MIN_ORTHOGONALITY * hadamard {
        return Err(format!(
            "object_to_world is singular or nearly so: |det| {:e} < 2^-20 x the product of its row lengths {:e}",
            det.abs(),
            hadamard
        ));
    }
    let (l64, w64) = (|i: usize, j: usize| f64::from(l[i][j]), |i: usize, j: usize| f64::from(w[i][j]));
    for i in 0..3 {
        for j in 0..4 {
            let (value, scale) = if j < 3 {
                let value = (0..3).map(|k| w64(i, k) * l64(k, j)).sum::<f64>() - if i == j { 1.0 } else { 0.0 };
                (value, (0..3).map(|k| (w64(i, k) * l64(k, j)).abs()).sum::<f64>())
            } else {
                let value = (0..3).map(|k| w64(i, k) * l64(k, 3)).sum::<f64>() + w64(i, 3);
                (value, (0..3).map(|k| (w64(i, k) * l64(k, 3)).abs()).sum::<f64>() + w64(i, 3).abs())
            };
            if value.abs() > INVERSE_TOLERANCE * scale {
                return Err(format!(
                    "world_to_object is not the inverse of object_to_world: entry ({i}, {j}) of their product is \
                     off by {value:e} (tolerance {:e})",
                    INVERSE_TOLERANCE * scale
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identity_maps_rays_and_normals_bit_for_bit() {
        let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let record = InstanceRecord::placing(0, identity).unwrap();
        assert_eq!(record.world_to_object, identity);
        let ray = Ray { origin: [1.5, -2.25, 1e7], direction: [0.1, -0.3, 0.7], t_min: 0.5, t_max: 9.0 };
        assert_eq!(object_ray(&record, &ray), ray);
        assert_eq!(world_normal(&record, [0.3, -0.7, 1e-3]), [0.3, -0.7, 1e-3]);
    }

    #[test]
    fn singular_and_non_finite_maps_are_refused() {
        let flat = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]];
        assert!(InstanceRecord::placing(0, flat).is_none());
        let nan = [[f32::NAN, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        assert!(InstanceRecord::placing(0, nan).is_none());
        let mut record =
            InstanceRecord::placing(0, [[2.0, 0.0, 0.0, 5.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]).unwrap();
        assert!(check_transform(&record).is_ok());
        record.world_to_object[0][3] = -2.0; // should be -2.5
        assert!(check_transform(&record).unwrap_err().contains("entry (0, 3)"));
    }

    #[test]
    fn mirrored_normal_stays_on_the_front_side() {
        // A mirror in x: a front side facing +z still faces +z, one facing +x faces -x (the side the mirror
        // takes it to); the flattened file, which reverses a mirrored triangle's winding, says the same.
        let mirror = [[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let record = InstanceRecord::placing(0, mirror).unwrap();
        assert_eq!(world_normal(&record, [0.0, 0.0, 2.0]), [0.0, 0.0, 2.0]);
        assert_eq!(world_normal(&record, [2.0, 0.0, 0.0]), [-2.0, 0.0, 0.0]);
        // Non-uniform scale: the normal of the plane x = y scaled by (2, 1, 1) is the inverse transpose's.
        let stretch = [[2.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let record = InstanceRecord::placing(0, stretch).unwrap();
        assert_eq!(world_normal(&record, [1.0, -1.0, 0.0]), [1.0, -2.0, 0.0]);
    }
}
