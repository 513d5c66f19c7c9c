//! What a walk looks for along a ray (`format-spec/bvh-1.md` 11.1): the query is a type parameter of every walk
//! (binary, wide, coherent packets, the GPU model), so each query is its own monomorphized kernel and nothing on
//! the walk asks at run time which one it runs.
//!
//! Both queries bound the walk by the closest hit taken so far: a hit shrinks `t_max` to its `t`, and boxes
//! entered beyond it (padded, 11.2) are culled. They differ in whether the first hit taken ends the walk. The
//! closest hit is the first in `(t, key)` order ([`precedes`]), the key being the triangle record, or with
//! split references its coordinates and source id ([`TieKey`]; in a two-level file the instance first): wherever two hits
//! meet (lanes of a packet, packets of a leaf, leaves, instances, the rays of a coherent packet), the walks keep
//! the one that precedes, so the order in which they meet never decides a tie (spec 11.1, revision 1.5.2). A query
//! that bounds by another measure (the closest point to a position: the distance to a box instead of the slab
//! test) would bring its own node and leaf tests as well.

/// A query of the walks: [`ClosestHit`] or [`AnyHit`].
pub(crate) trait Query {
    /// Whether the first hit taken ends the walk (an any-hit query needs no order among hits, so its walks skip
    /// the ordering of children and, in a packet of four triangles, the search for the nearest lane).
    const FIRST_HIT_ENDS: bool;
}

/// The closest hit: the walk goes on until no box nearer than the closest hit so far is left.
pub(crate) enum ClosestHit {}

/// Any hit (occlusion): the first hit found ends the walk.
pub(crate) enum AnyHit {}

impl Query for ClosestHit {
    const FIRST_HIT_ENDS: bool = false;
}

impl Query for AnyHit {
    const FIRST_HIT_ENDS: bool = true;
}

/// Whether a hit at `t` with tie key `key` precedes the closest hit so far, at `best_t` with key `best_key`: a
/// smaller `t`, or the same `t` and a lower key (spec 11.1: the lowest [`TieKey`] among the hits at the smallest
/// `t`; in a two-level file the lowest instance first). `keys` gives
/// `(key, best_key)` and is called only on a tie, so a walk pays for the keys' loads only there.
#[inline(always)]
pub(crate) fn precedes<K: Ord>(t: f32, best_t: f32, keys: impl FnOnce() -> (K, K)) -> bool {
    t < best_t
        || (t == best_t && {
            let (key, best_key) = keys();
            key < best_key
        })
}

/// A hit's place among the hits at one `t` (spec 11.1): in a file without `SPLIT_REFERENCES` its record index;
/// with them, its record's nine coordinates as bit patterns (`v0.x, v0.y, ..., v2.z`, compared as unsigned
/// integers in that order) and then its source id (0 for every record of a file without `triangle_ids`), since a
/// triangle's records are then interchangeable (5.2) and a walk may meet any of them, while two different
/// triangles at the same coordinates (a face modelled twice) are told apart by their ids. A file's keys are all of
/// one kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum TieKey {
    Record(u32),
    Coordinates([u32; 9], u32),
}

/// Which [`TieKey`] a tree's hits take: the triangles section's `SPLIT_REFERENCES` flag and, with it, the
/// records' source ids (the tree's range of the `triangle_ids` section, indexed by record).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TieOrder<'a> {
    split_references: bool,
    ids: Option<&'a [u32]>,
}

impl<'a> TieOrder<'a> {
    /// The order of a file with `SPLIT_REFERENCES` set or not, whose records have source ids `ids`.
    pub(crate) fn new(split_references: bool, ids: Option<&'a [u32]>) -> Self {
        TieOrder { split_references, ids: ids.filter(|_| split_references) }
    }

    /// Whether hits at one `t` are ordered by coordinates (the file has `SPLIT_REFERENCES`).
    pub(crate) fn by_coordinates(&self) -> bool {
        self.split_references
    }

    /// The key of `record`, whose coordinate bits `coordinates` gives (called only with split references). A
    /// record past the ids (which a verified file does not have) takes the last id, `u32::MAX`.
    #[inline]
    pub(crate) fn key(&self, record: u32, coordinates: impl FnOnce() -> [u32; 9]) -> TieKey {
        if !self.split_references {
            return TieKey::Record(record);
        }
        let id = self.ids.map_or(0, |ids| ids.get(record as usize).copied().unwrap_or(u32::MAX));
        TieKey::Coordinates(coordinates(), id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coordinates_rank_before_ids_and_ids_only_with_split_references() {
        let ids = [7, 3];
        let split = TieOrder::new(true, Some(&ids));
        let same = || [1; 9];
        assert!(split.key(1, same) < split.key(0, same), "equal coordinates: the lower id first");
        assert!(split.key(0, || [0; 9]) < split.key(1, same), "coordinates decide before ids");
        let records = TieOrder::new(false, Some(&ids));
        assert!(records.key(0, same) < records.key(1, same), "without split references the record decides");
        let no_ids = TieOrder::new(true, None);
        assert_eq!(no_ids.key(0, same), no_ids.key(1, same), "without ids equal coordinates are one key");
    }
}
