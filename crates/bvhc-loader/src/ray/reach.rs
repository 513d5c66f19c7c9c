//! Which of the triangle test's hits count, and how far beyond the closest hit so far a walk must still look
//! (`format-spec/bvh-1.md` 11.1, "The box condition", and 11.2, "The reach"; revision 1.5.8).
//!
//! **The box condition.** 11.1's binary32 test can accept a record that the exact ray passes by (within
//! rounding of an edge), and the `t` it reports for a hit can lie below the exact one by up to its accuracy
//! bound, `(64 psi + 12) 2^-24 (|t*| + depth)`: a bound that grows with the record's depth along the ray, so a
//! large triangle met near the ray's origin can report a `t` before the ray even enters its box. A record
//! therefore counts as a hit only where the ray meets its bounding box within the hit's **window**
//! `[max(t_min, t - w), t + w]`, `w = 2^-12 (t + Z |sz|)` (`Z` the spread of the record's coordinates along the
//! ray's major axis, `sz` the shear's `1 / d_kz`). Every hit of the exact ray at a `t*` from `t_min` on passes
//! (its exact point lies in the box and within the bound of `t`, which `w` exceeds); a hit that passes depends
//! on the ray and the record alone, not on the tree or the order of a walk.
//!
//! **The reach.** A walk culls a box that the ray enters beyond `reach(t) = t (1 + 2^-11) + 2^-11 D` of its
//! closest hit so far `t` (or of `t_max` before it has one), where `D` bounds the `Z |sz|` of every record
//! below its root: the root box's largest side over `|d|_inf` (in a top tree, times the largest
//! `||W||_inf ||L||_inf` of its instances, which bounds how much an instance stretches a record's extent). A hit's window then lies within the reach of every hit it precedes, and every box on the path to its
//! record contains the record's box, so no box holding a hit that precedes the closest one is ever culled,
//! whatever order a walk takes: the closest hit is the minimum of the definition over all records, on every
//! kernel (11.2 has the proof).

use crate::format::{PackedNode, PackedTriangle};
use crate::ray::slab::slab;
use crate::simd::Lanes;

/// The window's half-width relative to `t + Z |sz|`: `2^-12`, above the accuracy bound's `(48 * 64 + 11) 2^-24`
/// for a well-conditioned hit and `2^-24` for an ill-conditioned one, with room for the window's and the box
/// test's own roundings.
pub(crate) const WINDOW: f32 = 1.0 / 4096.0;

/// The reach's margin relative to `t + D`: `2^-11`, twice the window's, so that the reach of a hit covers the
/// window of any record whose `Z |sz|` is at most `D` after every rounding of both.
pub(crate) const REACH: f32 = 1.0 / 2048.0;

/// `1 + REACH`.
const REACH_SCALE: f32 = 1.0 + REACH;

/// The window `[max(t_min, t - w), t + w]` of a hit at `t` on a record whose vertices' coordinates along the
/// ray's major axis are `z` (binary32, as stored) for a ray from `t_min` with shear `sz` (11.1, "The box
/// condition"): `w = 2^-12 (t + (max z - min z) |sz|)`. For a hit at `t = +inf` (an overflowing test with
/// `t_max = +inf`) the window is the whole ray.
#[inline]
pub(crate) fn window(t: f32, z: [f32; 3], sz: f32, t_min: f32) -> (f32, f32) {
    let spread = max3(z) - min3(z);
    let half = (t + spread * sz.abs()) * WINDOW;
    let low = t - half;
    (if low > t_min { low } else { t_min }, t + half)
}

/// The largest of three values, in this order (`a.max(b).max(c)` with IEEE comparisons; the values of a hit are
/// finite).
#[inline(always)]
fn max3([a, b, c]: [f32; 3]) -> f32 {
    let m = if b > a { b } else { a };
    if c > m { c } else { m }
}

/// The smallest of three values, in this order.
#[inline(always)]
fn min3([a, b, c]: [f32; 3]) -> f32 {
    let m = if b < a { b } else { a };
    if c < m { c } else { m }
}

/// What the box test of a ray needs of it: origin, reciprocal direction, its padded twin for exit distances,
/// and per axis whether the direction's sign bit is set (as 11.2's box test reads them).
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoxRay {
    pub origin: [f32; 3],
    pub inverse: [f32; 3],
    pub exit_inverse: [f32; 3],
    pub negative: [bool; 3],
}

impl BoxRay {
    /// Whether the ray meets the box `min..max` within `[near, far]`: 11.2's robust slab test, the operations of
    /// [`PreparedRay::enter_box`] in its order.
    #[inline]
    pub(crate) fn meets(&self, (min, max): ([f32; 3], [f32; 3]), mut near: f32, mut far: f32) -> bool {
        for axis in 0..3 {
            let (entry, exit) = if self.negative[axis] { (max[axis], min[axis]) } else { (min[axis], max[axis]) };
            let inverses = (self.inverse[axis], self.exit_inverse[axis]);
            (near, far) = slab(entry, exit, self.origin[axis], inverses, near, far);
        }
        near <= far
    }

    /// The box condition of a hit at `t` on `triangle` for a ray from `t_min` whose shear has major axis `kz`
    /// and `sz = 1 / d_kz`: whether the ray meets the record's bounding box within the hit's [`window`].
    #[inline(never)]
    pub(crate) fn meets_record_box(
        &self,
        triangle: &PackedTriangle,
        t: f32,
        (t_min, kz, sz): (f32, usize, f32),
    ) -> bool {
        let [v0, v1, v2] = &triangle.vertices;
        let (near, far) = window(t, [v0[kz], v1[kz], v2[kz]], sz, t_min);
        let min = std::array::from_fn(|a| min3([v0[a], v1[a], v2[a]]));
        let max = std::array::from_fn(|a| max3([v0[a], v1[a], v2[a]]));
        self.meets((min, max), near, far)
    }
}

/// What a tree contributes to its walks' reach: `2^-11` times the largest side of its root box `root` times
/// `scale` (1 in a mesh; in a top tree, how much an instance stretches a record's extent along a ray relative to
/// the world's). A ray's `2^-11 D` is this times its `|sz|`. Every record's vertices lie in the root box (V17,
/// V19; with split references, the boxes that cover it do, V25), so its spread along any axis is at most that
/// side. NaN for a root that is not finite (a hostile file): its walks then cull nothing, bounded by their node
/// counts.
#[inline]
pub(crate) fn tree_scale(root: &PackedNode, scale: f32) -> f32 {
    let side = |a: usize| root.max[a] - root.min[a];
    let largest = side(0).max(side(1)).max(side(2));
    // A NaN side stays NaN (f32::max would drop it).
    let largest = if (0..3).any(|a| side(a).is_nan()) { f32::NAN } else { largest };
    largest * scale * REACH
}

/// The reach of `t` for a ray whose `2^-11 D` is `offset`: `t (1 + 2^-11) + 2^-11 D` (`+inf` for `t = +inf`;
/// NaN for a tree whose root is not finite, which culls nothing).
#[inline(always)]
pub(crate) fn cull(t: f32, offset: f32) -> f32 {
    t * REACH_SCALE + offset
}

/// [`cull`] in lanes: each lane the same two IEEE operations, so the same bits.
#[inline(always)]
pub(crate) fn cull_lanes<L: Lanes>(t: L, offset: L, reach_scale: L) -> L {
    t.mul(reach_scale).add(offset)
}

/// [`cull`]'s factor `1 + 2^-11`, for [`cull_lanes`].
pub(crate) const CULL_FACTOR: f32 = REACH_SCALE;

/// `2^-11 D = tree |sz|` for the rays of `L`'s lanes (one ray, or a coherent packet's eight) from their
/// reciprocal directions by axis, over a tree of [`tree_scale`] `tree`.
#[inline(always)]
pub(crate) fn offset<L: Lanes>(inverse: [L; 3], tree: L) -> L {
    inverse[0].abs().min_or(inverse[1].abs()).min_or(inverse[2].abs()).mul(tree)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::PortableLanes;

    #[test]
    fn the_window_grows_with_depth_and_covers_the_whole_line_at_infinity() {
        let (low, high) = window(1.0, [0.0, 10.0, 4.0], 1.0, 0.0);
        assert_eq!((low, high), (1.0 - 11.0 / 4096.0, 1.0 + 11.0 / 4096.0));
        assert_eq!(window(f32::INFINITY, [0.0, 1.0, 2.0], 1.0, 0.5), (0.5, f32::INFINITY));
        let (low, high) = window(2.0, [-3.0, -1.0, -2.0], -0.5, 0.0);
        assert_eq!((low, high), (2.0 - 3.0 / 4096.0, 2.0 + 3.0 / 4096.0));
        // The window starts no earlier than the ray.
        assert_eq!(window(1e-4, [0.0, 10.0, 4.0], 1.0, 1e-5).0, 1e-5);
    }

    #[test]
    fn the_reach_bounds_every_records_depth_and_the_lanes_agree() {
        let root = PackedNode { min: [-1.0, -2.0, -3.0], max: [1.0, 2.0, 3.0], index: 0, count: 0 };
        let tree = tree_scale(&root, 1.0);
        assert_eq!(tree, 6.0 * REACH);
        // D = 6 * 0.25: a record spread over the root's longest side, along a ray of |d|_inf = 4.
        assert_eq!(cull(1.0, 1.5 * REACH), 1.0 * (1.0 + REACH) + 1.5 * REACH);
        assert!(cull(1.0, 1.5 * REACH) > 1.0 + (1.0 + 1.5) * WINDOW);
        assert_eq!(cull(f32::INFINITY, 1.5 * REACH), f32::INFINITY);
        let splat = |x: f32| PortableLanes([x; 8]);
        assert_eq!(offset([splat(1.0), splat(0.5), splat(-0.25)], splat(tree)).to_array(), [1.5 * REACH; 8]);
        let hostile = PackedNode { min: [f32::NAN, 0.0, 0.0], ..root };
        assert!(tree_scale(&hostile, 1.0).is_nan());
    }
}
