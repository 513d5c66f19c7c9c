//! One test per validity rule of the wide sections (format 1.1): corrupt a good 1.1 file in one way and expect
//! exactly that rule (V29-V35), plus the wide clauses of V8, V9, V10 and V13.

use bvhc::loader::{
    BvhFile, Rule, format::EMPTY_SLOT, format::LEAF_BIT, format::TrianglePacket4, format::WideNode8, write::BvhWriter,
};

use crate::common::*;
use crate::corrupt::{broken_rule, data, entry, refresh_checksums};

/// Section table positions of the good file's wide sections (after nodes, triangles, ids, sources, metadata).
const WIDE_NODES: usize = 5;
const PACKETS: usize = 6;

/// A good 1.1 file (every section kind) as plain bytes.
pub fn good_wide_bytes() -> Vec<u8> {
    write_wide_file(&random_triangles(70, 160, 1.0), 2).as_bytes().to_vec()
}

fn nodes_of(bytes: &[u8]) -> Vec<WideNode8> {
    let file = BvhFile::from_bytes(bytes).unwrap();
    file.view().wide_sections().unwrap().nodes.to_vec()
}

fn packets_of(bytes: &[u8]) -> Vec<TrianglePacket4> {
    let file = BvhFile::from_bytes(bytes).unwrap();
    file.view().wide_sections().unwrap().packets.to_vec()
}

fn store_node(bytes: &mut [u8], i: usize, node: &WideNode8) {
    let at = data(bytes, WIDE_NODES) + i * size_of::<WideNode8>();
    bytes[at..at + size_of::<WideNode8>()].copy_from_slice(bytemuck::bytes_of(node));
}

fn store_packet(bytes: &mut [u8], p: usize, packet: &TrianglePacket4) {
    let at = data(bytes, PACKETS) + p * size_of::<TrianglePacket4>();
    bytes[at..at + size_of::<TrianglePacket4>()].copy_from_slice(bytemuck::bytes_of(packet));
}

/// Corrupts the good file's wide nodes or packets with `corrupt`, repairs the checksums, expects `rule`.
fn expect_wide(rule: Rule, corrupt: impl FnOnce(&mut Vec<WideNode8>, &mut Vec<TrianglePacket4>)) {
    let mut bytes = good_wide_bytes();
    assert_eq!(broken_rule(&bytes), None);
    let (mut nodes, mut packets) = (nodes_of(&bytes), packets_of(&bytes));
    corrupt(&mut nodes, &mut packets);
    for (i, node) in nodes.iter().enumerate() {
        store_node(&mut bytes, i, node);
    }
    for (p, packet) in packets.iter().enumerate() {
        store_packet(&mut bytes, p, packet);
    }
    refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).expect("wide rules are not structural");
    let error = file.view().verify().expect_err("the corruption is caught");
    assert_eq!(error.rule, rule, "expected {rule}, got {error}");
    assert_eq!(file.view().verify_in_parallel(), Err(error), "the wide checks on their own thread");
}

fn occupied(node: &WideNode8) -> usize {
    node.child.iter().take_while(|&&c| c != EMPTY_SLOT).count()
}

fn is_inner(child: u32) -> bool {
    child != EMPTY_SLOT && child & LEAF_BIT == 0
}

/// (node, slot) of the first slot that satisfies `pick`.
fn find_slot(nodes: &[WideNode8], pick: impl Fn(u32) -> bool) -> (usize, usize) {
    nodes
        .iter()
        .enumerate()
        .find_map(|(i, n)| n.child.iter().position(|&c| pick(c)).map(|s| (i, s)))
        .expect("the good file has such a slot")
}

#[test]
fn v8_wide_sections_come_together() {
    let mut bytes = good_wide_bytes();
    // triangle_packets becomes an unknown optional kind: wide_nodes alone.
    bytes[entry(PACKETS)..entry(PACKETS) + 4].copy_from_slice(&999u32.to_le_bytes());
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionMultiplicity));
}

#[test]
fn v8_wide_sections_only_in_files_of_1_1() {
    // Relabelled 1.0 (header and metadata), checksums repaired: the wide sections came with 1.1.
    let mut bytes = good_wide_bytes();
    crate::corrupt::relabel_minor(&mut bytes, 1, 0);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionMultiplicity));
    let error = BvhFile::from_bytes(&bytes).unwrap_err().to_string();
    assert!(error.contains("came with 1.1"), "{error}");
}

#[test]
fn v9_wide_sections_are_optional_and_sized() {
    let mut bytes = good_wide_bytes();
    bytes[entry(WIDE_NODES) + 4] = 1; // REQUIRED
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionKindLayout));
}

#[test]
fn v10_wide_counts() {
    let triangles = random_triangles(71, 40, 1.0);
    let tree = packed_tree(&triangles, 2);
    let wide = wide_sections_for(&tree, &triangles);
    let write = |nodes: &[WideNode8], packets: &[TrianglePacket4]| {
        BvhWriter::new(&tree.nodes, &tree.triangles).wide(nodes, packets).build().err().and_then(|e| e.rule())
    };
    assert_eq!(write(wide.nodes(), wide.packets()), None);
    // Fewer packets than a quarter of the triangles.
    assert_eq!(write(wide.nodes(), &wide.packets()[..2]), Some(Rule::Counts));
    // No wide root for a non-empty file.
    assert_eq!(write(&[], wide.packets()), Some(Rule::Counts));
    // More wide nodes than packets.
    let many: Vec<WideNode8> = std::iter::repeat_n(wide.nodes()[0], wide.packets().len() + 1).collect();
    assert_eq!(write(&many, wide.packets()), Some(Rule::Counts));
}

#[test]
fn v13_wide_node_reserved() {
    expect_wide(Rule::ReservedZero, |nodes, _| nodes[0].reserved[3] = 1);
}

#[test]
fn v29_wide_slots() {
    // A child before its parent.
    expect_wide(Rule::WideSlots, |nodes, _| {
        let (i, slot) = find_slot(&nodes[1..], is_inner);
        nodes[i + 1].child[slot] = 1.min(i as u32);
    });
    // An occupied slot after an empty one.
    expect_wide(Rule::WideSlots, |nodes, _| {
        let i = nodes.iter().position(|n| occupied(n) < 8).unwrap();
        let n = occupied(&nodes[i]);
        nodes[i].child.swap(n - 1, n);
    });
    // An empty slot whose box is not +inf..-inf.
    expect_wide(Rule::WideSlots, |nodes, _| {
        let i = nodes.iter().position(|n| occupied(n) < 8).unwrap();
        let n = occupied(&nodes[i]);
        nodes[i].min[0][n] = 0.0;
    });
    // A leaf past the packets.
    expect_wide(Rule::WideSlots, |nodes, packets| {
        let (i, slot) = find_slot(nodes, |c| c != EMPTY_SLOT && c & LEAF_BIT != 0);
        nodes[i].child[slot] = WideNode8::leaf(packets.len() as u32, 1).unwrap();
    });
    // An inner node (not the root) with one child.
    expect_wide(Rule::WideSlots, |nodes, _| {
        let i = nodes.len() - 1;
        for slot in 1..8 {
            nodes[i].child[slot] = EMPTY_SLOT;
            for axis in 0..3 {
                (nodes[i].min[axis][slot], nodes[i].max[axis][slot]) = (f32::INFINITY, f32::NEG_INFINITY);
            }
        }
    });
}

#[test]
fn v30_wide_tree_shape() {
    // Two slots of the root name the same node (and the node the first one named loses its parent).
    expect_wide(Rule::WideTreeShape, |nodes, _| {
        let inner: Vec<usize> = (0..8).filter(|&s| is_inner(nodes[0].child[s])).collect();
        assert!(inner.len() >= 2, "the root has two inner children");
        nodes[0].child[inner[0]] = nodes[0].child[inner[1]];
    });
}

#[test]
fn v31_packet_partition() {
    // One leaf takes the packets of another.
    expect_wide(Rule::PacketPartition, |nodes, _| {
        let leaves: Vec<(usize, usize)> = nodes
            .iter()
            .enumerate()
            .flat_map(|(i, n)| {
                (0..8).filter(|&s| n.child[s] != EMPTY_SLOT && n.child[s] & LEAF_BIT != 0).map(move |s| (i, s))
            })
            .collect();
        let (a, b) = (leaves[0], leaves[1]);
        nodes[a.0].child[a.1] = nodes[b.0].child[b.1];
    });
}

#[test]
fn v32_wide_box() {
    // An inner slot's box that does not contain its child's slots.
    expect_wide(Rule::WideBox, |nodes, _| {
        let (i, slot) = find_slot(nodes, is_inner);
        nodes[i].max[0][slot] = nodes[i].min[0][slot];
    });
    // A root slot outside the binary root's box.
    expect_wide(Rule::WideBox, |nodes, _| nodes[0].max[1][0] += 10.0);
    // A box that is not finite.
    expect_wide(Rule::WideBox, |nodes, _| nodes[0].min[2][0] = f32::NAN);
}

#[test]
fn v33_packet_lanes() {
    // A lane whose vertex differs from its triangle.
    expect_wide(Rule::PacketLanes, |_, packets| packets[0].vertices[1][2][0] += 0.25);
    // An unused lane with a coordinate.
    expect_wide(Rule::PacketLanes, |_, packets| {
        let p = packets.iter().position(|p| p.used_lanes() < 4).expect("a packet with an unused lane");
        let lane = packets[p].used_lanes();
        packets[p].vertices[0][0][lane] = 0.0;
    });
    // A lane naming a triangle past the section.
    expect_wide(Rule::PacketLanes, |_, packets| packets[0].triangle_index[0] = 1_000_000);
}

#[test]
fn v34_lane_coverage() {
    // The last used lane of the last packet repeats packet 0's lane 0: one triangle twice, another never.
    expect_wide(Rule::LaneCoverage, |_, packets| {
        repeat_first_lane_in_last(packets);
    });
}

#[test]
fn v35_lane_in_leaf() {
    // A leaf slot's box shrunk to a plane: its triangles stick out (the box stays inside its parent's).
    expect_wide(Rule::LaneInLeaf, |nodes, _| {
        let (i, slot) = find_slot(nodes, |c| c != EMPTY_SLOT && c & LEAF_BIT != 0);
        nodes[i].max[0][slot] = nodes[i].min[0][slot];
    });
}

#[test]
fn every_wide_rule_has_a_test_here() {
    let source = include_str!("rules_wide.rs");
    let wide_rules = Rule::WideSlots.number()..=Rule::LaneInLeaf.number();
    for rule in Rule::ALL.into_iter().filter(|rule| wide_rules.contains(&rule.number())) {
        assert!(source.contains(&format!("fn v{}_", rule.number())), "no test for {rule}");
    }
}
