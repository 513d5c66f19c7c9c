//! The watertight ray-triangle test of S. Woop, C. Benthin, I. Wald, "Watertight Ray/Triangle Intersection",
//! JCGT 2(1), 2013, written once for any number of lanes ([`Lanes`]): one triangle and one ray (`f32`, the
//! scalar test of `PreparedRay::intersect_triangle`), four triangles and one ray (a triangle packet),
//! or one triangle and eight rays (a coherent ray packet). Every caller runs these steps in this order, so every
//! lane width gives the scalar test's `t`, `u`, `v` bit for bit; lanes whose edge function is exactly 0 are
//! redone by the scalar test, whose f64 recomputation decides them, and so are lanes whose hit is
//! ill-conditioned ([`ill_conditioned`]), whose `t`, `u`, `v` are then exact ([`crate::ray::exact_hit`]).
//!
//! Symbols: the ray is sheared so that it runs along +z of a ray space whose z axis (`kz`) is the direction's
//! largest component; `sx, sy, sz` the shear; `U, V, W` the 2D edge functions, which are the barycentric
//! weights of v0, v1, v2 times the determinant `det = U + V + W`.

use crate::simd::{LaneMask, Lanes};

/// A triangle's vertices relative to the ray origin, in the ray's permuted axes `[kx, ky, kz]`, in lanes.
#[derive(Clone, Copy)]
pub(crate) struct RelativeTriangle<L> {
    /// `v0 - origin`.
    pub a: [L; 3],
    /// `v1 - origin`.
    pub b: [L; 3],
    /// `v2 - origin`.
    pub c: [L; 3],
}

/// The triangle's vertices sheared into the ray's 2D space: `[a, b, c]`, each `[x, y]`, with `x = k_x - sx k_z`
/// and `y = k_y - sy k_z`.
#[inline(always)]
pub(crate) fn sheared<L: Lanes>(r: &RelativeTriangle<L>, sx: L, sy: L) -> [[L; 2]; 3] {
    [
        [r.a[0].sub(sx.mul(r.a[2])), r.a[1].sub(sy.mul(r.a[2]))],
        [r.b[0].sub(sx.mul(r.b[2])), r.b[1].sub(sy.mul(r.b[2]))],
        [r.c[0].sub(sx.mul(r.c[2])), r.c[1].sub(sy.mul(r.c[2]))],
    ]
}

/// The edge functions `[U, V, W]` of the sheared triangle: `U = c_x b_y - c_y b_x`, `V = a_x c_y - a_y c_x`,
/// `W = b_x a_y - b_y a_x`.
#[inline(always)]
pub(crate) fn edge_functions<L: Lanes>([[ax, ay], [bx, by], [cx, cy]]: [[L; 2]; 3]) -> [L; 3] {
    [cx.mul(by).sub(cy.mul(bx)), ax.mul(cy).sub(ay.mul(cx)), bx.mul(ay).sub(by.mul(ax))]
}

/// The lanes where an edge function is exactly 0 (the scalar test redoes them in f64).
#[inline(always)]
pub(crate) fn has_zero_edge<L: Lanes>([u, v, w]: [L; 3], zero: L) -> L::Mask {
    u.eq(zero).or(v.eq(zero)).or(w.eq(zero))
}

/// A hit is **ill-conditioned** when `|det| < ILL_CONDITIONED * rho (rho + Z)`: its determinant is small against
/// the size of the sheared triangle (`rho`, the largest sheared coordinate's magnitude) and its depth spread along
/// the ray (`Z`): a needle or a sliver, or a ray nearly in the triangle's plane, whose f32 `t` could be far from
/// the exact one. `format-spec/bvh-1.md` 11.1 (step 5) derives the bound on `t` this gives the other hits.
pub(crate) const ILL_CONDITIONED: f32 = 1.0 / 64.0;

/// Below this `rho (rho + Z)` the edge functions' products come near the subnormal range, where f32 loses
/// relative precision: such hits are ill-conditioned too. `2^-100` (biased exponent 27, zero fraction).
pub(crate) const TINY_EXTENT: f32 = f32::from_bits(27 << 23);

/// What step 5 and the box condition ask of the lanes that hit: `(ill, exact_signs)`.
///
/// `ill`: the lanes whose hit is ill-conditioned (see [`ILL_CONDITIONED`]): `|det| < fraction * rho (rho + Z)`
/// or `rho (rho + Z) < tiny`, with `rho` the largest of the six sheared coordinates' magnitudes (taken in this
/// order with [`Lanes::max_or`]) and `Z = max(a_z, b_z, c_z) - min(a_z, b_z, c_z)` (11.1 step 5).
///
/// `exact_signs`: the lanes whose three edge functions are each farther from 0 than their rounding error can
/// reach, so that exact arithmetic on the same binary32 inputs gives each the same sign: `min(|U|, |V|, |W|) >
/// factor rho (rho + R)`, `R = max(|a_z|, |b_z|, |c_z|)`. An edge function's error is at most `2^-24 (|U| + 10
/// rho^2 + 16 rho R)` to first order (`docs/stability.md`, "Accuracy of `t`", steps 1-2), and with `factor =`
/// [`EXACT_SIGNS`] the threshold is over twice that. A well-conditioned hit of such a lane is a hit of the exact
/// ray inside the triangle, so it meets the box condition (`crate::ray::reach`) and the kernels need not test
/// it; other lanes (a ray within rounding of an edge) they test. Products that underflow break the first-order
/// bound, so this holds for well-conditioned hits only (their `rho (rho + R) >= rho (rho + Z) / 2 >= 2^-101`,
/// far above the underflow of a product).
///
/// Lanes that miss may come out either way; callers mask them.
#[inline(always)]
pub(crate) fn conditioning<L: Lanes>(
    e: [L; 3],
    [[ax, ay], [bx, by], [cx, cy]]: [[L; 2]; 3],
    r: &RelativeTriangle<L>,
    det: L,
    (fraction, tiny, factor): (L, L, L),
) -> (L::Mask, L::Mask) {
    let rho = ax.abs().max_or(ay.abs()).max_or(bx.abs()).max_or(by.abs()).max_or(cx.abs()).max_or(cy.abs());
    let (az, bz, cz) = (r.a[2], r.b[2], r.c[2]);
    let (high, low) = (az.max_or(bz).max_or(cz), az.min_or(bz).min_or(cz));
    let extent = rho.mul(rho.add(high.sub(low)));
    let ill = det.abs().lt(extent.mul(fraction)).or(extent.lt(tiny));
    let [u, v, w] = e;
    let smallest = u.abs().min_or(v.abs()).min_or(w.abs());
    let depth = high.abs().max_or(low.abs());
    (ill, smallest.gt(rho.mul(rho.add(depth)).mul(factor)))
}

/// `2^-18`: the factor of [`conditioning`]'s exact-sign threshold.
pub(crate) const EXACT_SIGNS: f32 = 1.0 / 262_144.0;

/// The lanes where the edge functions have mixed signs: the ray passes outside the triangle. Some edge function
/// is below 0 exactly when their minimum is, and some above 0 exactly when their maximum is (zeros of either sign
/// are neither); a lane with a NaN edge function may come out either way, and is dropped by its NaN determinant.
#[inline(always)]
pub(crate) fn outside<L: Lanes>([u, v, w]: [L; 3], zero: L) -> L::Mask {
    u.min_or(v).min_or(w).lt(zero).and(u.max_or(v).max_or(w).gt(zero))
}

/// `det = (U + V) + W`.
#[inline(always)]
pub(crate) fn determinant<L: Lanes>([u, v, w]: [L; 3]) -> L {
    u.add(v).add(w)
}

/// The hit distance `t = (U (sz a_z) + V (sz b_z) + W (sz c_z)) / det`.
#[inline(always)]
pub(crate) fn distance<L: Lanes>([u, v, w]: [L; 3], r: &RelativeTriangle<L>, sz: L, det: L) -> L {
    let (az, bz, cz) = (sz.mul(r.a[2]), sz.mul(r.b[2]), sz.mul(r.c[2]));
    u.mul(az).add(v.mul(bz)).add(w.mul(cz)).div(det)
}

/// The lanes that hit within `[t_min, t_max]`: inside, a non-zero determinant, `t` in range.
#[inline(always)]
pub(crate) fn hits<L: Lanes>(outside: L::Mask, det: L, t: L, zero: L, t_min: L, t_max: L) -> L::Mask {
    t.ge(t_min).and(t.le(t_max)).and_not(outside.or(det.eq(zero)))
}

/// The barycentric weights `(u, v)` of v1 and v2: `V / det` and `W / det`, through one reciprocal.
#[inline(always)]
pub(crate) fn barycentrics<L: Lanes>([_, v, w]: [L; 3], det: L, one: L) -> (L, L) {
    let inverse_det = one.div(det);
    (v.mul(inverse_det), w.mul(inverse_det))
}

/// [`edge_functions`] recomputed in f64 and rounded back to f32 (each product exact, one rounding), for a ray
/// through an edge or vertex of the triangle: the sign then decides which of the triangles sharing it is hit,
/// so at least one is.
#[inline(always)]
pub(crate) fn edge_functions_f64([[ax, ay], [bx, by], [cx, cy]]: [[f32; 2]; 3]) -> [f32; 3] {
    let edge =
        |px: f32, py: f32, qx: f32, qy: f32| (f64::from(px) * f64::from(qy) - f64::from(py) * f64::from(qx)) as f32;
    [edge(cx, cy, bx, by), edge(ax, ay, cx, cy), edge(bx, by, ax, ay)]
}

/// The GPU kernel's replacement for [`edge_functions_f64`] (`format-spec/bvh-1.md` 11.4): each edge function
/// that is exactly 0 in `e` (its two rounded products are equal) becomes the exact difference of its products
/// rounded to f32 ([`exact_product_difference`]), which is what 11.1's f64 recomputation gives that edge; the
/// others keep their f32 values, whose signs are already exact (rounding is monotone, so two distinct rounded
/// products are ordered as the exact ones). So every edge function has its exact sign, as in 11.1.
#[inline]
pub(crate) fn zero_edges_exact([[ax, ay], [bx, by], [cx, cy]]: [[f32; 2]; 3], mut e: [f32; 3]) -> [f32; 3] {
    let operands = [(cx, by, cy, bx), (ax, cy, ay, cx), (bx, ay, by, ax)];
    for (value, (a, b, c, d)) in e.iter_mut().zip(operands) {
        if *value == 0.0 {
            *value = exact_product_difference(a, b, c, d);
        }
    }
    e
}

/// `a b - c d` rounded once to f32, for products whose f32 roundings are equal and normal (their exact
/// difference then spans at most 27 bits, so the binary64 difference below is exact): 0 when they are equal,
/// `+-2^-126` with the exact sign where the difference is below the normal range (a GPU would flush a subnormal to
/// zero and lose the sign). Products that round to zero, a subnormal or an infinity are left to the f32
/// difference. The WGSL kernel computes the same value with integer arithmetic (`exact_product_difference` in
/// `gpu.wgsl`), since WGSL has no f64.
pub(crate) fn exact_product_difference(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let (p, q) = (a * b, c * d);
    if p != q || !p.is_normal() {
        return p - q;
    }
    let x = f64::from(a) * f64::from(b) - f64::from(c) * f64::from(d);
    if x == 0.0 {
        0.0
    } else if x.abs() < f64::from(f32::MIN_POSITIVE) {
        f32::MIN_POSITIVE.copysign(x as f32)
    } else {
        x as f32
    }
}
