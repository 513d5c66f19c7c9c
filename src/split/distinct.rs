//! Distinct triangle counts of subtrees over split references, for the bottom-up dynamic programs that choose
//! leaves (the leaf merging and the wide collapse): a leaf holds each triangle once (see [`super::records`]), so
//! it is priced by how many distinct triangles its subtree references. Only counts up to the leaf limit matter,
//! so each pending subtree keeps its distinct triangles while they fit in a leaf, and "too many" otherwise.

/// The distinct triangles (sorted) of each pending subtree that can still become one leaf, concatenated in the
/// order of the pending stack; a subtree with too many holds none here.
#[derive(Default)]
pub(crate) struct HeldTriangles {
    ids: Vec<u32>,
    union: Vec<u32>,
}

impl HeldTriangles {
    pub(crate) fn push_leaf(&mut self, triangle: u32) {
        self.ids.push(triangle);
    }

    /// Replaces the top two subtrees' lists (the left child's on top, `left` and `right` their distinct counts)
    /// by their union's, and returns its size, or `too_many` (holding nothing) when that reaches it.
    pub(crate) fn join(&mut self, left: u32, right: u32, too_many: u32) -> u32 {
        let listed = |count: u32| if count < too_many { count as usize } else { 0 };
        let end = self.ids.len();
        let (left_start, right_start) = (end - listed(left), end - listed(left) - listed(right));
        if left >= too_many || right >= too_many {
            self.ids.truncate(right_start);
            return too_many;
        }
        self.union.clear();
        let (mut a, mut b) = (right_start, left_start);
        while a < left_start || b < end {
            let next = match (self.ids.get(a).filter(|_| a < left_start), self.ids.get(b).filter(|_| b < end)) {
                (Some(&x), Some(&y)) if x == y => {
                    a += 1;
                    b += 1;
                    x
                }
                (Some(&x), Some(&y)) if x < y => {
                    a += 1;
                    x
                }
                (_, Some(&y)) => {
                    b += 1;
                    y
                }
                (Some(&x), None) => {
                    a += 1;
                    x
                }
                (None, None) => unreachable!("the loop runs while either list has entries"),
            };
            self.union.push(next);
        }
        self.ids.truncate(right_start);
        if self.union.len() >= too_many as usize {
            return too_many;
        }
        self.ids.extend_from_slice(&self.union);
        self.union.len() as u32
    }
}
