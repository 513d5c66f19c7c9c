//! Axis-aligned bounding boxes in f32, computed exactly by min/max over f32 vertices.

/// An axis-aligned box; the empty box has `min = +inf`, `max = -inf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: [f32; 3],
    /// Maximum corner.
    pub max: [f32; 3],
}

impl Aabb {
    /// The empty box, identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb { min: [f32::INFINITY; 3], max: [f32::NEG_INFINITY; 3] };

    /// The box of a triangle.
    pub fn of_triangle(vertices: &[[f32; 3]; 3]) -> Aabb {
        vertices.iter().fold(Aabb::EMPTY, |b, v| b.grow(v))
    }

    /// This box enlarged to contain `point`.
    pub fn grow(self, point: &[f32; 3]) -> Aabb {
        Aabb {
            min: std::array::from_fn(|a| self.min[a].min(point[a])),
            max: std::array::from_fn(|a| self.max[a].max(point[a])),
        }
    }

    /// The smallest box containing both.
    ///
    /// Boxes hold no NaN (the importers reject non-finite coordinates, and the empty box uses infinities), so
    /// the minimum and maximum are plain comparisons: one `minps`/`maxps` instruction each, where `f32::min`
    /// adds a NaN check. This is the innermost operation of the builder's binning and of the optimizer's
    /// searches. (With a NaN operand the result is one of the operands; nothing panics.)
    #[inline(always)]
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: std::array::from_fn(|a| if other.min[a] < self.min[a] { other.min[a] } else { self.min[a] }),
            max: std::array::from_fn(|a| if other.max[a] > self.max[a] { other.max[a] } else { self.max[a] }),
        }
    }

    /// The part of this box inside `clip` (f32 min/max, exact), or [`Aabb::EMPTY`] where they do not overlap.
    pub fn clipped_to(&self, clip: &Aabb) -> Aabb {
        let min: [f32; 3] = std::array::from_fn(|a| self.min[a].max(clip.min[a]));
        let max: [f32; 3] = std::array::from_fn(|a| self.max[a].min(clip.max[a]));
        if (0..3).all(|a| min[a] <= max[a]) { Aabb { min, max } } else { Aabb::EMPTY }
    }

    /// Whether `other` lies inside this box (boundaries included).
    pub fn contains(&self, other: &Aabb) -> bool {
        (0..3).all(|a| self.min[a] <= other.min[a] && other.max[a] <= self.max[a])
    }

    /// Surface area `2 (x y + y z + z x)` of the extents `x, y, z`, everything in f64: each extent is
    /// `f64(max) - f64(min)` (so boxes near `f32::MAX` give finite areas), clamped below at 0 (the empty box and
    /// points have area 0). This is the area the format spec's cost definition uses.
    pub fn surface_area(&self) -> f64 {
        bvhc_loader::format::cost::box_area(&self.min, &self.max)
    }

    /// The center of the box.
    pub fn center(&self) -> [f32; 3] {
        std::array::from_fn(|a| 0.5 * self.min[a] + 0.5 * self.max[a])
    }

    /// The axis along which the box is longest (0 = x).
    pub fn longest_axis(&self) -> usize {
        let e: [f32; 3] = std::array::from_fn(|a| self.max[a] - self.min[a]);
        if e[0] >= e[1] && e[0] >= e[2] {
            0
        } else if e[1] >= e[2] {
            1
        } else {
            2
        }
    }
}
