//! An independent reading of `format-spec/bvh-1.md` 11.1 for the accuracy tests: the hit test's steps in plain
//! f32 written from the spec (not the loader's code), and its exact values in big integers (num-bigint): the
//! weights, `t*`, `u*`, `v*` of step 6, rounded to f32 by integer division (not the loader's method of
//! comparing with midpoints).

use bvhc::loader::Ray;
use num_bigint::BigInt;
use num_traits::{Signed, Zero};

/// 11.1 step 5: a hit is ill-conditioned when `|det| < rho (rho + Z) / 64` or `rho (rho + Z) < 2^-100`.
pub const ILL_CONDITIONED: f32 = 1.0 / 64.0;
/// The proven bound of 11.1's "Accuracy" on a well-conditioned hit: `|t - t*| <= T_BOUND (|t*| + depth)`.
pub const T_BOUND: f64 = (64.0 * 64.0 + 12.0) / 16_777_216.0;

/// What the reference test says about one ray and one triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    /// Step 5's verdict.
    pub ill_conditioned: bool,
}

/// Exact values of step 6: `t*` (as f64 for measuring), its f32 rounding and `u*`, `v*` rounded, and the
/// triangle's depth spread about `t*` along the ray (`max |z_i - t*|`, f64).
#[derive(Clone, Copy, Debug)]
pub struct Exact {
    pub t: f64,
    pub rounded: [f32; 3],
    pub depth: f64,
}

/// Steps 1-8 for `ray` and `triangle`: [`steps_1_to_7`], then the box condition ([`meets_box_condition`]).
pub fn reference_hit(ray: &Ray, triangle: &[[f32; 3]; 3]) -> Option<ReferenceHit> {
    steps_1_to_7(ray, triangle).filter(|hit| meets_box_condition(ray, triangle, hit.t))
}

/// Step 8, written from the spec: the ray meets the record's box (its vertices' per-axis minima and maxima)
/// within the window `[max(t_min, t - w), t + w]`, `w = (t + Z' |sz|) 2^-12`, `Z'` the spread of the record's
/// coordinates along the major axis, by 11.2's robust slab test (the exit through the reciprocal padded by
/// `1 + 2 gamma(3)`, compare-selects that keep the accumulator on NaN).
pub fn meets_box_condition(ray: &Ray, triangle: &[[f32; 3]; 3], t: f32) -> bool {
    let d = ray.direction;
    let kz = major_axis(&d);
    let sz = 1.0 / d[kz];
    let z = [triangle[0][kz], triangle[1][kz], triangle[2][kz]];
    let spread = z[0].max(z[1]).max(z[2]) - z[0].min(z[1]).min(z[2]);
    let w = (t + spread * sz.abs()) * (1.0 / 4096.0);
    let (mut near, mut far) = if t == f32::INFINITY { (ray.t_min, t) } else { ((t - w).max(ray.t_min), t + w) };
    let eps = f32::EPSILON / 2.0;
    let padding = 1.0 + 2.0 * (3.0 * eps) / (1.0 - 3.0 * eps);
    for a in 0..3 {
        let lo = triangle[0][a].min(triangle[1][a]).min(triangle[2][a]);
        let hi = triangle[0][a].max(triangle[1][a]).max(triangle[2][a]);
        let inverse = 1.0 / d[a];
        let (entry, exit) = if d[a].is_sign_negative() { (hi, lo) } else { (lo, hi) };
        let t_entry = (entry - ray.origin[a]) * inverse;
        let t_exit = (exit - ray.origin[a]) * (inverse * padding);
        if t_entry > near {
            near = t_entry;
        }
        if t_exit < far {
            far = t_exit;
        }
    }
    near <= far
}

/// Steps 1-7 for `ray` and `triangle`, hits within `[t_min, t_max]`; ill-conditioned hits take the exact values.
pub fn steps_1_to_7(ray: &Ray, triangle: &[[f32; 3]; 3]) -> Option<ReferenceHit> {
    let d = ray.direction;
    let kz = major_axis(&d);
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    let o = ray.origin;
    let relative = |v: &[f32; 3]| {
        let a = [v[0] - o[0], v[1] - o[1], v[2] - o[2]];
        [a[kx], a[ky], a[kz]]
    };
    let (a, b, c) = (relative(&triangle[0]), relative(&triangle[1]), relative(&triangle[2]));
    let shear = |p: [f32; 3]| [p[0] - sx * p[2], p[1] - sy * p[2]];
    let (pa, pb, pc) = (shear(a), shear(b), shear(c));
    let edge = |p: [f32; 2], q: [f32; 2]| p[0] * q[1] - p[1] * q[0];
    let mut e = [edge(pc, pb), edge(pa, pc), edge(pb, pa)];
    if e.contains(&0.0) {
        let wide =
            |p: [f32; 2], q: [f32; 2]| (f64::from(p[0]) * f64::from(q[1]) - f64::from(p[1]) * f64::from(q[0])) as f32;
        e = [wide(pc, pb), wide(pa, pc), wide(pb, pa)];
    }
    if e.iter().any(|&x| x < 0.0) && e.iter().any(|&x| x > 0.0) {
        return None;
    }
    let det = (e[0] + e[1]) + e[2];
    if det == 0.0 {
        return None;
    }
    let rho = [pa[0], pa[1], pb[0], pb[1], pc[0], pc[1]].iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let spread = a[2].max(b[2]).max(c[2]) - a[2].min(b[2]).min(c[2]);
    let extent = rho * (rho + spread);
    let ill_conditioned = det.abs() < extent * ILL_CONDITIONED || extent < f32::from_bits(27 << 23);
    let (t, u, v) = match ill_conditioned.then(|| exact(ray, triangle)).flatten() {
        Some(exact) => (exact.rounded[0], exact.rounded[1], exact.rounded[2]),
        None => {
            let t = ((e[0] * (sz * a[2])) + (e[1] * (sz * b[2]))) + (e[2] * (sz * c[2]));
            let r = 1.0 / det;
            (t / det, e[1] * r, e[2] * r)
        }
    };
    (t >= ray.t_min && t <= ray.t_max).then_some(ReferenceHit { t, u, v, ill_conditioned })
}

pub fn major_axis(d: &[f32; 3]) -> usize {
    let m = d.map(f32::abs);
    if m[0] >= m[1] && m[0] >= m[2] {
        0
    } else if m[1] >= m[2] {
        1
    } else {
        2
    }
}

/// `x * 2^149` as an integer (every finite f32 is a multiple of `2^-149`).
fn scaled(x: f32) -> BigInt {
    let bits = x.to_bits();
    let field = (bits >> 23) & 0xff;
    let fraction = i64::from(bits & 0x7f_ffff);
    let magnitude = if field == 0 { BigInt::from(fraction) } else { BigInt::from(fraction | 0x80_0000) << (field - 1) };
    if x.is_sign_negative() { -magnitude } else { magnitude }
}

/// Step 6's exact values, or `None` when the weights sum to zero.
pub fn exact(ray: &Ray, triangle: &[[f32; 3]; 3]) -> Option<Exact> {
    let o = ray.origin.map(scaled);
    let d = ray.direction.map(scaled);
    let relative = |v: &[f32; 3]| -> [BigInt; 3] { std::array::from_fn(|a| scaled(v[a]) - &o[a]) };
    let p = [relative(&triangle[0]), relative(&triangle[1]), relative(&triangle[2])];
    // d . (q x r)
    let triple = |q: &[BigInt; 3], r: &[BigInt; 3]| {
        &d[0] * (&q[1] * &r[2] - &q[2] * &r[1])
            + &d[1] * (&q[2] * &r[0] - &q[0] * &r[2])
            + &d[2] * (&q[0] * &r[1] - &q[1] * &r[0])
    };
    let w = [triple(&p[2], &p[1]), triple(&p[0], &p[2]), triple(&p[1], &p[0])];
    let sum = &w[0] + &w[1] + &w[2];
    if sum.is_zero() {
        return None;
    }
    let kept: Vec<BigInt> = w.iter().map(|x| if x.sign() == sum.sign() { x.clone() } else { BigInt::zero() }).collect();
    let total = &kept[0] + &kept[1] + &kept[2];
    let kz = major_axis(&ray.direction);
    let numerator = &kept[0] * &p[0][kz] + &kept[1] * &p[1][kz] + &kept[2] * &p[2][kz];
    let denominator = &d[kz] * &total;
    let t = ratio_f64(&numerator, &denominator);
    let depth = (0..3).map(|i| (ratio_f64(&p[i][kz], &d[kz]) - t).abs()).fold(0.0, f64::max);
    Some(Exact {
        t,
        rounded: [
            round_to_f32(&numerator, &denominator),
            round_to_f32(&kept[1], &total),
            round_to_f32(&kept[2], &total),
        ],
        depth,
    })
}

/// `n / d` to f64 precision (for measuring errors), by integer division of scaled values.
fn ratio_f64(n: &BigInt, d: &BigInt) -> f64 {
    if n.is_zero() {
        return 0.0;
    }
    let shift = 64 + d.bits() as i64 - n.bits() as i64;
    let q = if shift >= 0 { (n.abs() << shift as u64) / d.abs() } else { n.abs() / (d.abs() << (-shift) as u64) };
    let value = q.to_string().parse::<f64>().unwrap() * 2f64.powi(-shift as i32);
    if n.is_negative() != d.is_negative() { -value } else { value }
}

/// `n / d` rounded to the nearest f32, ties to even: the quotient scaled to 24 significant bits (fewer below
/// the normal range) by integer division, rounded with its remainder.
pub fn round_to_f32(n: &BigInt, d: &BigInt) -> f32 {
    if n.is_zero() {
        return 0.0;
    }
    let negative = n.is_negative() != d.is_negative();
    let (n, d) = (n.abs(), d.abs());
    // e = floor(log2(n / d)).
    let mut e = n.bits() as i64 - d.bits() as i64;
    let at_least = |e: i64| if e >= 0 { n.clone() >= (d.clone() << e as u64) } else { (n.clone() << (-e) as u64) >= d };
    while !at_least(e) {
        e -= 1;
    }
    while at_least(e + 1) {
        e += 1;
    }
    let magnitude = if e >= 128 {
        f32::INFINITY
    } else {
        // The last kept bit's weight: 2^(e - 23) for normal numbers, 2^-149 below them.
        let unit = (e - 23).max(-149);
        let (scaled_n, scaled_d) = if unit <= 0 { (n << (-unit) as u64, d) } else { (n, d << unit as u64) };
        let (q, r) = (&scaled_n / &scaled_d, &scaled_n % &scaled_d);
        let twice = &r << 1u32;
        let round_up = twice > scaled_d || (twice == scaled_d && (&q & BigInt::from(1)) == BigInt::from(1));
        let k = if round_up { q + 1 } else { q };
        let k: f64 = k.to_string().parse().unwrap();
        (k * 2f64.powi(unit as i32)) as f32 // exact: k has at most 25 bits and the power is in range
    };
    if negative { -magnitude } else { magnitude }
}

/// The signs of the exact weights `w0, w1, w2`: all positive or all negative when the ray crosses the
/// triangle's interior in exact arithmetic.
pub fn exact_signs(ray: &Ray, triangle: &[[f32; 3]; 3]) -> [i32; 3] {
    // In f64 first: a sign is certain when the value exceeds 1e-12 of its permanent (the evaluation's error is
    // below 8 * 2^-53 of it); big integers only for the rest.
    let o = ray.origin.map(f64::from);
    let d = ray.direction.map(f64::from);
    let relative = |v: &[f32; 3]| -> [f64; 3] { std::array::from_fn(|a| f64::from(v[a]) - o[a]) };
    let p = [relative(&triangle[0]), relative(&triangle[1]), relative(&triangle[2])];
    let triple = |q: &[f64; 3], r: &[f64; 3]| {
        let terms = [
            d[0] * q[1] * r[2],
            -d[0] * q[2] * r[1],
            d[1] * q[2] * r[0],
            -d[1] * q[0] * r[2],
            d[2] * q[0] * r[1],
            -d[2] * q[1] * r[0],
        ];
        (terms.iter().sum::<f64>(), terms.iter().map(|t| t.abs()).sum::<f64>())
    };
    let estimates = [triple(&p[2], &p[1]), triple(&p[0], &p[2]), triple(&p[1], &p[0])];
    if estimates.iter().all(|&(value, permanent)| value.abs() > 1e-12 * permanent) {
        return estimates.map(|(value, _)| if value > 0.0 { 1 } else { -1 });
    }
    exact_signs_in_integers(ray, triangle)
}

/// [`exact_signs`] in big integers.
fn exact_signs_in_integers(ray: &Ray, triangle: &[[f32; 3]; 3]) -> [i32; 3] {
    let o = ray.origin.map(scaled);
    let d = ray.direction.map(scaled);
    let relative = |v: &[f32; 3]| -> [BigInt; 3] { std::array::from_fn(|a| scaled(v[a]) - &o[a]) };
    let p = [relative(&triangle[0]), relative(&triangle[1]), relative(&triangle[2])];
    let triple = |q: &[BigInt; 3], r: &[BigInt; 3]| {
        &d[0] * (&q[1] * &r[2] - &q[2] * &r[1])
            + &d[1] * (&q[2] * &r[0] - &q[0] * &r[2])
            + &d[2] * (&q[0] * &r[1] - &q[1] * &r[0])
    };
    let sign = |x: BigInt| {
        if x.is_zero() {
            0
        } else if x.is_negative() {
            -1
        } else {
            1
        }
    };
    [sign(triple(&p[2], &p[1])), sign(triple(&p[0], &p[2])), sign(triple(&p[1], &p[0]))]
}
