//! One identity per triangle, whatever record of it a hit names: with split references a triangle is stored as
//! several records (`format-spec/bvh-1.md` 5.2), so a hit's `triangle_index` differs between them.
//!
//! * With a `triangle_ids` section the identity is the source id (the same for every reference).
//! * Without ids and without `SPLIT_REFERENCES` every record is its own triangle: the identity is the record's
//!   index.
//! * Without ids, with `SPLIT_REFERENCES`, the references of a triangle are the records with the same nine
//!   coordinates: the identity is the lowest index of such a record, from a table built once (records sorted
//!   by a hash of their coordinates, equal hashes told apart exactly; 12 bytes a record while building, 4 after).
//!   Two source triangles with identical coordinates then share an identity: without ids a file cannot tell
//!   them apart (5.2).

use crate::format::PackedTriangle;
use crate::open::view::BvhView;
use crate::ray::hit::Hit;

impl<'a> BvhView<'a> {
    /// One identity per triangle for hits on any of its records (the source id with ids; with split references
    /// and no ids, the first record with the same coordinates): [`TriangleIdentities`]. O(1) for files with
    /// ids or without split references; otherwise a table built in O(n log n).
    pub fn triangle_identities(&self) -> TriangleIdentities<'a> {
        TriangleIdentities::new(self.triangles(), self.triangle_ids(), self.has_split_references())
    }
}

/// The identity of each record of a file ([`BvhView::triangle_identities`]).
#[derive(Clone, Debug)]
pub struct TriangleIdentities<'a> {
    kind: Kind<'a>,
}

#[derive(Clone, Debug)]
enum Kind<'a> {
    SourceIds(&'a [u32]),
    Records,
    FirstRecord(Vec<u32>),
}

impl<'a> TriangleIdentities<'a> {
    /// The identities of a file's `triangles` with its `triangle_ids` and `SPLIT_REFERENCES` flag.
    pub fn new(
        triangles: &'a [PackedTriangle],
        triangle_ids: Option<&'a [u32]>,
        split_references: bool,
    ) -> TriangleIdentities<'a> {
        let kind = match triangle_ids {
            Some(ids) => Kind::SourceIds(ids),
            None if !split_references => Kind::Records,
            None => Kind::FirstRecord(first_records(triangles)),
        };
        TriangleIdentities { kind }
    }

    /// The identity of record `triangle_index` (the index itself when it is out of range).
    pub fn get(&self, triangle_index: u32) -> u32 {
        let at = triangle_index as usize;
        match &self.kind {
            Kind::SourceIds(ids) => ids.get(at).copied(),
            Kind::Records => None,
            Kind::FirstRecord(first) => first.get(at).copied(),
        }
        .unwrap_or(triangle_index)
    }

    /// The identity of the triangle `hit` met.
    pub fn of(&self, hit: &Hit) -> u32 {
        self.get(hit.triangle_index)
    }
}

/// For each record, the lowest index of a record with the same coordinates.
fn first_records(triangles: &[PackedTriangle]) -> Vec<u32> {
    let bits = |t: u32| triangles[t as usize].coordinate_bits();
    let mut order: Vec<(u64, u32)> = (0..triangles.len() as u32).map(|t| (hash(&bits(t)), t)).collect();
    order.sort_unstable();
    let mut first: Vec<u32> = (0..triangles.len() as u32).collect();
    for run in order.chunk_by(|a, b| a.0 == b.0) {
        // Within a run of equal hashes (almost always one triangle's references), group by exact coordinates;
        // indices ascend within the run, so the first of each group is the lowest.
        let mut pending: Vec<u32> = run.iter().map(|&(_, t)| t).collect();
        while let Some(&lowest) = pending.first() {
            let key = bits(lowest);
            pending.retain(|&t| {
                let same = bits(t) == key;
                if same {
                    first[t as usize] = lowest;
                }
                !same
            });
        }
    }
    first
}

/// A 64-bit hash of a record's coordinate bits (FNV-1a over the words).
fn hash(bits: &[u32; 9]) -> u64 {
    bits.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &w| (h ^ u64::from(w)).wrapping_mul(0x0000_0100_0000_01b3))
}
