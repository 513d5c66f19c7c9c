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
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: std::array::from_fn(|a| self.min[a].min(other.min[a])),
            max: std::array::from_fn(|a| self.max[a].max(other.max[a])),
        }
    }

    /// Surface area `2 (x y + y z + z x)` of the extents `x, y, z`, everything in f64: each extent is
    /// `f64(max) - f64(min)` (so boxes near `f32::MAX` give finite areas), clamped below at 0 (the empty box and
    /// points have area 0). This is the area the format spec's cost definition uses.
    pub fn surface_area(&self) -> f64 {
        let e: [f64; 3] = std::array::from_fn(|a| (f64::from(self.max[a]) - f64::from(self.min[a])).max(0.0));
        2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
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
