//! A [`WideTree`] of width 8 in the loader's 8-wide layout ([`WideNode8`]), for [`bvhc_loader::WideBvh`].

use bvhc_loader::{PackedTriangle, WIDE, WideBvh, WideNode8};

use super::{WideChild, WideTree};

/// Packs `tree` (width at most 8, leaves of at most 8 triangles) over `triangles` into a checked [`WideBvh`].
pub fn pack_wide(tree: &WideTree, triangles: &[PackedTriangle]) -> Result<WideBvh, String> {
    if tree.width > WIDE {
        return Err(format!("width {} is more than the layout's {WIDE}", tree.width));
    }
    let mut nodes = Vec::with_capacity(tree.nodes.len());
    for (i, node) in tree.nodes.iter().enumerate() {
        let mut packed = WideNode8::EMPTY;
        for (lane, (aabb, child)) in node.children.iter().enumerate() {
            for axis in 0..3 {
                packed.min[axis][lane] = aabb.min[axis];
                packed.max[axis][lane] = aabb.max[axis];
            }
            packed.child[lane] = match *child {
                WideChild::Node(c) => c,
                WideChild::Leaf { first, count } => WideNode8::leaf(first, count)
                    .ok_or_else(|| format!("node {i} lane {lane}: leaf {first}+{count} does not fit a reference"))?,
            };
        }
        nodes.push(packed);
    }
    WideBvh::new(nodes, &tree.triangle_order, triangles, (tree.root_box.min, tree.root_box.max))
}
