//! Rules V29-V35 of `format-spec/bvh-1.md`: the wide BVH of format 1.1 (`wide_nodes` + `triangle_packets`).
//!
//! Together they make the wide tree a second, complete index of the same triangles: a tree of wide nodes
//! (V29, V30) whose leaves partition the packets (V31), with conservative boxes (V32, V35), whose used lanes
//! are exact copies of the triangles section's records (V33), each record in exactly one lane (V34). So a
//! traversal of the wide tree finds exactly the hits of the binary one, and reports them by the triangles
//! section's indices.
//!
//! Passes: in node index order, slots (V29) and then, since children come after parents, parents and depth
//! (V30) and packet ownership (V31); then the packets' lanes (V33, V34); then a pass over every occupied slot for
//! the boxes (V32) and the lanes inside their leaf (V35). Memory: a byte and a depth per wide node, a bit per
//! packet and per triangle (the coverage check of split references sorts one record per lane). No input
//! panics it; every count was bounded at open (V10).

use crate::error::{Rule, Violation, violation};
use crate::format::{
    EMPTY_SLOT, LEAF_BIT, MAX_DEPTH, PACKET_LANES, PackedTriangle, TrianglePacket4, UNUSED_LANE,
    UNUSED_LANE_COORDINATE_BITS, WIDE, WideNode8,
};
use crate::verify::references::{leaf_may_hold, verify_coverage};

/// What a wide tree is checked against: the triangles section and the binary root's box.
pub(crate) struct WideContext<'a> {
    /// The triangles section.
    pub triangles: &'a [PackedTriangle],
    /// The triangle ids, for grouping split references (V35).
    pub triangle_ids: Option<&'a [u32]>,
    /// The binary root's box (`nodes[0]`), the box of wide node 0; `None` for an empty file.
    pub root_box: Option<([f32; 3], [f32; 3])>,
    /// Whether the triangles section has `SPLIT_REFERENCES`.
    pub split_references: bool,
}

/// V29-V35.
pub(crate) fn verify_wide(
    nodes: &[WideNode8],
    packets: &[TrianglePacket4],
    context: &WideContext<'_>,
) -> Result<(), Violation> {
    for (i, node) in nodes.iter().enumerate() {
        check_slots(i, node, nodes.len(), packets.len())?;
    }
    check_shape_and_packets(nodes, packets.len())?;
    check_lanes(packets, context.triangles)?;
    check_boxes_and_leaves(nodes, packets, context)
}

fn slot_box(node: &WideNode8, slot: usize) -> ([f32; 3], [f32; 3]) {
    (std::array::from_fn(|a| node.min[a][slot]), std::array::from_fn(|a| node.max[a][slot]))
}

/// V29 for node `i`.
fn check_slots(i: usize, node: &WideNode8, node_count: usize, packet_count: usize) -> Result<(), Violation> {
    let fail = |slot: usize, why: String| Err(violation(Rule::WideSlots, format!("wide node {i} slot {slot}: {why}")));
    let occupied = node.child.iter().take_while(|&&c| c != EMPTY_SLOT).count();
    for (slot, &child) in node.child.iter().enumerate() {
        if slot >= occupied {
            if child != EMPTY_SLOT {
                return fail(slot, format!("reference {child:#x} after an empty slot (occupied slots come first)"));
            }
            let (min, max) = slot_box(node, slot);
            let empty = min.iter().all(|&v| v.to_bits() == f32::INFINITY.to_bits())
                && max.iter().all(|&v| v.to_bits() == f32::NEG_INFINITY.to_bits());
            if !empty {
                return fail(slot, format!("empty slot with box {min:?}..{max:?}, not +inf..-inf"));
            }
        } else if child & LEAF_BIT != 0 {
            let (first, count) = WideNode8::leaf_packets(child);
            if u64::from(first) + u64::from(count) > packet_count as u64 {
                return fail(
                    slot,
                    format!("leaf packets {first}..{} out of range ({packet_count} packets)", first + count),
                );
            }
        } else if child as usize <= i || child as usize >= node_count {
            return fail(slot, format!("child {child} must come after it and be < wide node count {node_count}"));
        }
    }
    let needed = if i == 0 { 1 } else { 2 };
    if occupied < needed {
        return Err(violation(
            Rule::WideSlots,
            format!("wide node {i}: {occupied} occupied slots, at least {needed} needed"),
        ));
    }
    Ok(())
}

/// V30 (one parent per node but the root, depth) and V31 (each packet in one leaf). Requires V29.
fn check_shape_and_packets(nodes: &[WideNode8], packet_count: usize) -> Result<(), Violation> {
    let mut parents = vec![0u8; nodes.len()];
    let mut depth = vec![0u16; nodes.len()];
    let mut owned = vec![0u64; packet_count.div_ceil(64)];
    for (i, node) in nodes.iter().enumerate() {
        if i > 0 && parents[i] != 1 {
            return Err(violation(Rule::WideTreeShape, format!("wide node {i}: {} parent slots, not 1", parents[i])));
        }
        for (slot, &child) in node.child.iter().enumerate().filter(|(_, c)| **c != EMPTY_SLOT) {
            if child & LEAF_BIT == 0 {
                let c = child as usize;
                parents[c] = parents[c].saturating_add(1);
                depth[c] = depth[i] + 1;
                if usize::from(depth[c]) > MAX_DEPTH {
                    return Err(violation(
                        Rule::WideTreeShape,
                        format!("wide node {c}: depth {} exceeds {MAX_DEPTH}", depth[c]),
                    ));
                }
                continue;
            }
            let (first, count) = WideNode8::leaf_packets(child);
            for p in first as usize..(first + count) as usize {
                let (word, bit) = (p / 64, 1u64 << (p % 64));
                if owned[word] & bit != 0 {
                    return Err(violation(
                        Rule::PacketPartition,
                        format!("packet {p}: in a second leaf (wide node {i} slot {slot})"),
                    ));
                }
                owned[word] |= bit;
            }
        }
    }
    if let Some(p) = (0..packet_count).find(|&p| owned[p / 64] & (1 << (p % 64)) == 0) {
        return Err(violation(Rule::PacketPartition, format!("packet {p}: in no leaf")));
    }
    Ok(())
}

/// V33 (lanes well formed, equal to their triangles) and V34 (every triangle in one lane).
fn check_lanes(packets: &[TrianglePacket4], triangles: &[PackedTriangle]) -> Result<(), Violation> {
    let mut seen = vec![0u64; triangles.len().div_ceil(64)];
    for (p, packet) in packets.iter().enumerate() {
        let used = packet.used_lanes();
        let fail =
            |lane: usize, why: String| Err(violation(Rule::PacketLanes, format!("packet {p} lane {lane}: {why}")));
        if used == 0 {
            return fail(0, "unused: a packet has at least one used lane".to_string());
        }
        for lane in 0..PACKET_LANES {
            let index = packet.triangle_index[lane];
            let coordinates = || packet.vertices.iter().flatten().map(move |axis| axis[lane].to_bits());
            if lane >= used {
                if index != UNUSED_LANE || coordinates().any(|b| b != UNUSED_LANE_COORDINATE_BITS) {
                    return fail(
                        lane,
                        format!(
                            "after an unused lane: index {index:#x} must be 0xffffffff and every coordinate the NaN 0x7fc00000"
                        ),
                    );
                }
                continue;
            }
            let Some(triangle) = triangles.get(index as usize) else {
                return fail(lane, format!("triangle {index} out of range (triangle_count {})", triangles.len()));
            };
            if !triangle.vertices.iter().flatten().map(|c| c.to_bits()).eq(coordinates()) {
                return fail(lane, format!("vertices differ from those of triangle {index}"));
            }
            let (word, bit) = (index as usize / 64, 1u64 << (index % 64));
            if seen[word] & bit != 0 {
                return Err(violation(
                    Rule::LaneCoverage,
                    format!("triangle {index}: in a second lane (packet {p} lane {lane})"),
                ));
            }
            seen[word] |= bit;
        }
    }
    if let Some(t) = (0..triangles.len()).find(|&t| seen[t / 64] & (1 << (t % 64)) == 0) {
        return Err(violation(Rule::LaneCoverage, format!("triangle {t}: in no packet lane")));
    }
    Ok(())
}

/// V32 (slot boxes finite, ordered, inside the parent's box; the root's inside the binary root's) and V35 (lanes
/// inside their leaf's box). Requires V29-V31 and V33.
fn check_boxes_and_leaves(
    nodes: &[WideNode8],
    packets: &[TrianglePacket4],
    context: &WideContext<'_>,
) -> Result<(), Violation> {
    let Some(root_box) = context.root_box else { return Ok(()) };
    // The box each node has in its parent's slot; the root's is the binary root's.
    let mut node_box = vec![root_box; nodes.len()];
    let mut placements = Vec::new();
    for (i, node) in nodes.iter().enumerate() {
        let (parent_min, parent_max) = node_box[i];
        for (slot, &child) in node.child.iter().enumerate().take_while(|(_, c)| **c != EMPTY_SLOT) {
            let (min, max) = slot_box(node, slot);
            let finite = min.iter().chain(&max).all(|v| v.is_finite());
            if !finite || (0..3).any(|a| min[a] > max[a]) {
                return Err(violation(
                    Rule::WideBox,
                    format!("wide node {i} slot {slot}: box {min:?}..{max:?} must be finite with min <= max"),
                ));
            }
            if (0..3).any(|a| min[a] < parent_min[a] || max[a] > parent_max[a]) {
                return Err(violation(
                    Rule::WideBox,
                    format!(
                        "wide node {i} slot {slot}: box {min:?}..{max:?} not inside the node's box \
                         {parent_min:?}..{parent_max:?}"
                    ),
                ));
            }
            if child & LEAF_BIT == 0 {
                node_box[child as usize] = (min, max);
                continue;
            }
            let (first, count) = WideNode8::leaf_packets(child);
            for packet in &packets[first as usize..(first + count) as usize] {
                for lane in 0..packet.used_lanes() {
                    let t = packet.triangle_index[lane];
                    let v = &context.triangles[t as usize].vertices;
                    let inside = leaf_may_hold(&(min, max), v, context.split_references);
                    if !inside {
                        return Err(violation(
                            Rule::LaneInLeaf,
                            format!(
                                "triangle {t}: {v:?} not inside its leaf, wide node {i} slot {slot} box {min:?}..{max:?}"
                            ),
                        ));
                    }
                    if context.split_references {
                        placements.push((t, (i * WIDE + slot) as u32));
                    }
                }
            }
        }
    }
    if context.split_references {
        let box_of = |container: u32| slot_box(&nodes[container as usize / WIDE], container as usize % WIDE);
        verify_coverage(
            &placements,
            box_of,
            context.triangles,
            context.triangle_ids,
            Rule::LaneInLeaf,
            "wide leaf slots (node x 8 + slot)",
        )?;
    }
    Ok(())
}
