//! A [`WideTree`] of width 8 in the loader's 8-wide layout ([`WideNode8`] and [`TrianglePacket4`]), for
//! [`bvhc_loader::WideBvh`]: each leaf's triangles are laid out in packets of four, the last one padded with
//! unused lanes, and each lane holds the triangle's index in `triangles`.

use bvhc_loader::{PACKET_LANES, PackedTriangle, TrianglePacket4, WIDE, WideBvh, WideNode8};

use super::{WideChild, WideTree};

/// Packs `tree` (width at most 8, leaves of at most 32 triangles) over `triangles` (indexed by the tree's
/// `triangle_order`) into a checked [`WideBvh`].
pub fn pack_wide(tree: &WideTree, triangles: &[PackedTriangle]) -> Result<WideBvh, String> {
    if tree.width > WIDE {
        return Err(format!("width {} is more than the layout's {WIDE}", tree.width));
    }
    let mut nodes = Vec::with_capacity(tree.nodes.len());
    let mut packets = Vec::with_capacity(tree.triangle_order.len().div_ceil(PACKET_LANES));
    for (i, node) in tree.nodes.iter().enumerate() {
        let mut packed = WideNode8::EMPTY;
        for (slot, (aabb, child)) in node.children.iter().enumerate() {
            for axis in 0..3 {
                packed.min[axis][slot] = aabb.min[axis];
                packed.max[axis][slot] = aabb.max[axis];
            }
            packed.child[slot] = match *child {
                WideChild::Node(c) => c,
                WideChild::Leaf { first, count } => {
                    let first_packet = packets.len() as u32;
                    let order = tree
                        .triangle_order
                        .get(first as usize..(first + count) as usize)
                        .ok_or_else(|| format!("node {i} slot {slot}: leaf {first}+{count} out of range"))?;
                    for chunk in order.chunks(PACKET_LANES) {
                        let lanes = chunk
                            .iter()
                            .map(|&t| triangles.get(t as usize).map(|triangle| (t, *triangle)))
                            .collect::<Option<Vec<_>>>()
                            .ok_or_else(|| format!("node {i} slot {slot}: a triangle index is out of range"))?;
                        packets.push(TrianglePacket4::new(&lanes));
                    }
                    let packet_count = packets.len() as u32 - first_packet;
                    WideNode8::leaf(first_packet, packet_count).ok_or_else(|| {
                        format!("node {i} slot {slot}: leaf of {count} triangles does not fit a reference")
                    })?
                }
            };
        }
        nodes.push(packed);
    }
    WideBvh::new(nodes, packets, (tree.root_box.min, tree.root_box.max), triangles)
}
