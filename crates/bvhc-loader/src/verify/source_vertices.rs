//! Rule V40 of `format-spec/bvh-1.md` (since 1.2): the `source_vertices` section agrees with the vertices it
//! indexes. A source vertex is one point of its primitive, so wherever records of one source range name the
//! same index, at any corner, that corner's coordinates are the same bits (the writer placed the vertex once);
//! and the references of one triangle (records with the same source id) name the same three vertices in the same
//! order. The indices themselves point into the source scene, which the file does not hold, so this is what a
//! reader can check: a writer that mixed up corners, primitives or the mirrored order breaks it.
//!
//! Cost: O(n) for `n` records with a table of the first corner that names each (range, index) and of the first
//! record of each id, where the indices and ids are dense (each range's indices span at most as many slots in
//! all as there are corners, 8 bytes each, as real scenes have); otherwise the corners are sorted, O(n log n)
//! and 16 bytes a corner.

use crate::error::{Rule, Violation, violation};
use crate::format::{PackedTriangle, SourceRange, SourceVertexIndices};

/// No corner or record seen yet in a table slot.
const NONE: u64 = u64::MAX;

/// V40 for a file's triangles, ids, source table and source vertices (V10 made their lengths agree, V22 put
/// every id in a range); `split_references` as the triangles section's flag (without it ids are distinct, V24).
pub(crate) fn verify_source_vertices(
    triangles: &[PackedTriangle],
    ids: &[u32],
    table: &[SourceRange],
    source_vertices: &[SourceVertexIndices],
    split_references: bool,
) -> Result<(), Violation> {
    if split_references {
        check_references_agree(ids, source_vertices)?;
    }
    let range_of: Vec<usize> =
        ids.iter().map(|&id| table.partition_point(|r| r.first_source_triangle <= id).saturating_sub(1)).collect();
    // Table slot of (range, index): the range's offset plus the index's distance from the range's lowest index,
    // when the ranges' index spans together are no longer than the corners (an OBJ model's `v` records are
    // numbered over the whole file, but lie close together).
    let mut span = vec![(u32::MAX, 0u32); table.len()];
    for (vertices, &range) in source_vertices.iter().zip(&range_of) {
        for &index in &vertices.indices {
            span[range] = (span[range].0.min(index), span[range].1.max(index));
        }
    }
    let mut offsets = Vec::with_capacity(table.len());
    let mut total = 0u64;
    for &(low, high) in &span {
        offsets.push(total.wrapping_sub(u64::from(low.min(high))));
        total += if low <= high { u64::from(high - low) + 1 } else { 0 };
    }
    let corner_count = 3 * source_vertices.len() as u64;
    let point = |corner: u64| triangles.get((corner / 3) as usize).map(|t| t.vertices[(corner % 3) as usize]);
    let differ = |a: u64, b: u64| point(a).map(bits) != point(b).map(bits);
    let mismatch = |range: usize, index: u32, first: u64, other: u64| {
        let (a, b) = (point(first).unwrap_or_default(), point(other).unwrap_or_default());
        violation(
            Rule::SourceVertices,
            format!(
                "triangle {} v{} and triangle {} v{} name source vertex {index} of source range {range}, but are \
                 different points ({a:?} and {b:?})",
                first / 3,
                first % 3,
                other / 3,
                other % 3
            ),
        )
    };
    if total <= corner_count.max(1024) {
        let mut first_corner = vec![NONE; total as usize];
        for (record, (vertices, &range)) in source_vertices.iter().zip(&range_of).enumerate() {
            for (corner, &index) in vertices.indices.iter().enumerate() {
                let at = 3 * record as u64 + corner as u64;
                let slot = &mut first_corner[offsets[range].wrapping_add(u64::from(index)) as usize];
                if *slot == NONE {
                    *slot = at;
                } else if differ(*slot, at) {
                    return Err(mismatch(range, index, *slot, at));
                }
            }
        }
        return Ok(());
    }
    // Sparse indices: sort the corners by (range, index) and compare each run with its first corner.
    let mut corners: Vec<(u64, u64)> = Vec::with_capacity(corner_count as usize);
    for (record, (vertices, &range)) in source_vertices.iter().zip(&range_of).enumerate() {
        for (corner, &index) in vertices.indices.iter().enumerate() {
            corners.push(((range as u64) << 32 | u64::from(index), 3 * record as u64 + corner as u64));
        }
    }
    corners.sort_unstable();
    for run in corners.chunk_by(|a, b| a.0 == b.0) {
        let (key, first) = run[0];
        if let Some(&(_, other)) = run.iter().find(|&&(_, at)| differ(first, at)) {
            return Err(mismatch((key >> 32) as usize, key as u32, first, other));
        }
    }
    Ok(())
}

/// Records with the same source id (a split triangle's references) name the same vertices in the same order.
fn check_references_agree(ids: &[u32], source_vertices: &[SourceVertexIndices]) -> Result<(), Violation> {
    let disagree = |a: usize, b: usize| {
        let (first, second) = (source_vertices[a].indices, source_vertices[b].indices);
        (first != second).then(|| {
            violation(
                Rule::SourceVertices,
                format!(
                    "triangles {a} and {b} are references of source triangle {} but name different source \
                     vertices ({first:?} and {second:?})",
                    ids[a]
                ),
            )
        })
    };
    let top = ids.iter().map(|&id| u64::from(id) + 1).max().unwrap_or(0);
    if top <= (2 * ids.len() as u64).max(1024) {
        let mut first_record = vec![NONE; top as usize];
        for (record, &id) in ids.iter().enumerate() {
            let slot = &mut first_record[id as usize];
            if *slot == NONE {
                *slot = record as u64;
            } else if let Some(error) = disagree(*slot as usize, record) {
                return Err(error);
            }
        }
        return Ok(());
    }
    let mut by_id: Vec<(u32, u32)> = ids.iter().enumerate().map(|(record, &id)| (id, record as u32)).collect();
    by_id.sort_unstable();
    for run in by_id.chunk_by(|a, b| a.0 == b.0) {
        if let Some(error) = run.iter().find_map(|&(_, record)| disagree(run[0].1 as usize, record as usize)) {
            return Err(error);
        }
    }
    Ok(())
}

/// A point's coordinate bits (so -0 and +0, and NaNs, compare as stored).
fn bits(point: [f32; 3]) -> [u32; 3] {
    point.map(f32::to_bits)
}
