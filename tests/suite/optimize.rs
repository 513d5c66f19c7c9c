//! The optimizer against oracles: exhaustive searches, invariants after every batch, cost never above the
//! input, leaf merging never above its input, and the same tree for any number of threads.

use std::ops::ControlFlow;

use bvhc::build_tree::{BuildNode, BuildTree};
use bvhc::builders::Builder;
use bvhc::cost::SahConstants;
use bvhc::geometry::Aabb;
use bvhc::layout::merge_leaves;
use bvhc::optimize::{
    Algorithm, NONE, OptTree, OptimizeParams, SearchQueue, Selection, area, best_insertion, best_move, cost_of,
    optimize,
};
use bvhc::options::Preset;

use crate::common::random_triangles;

fn tree_for(triangles: &[[[f32; 3]; 3]], builder: Builder) -> OptTree {
    OptTree::from_build_tree(&builder.build(triangles, 1), triangles)
}

/// Every invariant of an optimizer tree (the library's own check): links agree, boxes are exact unions,
/// every triangle in one leaf, every node reachable once.
fn check_invariants(tree: &OptTree, triangles: &[[[f32; 3]; 3]]) {
    if let Err(broken) = tree.check_invariants(triangles) {
        panic!("{broken}");
    }
}

/// The inner-area sum in f64, the quantity the searches minimize.
fn inner_area(tree: &OptTree) -> f64 {
    tree.area_sums().0
}

/// Detaches the subtree `c` of a copy (its parent spliced out, as Bittner's removal does) and tries every
/// insertion position: the minimum of `SA(new parent) + induced` over all positions.
#[test]
fn insertion_search_finds_the_exhaustive_minimum() {
    for seed in 0..40u64 {
        let triangles = random_triangles(seed, 8 + (seed as usize * 7) % 60, 1.0);
        let tree = tree_for(&triangles, if seed % 2 == 0 { Builder::BinnedSah } else { Builder::SpatialMedian });
        let mut queue = SearchQueue::default();
        for c in 0..tree.nodes.len() as u32 {
            let p = tree.nodes[c as usize].parent;
            if p == NONE || tree.nodes[p as usize].parent == NONE {
                continue;
            }
            let mut detached = tree.clone();
            let s = detached.sibling(c);
            let g = detached.nodes[p as usize].parent;
            detached.replace_child(g, p, s);
            detached.refit_from(g);
            let l = detached.nodes[c as usize].aabb;
            let cost_of_x = |x: u32| {
                let mut cost = area(&detached.nodes[x as usize].aabb.union(&l));
                let mut a = detached.nodes[x as usize].parent;
                while a != NONE {
                    let b = &detached.nodes[a as usize].aabb;
                    cost += area(&b.union(&l)) - area(b);
                    a = detached.nodes[a as usize].parent;
                }
                cost
            };
            let exhaustive = detached.depth_first().into_iter().map(cost_of_x).fold(f32::INFINITY, f32::min);
            let found = best_insertion(&detached, &mut queue, &l);
            let got = cost_of_x(found);
            assert!(
                got <= exhaustive * (1.0 + 1e-5) + 1e-6,
                "seed {seed} node {c}: search {got}, exhaustive {exhaustive}"
            );
        }
    }
}

/// Applies the move of `n` to sibling of `x` on a copy (or `None` when it is not a legal move).
fn moved(tree: &OptTree, n: u32, x: u32) -> Option<OptTree> {
    let p = tree.nodes[n as usize].parent;
    let mut y = x;
    while y != NONE {
        if y == n {
            return None; // inside the moving subtree
        }
        y = tree.nodes[y as usize].parent;
    }
    if x == p {
        return None;
    }
    let mut copy = tree.clone();
    let s = copy.sibling(n);
    let g = copy.nodes[p as usize].parent;
    copy.replace_child(g, p, s);
    copy.refit_from(g);
    let y = copy.nodes[x as usize].parent;
    let aabb = copy.nodes[x as usize].aabb.union(&copy.nodes[n as usize].aabb);
    copy.nodes[p as usize].aabb = aabb;
    copy.nodes[p as usize].left = x;
    copy.nodes[p as usize].right = n;
    copy.replace_child(y, x, p);
    copy.nodes[x as usize].parent = p;
    copy.nodes[n as usize].parent = p;
    copy.refit_from(y);
    Some(copy)
}

/// The search without removal predicts the exact change of the inner-area sum, and no legal move is better.
#[test]
fn move_search_finds_the_exhaustive_best_move_and_its_exact_gain() {
    let mut found_some = 0;
    for seed in 100..130u64 {
        let triangles = random_triangles(seed, 6 + (seed as usize * 5) % 40, 1.0);
        let tree = tree_for(&triangles, Builder::SpatialMedian);
        let before = inner_area(&tree);
        let mut queue = SearchQueue::default();
        for n in 0..tree.nodes.len() as u32 {
            if tree.nodes[n as usize].parent == NONE {
                continue;
            }
            let exhaustive = (0..tree.nodes.len() as u32)
                .filter_map(|x| moved(&tree, n, x).map(|t| inner_area(&t) - before))
                .fold(0.0f64, f64::min);
            match best_move(&tree, &mut queue, n) {
                None => assert!(exhaustive > -1e-4 * before, "seed {seed} node {n}: missed a gain of {exhaustive}"),
                Some(m) => {
                    let actual = inner_area(&moved(&tree, n, m.target).expect("a legal move")) - before;
                    let tolerance = 1e-4 * before;
                    assert!(
                        (f64::from(m.delta) - actual).abs() <= tolerance,
                        "seed {seed} node {n}: predicted {} actual {actual}",
                        m.delta
                    );
                    assert!(
                        actual <= exhaustive + tolerance,
                        "seed {seed} node {n}: {actual} vs exhaustive {exhaustive}"
                    );
                    found_some += 1;
                }
            }
        }
    }
    assert!(found_some > 50, "{found_some}");
}

fn params(algorithm: Algorithm, selection: Selection) -> OptimizeParams {
    OptimizeParams {
        algorithm,
        selection,
        batch_fraction: 0.05,
        decreasing_fractions: false,
        stop_after: 5,
        min_relative_improvement: 1e-4,
        ..Preset::Balanced.optimize_params()
    }
}

#[test]
fn optimizing_keeps_every_invariant_and_never_raises_the_cost() {
    let triangles = random_triangles(7, 3000, 10.0);
    for algorithm in [Algorithm::Parallel, Algorithm::Sequential] {
        for builder in [Builder::SpatialMedian, Builder::BinnedSah] {
            let mut tree = tree_for(&triangles, builder);
            let before = cost_of(&tree, SahConstants::default()).cost;
            let mut batches = 0;
            let report = optimize(&mut tree, &params(algorithm, Selection::Comb), &mut |_| {
                batches += 1;
                ControlFlow::Continue(())
            });
            check_invariants(&tree, &triangles);
            let after = cost_of(&tree, SahConstants::default());
            assert_eq!(after, report.best, "the returned tree is the best one");
            assert!(after.cost <= before, "{algorithm:?} {builder:?}: {before} -> {}", after.cost);
            assert!(report.batches == batches && batches > 0);
        }
    }
}

#[test]
fn the_spatial_median_start_improves_a_lot() {
    let triangles = random_triangles(8, 4000, 10.0);
    for algorithm in [Algorithm::Parallel, Algorithm::Sequential] {
        let mut tree = tree_for(&triangles, Builder::SpatialMedian);
        let report = optimize(&mut tree, &params(algorithm, Selection::Comb), &mut |_| ControlFlow::Continue(()));
        assert!(report.best.cost < 0.9 * report.initial.cost, "{algorithm:?}: {report:?}");
    }
}

#[test]
fn every_selection_strategy_converges() {
    let triangles = random_triangles(9, 2000, 10.0);
    for selection in Selection::ALL {
        for algorithm in [Algorithm::Parallel, Algorithm::Sequential] {
            let mut tree = tree_for(&triangles, Builder::SpatialMedian);
            let report = optimize(&mut tree, &params(algorithm, selection), &mut |_| ControlFlow::Continue(()));
            assert_eq!(report.stop, bvhc::optimize::StopReason::Converged, "{selection:?} {algorithm:?}");
            assert!(report.best.cost < report.initial.cost, "{selection:?} {algorithm:?}: {report:?}");
            check_invariants(&tree, &triangles);
        }
    }
}

#[test]
fn one_and_several_threads_give_identical_trees() {
    let triangles = random_triangles(10, 5000, 10.0);
    let run = |threads: usize| {
        crate::common::in_pool(threads, || {
            let mut tree = tree_for(&triangles, Builder::BinnedSah);
            optimize(&mut tree, &OptimizeParams::default(), &mut |_| ControlFlow::Continue(()));
            tree
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(4));
    assert_eq!(one, run(1), "and from run to run");
}

/// The children-first walk (which the leaf merging and the wide collapse use instead of an order array) is the
/// depth-first order reversed, on trees whose node numbering the optimizer has shuffled.
#[test]
fn the_children_first_walk_is_the_depth_first_order_reversed() {
    for (seed, count) in [(1u64, 1usize), (2, 2), (3, 7), (4, 500)] {
        let triangles = random_triangles(seed, count, 10.0);
        let mut tree = tree_for(&triangles, Builder::SpatialMedian);
        optimize(&mut tree, &OptimizeParams::default(), &mut |_| ControlFlow::Continue(()));
        let mut reversed = tree.depth_first();
        reversed.reverse();
        assert_eq!(tree.children_first().collect::<Vec<_>>(), reversed, "{count} triangles");
    }
    let empty = OptTree { nodes: Vec::new(), root: NONE };
    assert_eq!(empty.children_first().next(), None, "an empty tree");
}

#[test]
fn cancellation_and_time_budget_return_the_best_tree_so_far() {
    let triangles = random_triangles(11, 3000, 10.0);
    let mut tree = tree_for(&triangles, Builder::SpatialMedian);
    let report = optimize(&mut tree, &OptimizeParams::default(), &mut |p| {
        if p.batch == 3 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    });
    assert_eq!((report.stop, report.batches), (bvhc::optimize::StopReason::Cancelled, 3));
    check_invariants(&tree, &triangles);
    let budget = OptimizeParams { time_budget: Some(std::time::Duration::ZERO), ..OptimizeParams::default() };
    let report = optimize(&mut tree, &budget, &mut |_| ControlFlow::Continue(()));
    assert_eq!((report.stop, report.batches), (bvhc::optimize::StopReason::TimeBudget, 1));
}

#[test]
fn builders_place_every_triangle_in_exactly_one_leaf_with_exact_boxes() {
    // 20,000 triangles: large enough for the parallel subtree builds.
    let triangles = random_triangles(15, 20_000, 10.0);
    for builder in [Builder::SpatialMedian, Builder::BinnedSah] {
        for max_leaf_size in [1, 4] {
            let build = builder.build(&triangles, max_leaf_size);
            let mut order = build.triangle_order.clone();
            order.sort_unstable();
            assert_eq!(order, (0..triangles.len() as u32).collect::<Vec<_>>(), "{builder:?}");
            let mut covered = vec![false; triangles.len()];
            let mut stack = vec![0usize];
            while let Some(i) = stack.pop() {
                match build.nodes[i] {
                    BuildNode::Inner { aabb, left, right } => {
                        let union = build.nodes[left as usize].aabb().union(build.nodes[right as usize].aabb());
                        assert_eq!(aabb, union, "{builder:?} node {i}");
                        stack.extend([left as usize, right as usize]);
                    }
                    BuildNode::Leaf { aabb, first, count } => {
                        assert!((count as usize) <= max_leaf_size || max_leaf_size == 1 && count == 1);
                        let slots = &build.triangle_order[first as usize..(first + count) as usize];
                        let union =
                            slots.iter().fold(Aabb::EMPTY, |b, &t| b.union(&Aabb::of_triangle(&triangles[t as usize])));
                        assert_eq!(aabb, union, "{builder:?} leaf {i}");
                        for &t in slots {
                            assert!(!std::mem::replace(&mut covered[t as usize], true), "triangle {t} twice");
                        }
                    }
                }
            }
            assert!(covered.iter().all(|&c| c), "{builder:?}: a triangle is unreachable");
            let tree = OptTree::from_build_tree(&build, &triangles);
            check_invariants(&tree, &triangles);
        }
    }
}

#[test]
fn leaf_merging_never_raises_the_cost_and_respects_the_leaf_size() {
    let constants = SahConstants::default();
    for seed in 20..26u64 {
        let triangles = random_triangles(seed, 1500, 10.0);
        let mut tree = tree_for(&triangles, Builder::BinnedSah);
        optimize(&mut tree, &Preset::Fast.optimize_params(), &mut |_| ControlFlow::Continue(()));
        let single = cost_of(&tree, constants).cost;
        for max_leaf_size in [1, 2, 4, 8] {
            let merged: BuildTree = merge_leaves(&tree, constants, max_leaf_size);
            let cost = merged.sah_cost(constants).cost;
            assert!(cost <= single * (1.0 + 1e-9), "seed {seed}: merged {cost} > {single}");
            let mut order = merged.triangle_order.clone();
            order.sort_unstable();
            assert_eq!(order, (0..triangles.len() as u32).collect::<Vec<_>>());
            for node in &merged.nodes {
                if let BuildNode::Leaf { count, .. } = node {
                    assert!((*count as usize) <= max_leaf_size);
                }
            }
            if max_leaf_size == 1 {
                assert!((cost - single).abs() <= 1e-9 * single);
            }
        }
    }
}

#[test]
fn degenerate_inputs_run_through_every_preset() {
    let point = [[1.0f32, 1.0, 1.0]; 3];
    let cases: Vec<Vec<[[f32; 3]; 3]>> = vec![
        vec![],
        vec![point],
        vec![point, point],
        vec![point; 3000],
        random_triangles(12, 3, 1.0),
        (0..500).map(|i| [[i as f32, 0.0, 0.0], [i as f32, 1.0, 0.0], [i as f32, 0.0, 1.0]]).collect(),
        random_triangles(13, 500, 1e-6),
        random_triangles(14, 500, 1e6),
    ];
    for triangles in &cases {
        for preset in Preset::ALL {
            for builder in [Builder::SpatialMedian, Builder::BinnedSah] {
                let mut tree = tree_for(triangles, builder);
                if triangles.is_empty() {
                    assert!(tree.nodes.is_empty());
                    continue;
                }
                let report = optimize(&mut tree, &preset.optimize_params(), &mut |_| ControlFlow::Continue(()));
                assert!(report.best.cost.is_finite() && report.initial.cost.is_finite(), "{report:?}");
                check_invariants(&tree, triangles);
                let merged = merge_leaves(&tree, SahConstants::default(), 8);
                assert!(merged.sah_cost(SahConstants::default()).cost.is_finite());
                assert!(tree.max_depth() <= bvhc::loader::format::MAX_DEPTH);
            }
        }
    }
}

#[test]
fn the_edit_log_restores_the_marked_tree_exactly_and_tracks_the_inner_area() {
    // Moves made through the logged edits (the parallel loop's move: splice a node's parent out, reinsert it
    // above a target) must leave a running inner-area sum equal to a fresh one (up to rounding), and restoring
    // must give back the tree as it was at the mark, node for node.
    use bvhc::optimize::EditLog;
    use rand::RngExt;
    let mut moves = 0;
    for seed in 0..40u64 {
        let triangles = random_triangles(seed, 40 + seed as usize * 7, 10.0);
        let mut tree = tree_for(&triangles, Builder::BinnedSah);
        let mut log = EditLog::new(&tree, inner_area(&tree));
        let mut rng = crate::common::rng(seed);
        for round in 0..3 {
            let marked = tree.clone();
            for _ in 0..10 {
                let n = rng.random_range(0..tree.nodes.len() as u32);
                let x = rng.random_range(0..tree.nodes.len() as u32);
                let p = tree.nodes[n as usize].parent;
                if p == NONE || x == p || tree.is_in_subtree(x, n) {
                    continue;
                }
                tree.move_beside_logged(n, x, &mut log);
                moves += 1;
                check_invariants(&tree, &triangles);
                let fresh = inner_area(&tree);
                assert!(
                    (log.inner_area() - fresh).abs() <= 1e-9 * fresh,
                    "seed {seed}: {} vs {fresh}",
                    log.inner_area()
                );
            }
            if round == 1 {
                log.mark(&tree);
            } else {
                log.restore(&mut tree);
                assert_eq!(tree, marked, "seed {seed}, round {round}: the restored tree");
                let fresh = inner_area(&marked);
                assert!((log.inner_area() - fresh).abs() <= 1e-9 * fresh, "seed {seed}: the restored area");
            }
        }
    }
    assert!(moves > 500, "only {moves} moves were made");
}

#[test]
fn the_measure_index_kept_up_to_date_from_the_edit_log_equals_a_fresh_one() {
    // The parallel loop ranks its partial rounds' nodes from an index updated only where the edit log says
    // nodes were written (moves, restores, root changes). After every batch of edits the updated index must
    // equal one built from scratch, and its batches must be the set a full ranking takes (the ordered
    // selection sorts every eligible node by measure, an independent path).
    use bvhc::optimize::{EditLog, MeasureIndex, Selection};
    use rand::RngExt;
    let selections = [Selection::Comb, Selection::Sum, Selection::Min, Selection::Area];
    let mut root_changes = 0;
    for seed in 0..30u64 {
        let triangles = random_triangles(100 + seed, 30 + seed as usize * 11, 10.0);
        let mut tree = tree_for(&triangles, Builder::BinnedSah);
        let mut log = EditLog::new(&tree, inner_area(&tree));
        let mut indexes: Vec<MeasureIndex> = selections.iter().map(|&s| MeasureIndex::new(&tree, s)).collect();
        let mut rng = crate::common::rng(seed);
        for round in 0..8 {
            let root = tree.root;
            for step in 0..6 {
                // Every third move starts at a child of the root, which makes a new root.
                let root_node = tree.nodes[tree.root as usize];
                let n = if step % 3 == 0 && root_node.left != NONE {
                    root_node.left
                } else {
                    rng.random_range(0..tree.nodes.len() as u32)
                };
                let x = rng.random_range(0..tree.nodes.len() as u32);
                let p = tree.nodes[n as usize].parent;
                if p == NONE || x == p || tree.is_in_subtree(x, n) {
                    continue;
                }
                tree.move_beside_logged(n, x, &mut log);
            }
            root_changes += usize::from(tree.root != root);
            check_index_after_edits(&tree, &mut log, &mut indexes, &selections, &mut rng, (seed, round));
            // Restoring writes nodes too, in a round of its own (their moves' writes were taken already).
            match round % 3 {
                0 => log.mark(&tree),
                1 => log.restore(&mut tree),
                _ => {}
            }
            check_index_after_edits(&tree, &mut log, &mut indexes, &selections, &mut rng, (seed, round));
        }
    }
    assert!(root_changes > 5, "only {root_changes} rounds changed the root");
}

/// Updates each index from the log's touched list and checks it against a fresh index and a full ranking.
fn check_index_after_edits(
    tree: &OptTree,
    log: &mut bvhc::optimize::EditLog,
    indexes: &mut [bvhc::optimize::MeasureIndex],
    selections: &[bvhc::optimize::Selection],
    rng: &mut rand_pcg::Pcg64Mcg,
    case: (u64, u32),
) {
    use bvhc::optimize::{MeasureIndex, select_batch, select_batch_with};
    let touched = log.take_touched();
    for (index, &selection) in indexes.iter_mut().zip(selections) {
        index.update(tree, &touched);
        assert!(*index == MeasureIndex::new(tree, selection), "{case:?}, {selection:?}");
        for fraction in [1.0, 0.5, 0.2, 0.05] {
            let mut by_index = select_batch_with(tree, selection, fraction, false, rng, Some(index));
            let mut ranked = select_batch(tree, selection, fraction, true, rng);
            by_index.sort_unstable();
            ranked.sort_unstable();
            assert_eq!(by_index, ranked, "{case:?}, {selection:?}, fraction {fraction}");
        }
    }
}
