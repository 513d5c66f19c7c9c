//! The contract of a ray (`format-spec/rays-and-hits.md`, section "Ray records"): `origin`, `direction` and
//! `t_min` finite, `t_max` not NaN, the direction's largest component at least `2^-64` in magnitude (below it
//! the triangle test's shear would overflow), and `0 <= t_min <= t_max`. [`Ray::check`] says which rule a ray
//! breaks; a [`crate::Tracer`] checks every ray it is given unless made with [`crate::Tracer::trusting_rays`].
//!
//! A ray that breaks the contract has no specified answer: the kernels stay safe on it (no panic, no hang) but
//! may miss what a valid ray would hit, which is why the checked calls refuse it rather than answer.

use crate::ray::intersect::Ray;

/// The smallest allowed magnitude of a direction's largest component: `2^-64`.
pub const MIN_DIRECTION_COMPONENT: f32 = 1.0 / 18_446_744_073_709_551_616.0;

/// The rule of the ray contract a ray breaks (see the module doc), in the order [`Ray::check`] tests them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayError {
    /// A component of `origin` is infinite or NaN.
    OriginNotFinite,
    /// A component of `direction` is infinite or NaN.
    DirectionNotFinite,
    /// `direction` is the zero vector.
    DirectionZero,
    /// Every component of `direction` is below `2^-64` in magnitude, and some is not zero.
    DirectionTooShort,
    /// `t_min` is negative, infinite or NaN.
    TMinNotValid,
    /// `t_max` is NaN, or below `t_min`.
    TMaxNotValid,
}

impl std::fmt::Display for RayError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RayError::OriginNotFinite => "the origin is not finite",
            RayError::DirectionNotFinite => "the direction is not finite",
            RayError::DirectionZero => "the direction is zero",
            RayError::DirectionTooShort => {
                "the direction's largest component is below 2^-64 in magnitude (the hit test's shear would \
                 overflow); scale the direction up"
            }
            RayError::TMinNotValid => "t_min is negative, infinite or NaN (needs 0 <= t_min <= t_max)",
            RayError::TMaxNotValid => "t_max is NaN or below t_min (needs 0 <= t_min <= t_max)",
        })
    }
}

impl std::error::Error for RayError {}

/// A ray of a batch that breaks the contract: its index in the batch and the rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchRayError {
    /// The index of the first such ray.
    pub index: usize,
    /// The rule it breaks.
    pub error: RayError,
}

impl std::fmt::Display for BatchRayError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ray {}: {}", self.index, self.error)
    }
}

impl std::error::Error for BatchRayError {}

impl Ray {
    /// `Ok` when this ray keeps the contract (see the module doc), else the first rule it breaks.
    ///
    /// Branch-free on the common path: one test of all the rules together, then, only for a ray that fails it,
    /// the tests that name the rule.
    #[inline(always)]
    pub fn check(&self) -> Result<(), RayError> {
        if self.is_valid() { Ok(()) } else { Err(self.broken_rule()) }
    }

    /// Whether this ray keeps the contract: on x86-64, SSE2 tests over the ray's eight floats as integers
    /// ([`sse2_valid`]), elsewhere the same tests one value at a time ([`portable_valid`]); the same answer.
    #[inline(always)]
    fn is_valid(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            sse2_valid(self)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            portable_valid(self)
        }
    }

    /// The first rule a ray that fails [`Ray::is_valid`] breaks.
    #[cold]
    #[inline(never)]
    fn broken_rule(&self) -> RayError {
        if !self.origin.iter().all(|c| c.is_finite()) {
            RayError::OriginNotFinite
        } else if !self.direction.iter().all(|c| c.is_finite()) {
            RayError::DirectionNotFinite
        } else if self.direction.iter().all(|&c| c == 0.0) {
            RayError::DirectionZero
        } else if self.direction.iter().all(|c| c.abs() < MIN_DIRECTION_COMPONENT) {
            RayError::DirectionTooShort
        } else if !(self.t_min.is_finite() && self.t_min >= 0.0) {
            RayError::TMinNotValid
        } else {
            RayError::TMaxNotValid
        }
    }
}

/// The bits of a float's magnitude (its sign cleared): for magnitudes, integer order is float order, and every
/// value at or above [`INFINITY_BITS`] is infinite or NaN.
const MAGNITUDE: u32 = 0x7fff_ffff;
/// The bits of `+inf`.
const INFINITY_BITS: u32 = 0x7f80_0000;

/// [`Ray::is_valid`] on any machine: the seven values that must be finite have magnitudes below infinity's,
/// some direction component's magnitude is at least `2^-64`, and `0 <= t_min <= t_max` (false on NaN).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))] // the x86-64 build runs `sse2_valid`; the tests compare both
#[inline(always)]
fn portable_valid(ray: &Ray) -> bool {
    let magnitude = |x: f32| x.to_bits() & MAGNITUDE;
    let [ox, oy, oz] = ray.origin.map(magnitude);
    let [dx, dy, dz] = ray.direction.map(magnitude);
    let largest = ox.max(oy).max(oz).max(dx).max(dy).max(dz).max(magnitude(ray.t_min));
    let longest = dx.max(dy).max(dz);
    (largest < INFINITY_BITS)
        & (longest >= MIN_DIRECTION_COMPONENT.to_bits())
        & (ray.t_min >= 0.0)
        & (ray.t_min <= ray.t_max)
}

/// [`Ray::is_valid`] with SSE2 (every x86-64 has it): the ray's floats in two 4-lane registers, their
/// magnitudes compared as integers with infinity's and `2^-64`'s bits at once (`t_max`'s lane masked out),
/// then the two comparisons of `t_min`. About 20 instructions, against about 50 for the scalar tests.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(unsafe_code)] // SSE2 intrinsics, see the SAFETY note
fn sse2_valid(ray: &Ray) -> bool {
    use std::arch::x86_64::{
        _mm_and_si128, _mm_castsi128_ps, _mm_cmpgt_epi32, _mm_movemask_ps, _mm_or_si128, _mm_set1_epi32, _mm_setr_epi32,
    };
    let bits = |x: f32| x.to_bits() as i32;
    let [ox, oy, oz] = ray.origin.map(bits);
    let [dx, dy, dz] = ray.direction.map(bits);
    let mask = MAGNITUDE as i32;
    // SAFETY: SSE2 is part of the x86-64 baseline, which every x86-64 target enables, so these intrinsics run
    // on every machine this code is built for; they compute on registers only (no memory is read or written).
    let (infinite, long) = unsafe {
        // Lanes: origin and dx; dy, dz, t_min and nothing (t_max may be infinite).
        let low = _mm_and_si128(_mm_setr_epi32(ox, oy, oz, dx), _mm_set1_epi32(mask));
        let high = _mm_and_si128(_mm_setr_epi32(dy, dz, bits(ray.t_min), 0), _mm_setr_epi32(mask, mask, mask, 0));
        let not_finite = _mm_set1_epi32(INFINITY_BITS as i32 - 1);
        let infinite = _mm_or_si128(_mm_cmpgt_epi32(low, not_finite), _mm_cmpgt_epi32(high, not_finite));
        let short = _mm_set1_epi32(MIN_DIRECTION_COMPONENT.to_bits() as i32 - 1);
        let long = (_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(low, short))) & 0b1000)
            | (_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(high, short))) & 0b0011);
        (_mm_movemask_ps(_mm_castsi128_ps(infinite)), long)
    };
    (infinite == 0) & (long != 0) & (ray.t_min >= 0.0) & (ray.t_min <= ray.t_max)
}

/// `Ok` when every ray of `rays` keeps the contract, else the first that does not.
pub fn check_rays(rays: &[Ray]) -> Result<(), BatchRayError> {
    if all_valid(rays) {
        return Ok(());
    }
    // Only a failing batch looks for the ray, with the one-ray test.
    let index = rays.iter().position(|ray| !ray.is_valid()).unwrap_or(0);
    Err(BatchRayError { index, error: rays[index].broken_rule() })
}

/// Whether every ray of `rays` keeps the contract: eight rays at a time with AVX2 where the CPU has it
/// ([`avx2_all_valid`]), else one at a time; the same answer (the tests compare them).
fn all_valid(rays: &[Ray]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if let Some(token) = crate::simd::Avx2::detect() {
        return avx2_all_valid(token, rays);
    }
    one_by_one_all_valid(rays)
}

/// Whether every ray of `rays` keeps the contract, tested one ray at a time without an early exit.
fn one_by_one_all_valid(rays: &[Ray]) -> bool {
    rays.iter().fold(true, |valid, ray| valid & ray.is_valid())
}

/// [`all_valid`] with AVX2 (`token` proves the CPU has it): each 8 rays (8 x 32 bytes) transposed into eight
/// registers of one field each, then the tests of [`portable_valid`] on 8 rays at once: about 7 instructions a
/// ray, against about 30 one ray at a time. The rays left over are tested one by one.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // AVX2 intrinsics, see the SAFETY notes
fn avx2_all_valid(token: crate::simd::Avx2, rays: &[Ray]) -> bool {
    #[target_feature(enable = "avx2")]
    fn eights(rays: &[[Ray; 8]]) -> bool {
        use std::arch::x86_64::*;
        let magnitude = _mm256_set1_epi32(MAGNITUDE as i32);
        let not_finite = _mm256_set1_epi32(INFINITY_BITS as i32 - 1);
        let short = _mm256_set1_epi32(MIN_DIRECTION_COMPONENT.to_bits() as i32 - 1);
        let zero = _mm256_setzero_ps();
        let mut bad = _mm256_setzero_si256();
        for group in rays {
            // SAFETY: `Ray` is `#[repr(C)]`, eight f32 (32 bytes) with no padding, so `group` is 8 x 32 readable
            // bytes; the loads are unaligned.
            let r: [__m256; 8] = std::array::from_fn(|i| unsafe { _mm256_loadu_ps((&group[i] as *const Ray).cast()) });
            // Transpose: field k of the 8 rays into `field[k]` (origin x, y, z, direction x, y, z, t_min, t_max).
            let t = [0, 2, 4, 6].map(|i| (_mm256_unpacklo_ps(r[i], r[i + 1]), _mm256_unpackhi_ps(r[i], r[i + 1])));
            let q = [
                _mm256_shuffle_ps::<0x44>(t[0].0, t[1].0),
                _mm256_shuffle_ps::<0xEE>(t[0].0, t[1].0),
                _mm256_shuffle_ps::<0x44>(t[0].1, t[1].1),
                _mm256_shuffle_ps::<0xEE>(t[0].1, t[1].1),
                _mm256_shuffle_ps::<0x44>(t[2].0, t[3].0),
                _mm256_shuffle_ps::<0xEE>(t[2].0, t[3].0),
                _mm256_shuffle_ps::<0x44>(t[2].1, t[3].1),
                _mm256_shuffle_ps::<0xEE>(t[2].1, t[3].1),
            ];
            let field: [__m256; 8] = std::array::from_fn(|k| match k < 4 {
                true => _mm256_permute2f128_ps::<0x20>(q[k], q[k + 4]),
                false => _mm256_permute2f128_ps::<0x31>(q[k - 4], q[k]),
            });
            let m: [__m256i; 7] = std::array::from_fn(|k| _mm256_and_si256(_mm256_castps_si256(field[k]), magnitude));
            let largest = _mm256_max_epu32(
                _mm256_max_epu32(_mm256_max_epu32(m[0], m[1]), _mm256_max_epu32(m[2], m[6])),
                _mm256_max_epu32(_mm256_max_epu32(m[3], m[4]), m[5]),
            );
            let longest = _mm256_max_epu32(_mm256_max_epu32(m[3], m[4]), m[5]);
            let (t_min, t_max) = (field[6], field[7]);
            let times =
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(t_min, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(t_min, t_max));
            // Bad lanes: a value not finite, every direction component short, or the times out of order.
            let lane_bad = _mm256_or_si256(
                _mm256_cmpgt_epi32(largest, not_finite),
                _mm256_andnot_si256(_mm256_cmpgt_epi32(longest, short), _mm256_set1_epi32(-1)),
            );
            bad = _mm256_or_si256(
                bad,
                _mm256_or_si256(
                    lane_bad,
                    _mm256_castps_si256(_mm256_xor_ps(times, _mm256_castsi256_ps(_mm256_set1_epi32(-1)))),
                ),
            );
        }
        _mm256_testz_si256(bad, bad) == 1
    }
    let _ = token;
    let (groups, rest) = rays.as_chunks::<8>();
    // SAFETY: `token` exists, so `Avx2::detect` found AVX2 on this CPU.
    let groups_valid = unsafe { eights(groups) };
    groups_valid & one_by_one_all_valid(rest)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(origin: [f32; 3], direction: [f32; 3], t_min: f32, t_max: f32) -> Ray {
        Ray { origin, direction, t_min, t_max }
    }

    #[test]
    fn each_rule_is_named_and_the_limits_are_inclusive() {
        let good = ray([1.0, -2.0, 3.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY);
        assert_eq!(good.check(), Ok(()));
        for (bad, rule) in [
            (Ray { origin: [f32::NAN, 0.0, 0.0], ..good }, RayError::OriginNotFinite),
            (Ray { origin: [0.0, f32::INFINITY, 0.0], ..good }, RayError::OriginNotFinite),
            (Ray { origin: [0.0, 0.0, f32::NEG_INFINITY], ..good }, RayError::OriginNotFinite),
            (Ray { direction: [f32::NAN, 1.0, 0.0], ..good }, RayError::DirectionNotFinite),
            (Ray { direction: [0.0, 0.0, f32::INFINITY], ..good }, RayError::DirectionNotFinite),
            (Ray { direction: [0.0; 3], ..good }, RayError::DirectionZero),
            (Ray { direction: [-0.0, 0.0, -0.0], ..good }, RayError::DirectionZero),
            (Ray { direction: [0.0, 0.0, f32::from_bits(1)], ..good }, RayError::DirectionTooShort),
            (Ray { direction: [0.0, MIN_DIRECTION_COMPONENT * 0.5, 0.0], ..good }, RayError::DirectionTooShort),
            (Ray { t_min: -1.0, ..good }, RayError::TMinNotValid),
            (Ray { t_min: f32::NAN, ..good }, RayError::TMinNotValid),
            (Ray { t_min: f32::INFINITY, ..good }, RayError::TMinNotValid),
            (Ray { t_max: f32::NAN, ..good }, RayError::TMaxNotValid),
            (Ray { t_min: 2.0, t_max: 1.0, ..good }, RayError::TMaxNotValid),
            (Ray { t_max: -0.5, ..good }, RayError::TMaxNotValid),
        ] {
            assert_eq!(bad.check(), Err(rule), "{bad:?}");
            assert_eq!(check_rays(&[good, good, bad, good, bad]), Err(BatchRayError { index: 2, error: rule }));
        }
        // The limits themselves are valid.
        for fine in [
            Ray { direction: [0.0, -MIN_DIRECTION_COMPONENT, 0.0], ..good },
            Ray { t_min: 1.0, t_max: 1.0, ..good },
            Ray { t_min: -0.0, t_max: 0.0, ..good },
            Ray { origin: [f32::MAX, -f32::MAX, 0.0], direction: [f32::MAX, 0.0, f32::MIN_POSITIVE], ..good },
        ] {
            assert_eq!(fine.check(), Ok(()), "{fine:?}");
        }
        assert_eq!(check_rays(&[]), Ok(()));
        assert_eq!(check_rays(&[good; 17]), Ok(()));
    }

    #[test]
    fn the_sse2_and_portable_tests_agree_on_every_kind_of_value() {
        // Values at and around each limit, both signs, NaNs with payloads, and a stream of arbitrary bit patterns.
        let mut values = vec![0.0, -0.0, 1.0, -1.0, f32::MAX, f32::MIN, f32::MIN_POSITIVE, f32::from_bits(1)];
        values.extend([
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::from_bits(0x7f80_0001),
            f32::from_bits(0xffff_ffff),
        ]);
        let limit = MIN_DIRECTION_COMPONENT;
        values.extend([limit, -limit, f32::from_bits(limit.to_bits() - 1), f32::from_bits(limit.to_bits() + 1)]);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..200_000 {
            let pick = |r: u64| match r % 3 {
                0 => values[(r >> 8) as usize % values.len()],
                _ => f32::from_bits((r >> 16) as u32),
            };
            let f: [f32; 8] = std::array::from_fn(|_| pick(next()));
            let ray = Ray { origin: [f[0], f[1], f[2]], direction: [f[3], f[4], f[5]], t_min: f[6], t_max: f[7] };
            let expected = ray.origin.iter().chain(&ray.direction).all(|c| c.is_finite())
                && ray.direction.iter().any(|c| c.abs() >= limit)
                && ray.t_min.is_finite()
                && 0.0 <= ray.t_min
                && ray.t_min <= ray.t_max;
            assert_eq!(portable_valid(&ray), expected, "{ray:?}");
            #[cfg(target_arch = "x86_64")]
            assert_eq!(sse2_valid(&ray), expected, "{ray:?}");
            assert_eq!(ray.check().is_ok(), expected, "{ray:?}");
            // The same ray in every lane of a group of eight (the AVX2 batch test), among valid rays.
            let lane = (next() % 8) as usize;
            let mut group = [Ray::new([0.0; 3], [1.0, 0.0, 0.0]); 8];
            group[lane] = ray;
            assert_eq!(all_valid(&group), expected, "{ray:?} in lane {lane}");
        }
    }

    #[test]
    fn the_batch_test_finds_a_bad_ray_in_any_lane_of_any_group() {
        let good = ray([1.0, -2.0, 3.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY);
        let bad = [
            Ray { origin: [0.0, 0.0, f32::NAN], ..good },
            Ray { direction: [0.0; 3], ..good },
            Ray { t_min: 2.0, t_max: 1.0, ..good },
            Ray { t_max: f32::NAN, ..good },
            Ray { t_min: f32::INFINITY, ..good },
        ];
        for count in [0, 1, 7, 8, 9, 16, 23, 64] {
            let rays = vec![good; count];
            assert!(all_valid(&rays) && one_by_one_all_valid(&rays));
            for position in 0..count {
                for broken in bad {
                    let mut rays = rays.clone();
                    rays[position] = broken;
                    assert!(!all_valid(&rays) && !one_by_one_all_valid(&rays), "{count} {position} {broken:?}");
                    assert_eq!(check_rays(&rays).unwrap_err().index, position);
                }
            }
        }
    }

    #[test]
    fn the_messages_name_the_ray_and_the_rule() {
        let error = BatchRayError { index: 7, error: RayError::TMaxNotValid };
        assert_eq!(error.to_string(), "ray 7: t_max is NaN or below t_min (needs 0 <= t_min <= t_max)");
        assert!(RayError::DirectionTooShort.to_string().contains("2^-64"));
    }
}
