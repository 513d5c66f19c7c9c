//! The top-level tree in the 8-wide layout (the `top_wide_nodes` section of a two-level file with wide
//! sections, `format-spec/bvh-1.md` 5.13): the binary top tree collapsed greedily, each wide node taking its
//! binary node's two children and opening the inner child of largest surface area until it has eight (the
//! greedy collapse by area of Wald, Benthin, Boulos, "Getting Rid of Packets", 2008). A leaf slot holds one instance
//! (`LEAF_BIT | instance`), its box the instance's world box. Nodes are numbered depth first, children after
//! their parent. Deterministic: ties go to the lower slot.

use crate::format::{EMPTY_SLOT, LEAF_BIT, WIDE};
use crate::format::{PackedNode, WideNode8};

fn half_area(node: &PackedNode) -> f64 {
    let d: [f64; 3] = std::array::from_fn(|k| f64::from(node.max[k] - node.min[k]).max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

/// The wide top tree of the binary top tree `binary` (in the `top_nodes` layout); empty for an empty tree.
pub fn collapse_top_tree(binary: &[PackedNode]) -> Vec<WideNode8> {
    let Some(root) = binary.first() else { return Vec::new() };
    let mut wide = vec![WideNode8::EMPTY];
    // (wide node to fill, the binary nodes of its slots)
    let mut pending: Vec<(usize, Vec<usize>)> = Vec::new();
    let root_slots = if root.is_leaf() { vec![0] } else { vec![root.index as usize, root.index as usize + 1] };
    pending.push((0, root_slots));
    while let Some((w, mut slots)) = pending.pop() {
        // Open the inner slot of largest area (the first on a tie) until eight slots or none is inner.
        while slots.len() < WIDE {
            let mut inner: Option<(usize, f64)> = None;
            for (k, &b) in slots.iter().enumerate() {
                let area = half_area(&binary[b]);
                if !binary[b].is_leaf() && inner.is_none_or(|(_, best)| area > best) {
                    inner = Some((k, area));
                }
            }
            let Some((k, _)) = inner else { break };
            let first = binary[slots[k]].index as usize;
            slots.splice(k..=k, [first, first + 1]);
        }
        let mut children = Vec::new();
        for (slot, &b) in slots.iter().enumerate() {
            let node = &binary[b];
            for axis in 0..3 {
                wide[w].min[axis][slot] = node.min[axis];
                wide[w].max[axis][slot] = node.max[axis];
            }
            wide[w].child[slot] = if node.is_leaf() {
                LEAF_BIT | node.index
            } else {
                wide.push(WideNode8::EMPTY);
                let index = wide.len() - 1;
                children.push((index, vec![node.index as usize, node.index as usize + 1]));
                index as u32
            };
        }
        debug_assert!(wide[w].child[..slots.len()].iter().all(|&c| c != EMPTY_SLOT));
        // Depth first: the first child's subtree next.
        pending.extend(children.into_iter().rev());
    }
    wide
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::top_tree::build_top_tree;

    #[test]
    fn every_instance_is_in_one_leaf_slot_and_children_follow_their_parent() {
        for count in [1usize, 2, 7, 8, 9, 100, 1000] {
            let boxes: Vec<([f32; 3], [f32; 3])> = (0..count)
                .map(|i| {
                    let (x, y) = ((i % 37) as f32 * 1.5, (i / 37) as f32 * 2.0);
                    ([x, y, 0.0], [x + 1.0, y + 1.0, 1.0])
                })
                .collect();
            let wide = collapse_top_tree(&build_top_tree(&boxes));
            let mut seen = vec![0; count];
            let mut referenced = vec![0; wide.len()];
            for (i, node) in wide.iter().enumerate() {
                let occupied = node.child.iter().take_while(|&&c| c != EMPTY_SLOT).count();
                assert!(occupied >= if i == 0 { 1 } else { 2 }, "{count}: node {i}");
                for (slot, &child) in node.child[..occupied].iter().enumerate() {
                    if child & LEAF_BIT != 0 {
                        let instance = (child & !LEAF_BIT) as usize;
                        seen[instance] += 1;
                        let (min, max) = boxes[instance];
                        assert!((0..3).all(|a| node.min[a][slot] == min[a] && node.max[a][slot] == max[a]));
                    } else {
                        assert!(child as usize > i);
                        referenced[child as usize] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "{count}: {seen:?}");
            assert!(referenced[1..].iter().all(|&n| n == 1), "{count}");
            // Far fewer nodes than the binary tree's `count - 1` inner ones (100 instances: 43 wide nodes).
            assert!(wide.len() <= count / 2 + 1, "{count} instances, {} wide nodes", wide.len());
        }
    }
}
