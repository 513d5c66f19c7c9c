//! Fixed-width signed integers for exact arithmetic on f32 inputs ([`crate::ray::exact_hit`]'s last resort).
//!
//! Every finite f32 is an integer multiple of `2^-149`, so `x * 2^149` ([`Int::from_f32`]) is an integer below
//! `2^277`. The exact hit values of `format-spec/bvh-1.md` 11.1 are polynomials of degree at most four in such
//! numbers (`2^1116` at most, at scale `2^596`), and rounding their quotients needs one more product with a
//! 25-bit significand shifted by at most 279 bits: below `2^1420`. [`LIMBS`] 64-bit limbs (1536 bits, two's
//! complement) hold every such value, so no operation here overflows for those inputs; each operation wraps
//! modulo `2^1536` like the machine integers it is built from, which makes the results exact whenever the true
//! value fits. Memory is fixed (no allocation), and the work is proportional to the limbs in use.

/// Limbs of an [`Int`]: 1536 bits.
const LIMBS: usize = 24;

/// A signed integer of `64 * LIMBS` bits, two's complement, least significant limb first.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) struct Int([u64; LIMBS]);

impl std::fmt::Debug for Int {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (mantissa, exponent) = self.approx();
        write!(f, "Int(~{mantissa} * 2^{exponent})")
    }
}

impl Int {
    pub(crate) const ZERO: Int = Int([0; LIMBS]);

    /// `magnitude * 2^shift` with the sign of `negative`, for `shift + 64 <= 64 * LIMBS - 1`.
    fn from_parts(magnitude: u64, shift: u32, negative: bool) -> Int {
        let mut limbs = [0u64; LIMBS];
        let (limb, bit) = ((shift / 64) as usize, shift % 64);
        limbs[limb] = magnitude << bit;
        if bit != 0 && limb + 1 < LIMBS {
            limbs[limb + 1] = magnitude >> (64 - bit);
        }
        let value = Int(limbs);
        if negative { value.neg() } else { value }
    }

    /// `x * 2^149`, exactly, for finite `x` (an infinity or NaN gives 0, which callers never pass).
    pub(crate) fn from_f32(x: f32) -> Int {
        if !x.is_finite() {
            return Int::ZERO;
        }
        let bits = x.to_bits();
        let field = (bits >> 23) & 0xff;
        let fraction = u64::from(bits & 0x7f_ffff);
        // x = significand * 2^(field - 150) for normal numbers, fraction * 2^-149 for subnormal ones.
        let (significand, shift) = if field == 0 { (fraction, 0) } else { (fraction | 0x80_0000, field - 1) };
        Int::from_parts(significand, shift, x.is_sign_negative())
    }

    /// `significand * 2^shift` for a non-negative `shift` below `64 * (LIMBS - 1)`.
    pub(crate) fn from_scaled(significand: u64, shift: u32, negative: bool) -> Int {
        Int::from_parts(significand, shift, negative)
    }

    pub(crate) fn is_negative(&self) -> bool {
        self.0[LIMBS - 1] >> 63 == 1
    }

    pub(crate) fn is_zero(&self) -> bool {
        self.0.iter().all(|&limb| limb == 0)
    }

    /// -1, 0 or 1.
    pub(crate) fn signum(&self) -> i32 {
        if self.is_negative() {
            -1
        } else if self.is_zero() {
            0
        } else {
            1
        }
    }

    pub(crate) fn add(&self, other: &Int) -> Int {
        let mut out = [0u64; LIMBS];
        let mut carry = false;
        for (i, limb) in out.iter_mut().enumerate() {
            let (sum, c1) = self.0[i].overflowing_add(other.0[i]);
            let (sum, c2) = sum.overflowing_add(u64::from(carry));
            *limb = sum;
            carry = c1 || c2;
        }
        Int(out)
    }

    pub(crate) fn neg(&self) -> Int {
        let mut out = self.0.map(|limb| !limb);
        for limb in out.iter_mut() {
            let (sum, carry) = limb.overflowing_add(1);
            *limb = sum;
            if !carry {
                break;
            }
        }
        Int(out)
    }

    pub(crate) fn sub(&self, other: &Int) -> Int {
        self.add(&other.neg())
    }

    /// The magnitude's limbs and how many of them are in use.
    fn magnitude(&self) -> ([u64; LIMBS], usize) {
        let limbs = if self.is_negative() { self.neg().0 } else { self.0 };
        let used = limbs.iter().rposition(|&limb| limb != 0).map_or(0, |top| top + 1);
        (limbs, used)
    }

    /// The product, truncated to the width (exact when it fits, as for every value of the module's contract).
    pub(crate) fn mul(&self, other: &Int) -> Int {
        let ((a, a_used), (b, b_used)) = (self.magnitude(), other.magnitude());
        let mut out = [0u64; LIMBS];
        for i in 0..a_used {
            let mut carry = 0u128;
            for j in 0..b_used.min(LIMBS - i) {
                let wide = u128::from(a[i]) * u128::from(b[j]) + u128::from(out[i + j]) + carry;
                out[i + j] = wide as u64;
                carry = wide >> 64;
            }
            if i + b_used < LIMBS {
                out[i + b_used] = carry as u64;
            }
        }
        let product = Int(out);
        if self.is_negative() != other.is_negative() { product.neg() } else { product }
    }

    /// `self * 2^bits`, for `bits < 64 * LIMBS`.
    pub(crate) fn shl(&self, bits: u32) -> Int {
        let (limbs, bit) = ((bits / 64) as usize, bits % 64);
        let mut out = [0u64; LIMBS];
        for i in (limbs..LIMBS).rev() {
            let low = self.0[i - limbs];
            out[i] = if bit == 0 {
                low
            } else {
                (low << bit) | if i > limbs { self.0[i - limbs - 1] >> (64 - bit) } else { 0 }
            };
        }
        Int(out)
    }

    /// `self` as `mantissa * 2^exponent` with `|mantissa|` in `[2^63, 2^64)` as an f64 (within a relative
    /// `2^-52` of the value: the top 128 bits are rounded once), or `(0, 0)` for zero.
    pub(crate) fn approx(&self) -> (f64, i32) {
        let (limbs, used) = self.magnitude();
        if used == 0 {
            return (0.0, 0);
        }
        let top = used - 1;
        let high = u128::from(limbs[top]) << 64 | if top > 0 { u128::from(limbs[top - 1]) } else { 0 };
        let shift = high.leading_zeros();
        let window = high << shift;
        let mantissa = (window >> 64) as f64 + (window as u64) as f64 * 2f64.powi(-64);
        // The window's top bit is bit 127 of the 128 bits read, which sit at bits 64*(top-1) .. 64*top+63.
        let exponent = 64 * top as i32 - shift as i32;
        (if self.is_negative() { -mantissa } else { mantissa }, exponent)
    }

    /// The order of `self` and `other`.
    #[cfg(test)]
    fn compare(&self, other: &Int) -> std::cmp::Ordering {
        self.sub(other).signum().cmp(&0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(x: &Int) -> f64 {
        let (mantissa, exponent) = x.approx();
        mantissa * 2f64.powi(exponent - 149)
    }

    #[test]
    fn f32_values_scale_exactly() {
        for x in [0.0f32, 1.0, -1.0, 0.1, f32::MAX, -f32::MAX, f32::MIN_POSITIVE, 1e-45, -3.5e-44, 123456.78] {
            let int = Int::from_f32(x);
            assert_eq!(value(&int), f64::from(x), "{x}");
            assert_eq!(
                int.signum(),
                if x == 0.0 {
                    0
                } else if x < 0.0 {
                    -1
                } else {
                    1
                }
            );
        }
    }

    #[test]
    fn arithmetic_matches_i128_where_it_fits() {
        let samples: [i64; 9] = [0, 1, -1, 7, -123_456_789, i64::MAX, i64::MIN + 1, 1 << 40, -(1 << 50)];
        let int = |v: i64| Int::from_scaled(v.unsigned_abs(), 0, v < 0);
        let as_i128 = |x: &Int| {
            let low = u128::from(x.0[0]) | u128::from(x.0[1]) << 64;
            low as i128
        };
        for &a in &samples {
            for &b in &samples {
                let (x, y) = (int(a), int(b));
                assert_eq!(as_i128(&x.add(&y)), i128::from(a) + i128::from(b));
                assert_eq!(as_i128(&x.sub(&y)), i128::from(a) - i128::from(b));
                assert_eq!(as_i128(&x.mul(&y)), i128::from(a) * i128::from(b));
                assert_eq!(x.compare(&y), a.cmp(&b));
            }
        }
    }

    #[test]
    fn the_largest_products_fit() {
        // A degree-four product of f32 maxima (scaled by 2^149 each), times a 25-bit significand shifted by 279.
        let max = Int::from_f32(f32::MAX);
        let big = max.mul(&max).mul(&max).mul(&max).mul(&Int::from_scaled((1 << 25) - 1, 279, false));
        assert!(!big.is_negative() && !big.is_zero());
        assert!(big.neg().is_negative());
        let (mantissa, exponent) = big.approx();
        assert!(mantissa > 0.0 && exponent + 64 > 1400 && exponent + 64 < 1536);
        assert_eq!(Int::from_f32(2.0).shl(3), Int::from_f32(16.0));
        assert_eq!(Int::from_f32(-2.0).shl(70), Int::from_f32(-2.0).mul(&Int::from_scaled(1, 70, false)));
    }
}
