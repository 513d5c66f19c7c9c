//! A [`WideTree`] of width 8 in the loader's 8-wide layout ([`WideNode8`] and [`TrianglePacket4`]), as the
//! `wide_nodes` and `triangle_packets` sections store it: each leaf's triangles are laid out in packets of
//! four, the last one padded with unused lanes, and each lane holds the triangle's index in the file's
//! triangles section.

use bvhc_loader::{
    Error, format::PACKET_LANES, format::PackedTriangle, format::TrianglePacket4, format::WIDE, format::WideNode8,
    wide::WideBvh,
};

use crate::layout::{WideChild, WideTree};

/// Packs `tree` (width at most 8, leaves of at most 32 triangles) into a checked [`WideBvh`] over
/// `file_triangles`, the triangles section. The tree numbers triangles by their index in the soup it was built
/// over; `record_of(soup index)` gives the index in `file_triangles` of the record for the next lane that holds
/// that triangle (see [`super::PackedTree::record_cursor`]), `None` when there is none.
///
/// Fails with [`Error::Unwritable`] when the tree does not fit the layout (too wide, a leaf of more than 32
/// triangles, more than 2^28 packets) and with [`Error::Invalid`] when the result breaks a rule of V29-V35.
///
/// With `split_references` a triangle may be stored in several records (its leaves then repeat it, once a
/// record), and the check is V35's split-reference clause.
pub fn pack_wide(
    tree: &WideTree,
    file_triangles: &[PackedTriangle],
    record_of: &mut dyn FnMut(u32) -> Option<u32>,
    split_references: bool,
) -> Result<WideBvh, Error> {
    let unwritable = |why: String| Error::Unwritable(format!("wide sections: {why}"));
    if tree.width > WIDE {
        return Err(unwritable(format!("width {} is more than the layout's {WIDE}", tree.width)));
    }
    let mut nodes = crate::fallible::vec_with_capacity(tree.nodes.len(), "the wide nodes")?;
    // Exactly the packets the leaves need (a guess would let the vector double, up to twice the memory).
    let packet_count: usize = tree
        .nodes
        .iter()
        .flat_map(|node| &node.children)
        .map(|(_, child)| match *child {
            WideChild::Leaf { count, .. } => (count as usize).div_ceil(PACKET_LANES),
            WideChild::Node(_) => 0,
        })
        .sum();
    let mut packets = crate::fallible::vec_with_capacity(packet_count, "the triangle packets")?;
    let mut lanes = Vec::with_capacity(PACKET_LANES);
    for (i, node) in tree.nodes.iter().enumerate() {
        let mut packed = WideNode8::EMPTY;
        for (slot, (aabb, child)) in node.children.iter().enumerate() {
            let child = match *child {
                WideChild::Node(c) => c,
                WideChild::Leaf { first, count } => {
                    let first_packet = packets.len() as u32;
                    let order = tree.triangle_order.get(first as usize..(first + count) as usize).ok_or_else(|| {
                        unwritable(format!("node {i} slot {slot}: leaf {first}+{count} out of range"))
                    })?;
                    for chunk in order.chunks(PACKET_LANES) {
                        lanes.clear();
                        for &t in chunk {
                            let lane =
                                record_of(t).and_then(|index| Some((index, *file_triangles.get(index as usize)?)));
                            lanes.push(lane.ok_or_else(|| {
                                unwritable(format!("node {i} slot {slot}: triangle {t} is not in the file"))
                            })?);
                        }
                        packets.push(TrianglePacket4::new(&lanes));
                    }
                    let packet_count = packets.len() as u32 - first_packet;
                    WideNode8::leaf(first_packet, packet_count).ok_or_else(|| {
                        unwritable(format!(
                            "node {i} slot {slot}: a leaf of {count} triangles from packet {first_packet} does not \
                             fit a leaf reference (at most 8 packets, first below 2^28); convert with --no-wide"
                        ))
                    })?
                }
            };
            packed.set_slot(slot, (aabb.min, aabb.max), child);
        }
        nodes.push(packed);
    }
    let root_box = (tree.root_box.min, tree.root_box.max);
    Ok(if split_references {
        WideBvh::new_split_references(nodes, packets, root_box, file_triangles)?
    } else {
        WideBvh::new(nodes, packets, root_box, file_triangles)?
    })
}
