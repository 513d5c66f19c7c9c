//! The SBVH's spatial splits: [`BINS`] equal slabs of a node's box along each axis, each reference's piece of
//! its triangle chopped exactly at the slab planes it crosses, and the partition at the best plane, with the
//! paper's reference unsplitting (Stich et al. 2009, sections 4.2-4.3).

use std::borrow::Cow;

use super::sides::{BINS, Split, area_cost, boxes_union, center};
use crate::builders::reference::{Box4, Reference};
use crate::builders::sweep::best_plane as sweep;
use crate::geometry::Aabb;
use crate::geometry::clip::Piece;

/// The spatial plane of lowest binned cost on any axis (every reference that crosses it counted on both
/// sides).
pub(super) fn best_spatial_split(
    references: &[Reference],
    aabb: &Aabb,
    piece_of: &impl Fn(&Reference) -> Option<Piece>,
) -> Option<SpatialPlane> {
    let slabs: [Option<Slabs>; 3] = std::array::from_fn(|axis| Slabs::new(aabb, axis));
    let mut bounds = [[Box4::EMPTY; BINS]; 3];
    let (mut enters, mut exits) = ([[0u32; BINS]; 3], [[0u32; BINS]; 3]);
    for reference in references {
        // Most references lie in one slab an axis; only those that cross a plane are clipped (once, for all
        // the axes on which they cross one).
        let mut piece = None;
        for (axis, slabs) in slabs.iter().enumerate() {
            let Some(slabs) = slabs else { continue };
            let mut add = |bin: usize, aabb: Aabb, enter: bool, exit: bool| {
                bounds[axis][bin] = bounds[axis][bin].union(&Box4::of(&aabb));
                enters[axis][bin] += u32::from(enter);
                exits[axis][bin] += u32::from(exit);
            };
            let first = slabs.slab_from(reference.bounds.min[axis]);
            if first >= slabs.slab_to(reference.bounds.max[axis]) {
                add(first, reference.aabb(), true, true);
            } else {
                let piece = piece.get_or_insert_with(|| piece_of(reference));
                chop(reference, piece.as_ref(), slabs, &mut add);
            }
        }
    }
    let mut best: Option<SpatialPlane> = None;
    for (axis, slabs) in slabs.iter().enumerate() {
        let Some(slabs) = slabs else { continue };
        let ceiling = best.as_ref().map_or(f64::INFINITY, |b| b.cost);
        if let Some(plane) = sweep(&bounds[axis], &enters[axis], &exits[axis], ceiling, area_cost) {
            best = Some(SpatialPlane { axis, position: slabs.planes[plane.bin - 1], cost: plane.cost });
        }
    }
    best
}

/// Sends each reference to the side of `plane` it lies on. One that crosses it is cut in two, or kept whole
/// on one side where the paper's unsplitting test finds that cheaper; at most `extra` are cut, the largest
/// first, and the rest go whole to their cheaper side. Returns the split and its cost (`A_left n_left +
/// A_right n_right` of the sides as they are), `None` when a side ends up empty.
pub(super) fn spatial_partition(
    references: &[Reference],
    plane: &SpatialPlane,
    extra: usize,
    piece_of: &impl Fn(&Reference) -> Option<Piece>,
) -> Option<(Split, f64)> {
    let (axis, position) = (plane.axis, plane.position);
    let (mut left, mut right) = (Vec::new(), Vec::new());
    let mut crossing = Vec::new();
    for r in references {
        if r.bounds.max[axis] <= position {
            left.push(*r);
        } else if r.bounds.min[axis] >= position {
            right.push(*r);
        } else {
            crossing.push(*r);
        }
    }
    let (mut left_box, mut right_box) = (boxes_union(&left), boxes_union(&right));
    let mut cut: Vec<(Reference, Piece, Piece)> = Vec::new();
    for r in crossing {
        match piece_of(&r).map(|p| p.cut(axis, position)) {
            Some((below, above)) if below.corners.len() >= 3 && above.corners.len() >= 3 => {
                left_box = left_box.union(&below.aabb);
                right_box = right_box.union(&above.aabb);
                cut.push((r, below, above));
            }
            // No area on one side (or not to be cut): the reference goes whole to the side of its centre.
            _ => {
                if center(&r, axis) < position {
                    left_box = left_box.union(&r.aabb());
                    left.push(r);
                } else {
                    right_box = right_box.union(&r.aabb());
                    right.push(r);
                }
            }
        }
    }
    // The largest references first (a node holds one reference of a triangle at most, so the order is
    // total), since cutting them removes the most area.
    cut.sort_unstable_by(|(a, ..), (b, ..)| {
        b.aabb().surface_area().total_cmp(&a.aabb().surface_area()).then(a.triangle().cmp(&b.triangle()))
    });
    // Unsplitting (Stich et al., section 4.3): with the sides as they stand, cutting costs
    // A_l n_l + A_r n_r against the whole reference on one side (one fewer on the other).
    let mut added = 0;
    let (n_left, n_right) = (left.len() + cut.len(), right.len() + cut.len());
    let (mut n_left, mut n_right) = (n_left as f64, n_right as f64);
    for (r, below, above) in cut {
        let (a_left, a_right) = (left_box.surface_area(), right_box.surface_area());
        let split_cost = if added < extra { a_left * n_left + a_right * n_right } else { f64::INFINITY };
        let whole_left = left_box.union(&r.aabb()).surface_area() * n_left + a_right * (n_right - 1.0);
        let whole_right = a_left * (n_left - 1.0) + right_box.union(&r.aabb()).surface_area() * n_right;
        if whole_left <= split_cost && whole_left <= whole_right {
            left_box = left_box.union(&r.aabb());
            n_right -= 1.0;
            left.push(r);
        } else if whole_right <= split_cost {
            right_box = right_box.union(&r.aabb());
            n_left -= 1.0;
            right.push(r);
        } else {
            left.push(Reference::new(&below.aabb, r.triangle()));
            right.push(Reference::new(&above.aabb, r.triangle()));
            added += 1;
        }
    }
    if left.is_empty() || right.is_empty() {
        return None;
    }
    let boxes = [boxes_union(&left), boxes_union(&right)];
    let cost = boxes[0].surface_area() * left.len() as f64 + boxes[1].surface_area() * right.len() as f64;
    Some((Split { left, right, boxes, added }, cost))
}

/// The slab planes of a node's box along one axis: `BINS - 1` increasing f32 positions strictly inside it.
struct Slabs {
    axis: usize,
    planes: [f32; BINS - 1],
}

impl Slabs {
    /// `None` where the box is too thin along `axis` for distinct planes strictly inside it.
    fn new(aabb: &Aabb, axis: usize) -> Option<Slabs> {
        let (low, high) = (f64::from(aabb.min[axis]), f64::from(aabb.max[axis]));
        let planes: [f32; BINS - 1] =
            std::array::from_fn(|k| (low + (high - low) * (k + 1) as f64 / BINS as f64) as f32);
        let inside = planes.iter().all(|&p| aabb.min[axis] < p && p < aabb.max[axis]);
        let increasing = planes.windows(2).all(|w| w[0] < w[1]);
        (inside && increasing).then_some(Slabs { axis, planes })
    }

    /// The slab holding coordinate `x` at its low end: planes at or below `x`.
    fn slab_from(&self, x: f32) -> usize {
        self.planes.partition_point(|&p| p <= x)
    }

    /// The slab holding coordinate `x` at its high end: planes below `x`.
    fn slab_to(&self, x: f32) -> usize {
        self.planes.partition_point(|&p| p < x)
    }
}

/// Hands `emit(slab, box, enters, exits)` the box of each slab's part of `reference` (its `piece`, cut exactly
/// at the planes it crosses; a reference without a piece goes whole to the slab of its centre). `enters` is
/// true in the reference's first slab and `exits` in its last.
fn chop(reference: &Reference, piece: Option<&Piece>, slabs: &Slabs, emit: &mut impl FnMut(usize, Aabb, bool, bool)) {
    let axis = slabs.axis;
    let Some(piece) = piece else {
        let slab = slabs.slab_from(center(reference, axis));
        emit(slab, reference.aabb(), true, true);
        return;
    };
    let (first, last) = (slabs.slab_from(piece.aabb.min[axis]), slabs.slab_to(piece.aabb.max[axis]));
    if first >= last {
        emit(first, piece.aabb, true, true);
        return;
    }
    let mut rest = Cow::Borrowed(piece);
    let (mut slab, mut entered) = (first, false);
    for k in first..last {
        let plane = slabs.planes[k];
        if !(rest.aabb.min[axis] < plane && plane < rest.aabb.max[axis]) {
            break;
        }
        let (below, above) = rest.cut(axis, plane);
        if above.corners.len() < 3 {
            rest = Cow::Owned(below);
            break;
        }
        if below.corners.len() >= 3 {
            emit(slab, below.aabb, !entered, false);
            entered = true;
        }
        rest = Cow::Owned(above);
        slab = k + 1;
    }
    emit(slab, rest.aabb, !entered, true);
}

/// A spatial split: references left of `position` along `axis` go left, those right of it right.
pub(super) struct SpatialPlane {
    axis: usize,
    position: f32,
    pub cost: f64,
}
