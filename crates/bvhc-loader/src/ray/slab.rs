//! The robust slab test of one box axis (Ize 2013, "Robust BVH Ray Traversal"; `format-spec/bvh-1.md` 11.2),
//! which every box test builds on: the binary kernel's, the box condition's (`crate::ray::reach`), and in lanes
//! the wide and coherent kernels'.

/// Machine epsilon for f32 rounding, 2^-24.
const EPSILON: f32 = f32::EPSILON * 0.5;
/// Ize's padding of the slab exit distance, `1 + 2 gamma(3)`.
pub(crate) const EXIT_PADDING: f32 = 1.0 + 2.0 * (3.0 * EPSILON) / (1.0 - 3.0 * EPSILON);

/// One slab of the robust box test: the distances to the entry and exit planes of one axis (the exit through the
/// padded reciprocal `exit_inverse`) narrow the interval `near..far`. Compare-selects keep the accumulator when
/// the new value is NaN (an origin on a slab plane of a zero direction component), as `f32::max`/`min` would, in
/// one instruction each. The SIMD box tests perform exactly these operations in lanes.
#[inline(always)]
pub(crate) fn slab(
    entry_plane: f32,
    exit_plane: f32,
    origin: f32,
    (inverse, exit_inverse): (f32, f32),
    near: f32,
    far: f32,
) -> (f32, f32) {
    let t_entry = (entry_plane - origin) * inverse;
    let t_exit = (exit_plane - origin) * exit_inverse;
    (if t_entry > near { t_entry } else { near }, if t_exit < far { t_exit } else { far })
}
