//! Reinsertion over clusters: the leaf layout's clusters stay as built, node for node, and the tree above them
//! is optimized deterministically.

use bvhc::builders::Builder;
use bvhc::layout::cluster_roots;
use bvhc::optimize::{NONE, OptTree, cost_of, optimize_over_clusters};
use bvhc::options::Preset;

/// Triangles scattered in a cube, from a fixed linear congruential sequence.
fn scattered_triangles(count: usize) -> Vec<[[f32; 3]; 3]> {
    let mut state = 12345u64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..count)
        .map(|_| {
            let c = [next() * 10.0, next() * 10.0, next() * 10.0];
            std::array::from_fn(|_| std::array::from_fn(|a| c[a] + next() * 0.6))
        })
        .collect()
}

/// A subtree's shape and contents, depth first: each node as its box's bits and, for a leaf, its reference.
fn subtree_contents(tree: &OptTree, root: u32) -> Vec<(Vec<u32>, u32)> {
    let mut out = Vec::new();
    let mut stack = vec![root];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i as usize];
        let bits = node.aabb.min.iter().chain(&node.aabb.max).map(|c| c.to_bits()).collect();
        out.push((bits, if node.left == NONE { node.right } else { NONE }));
        if node.left != NONE {
            stack.push(node.right);
            stack.push(node.left);
        }
    }
    out
}

/// Every cluster of the built tree is found whole, node for node, in the optimized tree; the tree keeps
/// its invariants and every reference; its cost is not above the built tree's and is what the report says;
/// and the result does not depend on the thread count.
#[test]
fn clusters_stay_as_built_and_the_tree_above_them_is_optimized() {
    let triangles = scattered_triangles(3000);
    let built = OptTree::from_build(Builder::BinnedSah.build(&triangles, 1), &triangles);
    let params = Preset::Balanced.optimize_params();
    let roots = cluster_roots(&built, params.constants, 4);
    assert!(roots.len() < 2900, "hardly any cluster holds several references: {}", roots.len());
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut tree = built.clone();
            let report =
                optimize_over_clusters(&mut tree, &params, &roots, &mut |_| std::ops::ControlFlow::Continue(()));
            (tree, report)
        })
    };
    let (tree, report) = run(2);
    tree.check_invariants(&triangles).unwrap();
    assert!(report.best.cost < report.initial.cost);
    assert_eq!(report.initial.cost, cost_of(&built, params.constants).cost);
    assert_eq!(report.best.cost, cost_of(&tree, params.constants).cost);
    let all: std::collections::HashSet<Vec<(Vec<u32>, u32)>> =
        (0..tree.nodes.len() as u32).map(|i| subtree_contents(&tree, i)).collect();
    for &root in &roots {
        assert!(all.contains(&subtree_contents(&built, root)), "cluster at {root} was changed");
    }
    assert_eq!(run(1).0, tree, "1 and 2 threads differ");
}
