//! `t`, `u`, `v` of an ill-conditioned hit, exactly (`format-spec/bvh-1.md` 11.1, step 6).
//!
//! The f32 test of Woop, Benthin and Wald decides hit or miss watertightly, but its `t` is `T / det` with both
//! rounded: for a needle or a sliver, or a ray nearly in the triangle's plane, `det` is small against the
//! products it is the difference of, and `t` can be off by much of the triangle's depth along the ray. So
//! when step 5's test calls a hit ill-conditioned, `t`, `u`, `v` are instead the exact values, rounded to the
//! nearest f32, of
//!
//! ```text
//! w0 = d . ((v2 - o) x (v1 - o)),  w1 = d . ((v0 - o) x (v2 - o)),  w2 = d . ((v1 - o) x (v0 - o))
//! (each weight with the sign of S = w0 + w1 + w2 kept, the others set to 0; S = 0: no exact values)
//! t = (w0 (v0 - o)_kz + w1 (v1 - o)_kz + w2 (v2 - o)_kz) / (d_kz (w0 + w1 + w2)),  u = w1 / (w0 + w1 + w2),
//! v = w2 / (w0 + w1 + w2)
//! ```
//!
//! The weights are the edge functions `U, V, W` of the sheared test times `|d_kz|`, computed without rounding;
//! for a ray that meets the triangle they are the barycentric weights of the hit point on its plane, and a weight
//! of the wrong sign (the ray passes within rounding of an edge, where the f32 test said hit) is dropped, so the
//! point is the nearest edge point and `t` stays within the triangle's depth range.
//!
//! Evaluation is adaptive, as in J. R. Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast Robust
//! Geometric Predicates" (Discrete Comput. Geom. 18, 1997): first in f64 with a rigorous error bound on every
//! value, which settles the signs and the f32 rounding of `t`, `u`, `v` unless a value lies within its bound
//! of zero or of a rounding boundary; then, for those rare cases, in fixed-width integers ([`crate::ray::exact_int`]),
//! which is exact for every finite input. Both give the same bits: the correctly rounded exact values.

use std::cmp::Ordering;

use crate::ray::exact_int::Int;
use crate::ray::hit::TriangleHit;

/// f64 unit roundoff, `2^-53`.
const UNIT: f64 = 1.0 / 9_007_199_254_740_992.0;
/// Widens a computed error bound over the rounding of its own computation and second-order terms.
const WIDEN: f64 = 1.0 + 1.0 / 1_099_511_627_776.0; // 1 + 2^-40

/// The exact `t`, `u`, `v` (each rounded to the nearest f32, ties to even) of the ray from `origin` along
/// `direction` (major axis `kz`) and the triangle `vertices`, or `None` when the weights sum to zero (a triangle
/// with no area as seen along the ray: the f32 test's values stand).
pub(crate) fn exact_hit(
    origin: &[f32; 3],
    direction: &[f32; 3],
    kz: usize,
    vertices: &[[f32; 3]; 3],
) -> Option<TriangleHit> {
    match estimate(origin, direction, kz, vertices) {
        Estimate::Certain(hit) => hit,
        Estimate::Uncertain => exact(origin, direction, kz, vertices),
    }
}

enum Estimate {
    /// The f64 evaluation settled every sign and rounding.
    Certain(Option<TriangleHit>),
    /// Some value lies within its error bound of zero or of an f32 rounding boundary.
    Uncertain,
}

/// `d . (p x q)` and its permanent (the same sum with every product's magnitude), in f64.
#[inline(always)]
fn triple(d: [f64; 3], p: [f64; 3], q: [f64; 3]) -> (f64, f64) {
    let (x1, x2) = (p[1] * q[2], p[2] * q[1]);
    let (y1, y2) = (p[2] * q[0], p[0] * q[2]);
    let (z1, z2) = (p[0] * q[1], p[1] * q[0]);
    let value = d[0] * (x1 - x2) + d[1] * (y1 - y2) + d[2] * (z1 - z2);
    let permanent =
        d[0].abs() * (x1.abs() + x2.abs()) + d[1].abs() * (y1.abs() + y2.abs()) + d[2].abs() * (z1.abs() + z2.abs());
    (value, permanent)
}

/// A weight kept (its sign is the sum's) or dropped (set to 0, exactly), with its error bound; `None` when its
/// sign is uncertain.
#[inline(always)]
fn kept(weight: f64, error: f64, sum: f64) -> Option<(f64, f64)> {
    let sign_certain = weight.abs() > error; // false for NaN too
    if !sign_certain {
        return None;
    }
    Some(if (weight > 0.0) == (sum > 0.0) { (weight, error) } else { (0.0, 0.0) })
}

/// The f32 nearest to every value within `error` of `value`, if they all round alike (an exact `value`, with
/// `error` 0, rounds to itself: +0 for zero).
#[inline(always)]
fn certain_f32(value: f64, error: f64) -> Option<f32> {
    if error == 0.0 {
        return value.is_finite().then_some(if value == 0.0 { 0.0 } else { value as f32 });
    }
    // Widened so that the two roundings of `value -+ error` below cannot narrow the interval.
    let error = error * WIDEN + 2.0 * UNIT * value.abs();
    let (low, high) = ((value - error) as f32, (value + error) as f32);
    (low.to_bits() == high.to_bits() && value.is_finite() && error.is_finite()).then_some(low)
}

/// The f64 evaluation with error bounds. Error analysis (first order in `u = 2^-53`; [`WIDEN`] covers the
/// second-order terms and the rounding of the bounds' own arithmetic): the relative vertices carry one rounding
/// each; a weight is within `8 u` of its permanent ([`triple`]: seven roundings); the sums of same-signed kept
/// weights add `2 u` of their magnitudes; the numerator adds `4 u` of its terms' magnitudes (the depth's
/// rounding, the product's and two sums'); a quotient's error is `(e_x + |q| e_y) / (|y| - e_y) + u |q|`.
fn estimate(origin: &[f32; 3], direction: &[f32; 3], kz: usize, vertices: &[[f32; 3]; 3]) -> Estimate {
    let o = [f64::from(origin[0]), f64::from(origin[1]), f64::from(origin[2])];
    let relative = |v: &[f32; 3]| [f64::from(v[0]) - o[0], f64::from(v[1]) - o[1], f64::from(v[2]) - o[2]];
    let (a, b, c) = (relative(&vertices[0]), relative(&vertices[1]), relative(&vertices[2]));
    let d = [f64::from(direction[0]), f64::from(direction[1]), f64::from(direction[2])];
    let ((w0, p0), (w1, p1), (w2, p2)) = (triple(d, c, b), triple(d, a, c), triple(d, b, a));
    let (e0, e1, e2) = (8.0 * UNIT * p0, 8.0 * UNIT * p1, 8.0 * UNIT * p2);
    let sum = (w0 + w1) + w2;
    let sum_error = (e0 + e1 + e2 + 2.0 * UNIT * (w0.abs() + w1.abs() + w2.abs())) * WIDEN;
    let sign_certain = sum.abs() > sum_error; // false for NaN too
    if !sign_certain {
        return Estimate::Uncertain;
    }
    let (Some((k0, f0)), Some((k1, f1)), Some((k2, f2))) = (kept(w0, e0, sum), kept(w1, e1, sum), kept(w2, e2, sum))
    else {
        return Estimate::Uncertain;
    };
    let total = (k0 + k1) + k2;
    let total_error = (f0 + f1 + f2 + 2.0 * UNIT * total.abs()) * WIDEN;
    let (za, zb, zc) = (a[kz], b[kz], c[kz]);
    let numerator = (k0 * za + k1 * zb) + k2 * zc;
    let numerator_error = (f0 * za.abs()
        + f1 * zb.abs()
        + f2 * zc.abs()
        + 4.0 * UNIT * ((k0 * za).abs() + (k1 * zb).abs() + (k2 * zc).abs()))
        * WIDEN;
    let denominator = d[kz] * total;
    let denominator_error = (d[kz].abs() * total_error + UNIT * denominator.abs()) * WIDEN;
    let (denominator_margin, total_margin) =
        ((denominator.abs() - denominator_error) / WIDEN, (total.abs() - total_error) / WIDEN);
    if !(denominator_margin > 0.0 && total_margin > 0.0) {
        return Estimate::Uncertain;
    }
    let (t, u, v) = (numerator / denominator, k1 / total, k2 / total);
    let quotient_error = |x_error: f64, q: f64, y_error: f64, margin: f64| {
        ((x_error + q.abs() * y_error) / margin + UNIT * q.abs()) * WIDEN
    };
    let t = certain_f32(t, quotient_error(numerator_error, t, denominator_error, denominator_margin));
    let u = certain_f32(u, quotient_error(f1, u, total_error, total_margin));
    let v = certain_f32(v, quotient_error(f2, v, total_error, total_margin));
    match (t, u, v) {
        (Some(t), Some(u), Some(v)) => Estimate::Certain(Some(TriangleHit { t, u, v })),
        _ => Estimate::Uncertain,
    }
}

/// The evaluation in exact integer arithmetic (every value scaled by a power of two, see [`Int::from_f32`]).
fn exact(origin: &[f32; 3], direction: &[f32; 3], kz: usize, vertices: &[[f32; 3]; 3]) -> Option<TriangleHit> {
    let o = origin.map(Int::from_f32);
    let relative = |v: &[f32; 3]| -> [Int; 3] { std::array::from_fn(|a| Int::from_f32(v[a]).sub(&o[a])) };
    let [a, b, c] = [relative(&vertices[0]), relative(&vertices[1]), relative(&vertices[2])];
    let d = direction.map(Int::from_f32);
    let triple = |p: &[Int; 3], q: &[Int; 3]| {
        let cross = [
            p[1].mul(&q[2]).sub(&p[2].mul(&q[1])),
            p[2].mul(&q[0]).sub(&p[0].mul(&q[2])),
            p[0].mul(&q[1]).sub(&p[1].mul(&q[0])),
        ];
        d[0].mul(&cross[0]).add(&d[1].mul(&cross[1])).add(&d[2].mul(&cross[2]))
    };
    let weights = [triple(&c, &b), triple(&a, &c), triple(&b, &a)];
    let sum_sign = weights[0].add(&weights[1]).add(&weights[2]).signum();
    if sum_sign == 0 {
        return None;
    }
    let kept = weights.map(|w| if w.signum() == sum_sign { w } else { Int::ZERO });
    let total = kept[0].add(&kept[1]).add(&kept[2]);
    let numerator = kept[0].mul(&a[kz]).add(&kept[1].mul(&b[kz])).add(&kept[2].mul(&c[kz]));
    let denominator = d[kz].mul(&total);
    Some(TriangleHit {
        t: rounded_quotient(&numerator, &denominator),
        u: rounded_quotient(&kept[1], &total),
        v: rounded_quotient(&kept[2], &total),
    })
}

/// `x / y` rounded to the nearest f32, ties to even, for `y != 0`.
pub(crate) fn rounded_quotient(x: &Int, y: &Int) -> f32 {
    if x.is_zero() {
        return 0.0;
    }
    let negative = x.is_negative() != y.is_negative();
    let (x, y) = (if x.is_negative() { x.neg() } else { *x }, if y.is_negative() { y.neg() } else { *y });
    let ((mx, ex), (my, ey)) = (x.approx(), y.approx());
    // Within a few f64 ulps of x / y (exponents beyond the f32 range saturate, which the loop corrects).
    let mut f = ((mx / my) * 2f64.powi((ex - ey).clamp(-400, 400))) as f32;
    for _ in 0..8 {
        let below = compare_quotient(&x, &y, lower_midpoint(f));
        let above = upper_midpoint(f).map_or(Ordering::Less, |m| compare_quotient(&x, &y, m));
        let odd = f.to_bits() & 1 == 1;
        if below == Ordering::Less || (below == Ordering::Equal && odd) {
            f = f.next_down();
        } else if above == Ordering::Greater || (above == Ordering::Equal && odd) {
            f = f.next_up();
        } else {
            break;
        }
    }
    if negative { -f } else { f }
}

/// The point halfway between `f >= 0` and the next f32 below it (`-2^-150` for zero).
fn lower_midpoint(f: f32) -> f64 {
    if f == f32::INFINITY {
        return f64::from(f32::MAX) + 2f64.powi(103);
    }
    (f64::from(f) + f64::from(f.next_down())) / 2.0
}

/// The point halfway between `f >= 0` and the next f32 above it; above `f32::MAX`, the threshold from which a
/// value rounds to infinity; none above infinity.
fn upper_midpoint(f: f32) -> Option<f64> {
    if f == f32::INFINITY {
        None
    } else if f == f32::MAX {
        Some(f64::from(f32::MAX) + 2f64.powi(103))
    } else {
        Some((f64::from(f) + f64::from(f.next_up())) / 2.0)
    }
}

/// The order of `x / y` (both positive) and `m` (a dyadic f64 with at most 26 significant bits).
fn compare_quotient(x: &Int, y: &Int, m: f64) -> Ordering {
    if m <= 0.0 {
        return Ordering::Greater;
    }
    let bits = m.to_bits();
    let field = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1 << 52) - 1);
    // m = significand * 2^exponent, with the significand's trailing zeros dropped (at most 26 bits remain).
    let (significand, exponent) = if field == 0 { (fraction, -1074) } else { (fraction | 1 << 52, field - 1075) };
    let zeros = significand.trailing_zeros();
    let (significand, exponent) = (significand >> zeros, exponent + zeros as i32);
    let scaled = Int::from_scaled(significand, 0, false).mul(y);
    let difference =
        if exponent >= 0 { x.sub(&scaled.shl(exponent as u32)) } else { x.shl(exponent.unsigned_abs()).sub(&scaled) };
    difference.signum().cmp(&0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift64*) for the tests' inputs.
    struct Numbers(u64);

    impl Numbers {
        fn unit(&mut self) -> f32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        }

        fn vector(&mut self, scale: f32) -> [f32; 3] {
            [self.unit() * scale, self.unit() * scale, self.unit() * scale]
        }
    }

    fn major_axis(d: &[f32; 3]) -> usize {
        let a = d.map(f32::abs);
        if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        }
    }

    #[test]
    fn quotients_round_to_nearest_even() {
        let int = |v: u64| Int::from_scaled(v, 0, false);
        assert_eq!(rounded_quotient(&int(1), &int(3)), 1.0f32 / 3.0);
        assert_eq!(rounded_quotient(&int(2), &int(3)), 2.0f32 / 3.0);
        assert_eq!(rounded_quotient(&int((1 << 24) + 1), &int(1)), 16_777_216.0, "a tie goes to the even neighbour");
        assert_eq!(rounded_quotient(&int((1 << 24) + 3), &int(1)), 16_777_220.0, "a tie goes to the even neighbour");
        assert_eq!(rounded_quotient(&int(7).neg(), &int(2)), -3.5);
        assert_eq!(rounded_quotient(&Int::ZERO, &int(5)).to_bits(), 0, "an exact zero is +0");
        // Beyond f32::MAX, and below the smallest subnormal.
        let huge = Int::from_f32(f32::MAX).mul(&int(4));
        assert_eq!(rounded_quotient(&huge, &Int::from_f32(1.0)), f32::INFINITY);
        assert_eq!(rounded_quotient(&Int::from_f32(1e-45), &Int::from_f32(3.0)), 0.0);
        assert_eq!(rounded_quotient(&Int::from_f32(1e-45), &Int::from_f32(0.75)), 1e-45);
        for (x, y) in [(1u64, 7u64), (10, 3), (123_456_789, 1000), (5, 1 << 40), (1 << 50, 3)] {
            let expected = (x as f64 / y as f64) as f32; // one f64 rounding first: equal here, checked by hand
            assert_eq!(rounded_quotient(&int(x), &int(y)), expected, "{x} / {y}");
        }
    }

    #[test]
    fn the_f64_estimate_and_the_integers_agree() {
        // Needles, slivers and grazing rays: wherever the f64 evaluation settles a value, the exact integer
        // evaluation gives the same bits.
        let mut numbers = Numbers(0x9e37_79b9_7f4a_7c15);
        let (mut settled, mut unsettled) = (0, 0);
        for case in 0..20_000 {
            let scale = [1e-3f32, 1.0, 1e3, 1e6][case % 4];
            let v0 = numbers.vector(scale);
            let along = numbers.vector(scale);
            let thin = 10f32.powi(-(case as i32 % 9)) * scale;
            let v1: [f32; 3] = std::array::from_fn(|a| v0[a] + along[a]);
            let v2: [f32; 3] = std::array::from_fn(|a| v0[a] + 0.5 * along[a] + thin * numbers.unit());
            let target: [f32; 3] = std::array::from_fn(|a| (v0[a] + v1[a] + v2[a]) / 3.0);
            let origin = numbers.vector(scale * 4.0);
            let direction: [f32; 3] = if case % 3 == 0 {
                std::array::from_fn(|a| along[a] + 1e-4 * scale * numbers.unit()) // nearly in the plane
            } else {
                std::array::from_fn(|a| target[a] - origin[a])
            };
            let kz = major_axis(&direction);
            let vertices = [v0, v1, v2];
            let exact = exact(&origin, &direction, kz, &vertices);
            match estimate(&origin, &direction, kz, &vertices) {
                Estimate::Certain(hit) => {
                    settled += 1;
                    assert_eq!(
                        hit.map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                        exact.map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                        "case {case}: {origin:?} {direction:?} {vertices:?}"
                    );
                }
                Estimate::Uncertain => unsettled += 1,
            }
            if let Some(hit) = exact {
                assert!(hit.u >= 0.0 && hit.v >= 0.0 && hit.u + hit.v <= 1.0 + 2.0 * f32::EPSILON, "{hit:?}");
            }
        }
        // A third of the cases are needles 1e-6 to 1e-8 of their length wide, which f64 rarely settles.
        assert!(settled > 12_000, "the f64 evaluation settles most cases ({settled} of 20000, {unsettled} not)");
    }

    #[test]
    fn weights_of_the_wrong_sign_are_dropped() {
        // A ray just outside the edge v1-v2 of a right triangle: the exact weight of v0 is negative, so it is
        // dropped and the point is on that edge (u + v = 1).
        let vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let hit = exact_hit(&[0.5, 0.5000001, 1.0], &[0.0, 0.0, -1.0], 2, &vertices).unwrap();
        assert_eq!(hit.t, 1.0);
        assert!((hit.u + hit.v - 1.0).abs() <= f32::EPSILON, "{hit:?}");
        // A ray in the triangle's plane: no exact values.
        assert!(exact_hit(&[-1.0, 0.25, 0.0], &[1.0, 0.0, 0.0], 0, &vertices).is_none());
    }
}
