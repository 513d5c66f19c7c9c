//! Rules V24 and V25 of `format-spec/bvh-1.md`: how triangles may be referenced.
//!
//! V24: without `SPLIT_REFERENCES` every triangle id is distinct (each source triangle stored once). Checked with a
//! bitmap of the ids, or a sorted copy when they are sparse (memory: less than the ids section).
//!
//! V25: with `SPLIT_REFERENCES`, the *references* of a triangle (the records with the same id, when ids are
//! stored, and the same vertices) lie in leaves whose boxes together cover every point of the triangle. This is
//! what makes traversal exact with split references: a ray that meets the triangle meets it inside one of those
//! boxes, which the conservative box test never rejects. Checked by subtracting the leaf boxes from the triangle
//! (convex polygons clipped by the boxes' planes in f64): what is left must be negligible, its area at most
//! `2^-40` of the triangle's, a margin far above f64 rounding of the clip points and far below any gap a ray
//! could pass (a zero-area triangle must have each vertex in one of the boxes).

use crate::error::{Rule, Violation, violation};
use crate::format::{PackedNode, PackedTriangle};

/// The leftover area, relative to the triangle's, under which a triangle counts as covered.
const COVERAGE_TOLERANCE: f64 = 1.0 / (1u64 << 40) as f64;

/// V24 and V25 over a file's nodes, triangles and triangle ids: distinct records without split references,
/// every triangle covered by its records' leaves with them.
pub(crate) fn verify_references(
    nodes: &[PackedNode],
    triangles: &[PackedTriangle],
    triangle_ids: Option<&[u32]>,
    split_references: bool,
) -> Result<(), Violation> {
    if split_references {
        verify_split_coverage(nodes, triangles, triangle_ids)
    } else {
        verify_distinct_ids(triangle_ids.unwrap_or(&[]))
    }
}

/// V24. With a bitmap over `0..=max id` when it is no larger than the ids themselves (always so for files whose
/// ids number the scene's triangles), else on a sorted copy; either way memory stays below the section's size.
fn verify_distinct_ids(ids: &[u32]) -> Result<(), Violation> {
    let Some(&max_id) = ids.iter().max() else { return Ok(()) };
    let words = (max_id as usize + 1).div_ceil(64);
    if words * 8 <= ids.len() * 4 {
        let mut seen = vec![0u64; words];
        for (t, &id) in ids.iter().enumerate() {
            let (word, bit) = (id as usize / 64, 1u64 << (id % 64));
            if seen[word] & bit != 0 {
                let first = ids.iter().position(|&other| other == id).unwrap_or(t);
                return Err(repeated(first as u32, t as u32, id));
            }
            seen[word] |= bit;
        }
        return Ok(());
    }
    let mut sorted: Vec<(u32, u32)> = ids.iter().enumerate().map(|(t, &id)| (id, t as u32)).collect();
    sorted.sort_unstable();
    match sorted.windows(2).find(|w| w[0].0 == w[1].0) {
        Some(w) => Err(repeated(w[0].1, w[1].1, w[0].0)),
        None => Ok(()),
    }
}

fn repeated(first: u32, second: u32, id: u32) -> Violation {
    violation(
        Rule::RepeatedId,
        format!("triangles {first} and {second}: both have id {id} but SPLIT_REFERENCES is not set"),
    )
}

/// V25. Nodes and triangles already passed V14-V19, so every leaf range is in bounds.
fn verify_split_coverage(
    nodes: &[PackedNode],
    triangles: &[PackedTriangle],
    ids: Option<&[u32]>,
) -> Result<(), Violation> {
    let placements: Vec<(u32, u32)> = nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.is_leaf())
        .flat_map(|(leaf, node)| (node.index..node.index + node.count).map(move |t| (t, leaf as u32)))
        .collect();
    let box_of = |leaf: u32| (nodes[leaf as usize].min, nodes[leaf as usize].max);
    verify_coverage(&placements, box_of, triangles, ids, Rule::SplitCoverage, "leaves")
}

/// Whether the boxes that hold the references of each triangle (the records with the same id, with ids, and
/// the same vertices) cover it; `rule` names the failure. `placements` are (record, container) pairs: the
/// record's index in the triangles section (in bounds) and the binary leaf (V25) or the wide slot as `node * 8
/// + slot` (V35) whose box, `box_of(container)`, holds it.
///
/// A triangle whose every record lies in a box holding all of it is covered; only the others are grouped (by
/// sorting on the id and a 32-bit hash of the vertices' bits, then exactly on the vertices within each run of
/// equal hashes), with every record of theirs. Memory: the keys of those triangles, and 16 bytes a record of
/// theirs.
pub(crate) fn verify_coverage(
    placements: &[(u32, u32)],
    box_of: impl Fn(u32) -> ([f32; 3], [f32; 3]),
    triangles: &[PackedTriangle],
    ids: Option<&[u32]>,
    rule: Rule,
    containers: &str,
) -> Result<(), Violation> {
    let bits = |t: u32| triangles[t as usize].coordinate_bits();
    let key = |t: u32| (ids.map_or(0, |ids| ids[t as usize]), hash(&bits(t)));
    let held_whole = |t: u32, container: u32| holds_triangle(&box_of(container), &triangles[t as usize].vertices);
    let mut partly_held: Vec<(u32, u32)> =
        placements.iter().filter(|&&(t, c)| !held_whole(t, c)).map(|&(t, _)| key(t)).collect();
    partly_held.sort_unstable();
    partly_held.dedup();
    let mut references: Vec<(u32, u32, u32, u32)> = placements
        .iter()
        .filter_map(|&(t, container)| {
            let (id, hash) = key(t);
            partly_held.binary_search(&(id, hash)).is_ok().then_some((id, hash, t, container))
        })
        .collect();
    references.sort_unstable();
    for run in references.chunk_by_mut(|a, b| a.0 == b.0 && a.1 == b.1) {
        run.sort_by_key(|r| (bits(r.2), r.2, r.3));
        for group in run.chunk_by(|a, b| bits(a.2) == bits(b.2)) {
            let t = group[0].2 as usize;
            let boxes: Vec<([f32; 3], [f32; 3])> = group.iter().map(|r| box_of(r.3)).collect();
            if !is_covered(&triangles[t].vertices, &boxes) {
                let held_by: Vec<u32> = group.iter().map(|r| r.3).collect();
                return Err(violation(
                    rule,
                    format!("triangle {t}: the boxes of its {containers} {held_by:?} do not cover all of it"),
                ));
            }
        }
    }
    Ok(())
}

/// A 32-bit hash of a triangle's vertex bits (FNV-1a over the words), for grouping; equal hashes are then
/// told apart exactly.
fn hash(bits: &[u32; 9]) -> u32 {
    bits.iter().fold(0x811c_9dc5u32, |h, &w| (h ^ w).wrapping_mul(0x0100_0193))
}

/// Whether the box holds the point (boundaries included).
fn holds_point((min, max): &([f32; 3], [f32; 3]), v: &[f32; 3]) -> bool {
    (0..3).all(|a| min[a] <= v[a] && v[a] <= max[a])
}

/// Whether a leaf's box may hold the triangle (V19, V35, V50): all of it, or with split references (where a
/// reference is clipped to its leaf) overlapping it.
pub(crate) fn leaf_may_hold(aabb: &([f32; 3], [f32; 3]), vertices: &[[f32; 3]; 3], split_references: bool) -> bool {
    if !split_references {
        return holds_triangle(aabb, vertices);
    }
    let (min, max) = aabb;
    let v = vertices;
    (0..3).all(|a| v[0][a].min(v[1][a]).min(v[2][a]) <= max[a] && v[0][a].max(v[1][a]).max(v[2][a]) >= min[a])
}

/// Whether the box holds the triangle: its three corners, and so (being convex) all of it.
fn holds_triangle(aabb: &([f32; 3], [f32; 3]), vertices: &[[f32; 3]; 3]) -> bool {
    vertices.iter().all(|v| holds_point(aabb, v))
}

type Point = [f64; 3];

/// Whether the boxes cover the triangle (see the module doc for the tolerance).
fn is_covered(vertices: &[[f32; 3]; 3], boxes: &[([f32; 3], [f32; 3])]) -> bool {
    // Most references are whole triangles: a box that holds one spares the clipping.
    if boxes.iter().any(|b| holds_triangle(b, vertices)) {
        return true;
    }
    let triangle: Vec<Point> = vertices.iter().map(|v| v.map(f64::from)).collect();
    let area = polygon_area(&triangle);
    if area == 0.0 {
        return vertices.iter().all(|v| boxes.iter().any(|b| holds_point(b, v)));
    }
    let mut pieces = vec![triangle];
    for b in boxes {
        let mut outside = Vec::new();
        for piece in pieces {
            subtract_box(piece, b, &mut outside);
        }
        outside.retain(|p| polygon_area(p) > 0.0);
        pieces = outside;
    }
    pieces.iter().map(|p| polygon_area(p)).sum::<f64>() <= COVERAGE_TOLERANCE * area
}

/// Appends the parts of convex `piece` outside box `b` (at most six convex polygons).
fn subtract_box(mut piece: Vec<Point>, (min, max): &([f32; 3], [f32; 3]), outside: &mut Vec<Vec<Point>>) {
    for a in 0..3 {
        for (plane, keep_below) in [(f64::from(min[a]), false), (f64::from(max[a]), true)] {
            let (inside, out) = split(&piece, a, plane, keep_below);
            if out.len() >= 3 {
                outside.push(out);
            }
            if inside.len() < 3 {
                return;
            }
            piece = inside;
        }
    }
}

/// Splits a convex polygon by the plane `x[a] = plane` into the part on the box's side (`x[a] <= plane` when
/// `keep_below`, else `x[a] >= plane`) and the rest (Sutherland-Hodgman).
fn split(polygon: &[Point], a: usize, plane: f64, keep_below: bool) -> (Vec<Point>, Vec<Point>) {
    let side = |p: &Point| if keep_below { plane - p[a] } else { p[a] - plane };
    let (mut inside, mut outside) = (Vec::new(), Vec::new());
    for (i, p) in polygon.iter().enumerate() {
        let q = &polygon[(i + 1) % polygon.len()];
        let (sp, sq) = (side(p), side(q));
        if sp >= 0.0 {
            inside.push(*p);
        } else {
            outside.push(*p);
        }
        if (sp >= 0.0) != (sq >= 0.0) && sp != sq {
            let f = sp / (sp - sq);
            let mut x: Point = std::array::from_fn(|k| p[k] + f * (q[k] - p[k]));
            x[a] = plane;
            inside.push(x);
            outside.push(x);
        }
    }
    (inside, outside)
}

/// Area of a planar polygon (half the length of its Newell normal).
fn polygon_area(polygon: &[Point]) -> f64 {
    let mut normal = [0.0f64; 3];
    for (i, p) in polygon.iter().enumerate() {
        let q = &polygon[(i + 1) % polygon.len()];
        normal[0] += (p[1] - q[1]) * (p[2] + q[2]);
        normal[1] += (p[2] - q[2]) * (p[0] + q[0]);
        normal[2] += (p[0] - q[0]) * (p[1] + q[1]);
    }
    0.5 * (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt()
}
