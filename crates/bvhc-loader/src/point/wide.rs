//! The point walk of a wide tree: the eight slot boxes of a node measured at once (f32 lanes, against a
//! threshold that covers their rounding: `Space::lane_threshold`), the slots within the cull visited nearest
//! first (each prefetched as it is found within the cull, as the ray walk prefetches: a hint, no effect on
//! answers), the others pushed with their distances and popped only while still within it. Leaves are triangle
//! packets ([`PacketRecords`]). The same bounds as the ray walks: a fixed stack, at most `nodes.len()` node
//! visits, every index checked, so any bytes give an answer, never a panic or a hang.

use crate::format::{EMPTY_SLOT, LEAF_BIT, WIDE};
use crate::point::nearest::Nearest;
use crate::point::records::PacketRecords;
use crate::point::space::{Space, lane_d2};
use crate::simd::{Isa, Kernel};
use crate::walk_stack::WalkStack;
use crate::wide::walk::{STACK_LEN, Sections, prefetch};

/// Walks the wide tree of `sections` (boxes in `space`), offering its packets to `nearest` through `leaves`:
/// compiled for AVX2 as a whole where `leaves` has the token (the same arithmetic, no fused operation, so the
/// same answers as the portable path), else portable.
pub(crate) fn walk_wide_points(
    sections: &Sections<'_>,
    space: &Space,
    nearest: &mut Nearest,
    leaves: &PacketRecords<'_>,
) {
    crate::simd::run(leaves.avx2, PointWalk { sections, space, nearest, leaves });
}

/// [`walk_wide_points`] as a kernel for `crate::simd::run`.
struct PointWalk<'w, 's> {
    sections: &'w Sections<'s>,
    space: &'w Space,
    nearest: &'w mut Nearest,
    leaves: &'w PacketRecords<'s>,
}

impl Kernel for PointWalk<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, _isa: I) {
        walk(self.sections, self.space, self.nearest, self.leaves);
    }
}

#[inline(always)]
fn walk(sections: &Sections<'_>, space: &Space, nearest: &mut Nearest, leaves: &PacketRecords<'_>) {
    if sections.nodes.is_empty() {
        return;
    }
    let mut stack = WalkStack::<(u32, f32), STACK_LEN>::new();
    let mut threshold = space.lane_threshold(nearest.cull_d2);
    let mut current = 0u32;
    let mut visits_left = sections.nodes.len();
    'walk: loop {
        'visit: {
            if current & LEAF_BIT != 0 {
                leaves.test_leaf(current, nearest);
                threshold = space.lane_threshold(nearest.cull_d2);
                break 'visit;
            }
            let Some(node) = sections.nodes.get(current as usize).filter(|_| visits_left > 0) else {
                return; // only on a file that breaks V29-V35
            };
            visits_left -= 1;
            let d2 = lane_d2(node, space.point32);
            // The slots within the cull, nearest first (insertion sort of at most eight).
            let mut order = [(0u32, 0f32); WIDE];
            let mut n = 0;
            for (&child, &d) in node.child.iter().zip(&d2) {
                if child == EMPTY_SLOT || d > threshold {
                    continue;
                }
                prefetch(sections, child);
                let mut at = n;
                while at > 0 && order[at - 1].1 > d {
                    order[at] = order[at - 1];
                    at -= 1;
                }
                order[at] = (child, d);
                n += 1;
            }
            if n == 0 {
                break 'visit;
            }
            for &entry in order[1..n].iter().rev() {
                stack.push(entry);
            }
            current = order[0].0;
            continue 'walk;
        }
        loop {
            let Some((next, d)) = stack.pop() else { return };
            if d <= threshold {
                current = next;
                break;
            }
        }
    }
}
