//! The state of one point query: the query point, the closest candidate so far with its tie key, and the two
//! bounds a walk reads: which squared distances a triangle may have to be taken, and beyond which a box is
//! culled.

use crate::point::{Point3, TrianglePoint};
use crate::ray::query::TieKey;

/// The relative slack of the cull: a box is kept unless its distance exceeds the closest distance so far by more
/// than this fraction of it plus this fraction of the query's far distance (`Nearest::new`). The f64 arithmetic
/// of a triangle and of a box is far more accurate (about `2^-50` of the far distance); the slack only keeps
/// boxes that are almost as far as the answer, so it never changes the answer.
const CULL_SLACK: f64 = 1.0 / 1_048_576.0;

/// The closest candidate so far.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub found: TrianglePoint,
    /// The triangle record (absolute in a two-level file).
    pub record: u32,
    pub instance: Option<u32>,
    /// Its tie key (spec 11.1's key of its record).
    pub key: TieKey,
}

/// One query's state.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Nearest {
    /// The query point, in world space.
    pub point: Point3,
    pub best: Option<Candidate>,
    /// A triangle is a candidate when its squared distance is at most this (the query's distance squared,
    /// then the best's).
    accept_d2: f64,
    /// A box whose world-space squared distance (a lower bound) exceeds this is culled.
    pub cull_d2: f64,
    /// The absolute part of the cull's slack.
    slack: f64,
}

impl Nearest {
    /// The query of `point` within `max_distance` (inclusive; `f32::INFINITY` for no bound), over a scene whose
    /// triangles lie in the box `root` (world space), whose farthest corner sets the slack's scale.
    pub(crate) fn new(point: [f32; 3], max_distance: f32, root: ([f32; 3], [f32; 3])) -> Nearest {
        let point = point.map(f64::from);
        let far2: f64 = (0..3)
            .map(|a| {
                let far = (point[a] - f64::from(root.0[a])).abs().max((f64::from(root.1[a]) - point[a]).abs());
                far * far
            })
            .sum();
        let max = f64::from(max_distance);
        let mut nearest =
            Nearest { point, best: None, accept_d2: max * max, cull_d2: 0.0, slack: CULL_SLACK * far2.sqrt() };
        nearest.cull_d2 = nearest.cull_beyond(max);
        nearest
    }

    /// The squared cull distance for a closest distance `distance`.
    fn cull_beyond(&self, distance: f64) -> f64 {
        let reach = distance * (1.0 + CULL_SLACK) + self.slack;
        if reach.is_nan() { f64::INFINITY } else { reach * reach }
    }

    /// Narrows the query to squared distances at most `d2`, that of a triangle the walk will offer (a bound that
    /// only spares the walk nodes farther than that triangle: the answer is the same, found sooner).
    pub(crate) fn bound_by(&mut self, d2: f64) {
        if d2 < self.accept_d2 {
            self.accept_d2 = d2;
            self.cull_d2 = self.cull_beyond(d2.sqrt());
        }
    }

    /// Whether a triangle at squared distance `d2` may still be taken (before its tie key is read).
    #[inline(always)]
    pub(crate) fn admits(&self, d2: f64) -> bool {
        d2 <= self.accept_d2
    }

    /// Offers a triangle's closest point: taken when it is within the bound and precedes the best (a smaller
    /// squared distance, or the same and a lower `(instance, key)`). `key` is read only on a tie or a take.
    #[inline(always)]
    pub(crate) fn offer(
        &mut self,
        found: TrianglePoint,
        record: u32,
        instance: Option<u32>,
        key: impl FnOnce() -> TieKey,
    ) {
        if !self.admits(found.d2) {
            return;
        }
        let key = key();
        if let Some(best) = &self.best
            && found.d2 == best.found.d2
            && (instance, key) >= (best.instance, best.key)
        {
            return;
        }
        self.best = Some(Candidate { found, record, instance, key });
        self.accept_d2 = found.d2;
        self.cull_d2 = self.cull_beyond(found.d2.sqrt());
    }
}
