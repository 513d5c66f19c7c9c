//! Lanes of f32: the operations the kernels are written in, once, for every lane width. Each operation is the
//! IEEE one, unfused, lane by lane, so one formula gives the same bits in one lane (`f32`), in portable arrays
//! (`[f32; N]`) and in SSE2 or AVX2 registers ([`super::x86`]).

/// f32 lanes. Comparisons are ordered (false where a lane is NaN) and give a [`LaneMask`].
pub(crate) trait Lanes: Copy {
    /// The lanes as an array (`f32` for one lane).
    type Array;
    /// A mask of lanes.
    type Mask: LaneMask;
    /// The lanes of an array.
    fn to_array(self) -> Self::Array;
    /// `self + other`.
    fn add(self, other: Self) -> Self;
    /// `self - other`.
    fn sub(self, other: Self) -> Self;
    /// `self * other`.
    fn mul(self, other: Self) -> Self;
    /// `self / other`.
    fn div(self, other: Self) -> Self;
    /// `|self|`: the sign bit cleared.
    fn abs(self) -> Self;
    /// `self > other ? self : other` per lane (`other` where either is NaN), as `maxps` computes it.
    fn max_or(self, other: Self) -> Self;
    /// `self < other ? self : other` per lane (`other` where either is NaN), as `minps` computes it.
    fn min_or(self, other: Self) -> Self;
    /// `self == other`.
    fn eq(self, other: Self) -> Self::Mask;
    /// `self < other`.
    fn lt(self, other: Self) -> Self::Mask;
    /// `self > other`.
    fn gt(self, other: Self) -> Self::Mask;
    /// `self <= other`.
    fn le(self, other: Self) -> Self::Mask;
    /// `self >= other`.
    fn ge(self, other: Self) -> Self::Mask;
    /// The lanes that are not NaN.
    fn is_number(self) -> Self::Mask;
    /// The lanes whose sign bit is set.
    fn is_sign_negative(self) -> Self::Mask;
    /// `if_true` in the lanes of `mask`, `if_false` elsewhere.
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self;
    /// The smallest lane in every lane (for lanes without NaN).
    fn min_across(self) -> Self;
}

/// A mask of lanes.
pub(crate) trait LaneMask: Copy {
    /// Lanes in either.
    fn or(self, other: Self) -> Self;
    /// Lanes in both.
    fn and(self, other: Self) -> Self;
    /// Lanes in `self` and not in `other`.
    fn and_not(self, other: Self) -> Self;
    /// Bit `l` set for lane `l`.
    fn bits(self) -> u32;
}

impl LaneMask for bool {
    #[inline(always)]
    fn or(self, other: bool) -> bool {
        self | other
    }
    #[inline(always)]
    fn and(self, other: bool) -> bool {
        self & other
    }
    #[inline(always)]
    fn and_not(self, other: bool) -> bool {
        self & !other
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        u32::from(self)
    }
}

/// One lane: the scalar test.
impl Lanes for f32 {
    type Array = f32;
    type Mask = bool;
    #[inline(always)]
    fn to_array(self) -> f32 {
        self
    }
    #[inline(always)]
    fn add(self, other: f32) -> f32 {
        self + other
    }
    #[inline(always)]
    fn sub(self, other: f32) -> f32 {
        self - other
    }
    #[inline(always)]
    fn mul(self, other: f32) -> f32 {
        self * other
    }
    #[inline(always)]
    fn div(self, other: f32) -> f32 {
        self / other
    }
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn max_or(self, other: f32) -> f32 {
        if self > other { self } else { other }
    }
    #[inline(always)]
    fn min_or(self, other: f32) -> f32 {
        if self < other { self } else { other }
    }
    #[inline(always)]
    fn eq(self, other: f32) -> bool {
        self == other
    }
    #[inline(always)]
    fn lt(self, other: f32) -> bool {
        self < other
    }
    #[inline(always)]
    fn gt(self, other: f32) -> bool {
        self > other
    }
    #[inline(always)]
    fn le(self, other: f32) -> bool {
        self <= other
    }
    #[inline(always)]
    fn ge(self, other: f32) -> bool {
        self >= other
    }
    #[inline(always)]
    fn is_number(self) -> bool {
        !self.is_nan()
    }
    #[inline(always)]
    fn is_sign_negative(self) -> bool {
        f32::is_sign_negative(self)
    }
    #[inline(always)]
    fn select(mask: bool, if_true: f32, if_false: f32) -> f32 {
        if mask { if_true } else { if_false }
    }
    #[inline(always)]
    fn min_across(self) -> f32 {
        self
    }
}

/// A mask of up to 32 portable lanes, bit `l` for lane `l`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Bits(u32);

impl LaneMask for Bits {
    #[inline(always)]
    fn or(self, other: Bits) -> Bits {
        Bits(self.0 | other.0)
    }
    #[inline(always)]
    fn and(self, other: Bits) -> Bits {
        Bits(self.0 & other.0)
    }
    #[inline(always)]
    fn and_not(self, other: Bits) -> Bits {
        Bits(self.0 & !other.0)
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        self.0
    }
}

/// `N` lanes in plain Rust: the portable path, lane by lane the scalar operation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PortableLanes<const N: usize>(pub [f32; N]);

impl<const N: usize> PortableLanes<N> {
    #[inline(always)]
    fn map2(self, other: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        PortableLanes(std::array::from_fn(|l| f(self.0[l], other.0[l])))
    }

    #[inline(always)]
    fn mask(self, other: Self, f: impl Fn(f32, f32) -> bool) -> Bits {
        Bits((0..N).fold(0, |m, l| m | u32::from(f(self.0[l], other.0[l])) << l))
    }
}

impl<const N: usize> Lanes for PortableLanes<N> {
    type Array = [f32; N];
    type Mask = Bits;
    #[inline(always)]
    fn to_array(self) -> [f32; N] {
        self.0
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self.map2(other, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        self.map2(other, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        self.map2(other, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, other: Self) -> Self {
        self.map2(other, |a, b| a / b)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        PortableLanes(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn max_or(self, other: Self) -> Self {
        self.map2(other, f32::max_or)
    }
    #[inline(always)]
    fn min_or(self, other: Self) -> Self {
        self.map2(other, f32::min_or)
    }
    #[inline(always)]
    fn eq(self, other: Self) -> Bits {
        self.mask(other, |a, b| a == b)
    }
    #[inline(always)]
    fn lt(self, other: Self) -> Bits {
        self.mask(other, |a, b| a < b)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> Bits {
        self.mask(other, |a, b| a > b)
    }
    #[inline(always)]
    fn le(self, other: Self) -> Bits {
        self.mask(other, |a, b| a <= b)
    }
    #[inline(always)]
    fn ge(self, other: Self) -> Bits {
        self.mask(other, |a, b| a >= b)
    }
    #[inline(always)]
    fn is_number(self) -> Bits {
        self.mask(self, |a, _| !a.is_nan())
    }
    #[inline(always)]
    fn is_sign_negative(self) -> Bits {
        self.mask(self, |a, _| a.is_sign_negative())
    }
    #[inline(always)]
    fn select(mask: Bits, if_true: Self, if_false: Self) -> Self {
        PortableLanes(std::array::from_fn(|l| if mask.0 & (1 << l) != 0 { if_true.0[l] } else { if_false.0[l] }))
    }
    #[inline(always)]
    fn min_across(self) -> Self {
        let smallest = self.0.iter().fold(f32::INFINITY, |m, &x| x.min_or(m));
        PortableLanes([smallest; N])
    }
}
