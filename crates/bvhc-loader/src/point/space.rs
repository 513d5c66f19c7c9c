//! The space a point walk measures boxes in: world space for a one-level file and the top tree, an instance's
//! object space inside its mesh. A box's squared distance from the mapped point, scaled by the square of the
//! smallest stretch of the instance's map, is a lower bound on the world-space squared distance of anything in it.

use crate::format::{InstanceRecord, PackedNode};
use crate::point::Point3;

/// How far below the f64 bound a box's lower bound is taken, against the rounding of the mapped point.
const BOUND_SHRINK: f64 = 1.0 - 1.0 / 1_048_576.0;

/// The query point in a tree's space, and the scale of that space's squared distances in world space.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Space {
    pub point: Point3,
    scale2: f64,
    /// The point rounded to f32, for the wide walk's box tests in lanes ([`Space::lane_threshold`]).
    pub point32: [f32; 3],
    /// A bound on how far `point32` lies from `point` (0 when the point is an f32 already).
    offset: f64,
}

impl Space {
    /// World space.
    pub(crate) fn world(point: Point3) -> Space {
        Space::at(point, 1.0)
    }

    /// The space of `point` with squared stretch `scale2`.
    fn at(point: Point3, scale2: f64) -> Space {
        let point32 = point.map(|c| c as f32);
        // Each coordinate rounds by at most 2^-24 of itself, so the point moves by less than 2^-23 of its largest.
        let largest = point.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        let exact = point32.iter().zip(&point).all(|(&r, &c)| f64::from(r) == c);
        Space { point, scale2, point32, offset: if exact { 0.0 } else { largest / 8_388_608.0 } }
    }

    /// The object space of `instance`, for the world point `point`: `L^-1 (p - t)` in f64 for the linear part
    /// `L` and translation `t` of `object_to_world` (its inverse by cofactors, not the stored `world_to_object`,
    /// which rule V42 lets be looser), and a squared stretch bound `<= sigma_min(L)^2`: the larger of the
    /// Gershgorin bound on the smallest eigenvalue of `L^T L` and `1 / |L^-1|_F^2`. `None` for a singular or
    /// non-finite map (which a verified file does not have).
    pub(crate) fn instance(instance: &InstanceRecord, point: Point3) -> Option<Space> {
        let m = &instance.object_to_world;
        let a = |i: usize, j: usize| f64::from(m[i][j]);
        let cofactor = |i: usize, j: usize| {
            let (r0, r1, c0, c1) = ((i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3);
            a(r0, c0) * a(r1, c1) - a(r0, c1) * a(r1, c0)
        };
        let det = a(0, 0) * cofactor(0, 0) + a(0, 1) * cofactor(0, 1) + a(0, 2) * cofactor(0, 2);
        let cofactors: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| cofactor(i, j)));
        let frobenius2: f64 = cofactors.iter().flatten().map(|c| c * c).sum();
        if !(det.is_finite() && det != 0.0 && frobenius2.is_finite()) {
            return None;
        }
        let relative: Point3 = std::array::from_fn(|k| point[k] - a(k, 3));
        // (L^-1)_ij = cofactor(j, i) / det.
        let mapped = std::array::from_fn(|i| (0..3).map(|j| cofactors[j][i] * relative[j]).sum::<f64>() / det);
        // sigma_min(L)^2 is the smallest eigenvalue of L^T L, at least its Gershgorin bound (exact for a rotation
        // times a scale, where 1 / |L^-1|_F^2 is a third of it) and at least 1 / |L^-1|_F^2 (the better of the two).
        // The Gram entries are sums of exact products, so the bound is off by far less than its 2^-40 allowance.
        let gram = |i: usize, j: usize| (0..3).map(|k| a(k, i) * a(k, j)).sum::<f64>();
        let allowance = (0..3).map(|i| gram(i, i)).fold(0.0, f64::max) / 1_099_511_627_776.0;
        let gershgorin = (0..3)
            .map(|i| gram(i, i) - (0..3).filter(|&j| j != i).map(|j| gram(i, j).abs()).sum::<f64>())
            .fold(f64::INFINITY, f64::min);
        let stretch2 = (gershgorin - allowance).max(det * det / frobenius2);
        Some(Space::at(mapped, stretch2 * BOUND_SHRINK))
    }

    /// The threshold of the wide walk's lanes for the cull `cull_d2` (world space): a slot whose squared
    /// distance from `point32`, computed in f32 ([`lane_d2`]), exceeds it lies beyond the cull. f32 rounding makes
    /// a lane's value at most `2^-21` of itself too large; the threshold allows `2^-19`, the move from `point` to
    /// `point32` and this space's stretch, and is `+inf` (no slot culled) where it does not fit f32.
    pub(crate) fn lane_threshold(&self, cull_d2: f64) -> f32 {
        let reach = (cull_d2 / self.scale2).sqrt() + self.offset;
        let threshold = reach * reach * (1.0 + 1.0 / 524_288.0);
        if threshold.is_nan() || threshold >= f64::from(f32::MAX) {
            return f32::INFINITY;
        }
        let rounded = threshold as f32;
        if f64::from(rounded) < threshold { rounded.next_up() } else { rounded }
    }

    /// A lower bound on the world-space squared distance from the query point to anything inside `node`'s box
    /// (0 when the box is malformed, so such a box is never culled).
    #[inline(always)]
    pub(crate) fn box_d2(&self, node: &PackedNode) -> f64 {
        let mut d2 = 0.0;
        for a in 0..3 {
            let below = f64::from(node.min[a]) - self.point[a];
            let above = self.point[a] - f64::from(node.max[a]);
            // `max` returns the other operand for a NaN, so a NaN bound counts as no distance.
            let gap = below.max(above).max(0.0);
            d2 += gap * gap;
        }
        if self.scale2 == 1.0 { d2 } else { d2 * self.scale2 }
    }
}

/// The squared distances, in f32, from `point` to the eight slot boxes of `node`: a slot's gap on each axis is
/// `max(min - p, p - max, 0)`, so an empty slot (min `+inf`, max `-inf`) is at `+inf`.
#[inline(always)]
pub(crate) fn lane_d2(node: &crate::format::WideNode8, point: [f32; 3]) -> [f32; crate::format::WIDE] {
    let mut d2 = [0.0f32; crate::format::WIDE];
    for ((min, max), &p) in node.min.iter().zip(&node.max).zip(&point) {
        for (slot, d) in d2.iter_mut().enumerate() {
            let below = min[slot] - p;
            let above = p - max[slot];
            let gap = if below > above { below } else { above };
            let gap = if gap > 0.0 { gap } else { 0.0 };
            *d += gap * gap;
        }
    }
    d2
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `|L u|^2` over many unit directions `u`: at least the true `sigma_min(L)^2`, so never below a valid bound.
    fn sampled_min_stretch2(m: &crate::format::Affine3x4) -> f64 {
        let mut smallest = f64::INFINITY;
        for i in 0..64 {
            for j in 0..128 {
                let (theta, phi) =
                    (std::f64::consts::PI * (i as f64 + 0.5) / 64.0, std::f64::consts::TAU * j as f64 / 128.0);
                let u = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
                let lu: f64 = (0..3).map(|r| (0..3).map(|c| f64::from(m[r][c]) * u[c]).sum::<f64>().powi(2)).sum();
                smallest = smallest.min(lu);
            }
        }
        smallest
    }

    #[test]
    fn the_stretch_bound_is_below_the_smallest_stretch_and_tight_for_a_scaled_rotation() {
        let (c, s) = (0.6f32, 0.8f32);
        let maps: [crate::format::Affine3x4; 4] = [
            [[2.0 * c, -2.0 * s, 0.0, 1.0], [2.0 * s, 2.0 * c, 0.0, -3.0], [0.0, 0.0, 2.0, 0.5]], // rotation, scale 2
            [[1.0, 0.7, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 2.0, 0.0]],                   // shear
            [[-0.2, 0.0, 0.0, 5.0], [0.0, 3.0, 0.0, 0.0], [0.0, 0.0, 0.01, 0.0]],                 // mirror, uneven
            [[0.3, 0.9, 0.1, 0.0], [-0.8, 0.2, 0.4, 0.0], [0.2, -0.3, 0.9, 0.0]],                 // general
        ];
        for (k, m) in maps.iter().enumerate() {
            let instance = InstanceRecord::placing(0, *m).unwrap();
            let space = Space::instance(&instance, [0.3, -0.2, 0.7]).unwrap();
            let sampled = sampled_min_stretch2(m);
            assert!(space.scale2 <= sampled, "map {k}: bound {} above a sampled stretch {sampled}", space.scale2);
            if k == 0 {
                assert!(
                    space.scale2 > 4.0 * 0.999_99,
                    "a scaled rotation's bound is its scale squared: {}",
                    space.scale2
                );
            }
        }
    }
}
