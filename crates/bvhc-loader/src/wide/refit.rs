//! The wide layout's refit: each packet lane's vertices copied from the triangle record it names, then every
//! slot's box recomputed bottom up (a leaf slot's from its packets' lanes, an inner slot's from its child's slots),
//! keeping the tree's shape.

use crate::format::{
    Bounds, EMPTY_BOUNDS, LEAF_BIT, PACKET_LANES, PackedTriangle, TrianglePacket4, UNUSED_LANE, WIDE, WideNode8,
    triangle_bounds, union_bounds,
};

/// Rewrites `packets`' used lanes from `triangles` (each lane's `triangle_index` record) and every slot box of
/// `nodes` (a verified file's wide tree, children after parents, V29-V30) bottom up, as the converter's packing
/// computes them. Indices out of range (a file that does not verify) leave lanes as they are and boxes empty
/// rather than panic.
pub(crate) fn refit_wide(nodes: &mut [WideNode8], packets: &mut [TrianglePacket4], triangles: &[PackedTriangle]) {
    for packet in packets.iter_mut() {
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
    let node_box =
        |node: &WideNode8| (0..WIDE).filter_map(|s| node.slot(s)).fold(EMPTY_BOUNDS, |b, (sb, _)| union_bounds(b, sb));
    for i in (0..nodes.len()).rev() {
        for slot in 0..WIDE {
            let Some((_, child)) = nodes[i].slot(slot) else { continue };
            let bounds: Bounds = if child & LEAF_BIT == 0 {
                nodes.get(child as usize).map_or(EMPTY_BOUNDS, node_box)
            } else {
                let (first, count) = WideNode8::leaf_packets(child);
                let leaf = packets.get(first as usize..(first as usize).saturating_add(count as usize)).unwrap_or(&[]);
                leaf.iter()
                    .flat_map(|p| p.triangle_index.iter())
                    .filter(|&&index| index != UNUSED_LANE)
                    .filter_map(|&index| triangles.get(index as usize))
                    .fold(EMPTY_BOUNDS, |b, t| union_bounds(b, triangle_bounds(&t.vertices)))
            };
            nodes[i].set_slot_box(slot, bounds);
        }
    }
}
