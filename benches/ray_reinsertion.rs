//! An experiment for issue 28's last lever: reinsertion judged by sampled rays instead of surface area. Starting
//! from the default conversion's optimized binary tree (SBVH at budget 0.3, the balanced preset's reinsertion over
//! clusters; with `BVHC_REINSERT_START=sah` a binned SAH build optimized without splits), nodes move to
//! where they lower the **sampled cost**: over the inner nodes, the number of training ray segments
//! `[t_min, t_hit]` that enter the node's box (Bittner and Havran, "RDH: Ray Distribution Heuristics", SCCG 2009:
//! the ray-count measure of a box, which the order of a traversal only lowers), plus a prior worth
//! `BVHC_REINSERT_PRIOR` rays (default 32) times the box's share of the root's area, as RSC smooths. That measure
//! is a monotone function of the box like its area, so Bittner's move search (`bvhc::optimize::best_move`:
//! removal boxes along the path, branch and bound on the induced cost) carries over with it in place of areas;
//! each evaluation tests every training ray (sequential, scalar: an experiment, not a pipeline stage). The nodes
//! most rays reach are tried first, `BVHC_REINSERT_NODES` of them (default 5,000), in `BVHC_REINSERT_PASSES`
//! passes (default 1).
//!
//! Both trees are then finished as conversions finish theirs (SAH leaf merge and wide collapse) and measured on
//! rays they were not moved by: the training distribution from seed 99 and the evaluate benchmark's set. Printed:
//! the sampled cost before and after, moves, seconds, and the wide kernel's node visits and packet tests.
//!
//! `cargo bench --bench ray_reinsertion`; `BVHC_REINSERT_SCENES=engine,bunny`, `BVHC_REINSERT_RAYS` (training
//! rays, default 16,384).

#[path = "common/harness.rs"]
mod harness;

#[path = "evaluate/ray_set.rs"]
#[allow(dead_code)]
mod ray_set;

use bvhc::loader::Trace;
use std::time::Instant;

use bvhc::builders::Builder;
use bvhc::builders::sbvh::{SbvhParams, build_sbvh};
use bvhc::convert::merge_and_collapse;
use bvhc::geometry::Aabb;
use bvhc::import::{ImportOptions, import};
use bvhc::layout::cluster_roots;
use bvhc::loader::{BvhFile, Ray, TraversalStats, write::BvhWriter};
use bvhc::optimize::{NONE, OptTree, optimize, optimize_over_clusters};
use bvhc::options::preset::CLUSTER_SIZE;
use bvhc::options::{ConvertOptions, Preset};
use bvhc::pack::{pack, pack_wide};
use bvhc::sampling::{trace_counting, training_rays};

type Triangle = [[f32; 3]; 3];

const SCENES: [(&str, &str); 5] = [
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
    ("toy car", "khr-toy-car/ToyCar.gltf"),
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("buddha", "happy-buddha-decimated/stanford-buddha.obj"),
];

/// Training ray segments in columns: origin, reciprocal direction, and `[t_min, t_hit]`.
struct Segments {
    origin: [Vec<f32>; 3],
    inverse: [Vec<f32>; 3],
    t_min: Vec<f32>,
    t_hit: Vec<f32>,
    /// The surface-area estimate's weight in rays, `prior / SA(root)` a unit of area (RSC's smoothing).
    prior_per_area: f32,
}

impl Segments {
    /// Each ray up to its closest hit in `tree` (its `t_max` where it hits nothing).
    fn new(tree: &OptTree, triangles: &[Triangle], rays: &[Ray], prior: f32) -> Segments {
        let mut visits = vec![0u32; tree.nodes.len()];
        let root_area = tree.nodes[tree.root as usize].aabb.surface_area() as f32;
        let mut s = Segments {
            origin: Default::default(),
            inverse: Default::default(),
            t_min: Vec::new(),
            t_hit: Vec::new(),
            prior_per_area: if root_area > 0.0 { prior / root_area } else { 0.0 },
        };
        for ray in rays {
            let hit = trace_counting(tree, triangles, ray, &mut visits).map_or(ray.t_max, |h| h.t);
            for a in 0..3 {
                s.origin[a].push(ray.origin[a]);
                s.inverse[a].push(1.0 / ray.direction[a]);
            }
            s.t_min.push(ray.t_min);
            s.t_hit.push(hit);
        }
        s
    }

    /// How many segments enter `b` (the slab test; a zero direction component gives infinite slab distances),
    /// plus the prior's share of `b`'s area: still a monotone function of the box.
    fn count(&self, b: &Aabb) -> f32 {
        let mut n = 0u32;
        for i in 0..self.t_min.len() {
            let mut near = self.t_min[i];
            let mut far = self.t_hit[i];
            for a in 0..3 {
                let t0 = (b.min[a] - self.origin[a][i]) * self.inverse[a][i];
                let t1 = (b.max[a] - self.origin[a][i]) * self.inverse[a][i];
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            n += u32::from(near <= far);
        }
        n as f32 + self.prior_per_area * b.surface_area() as f32
    }
}

/// The best sibling for box `l` under `start` by sampled counts (Bittner's branch and bound with counts for
/// areas), if one gives a total below `best`: `(total, node)`.
fn search(
    tree: &OptTree,
    s: &Segments,
    l: &Aabb,
    count_l: f32,
    start: u32,
    base: f32,
    best: f32,
) -> Option<(f32, u32)> {
    let mut best = best;
    let mut found = None;
    let mut heap: Vec<(f32, u32)> = vec![(0.0, start)];
    while let Some(k) = (0..heap.len()).min_by(|&a, &b| heap[a].0.total_cmp(&heap[b].0)) {
        let (induced, node) = heap.swap_remove(k);
        if base + induced + count_l >= best {
            break;
        }
        let x = &tree.nodes[node as usize];
        let direct = s.count(&x.aabb.union(l));
        if base + induced + direct < best {
            best = base + induced + direct;
            found = Some((best, node));
        }
        if x.left != NONE {
            let below = induced + direct - s.count(&x.aabb);
            if base + below + count_l < best {
                heap.push((below, x.left));
                heap.push((below, x.right));
            }
        }
    }
    found
}

/// The move of `n` that lowers the sampled cost most (`best_move`'s walk up the path with counts), if any:
/// `(delta, target)`.
fn best_sampled_move(tree: &OptTree, s: &Segments, n: u32) -> Option<(f32, u32)> {
    let p = tree.nodes[n as usize].parent;
    if p == NONE {
        return None;
    }
    let l = tree.nodes[n as usize].aabb;
    let count_l = s.count(&l);
    let mut base = -s.count(&tree.nodes[p as usize].aabb);
    let mut best = -0.5f32;
    let mut found = None;
    let sibling = tree.sibling(n);
    let mut removal = tree.nodes[sibling as usize].aabb;
    if let Some(hit) = search(tree, s, &l, count_l, sibling, base, best) {
        (best, found) = (hit.0, Some(hit));
    }
    let mut ancestor = p;
    loop {
        let above = tree.nodes[ancestor as usize].parent;
        if above == NONE {
            break;
        }
        let above_node = tree.nodes[above as usize];
        let off_path = if above_node.left == ancestor { above_node.right } else { above_node.left };
        if let Some(hit) = search(tree, s, &l, count_l, off_path, base, best) {
            (best, found) = (hit.0, Some(hit));
        }
        removal = removal.union(&tree.nodes[off_path as usize].aabb);
        let removal_count = s.count(&removal);
        if base + removal_count < best {
            best = base + removal_count;
            found = Some((best, above));
        }
        base += removal_count - s.count(&above_node.aabb);
        ancestor = above;
    }
    found
}

/// The sampled cost: segments entering each inner node's box, summed.
fn sampled_cost(tree: &OptTree, s: &Segments) -> f64 {
    tree.nodes.iter().filter(|n| n.left != NONE).map(|n| f64::from(s.count(&n.aabb))).sum()
}

fn main() {
    let full = harness::benchmarking("ray_reinsertion");
    let scenes = harness::scenes(&SCENES, Some("BVHC_REINSERT_SCENES"));
    let scenes = if full { scenes } else { scenes.into_iter().take(1).collect() };
    let number = |v: &str, default: usize| std::env::var(v).ok().and_then(|s| s.parse().ok()).unwrap_or(default);
    let (ray_count, node_budget, passes) =
        (number("BVHC_REINSERT_RAYS", 16_384), number("BVHC_REINSERT_NODES", 5_000), number("BVHC_REINSERT_PASSES", 1));
    let prior = number("BVHC_REINSERT_PRIOR", 32) as f32;
    let default_start = std::env::var("BVHC_REINSERT_START").map_or(true, |v| v != "sah");
    let (ray_count, node_budget) = if full { (ray_count, node_budget) } else { (256, 200) };
    println!(
        "training rays {ray_count} (seed 1), prior {prior} rays, nodes tried a pass {node_budget}, passes {passes}, \
         start: {}",
        if default_start {
            "SBVH 0.3 optimized over clusters (the default conversion's)"
        } else {
            "binned SAH optimized, no splits"
        }
    );
    println!(
        "| scene | sampled cost SAH tree | moved | moves | seconds | rays | wide visits SAH | moved | ratio | packet tests SAH | moved | ratio |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (name, path) in scenes {
        let triangles = import(&path, &ImportOptions::default()).expect("imports").soup.triangle_vertices();
        let (tree, repeats) = start_tree(&triangles, default_start);
        let segments = Segments::new(&tree, &triangles, &training_rays(&tree, &triangles, ray_count, 1), prior);
        let before = sampled_cost(&tree, &segments);
        let mut moved = tree.clone();
        let start = Instant::now();
        let mut moves = 0;
        for _ in 0..passes {
            let mut order: Vec<(f32, u32)> = (0..moved.nodes.len() as u32)
                .filter(|&i| i != moved.root && moved.nodes[i as usize].parent != NONE)
                .map(|i| (segments.count(&moved.nodes[i as usize].aabb), i))
                .collect();
            order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            for &(_, n) in order.iter().take(node_budget) {
                if moved.nodes[n as usize].parent == NONE {
                    continue;
                }
                if let Some((_, target)) = best_sampled_move(&moved, &segments, n) {
                    moved.move_beside_logged(n, target, &mut ());
                    moves += 1;
                }
            }
        }
        let seconds = start.elapsed().as_secs_f64();
        let after = sampled_cost(&moved, &segments);
        let (sah_file, moved_file) = (file_of(&tree, &triangles, repeats), file_of(&moved, &triangles, repeats));
        let held_out = training_rays(&tree, &triangles, if full { 1 << 17 } else { 2048 }, 99);
        let (min, max) = sah_file.view().scene_box().expect("a scene");
        let other = ray_set::ray_set(&sah_file.view().tracer(), min, max);
        let other: Vec<Ray> = [other.primary, other.ao, other.incoherent].concat();
        for (set, rays) in [("same distribution, seed 99", &held_out), ("evaluate set", &other)] {
            let (a, b) = (wide_counts(&sah_file, rays), wide_counts(&moved_file, rays));
            println!(
                "| {name} | {before:.0} | {after:.0} | {moves} | {seconds:.1} | {set} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |",
                a.0,
                b.0,
                b.0 / a.0,
                a.1,
                b.1,
                b.1 / a.1
            );
        }
    }
}

/// The tree the experiment starts from: the balanced preset's reinsertion over a binned SAH build, or with
/// `default_start` over the default conversion's SBVH (budget 0.3, split references) and clusters; and whether
/// its leaves repeat triangles.
fn start_tree(triangles: &[Triangle], default_start: bool) -> (OptTree, bool) {
    let params = Preset::Balanced.optimize_params();
    let mut go = |_: &bvhc::optimize::Progress| std::ops::ControlFlow::Continue(());
    if !default_start {
        let mut tree = OptTree::from_build(Builder::BinnedSah.build(triangles, 1), triangles);
        optimize(&mut tree, &params, &mut go);
        return (tree, false);
    }
    let build = build_sbvh(triangles, &SbvhParams::with_budget(0.3));
    let repeats = build.triangle_order.len() > triangles.len();
    let mut tree = OptTree::from_build(build, triangles);
    let roots = cluster_roots(&tree, params.constants, CLUSTER_SIZE);
    optimize_over_clusters(&mut tree, &params, &roots, &mut go);
    (tree, repeats)
}

/// An in-memory file of `tree` finished as conversions finish theirs (default options: SAH leaf merge, wide
/// collapse, both packed; with `repeats`, split references held once a leaf).
fn file_of(tree: &OptTree, triangles: &[Triangle], repeats: bool) -> BvhFile {
    let (binary, wide) = merge_and_collapse(tree, &ConvertOptions::default(), triangles.len(), repeats);
    let (wide, _) = wide.expect("the default options collapse a wide tree");
    let packed = pack(&binary, triangles).expect("memory for the packed tree");
    let split = packed.triangles.len() > triangles.len();
    let mut records = packed.record_cursor(triangles.len()).expect("memory");
    let bvh = pack_wide(&wide, &packed.triangles, &mut |t| records.next(t), split).unwrap();
    BvhWriter::new(&packed.nodes, &packed.triangles)
        .split_references(split)
        .wide(bvh.nodes(), bvh.packets())
        .build()
        .unwrap()
}

/// Wide-kernel node visits and packet tests per ray (closest hits).
fn wide_counts(file: &BvhFile, rays: &[Ray]) -> (f64, f64) {
    let tracer = file.view().tracer();
    let mut stats = TraversalStats::default();
    for ray in rays {
        tracer.closest_hit_counted(ray, &mut stats);
    }
    (stats.node_visits as f64 / rays.len() as f64, stats.triangle_tests as f64 / rays.len() as f64)
}
