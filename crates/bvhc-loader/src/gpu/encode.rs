//! The GPU node's encoder, beside its decoder ([`GpuNode::decode`], [`GpuNode::slot_box`]): quantization of a
//! node's child boxes (format 1.4, `format-spec/bvh-1.md` 5.14): per axis an origin and a power-of-two step such
//! that 255 steps reach the node's box, and per slot the bytes whose decoded values (`origin + q * step` in
//! f32, as every reader decodes them) enclose the slot's box, rounding outward: the minimum down, the maximum
//! up. Decoded values are kept zero or normal (a GPU may flush subnormals to zero, which would move a bound
//! inward), and finite (rule V48). The converter packs with it, and an edit of a file's GPU nodes
//! ([`crate::BvhFile::edit`]) re-encodes them with it.

use crate::format::{Bounds, GPU_WIDE, GpuNode};

/// The step exponent's bias (that of f32): a biased exponent `e` stands for the step `2^(e - 127)`.
const EXPONENT_BIAS: i32 = 127;

/// Whether `value` is something a GPU decodes as itself: finite, and zero or normal.
fn usable(value: f32) -> bool {
    value.is_finite() && (value == 0.0 || value.abs() >= f32::MIN_POSITIVE)
}

/// The decoded value of grid coordinate `q`, as [`GpuNode::decode`] computes it.
fn decode(origin: f32, exponent: u8, q: u8) -> f32 {
    origin + f32::from(q) * f32::from_bits(u32::from(exponent) << 23)
}

/// An origin at or below `min` that decodes as itself on a GPU: `min`, or for a subnormal `min` the zero or
/// negative smallest normal below it.
fn grid_origin(min: f32) -> f32 {
    match min {
        m if usable(m) => m,
        m if m > 0.0 => 0.0,
        _ => -f32::MIN_POSITIVE,
    }
}

/// `ceil(log2(x))` of a positive, finite `x`, exactly: the binary exponent, plus one unless `x` is a power of two.
fn ceil_log2(x: f64) -> i32 {
    let bits = x.to_bits();
    let (biased, fraction) = (((bits >> 52) & 0x7ff) as i32, bits & ((1 << 52) - 1));
    if biased == 0 {
        // Subnormal: 2^-1074 times the fraction (which a difference of f32 values divided by 255 never is).
        return -1074 + (64 - (fraction.max(1) - 1).leading_zeros()) as i32;
    }
    biased - 1023 + i32::from(fraction != 0)
}

/// The bytes of one axis for every box in `boxes` (at most [`GPU_WIDE`]; slot `k` of the result for box `k`, the
/// rest zero) on the grid (`origin`, `exponent`), or `None` when some bound cannot be enclosed by a usable decoded
/// value on this grid (a coarser one is then needed). No allocation: a refit encodes every node of a file.
fn quantize_axis(boxes: &[Bounds], axis: usize, origin: f32, exponent: u8) -> Option<[(u8, u8); GPU_WIDE]> {
    // The step is a power of two from 2^-126 to 2^127, so multiplying by its reciprocal (also exact in f64)
    // gives the quotient bit for bit, without a division per bound.
    let inverse_step = 1.0 / f64::from(f32::from_bits(u32::from(exponent) << 23));
    let value = |q: u8| decode(origin, exponent, q);
    let mut bytes = [(0u8, 0u8); GPU_WIDE];
    for (slot, b) in bytes.iter_mut().zip(boxes) {
        *slot = {
            let (lo, hi) = (b.0[axis], b.1[axis]);
            // Estimates in f64, then corrected on the exact f32 decode.
            let guess = |v: f32| ((f64::from(v) - f64::from(origin)) * inverse_step).clamp(0.0, 255.0);
            // Truncation is the floor here (the guesses are 0 to 255, or NaN, which gives 0 either way).
            let mut q_lo = guess(lo) as u8;
            while q_lo > 0 && !(value(q_lo) <= lo && usable(value(q_lo))) {
                q_lo -= 1;
            }
            let mut q_hi = {
                let g = guess(hi);
                let below = g as u8;
                if f64::from(below) < g { below + 1 } else { below }
            };
            while q_hi < 255 && !(value(q_hi) >= hi && usable(value(q_hi))) {
                q_hi += 1;
            }
            let fits = value(q_lo) <= lo && usable(value(q_lo)) && value(q_hi) >= hi && usable(value(q_hi));
            fits.then_some((q_lo, q_hi))?
        };
    }
    Some(bytes)
}

/// A node whose slots `0..boxes.len()` hold `boxes` (at most 8, each `(min, max)`), quantized; the other fields
/// are left for the caller. `None` when a coordinate is too large for any grid to enclose with finite values
/// (magnitudes near `f32::MAX`), or for more than 8 boxes.
pub fn quantize_node(boxes: &[Bounds]) -> Option<GpuNode> {
    if boxes.len() > GPU_WIDE {
        return None;
    }
    let mut node = GpuNode::EMPTY;
    for axis in 0..3 {
        let lo = boxes.iter().map(|b| b.0[axis]).fold(f32::INFINITY, f32::min);
        let hi = boxes.iter().map(|b| b.1[axis]).fold(f32::NEG_INFINITY, f32::max);
        let origin = grid_origin(lo);
        // The smallest power-of-two step with 255 steps reaching `hi` (the exact `ceil(log2(extent))`, read
        // from the bits rather than computed by `log2`, so every platform starts alike), then coarser while some
        // bound does not fit.
        let extent = (f64::from(hi) - f64::from(origin)).max(0.0) / 255.0;
        let first = if extent > 0.0 { ceil_log2(extent) + EXPONENT_BIAS } else { 1 };
        let fitted = (first.clamp(1, 254)..=254).find_map(|e| {
            let exponent = e as u8;
            (decode(origin, exponent, 255) >= hi)
                .then(|| quantize_axis(boxes, axis, origin, exponent))
                .flatten()
                .map(|bytes| (exponent, bytes))
        });
        let (exponent, bytes) = fitted?;
        node.origin[axis] = origin;
        node.exponents[axis] = exponent;
        for (slot, (q_lo, q_hi)) in bytes.into_iter().enumerate().take(boxes.len()) {
            node.quantized_min[axis][slot] = q_lo;
            node.quantized_max[axis][slot] = q_hi;
        }
    }
    Some(node)
}

impl GpuNode {
    /// Encodes `boxes` (one per slot: `Some` for an occupied slot) as this node's grid and quantized bytes, as
    /// [`quantize_node`] over the occupied slots in slot order; the children, masks and bases stay. Empty slots
    /// get zero bytes. `false`, with the node unchanged, when a coordinate is too large for a finite grid.
    pub fn encode_slot_boxes(&mut self, boxes: &[Option<Bounds>; GPU_WIDE]) -> bool {
        let mut occupied = [([0.0; 3], [0.0; 3]); GPU_WIDE];
        let mut count = 0;
        for (slot, bounds) in occupied.iter_mut().zip(boxes.iter().flatten()) {
            *slot = *bounds;
            count += 1;
        }
        let Some(quantized) = quantize_node(&occupied[..count]) else { return false };
        self.origin = quantized.origin;
        self.exponents = quantized.exponents;
        self.quantized_min = [[0; GPU_WIDE]; 3];
        self.quantized_max = [[0; GPU_WIDE]; 3];
        for (k, slot) in (0..GPU_WIDE).filter(|&s| boxes[s].is_some()).enumerate() {
            for a in 0..3 {
                self.quantized_min[a][slot] = quantized.quantized_min[a][k];
                self.quantized_max[a][slot] = quantized.quantized_max[a][k];
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ceil_log2_is_exact_at_and_beside_powers_of_two() {
        for e in -1074..=1023 {
            let x = if e < -1022 { f64::from_bits(1 << (e + 1074)) } else { f64::from_bits(((e + 1023) as u64) << 52) };
            assert_eq!(ceil_log2(x), e, "2^{e}");
            if e > -1074 && e < 1023 {
                assert_eq!(ceil_log2(f64::from_bits(x.to_bits() + 1)), e + 1, "just above 2^{e}");
            }
        }
        for x in [3.0, 255.0, 1e-30, 7.5e12, 0.3] {
            assert_eq!(ceil_log2(x), x.log2().ceil() as i32, "{x}");
        }
    }

    fn aabb(min: [f32; 3], max: [f32; 3]) -> Bounds {
        (min, max)
    }

    /// Every decoded box encloses its box, whatever the magnitudes and offsets.
    #[test]
    fn decoded_boxes_enclose_their_boxes() {
        let cases = [
            vec![aabb([0.0; 3], [1.0; 3]), aabb([0.5; 3], [0.75; 3])],
            vec![
                aabb([1000.0, -3.0, 1e-30], [1000.001, -2.9999, 2e-30]),
                aabb([1000.0005, -3.0, 1e-30], [1000.0007, -2.99995, 1.5e-30]),
            ],
            vec![aabb([-1e-40, 0.0, -5.0], [1e-40, 0.0, 5.0])],
            vec![aabb([1e30, -1e30, 0.1], [2e30, 1e30, 0.1])],
        ];
        for boxes in cases {
            let node = quantize_node(&boxes).expect("fits");
            for (slot, b) in boxes.iter().enumerate() {
                let (min, max) = node.slot_box(slot);
                for a in 0..3 {
                    assert!(min[a] <= b.0[a] && max[a] >= b.1[a], "{slot} axis {a}: {min:?}..{max:?} vs {b:?}");
                    assert!(usable(min[a]) && usable(max[a]));
                }
            }
        }
    }

    #[test]
    fn coordinates_near_the_largest_float_are_refused() {
        assert!(quantize_node(&[aabb([0.0; 3], [f32::MAX; 3])]).is_none());
    }
}
