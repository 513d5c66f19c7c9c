//! The wide layout's refit: each packet lane's vertices copied from the triangle record it names, then every
//! slot's box recomputed bottom up (a leaf slot's from its packets' lanes, an inner slot's from its child's slots),
//! keeping the tree's shape.

use crate::format::{
    Bounds, EMPTY_BOUNDS, EMPTY_SLOT, LEAF_BIT, PACKET_LANES, PackedTriangle, TrianglePacket4, UNUSED_LANE, WIDE,
    WideNode8, union_bounds,
};
use crate::parallel::Workers;

/// Packets, or nodes, a thread takes at least in a parallel pass.
const MIN_CHUNK: usize = 1 << 16;

/// Rewrites `packets`' used lanes from `triangles` (each lane's `triangle_index` record) and every slot box of
/// `nodes` (a verified file's wide tree, children after parents, V29-V30) bottom up, as the converter's packing
/// computes them: the lanes, then the leaf slots, in parallel over chunks, then the inner slots in reverse node
/// order. Indices out of range (a file that does not verify) leave lanes as they are and boxes empty rather than
/// panic.
pub(crate) fn refit_wide(
    nodes: &mut [WideNode8],
    packets: &mut [TrianglePacket4],
    triangles: &[PackedTriangle],
    workers: Workers,
) {
    workers.for_chunks(packets, MIN_CHUNK, |_, chunk| chunk.iter_mut().for_each(|p| write_lanes(p, triangles)));
    let packets: &[TrianglePacket4] = packets;
    workers.for_chunks(nodes, MIN_CHUNK / 4, |_, chunk| {
        for node in chunk {
            for slot in 0..WIDE {
                let child = node.child[slot];
                if child == EMPTY_SLOT || child & LEAF_BIT == 0 {
                    continue;
                }
                let (first, count) = WideNode8::leaf_packets(child);
                let leaf = packets.get(first as usize..(first as usize).saturating_add(count as usize));
                let bounds = leaf.unwrap_or(&[]).iter().fold(EMPTY_BOUNDS, |b, p| union_bounds(b, packet_bounds(p)));
                node.set_slot_box(slot, bounds);
            }
        }
    });
    for i in (0..nodes.len()).rev() {
        for slot in 0..WIDE {
            let child = nodes[i].child[slot];
            if child == EMPTY_SLOT || child & LEAF_BIT != 0 {
                continue;
            }
            let bounds = nodes.get(child as usize).map_or(EMPTY_BOUNDS, node_box);
            nodes[i].set_slot_box(slot, bounds);
        }
    }
}

/// Copies each used lane's vertices from the record it names (a lane naming no record keeps its vertices).
fn write_lanes(packet: &mut TrianglePacket4, triangles: &[PackedTriangle]) {
    for lane in 0..PACKET_LANES {
        let index = packet.triangle_index[lane];
        let Some(triangle) = triangles.get(index as usize).filter(|_| index != UNUSED_LANE) else { continue };
        for (vertex, corner) in triangle.vertices.iter().enumerate() {
            for (axis, &coordinate) in corner.iter().enumerate() {
                packet.vertices[vertex][axis][lane] = coordinate;
            }
        }
    }
}

/// The box of a packet's used lanes: an unused lane holds NaN in every coordinate (`UNUSED_LANE_COORDINATE_BITS`),
/// which the comparisons pass over (`value < bound` is false for a NaN), so all four lanes are folded alike, a
/// compare-and-select a lane (the lanes vectorize).
fn packet_bounds(packet: &TrianglePacket4) -> Bounds {
    type Four = [f32; PACKET_LANES];
    let lower = |a: Four, b: Four| -> Four { std::array::from_fn(|i| if b[i] < a[i] { b[i] } else { a[i] }) };
    let upper = |a: Four, b: Four| -> Four { std::array::from_fn(|i| if b[i] > a[i] { b[i] } else { a[i] }) };
    let [v0, v1, v2] = &packet.vertices;
    let low: [Four; 3] =
        std::array::from_fn(|a| lower(lower([f32::INFINITY; PACKET_LANES], v0[a]), lower(v1[a], v2[a])));
    let high: [Four; 3] =
        std::array::from_fn(|a| upper(upper([f32::NEG_INFINITY; PACKET_LANES], v0[a]), upper(v1[a], v2[a])));
    // Across the lanes: pairs, then the two halves.
    let across = |l: Four, pick: fn(f32, f32) -> f32| pick(pick(l[0], l[2]), pick(l[1], l[3]));
    let min = |a: f32, b: f32| if b < a { b } else { a };
    let max = |a: f32, b: f32| if b > a { b } else { a };
    (low.map(|l| across(l, min)), high.map(|h| across(h, max)))
}

/// A wide node's box: the union of its eight slots' boxes (empty slots hold the empty box `+inf..-inf`, V29, so
/// all eight are folded alike).
pub(crate) fn node_box(node: &WideNode8) -> Bounds {
    let lowest = |axis: &[f32; WIDE]| axis.iter().fold(f32::INFINITY, |m, &v| m.min(v));
    let highest = |axis: &[f32; WIDE]| axis.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
    (node.min.each_ref().map(lowest), node.max.each_ref().map(highest))
}
