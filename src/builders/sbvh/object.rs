//! The SBVH's object splits: the binned SAH split of a node's references by their centroids (Wald 2007, the
//! sweep of [`crate::builders::sweep`]), priced in f64 surface areas, and the median split where binning cannot
//! separate them.

use super::sides::{BINS, Split, area_cost, boxes_union};
use crate::builders::reference::{Box4, Reference, median, union_of};
use crate::builders::sweep::best_plane as sweep;
use crate::geometry::Aabb;

/// An object split: references whose (doubled) centroid lies in a bin below `bin` go left.
#[derive(Clone, Copy)]
pub(super) struct ObjectSplit {
    axis: usize,
    low: f32,
    scale: f32,
    /// The number of bins used.
    bins: usize,
    bin: usize,
    /// References that go left.
    pub left_count: usize,
    /// The union of the boxes of the references that go left, then right (from the bins, exact).
    pub boxes: [Aabb; 2],
    pub cost: f64,
    /// Surface area of the intersection of the two children's boxes.
    pub overlap: f64,
}

impl ObjectSplit {
    /// The bin of doubled centroid coordinate `c` (`min + max`: the binned builder's, and the same bins as the
    /// centroid itself, since doubling is exact).
    fn bin_of(&self, c: f32) -> usize {
        (((c - self.low) * self.scale) as usize).min(self.bins - 1)
    }

    pub(super) fn goes_left(&self, r: &Reference) -> bool {
        self.bin_of(r.centroid2()[self.axis]) < self.bin
    }
}

/// The binned SAH object split of lowest `A_left n_left + A_right n_right`; `None` where no axis has spread
/// centroids. Nodes of at most 2, 4 or 8 references use that many bins (as the binned builder does): most nodes
/// are small, and sweeping 16 bins on three axes for two references made the SBVH build twice as slow.
pub(super) fn best_object_split(references: &[Reference]) -> Option<ObjectSplit> {
    match references.len() {
        0..=2 => best_object_split_in::<2>(references),
        3..=4 => best_object_split_in::<4>(references),
        5..=8 => best_object_split_in::<8>(references),
        _ => best_object_split_in::<BINS>(references),
    }
}

/// [`best_object_split`] with `B` bins an axis.
fn best_object_split_in<const B: usize>(references: &[Reference]) -> Option<ObjectSplit> {
    let centroids = union_of(references, Reference::centroid_box);
    let splits: [Option<ObjectSplit>; 3] = std::array::from_fn(|axis| {
        let (low, high) = (centroids.min[axis], centroids.max[axis]);
        let scale = B as f32 / (high - low);
        (high > low && scale.is_finite()).then_some(ObjectSplit {
            axis,
            low,
            scale,
            bins: B,
            bin: 0,
            left_count: 0,
            boxes: [Aabb::EMPTY; 2],
            cost: f64::INFINITY,
            overlap: 0.0,
        })
    });
    // One pass bins all three axes.
    let (mut bounds, mut counts) = ([[Box4::EMPTY; B]; 3], [[0u32; B]; 3]);
    for r in references {
        for (axis, split) in splits.iter().enumerate() {
            if let Some(split) = split {
                let b = split.bin_of(r.centroid2()[axis]);
                bounds[axis][b] = bounds[axis][b].union(&r.bounds);
                counts[axis][b] += 1;
            }
        }
    }
    let mut best: Option<ObjectSplit> = None;
    for (axis, split) in splits.into_iter().enumerate() {
        let Some(split) = split else { continue };
        let ceiling = best.as_ref().map_or(f64::INFINITY, |b| b.cost);
        if let Some(plane) = sweep(&bounds[axis], &counts[axis], &counts[axis], ceiling, area_cost) {
            let boxes = [plane.left.to_aabb(), plane.right.to_aabb()];
            let left_count = plane.left_count as usize;
            best = Some(ObjectSplit { bin: plane.bin, left_count, boxes, cost: plane.cost, ..split });
        }
    }
    best.map(|mut split| {
        split.overlap = intersection(&split.boxes[0], &split.boxes[1]).surface_area();
        split
    })
}

/// The intersection of two boxes (empty, with zero area, when they are apart).
fn intersection(a: &Aabb, b: &Aabb) -> Aabb {
    Aabb { min: std::array::from_fn(|i| a.min[i].max(b.min[i])), max: std::array::from_fn(|i| a.max[i].min(b.max[i])) }
}

/// Splits at the median reference by centroid along the longest axis of the node's centroids (ties by
/// triangle: a node holds at most one reference of a triangle, so the order is total and the split
/// deterministic).
pub(super) fn median_split(mut references: Vec<Reference>) -> Split {
    let axis = union_of(&references, Reference::centroid_box).to_aabb().longest_axis();
    let mid = median(&mut references, axis);
    let right = references.split_off(mid);
    Split { boxes: [boxes_union(&references), boxes_union(&right)], left: references, right, added: 0 }
}
