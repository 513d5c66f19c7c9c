//! The leaf layout over split references (`bvhc::layout`): repeats inside a leaf removed with both trees
//! holding each triangle equally often, and the binary merge and wide collapse counting a triangle once a leaf.

use bvhc::builders::split_triangles;
use bvhc::geometry::Aabb;
use bvhc::optimize::{OptTree, optimize};
use bvhc::options::Preset;

use crate::common::random_triangles;
use crate::split::long_triangles;

/// Repeats inside a leaf are removed, then the side holding a triangle less often repeats it inside a leaf
/// that holds it, so that both trees hold every triangle equally often (V15 and V34 for one records section);
/// where the wide leaves have no room, nothing changes.
#[test]
fn repeats_are_removed_and_both_trees_keep_equal_record_counts() {
    use bvhc::build_tree::{BuildNode, BuildTree};
    use bvhc::layout::records::remove_repeats_and_balance;
    use bvhc::layout::{WideChild, WideNode, WideTree};
    let b = Aabb { min: [0.0; 3], max: [1.0; 3] };
    // Binary: leaves [0 0 1] and [2 1]; wide: leaves [0] and [0 1 2 2].
    let mut binary = BuildTree {
        nodes: vec![
            BuildNode::Inner { aabb: b, left: 1, right: 2 },
            BuildNode::Leaf { aabb: b, first: 0, count: 3 },
            BuildNode::Leaf { aabb: b, first: 3, count: 2 },
        ],
        triangle_order: vec![0, 0, 1, 2, 1],
    };
    let wide_with = |order: Vec<u32>, first_count: u32| WideTree {
        width: 8,
        nodes: vec![WideNode {
            children: vec![
                (b, WideChild::Leaf { first: 0, count: first_count }),
                (b, WideChild::Leaf { first: first_count, count: order.len() as u32 - first_count }),
            ],
        }],
        triangle_order: order,
        root_box: b,
    };
    let mut wide = wide_with(vec![0, 0, 1, 2, 2], 1);
    assert!(remove_repeats_and_balance(&mut binary, &mut wide, 3));
    // Distinct per leaf: binary 0:1 1:2 2:1, wide 0:2 1:1 2:1 -> binary repeats 0 in its first leaf, wide 1 in
    // the leaf that holds it.
    assert_eq!(binary.triangle_order, vec![0, 0, 1, 2, 1]);
    assert_eq!(binary.nodes[1], BuildNode::Leaf { aabb: b, first: 0, count: 3 });
    assert_eq!(wide.triangle_order, vec![0, 0, 1, 2, 1]);
    assert_eq!(wide.nodes[0].children[1].1, WideChild::Leaf { first: 1, count: 4 });
    let count = |order: &[u32], t: u32| order.iter().filter(|&&x| x == t).count();
    for t in 0..3 {
        assert_eq!(count(&binary.triangle_order, t), count(&wide.triangle_order, t), "triangle {t}");
    }
    // Plain repeats on both sides: both drop them.
    let mut binary =
        BuildTree { nodes: vec![BuildNode::Leaf { aabb: b, first: 0, count: 3 }], triangle_order: vec![1, 0, 1] };
    let mut wide = wide_with(vec![1, 0, 1], 3);
    wide.nodes[0].children.truncate(1);
    assert!(remove_repeats_and_balance(&mut binary, &mut wide, 2));
    assert_eq!((binary.triangle_order, wide.triangle_order.clone()), (vec![1, 0], vec![1, 0]));
    // No room: a wide leaf of 32 distinct triangles cannot take the binary side's extra copy.
    let order: Vec<u32> = (0..32).collect();
    let mut binary_order = order.clone();
    binary_order.push(5);
    let mut binary = BuildTree {
        nodes: vec![
            BuildNode::Inner { aabb: b, left: 1, right: 2 },
            BuildNode::Leaf { aabb: b, first: 0, count: 32 },
            BuildNode::Leaf { aabb: b, first: 32, count: 1 },
        ],
        triangle_order: binary_order.clone(),
    };
    let mut wide = wide_with(order.clone(), 32);
    wide.nodes[0].children.truncate(1);
    assert!(!remove_repeats_and_balance(&mut binary, &mut wide, 32));
    assert_eq!((binary.triangle_order, wide.triangle_order), (binary_order, order));
}

/// Merging over split references counts a triangle once per leaf: where no triangle repeats it is the plain
/// merge; over references its cost (after repeats are removed) is never above the plain merge's with repeats
/// removed afterwards (the dynamic program is exact for the distinct count, and that tree is one of its
/// options), and no leaf holds more distinct triangles than the limit.
#[test]
fn merging_over_references_counts_each_triangle_once_a_leaf() {
    use bvhc::build_tree::BuildNode;
    use bvhc::builders::Builder;
    use bvhc::cost::SahConstants;
    use bvhc::layout::records::remove_binary_repeats;
    use bvhc::layout::{merge_leaves, merge_leaves_of_references};
    let constants = SahConstants::default();
    let plain = random_triangles(5, 800, 10.0);
    let tree = OptTree::from_build(Builder::BinnedSah.build(&plain, 1), &plain);
    for limit in [1, 4, 8] {
        assert_eq!(merge_leaves_of_references(&tree, constants, limit), merge_leaves(&tree, constants, limit));
    }
    let triangles = long_triangles(13, 1500);
    let references = split_triangles(&triangles, 1.0);
    assert!(references.len() > 2500);
    let mut tree = OptTree::from_build(Builder::BinnedSah.build_references(&references), &triangles);
    optimize(&mut tree, &Preset::Fast.optimize_params(), &mut |_| std::ops::ControlFlow::Continue(()));
    for limit in [2, 4, 8] {
        let mut aware = merge_leaves_of_references(&tree, constants, limit);
        let mut naive = merge_leaves(&tree, constants, limit);
        remove_binary_repeats(&mut aware, triangles.len());
        remove_binary_repeats(&mut naive, triangles.len());
        let (aware_cost, naive_cost) = (aware.sah_cost(constants).cost, naive.sah_cost(constants).cost);
        assert!(aware_cost <= naive_cost * (1.0 + 1e-12), "limit {limit}: {aware_cost} > {naive_cost}");
        assert!(aware_cost < naive_cost, "limit {limit}: no leaf gained from counting distinct triangles");
        for node in &aware.nodes {
            if let BuildNode::Leaf { count, .. } = node {
                assert!(*count as usize <= limit);
            }
        }
    }
}

/// The wide collapse over split references counts each triangle once a leaf: where no triangle repeats it is
/// the plain collapse; over references its cost with leaves priced by distinct triangles is never above the
/// plain collapse's priced the same way (its dynamic program is exact for that cost, and the plain tree is one
/// of its options), and no leaf holds more distinct triangles than the limit.
#[test]
fn the_wide_collapse_over_references_counts_each_triangle_once_a_leaf() {
    use bvhc::builders::Builder;
    use bvhc::layout::{WideChild, WideCosts, WideTree, collapse, collapse_references};
    let costs = WideCosts::default();
    let plain = random_triangles(6, 800, 10.0);
    let tree = OptTree::from_build(Builder::BinnedSah.build(&plain, 1), &plain);
    assert_eq!(collapse_references(&tree, &costs), collapse(&tree, &costs));
    let distinct_cost = |wide: &WideTree| {
        let mut counted = wide.clone();
        for node in &mut counted.nodes {
            for (_, child) in &mut node.children {
                if let WideChild::Leaf { first, count } = child {
                    let mut leaf = wide.triangle_order[*first as usize..(*first + *count) as usize].to_vec();
                    leaf.sort_unstable();
                    leaf.dedup();
                    *count = leaf.len() as u32;
                }
            }
        }
        counted
    };
    let triangles = long_triangles(14, 1500);
    let references = split_triangles(&triangles, 1.0);
    let mut tree = OptTree::from_build(Builder::BinnedSah.build_references(&references), &triangles);
    optimize(&mut tree, &Preset::Fast.optimize_params(), &mut |_| std::ops::ControlFlow::Continue(()));
    for max_leaf_size in [4, 8] {
        let costs = WideCosts { max_leaf_size, ..WideCosts::default() };
        let aware = distinct_cost(&collapse_references(&tree, &costs));
        let naive = distinct_cost(&collapse(&tree, &costs));
        let (aware_cost, naive_cost) = (aware.cost(&costs), naive.cost(&costs));
        assert!(aware_cost <= naive_cost * (1.0 + 1e-12), "limit {max_leaf_size}: {aware_cost} > {naive_cost}");
        assert!(aware_cost < naive_cost, "limit {max_leaf_size}: no leaf gained from counting distinct triangles");
        for node in &aware.nodes {
            for (_, child) in &node.children {
                if let WideChild::Leaf { count, .. } = child {
                    assert!(*count as usize <= max_leaf_size);
                }
            }
        }
    }
}
