//! The wide collapse (Ylitie et al. 2017) against oracles: the tree's invariants on random scenes and widths,
//! the binary tree itself at width 2 with single-triangle leaves, and the minimum over every possible collapse
//! of small trees, enumerated exhaustively and priced independently.

use bvhc::builders::Builder;
use bvhc::geometry::Aabb;
use bvhc::layout::{WideChild, WideCosts, WideTree, collapse};
use bvhc::optimize::{NONE, OptTree};
use bvhc_loader::Trace;

use crate::common::{Triangle, random_triangles};

fn binary(triangles: &[Triangle]) -> OptTree {
    OptTree::from_build_tree(&Builder::BinnedSah.build(triangles, 1), triangles)
}

/// Every invariant of `WideTree` (see its doc) over `triangles`.
fn check(wide: &WideTree, triangles: &[Triangle], costs: &WideCosts) {
    if wide.nodes.is_empty() {
        assert!(triangles.is_empty());
        return;
    }
    let mut referenced = vec![0u32; wide.nodes.len()];
    let mut next_triangle = 0u32;
    let mut seen = vec![false; triangles.len()];
    visit(wide, 0, triangles, costs, &mut referenced, &mut next_triangle, &mut seen);
    assert_eq!(next_triangle as usize, triangles.len());
    assert!(seen.iter().all(|&s| s));
    assert!(referenced.iter().skip(1).all(|&r| r == 1), "every node but the root has one parent");
}

/// Depth first in child order, checking node `i`'s children.
fn visit(
    wide: &WideTree,
    i: u32,
    triangles: &[Triangle],
    costs: &WideCosts,
    referenced: &mut [u32],
    next_triangle: &mut u32,
    seen: &mut [bool],
) {
    let node = &wide.nodes[i as usize];
    assert!(
        node.children.len() <= wide.width && !node.children.is_empty(),
        "node {i} has {} children",
        node.children.len()
    );
    assert!(node.children.len() >= 2 || wide.nodes.len() == 1, "node {i} has one child");
    for (aabb, child) in &node.children {
        match *child {
            WideChild::Node(c) => {
                assert!(c > i, "child {c} before its parent {i}");
                referenced[c as usize] += 1;
                assert_eq!(*aabb, subtree_box(wide, c, triangles), "box of child node {c}");
                visit(wide, c, triangles, costs, referenced, next_triangle, seen);
            }
            WideChild::Leaf { first, count } => {
                assert!(count >= 1 && count as usize <= costs.max_leaf_size.max(1) || wide.nodes.len() == 1);
                assert_eq!(first, *next_triangle, "leaves consecutive in depth-first order");
                *next_triangle += count;
                let mut union = Aabb::EMPTY;
                for &t in &wide.triangle_order[first as usize..(first + count) as usize] {
                    assert!(!std::mem::replace(&mut seen[t as usize], true), "triangle {t} twice");
                    union = union.union(&Aabb::of_triangle(&triangles[t as usize]));
                }
                assert_eq!(*aabb, union, "leaf box");
            }
        }
    }
}

fn subtree_box(wide: &WideTree, i: u32, triangles: &[Triangle]) -> Aabb {
    wide.nodes[i as usize].children.iter().fold(Aabb::EMPTY, |b, (_, child)| match *child {
        WideChild::Node(c) => b.union(&subtree_box(wide, c, triangles)),
        WideChild::Leaf { first, count } => wide.triangle_order[first as usize..(first + count) as usize]
            .iter()
            .fold(b, |b, &t| b.union(&Aabb::of_triangle(&triangles[t as usize]))),
    })
}

#[test]
fn collapsed_trees_keep_every_invariant() {
    for (seed, count) in [(1u64, 1usize), (2, 2), (3, 5), (4, 37), (5, 500), (6, 3000)] {
        let triangles = random_triangles(seed, count, 10.0);
        let tree = binary(&triangles);
        for width in [2, 3, 4, 8] {
            for max_leaf_size in [1, 4, 8] {
                let costs = WideCosts { width, max_leaf_size, ..WideCosts::default() };
                let wide = collapse(&tree, &costs);
                check(&wide, &triangles, &costs);
                assert!(wide.cost(&costs).is_finite());
            }
        }
    }
    assert!(collapse(&OptTree::from_build_tree(&Default::default(), &[]), &WideCosts::default()).nodes.is_empty());
}

#[test]
fn width_two_with_single_leaves_is_the_binary_tree() {
    let triangles = random_triangles(7, 400, 5.0);
    let tree = binary(&triangles);
    let costs = WideCosts { width: 2, packet_width: 1, max_leaf_size: 1, node_visit: 3.0, packet_test: 2.0 };
    let wide = collapse(&tree, &costs);
    assert_eq!(wide.nodes.len(), triangles.len() - 1, "one wide node per binary inner node");
    let binary_cost =
        bvhc::optimize::cost_of(&tree, bvhc::cost::SahConstants { traversal: 3.0, intersection: 2.0 }).cost;
    assert!((wide.cost(&costs) - binary_cost).abs() <= 1e-9 * binary_cost, "{} vs {binary_cost}", wide.cost(&costs));
}

/// A collapse choice: a binary node kept as a leaf, or as a wide node whose children are these choices.
#[derive(Clone)]
enum Choice {
    Leaf(u32),
    Node(u32, Vec<Choice>),
}

/// Every way binary node `n` can appear as at most `slots` children of a wide node.
fn forests(tree: &OptTree, n: u32, slots: usize, costs: &WideCosts, triangles: &[u32]) -> Vec<Vec<Choice>> {
    let mut out: Vec<Vec<Choice>> = singles(tree, n, costs, triangles).into_iter().map(|c| vec![c]).collect();
    let node = tree.nodes[n as usize];
    if node.left != NONE && slots >= 2 {
        for k in 1..slots {
            for left in forests(tree, node.left, k, costs, triangles) {
                for right in forests(tree, node.right, slots - k, costs, triangles) {
                    out.push(left.iter().chain(&right).cloned().collect());
                }
            }
        }
    }
    out
}

/// Every way binary node `n` can be one child: a leaf (if small enough) or a wide node.
fn singles(tree: &OptTree, n: u32, costs: &WideCosts, triangles: &[u32]) -> Vec<Choice> {
    let node = tree.nodes[n as usize];
    let mut out = Vec::new();
    if triangles[n as usize] as usize <= costs.max_leaf_size {
        out.push(Choice::Leaf(n));
    }
    if node.left != NONE {
        for k in 1..costs.width {
            for left in forests(tree, node.left, k, costs, triangles) {
                for right in forests(tree, node.right, costs.width - k, costs, triangles) {
                    out.push(Choice::Node(n, left.iter().chain(&right).cloned().collect()));
                }
            }
        }
    }
    out
}

fn price(tree: &OptTree, choice: &Choice, costs: &WideCosts, triangles: &[u32]) -> f64 {
    match choice {
        Choice::Leaf(n) => costs.leaf(triangles[*n as usize] as usize) * tree.nodes[*n as usize].aabb.surface_area(),
        Choice::Node(n, children) => {
            costs.node_visit * tree.nodes[*n as usize].aabb.surface_area()
                + children.iter().map(|c| price(tree, c, costs, triangles)).sum::<f64>()
        }
    }
}

#[test]
fn the_collapse_is_optimal_for_the_binary_topology() {
    for seed in 0..40u64 {
        let triangles = random_triangles(100 + seed, 2 + (seed as usize % 6), 10.0);
        let tree = binary(&triangles);
        let mut count = vec![0u32; tree.nodes.len()];
        for &i in tree.depth_first().iter().rev() {
            let node = tree.nodes[i as usize];
            count[i as usize] =
                if node.left == NONE { 1 } else { count[node.left as usize] + count[node.right as usize] };
        }
        for (width, max_leaf_size, packet_width, packet_test) in
            [(2, 1, 1, 1.0), (3, 2, 1, 2.0), (4, 4, 2, 1.5), (4, 3, 4, 0.7)]
        {
            let costs = WideCosts { width, packet_width, max_leaf_size, node_visit: 1.0, packet_test };
            let root_area = tree.nodes[tree.root as usize].aabb.surface_area();
            // The root is a wide node (the collapse never makes a lone leaf of a scene over the leaf limit).
            let mut candidates: Vec<Choice> = singles(&tree, tree.root, &costs, &count)
                .into_iter()
                .filter(|c| matches!(c, Choice::Node(..)) || count[tree.root as usize] as usize <= max_leaf_size)
                .collect();
            // A root leaf is stored as a wide root with one leaf child: priced as node + leaf.
            for c in &mut candidates {
                if let Choice::Leaf(n) = c {
                    *c = Choice::Node(*n, vec![Choice::Leaf(*n)]);
                }
            }
            let best =
                candidates.iter().map(|c| price(&tree, c, &costs, &count)).fold(f64::INFINITY, f64::min) / root_area;
            let wide = collapse(&tree, &costs);
            check(&wide, &triangles, &costs);
            let got = wide.cost(&costs);
            assert!((got - best).abs() <= 1e-9 * best, "seed {seed} width {width}: collapse {got}, exhaustive {best}");
        }
    }
}

/// Wide traversal (every kernel path) equals the binary kernel and brute force: closest t (a triangle at that t)
/// and any hit, on random scenes and the stress scenes' kinds of rays (axis-parallel, +0/-0 components).
#[test]
fn wide_traversal_equals_binary_traversal_and_brute_force_on_every_path() {
    use bvhc::loader::{KernelPath, WideTracer, format::PackedTriangle};
    for (seed, count, extent) in [(11u64, 1usize, 1.0f32), (12, 7, 1.0), (13, 300, 10.0), (14, 3000, 100.0)] {
        let triangles = random_triangles(seed, count, extent);
        let tree = binary(&triangles);
        let packed: Vec<PackedTriangle> = triangles.iter().map(|&vertices| PackedTriangle { vertices }).collect();
        let ids: Vec<u32> = (0..triangles.len() as u32).map(|i| 1000 + i).collect();
        let binary_file = crate::common::write_file(&crate::common::packed_tree(&triangles, 4));
        let binary_tracer = binary_file.view().tracer();
        let rays = crate::common::random_rays(seed + 50, 4000, extent * 1.5);
        for (width, max_leaf_size) in [(8, 8), (4, 4), (8, 1)] {
            let wide = collapse(&tree, &WideCosts { width, max_leaf_size, ..WideCosts::default() });
            let bvh = bvhc::pack::pack_wide(&wide, &packed, &mut Some, false).unwrap();
            for path in [KernelPath::Portable, KernelPath::Avx2] {
                if !path.is_supported() {
                    crate::skips::skipped(
                        crate::skips::Needs::Machine,
                        format!("part: kernel path {path:?} (not supported on this machine)"),
                    );
                    continue;
                }
                let tracer = WideTracer::new(&bvh, Some(&ids), path);
                for ray in &rays {
                    let ours = tracer.closest_hit(ray);
                    let reference = binary_tracer.closest_hit(ray);
                    assert_eq!(ours.map(|h| h.t), reference.map(|h| h.t), "{path:?} width {width}: {ray:?}");
                    if let Some(hit) = ours {
                        assert_eq!(hit.source_triangle_id, Some(1000 + hit.triangle_index));
                        let brute = crate::common::brute_force_closest(&triangles, ray).unwrap();
                        assert_eq!(hit.t, brute.0);
                        let prepared = bvhc::loader::ray::PreparedRay::new(ray);
                        let at_t = prepared.intersect_triangle(&packed[hit.triangle_index as usize], f32::INFINITY);
                        assert_eq!(at_t.map(|h| h.t), Some(hit.t), "the reported triangle is hit at t");
                    }
                    assert_eq!(tracer.any_hit(ray), binary_tracer.any_hit(ray), "{path:?}: any hit {ray:?}");
                }
            }
        }
    }
}

#[test]
fn wide_layout_refuses_lanes_that_do_not_match_the_triangles() {
    use bvhc::loader::{Rule, format::PackedTriangle, wide::WideBvh};
    let triangles = random_triangles(300, 200, 1.0);
    let good = crate::common::wide_bvh(&triangles);
    let packed: Vec<PackedTriangle> = triangles.iter().map(|&vertices| PackedTriangle { vertices }).collect();
    let root = ([-10.0; 3], [10.0; 3]);
    let rebuild = |nodes: Vec<_>, packets: Vec<_>, tris: &[PackedTriangle]| WideBvh::new(nodes, packets, root, tris);
    assert!(rebuild(good.nodes().to_vec(), good.packets().to_vec(), &packed).is_ok());
    // A lane whose vertices differ from the triangle it names.
    let mut packets = good.packets().to_vec();
    packets[0].vertices[0][0][0] += 1.0;
    let error = rebuild(good.nodes().to_vec(), packets, &packed).unwrap_err();
    assert_eq!(error.rule, Rule::PacketLanes);
    assert!(error.detail.contains("packet 0 lane 0"), "{error}");
    // A triangle that no lane holds.
    let mut more = packed.clone();
    more.push(packed[0]);
    let error = rebuild(good.nodes().to_vec(), good.packets().to_vec(), &more).unwrap_err();
    assert_eq!(error.rule, Rule::LaneCoverage);
    assert!(error.detail.contains("in no packet lane"), "{error}");
    // Two lanes naming one triangle.
    let mut packets = good.packets().to_vec();
    crate::common::repeat_first_lane_in_last(&mut packets);
    assert_eq!(rebuild(good.nodes().to_vec(), packets, &packed).unwrap_err().rule, Rule::LaneCoverage);
    // A leaf pointing past the packets.
    let mut nodes = good.nodes().to_vec();
    let slot = nodes[0].child.iter().position(|&c| c != bvhc::loader::format::EMPTY_SLOT).unwrap();
    nodes[0].child[slot] = bvhc::loader::format::WideNode8::leaf(good.packets().len() as u32, 1).unwrap();
    assert_eq!(rebuild(nodes, good.packets().to_vec(), &packed).unwrap_err().rule, Rule::WideSlots);
}

/// The stream entry points (rays interleaved, and one by one) give each ray's single-ray answer, on every path,
/// for more rays than a stream keeps in flight, rays that miss the root among them, and groups of 8 rays that
/// share their origin bit for bit or start close together in one direction octant, which the stream traces as
/// packets: from one point in mixed directions (so mixed shear axes in a packet, as ambient-occlusion rays), a
/// camera's fan whose last group takes in a ray from elsewhere, segments from nearby points toward a light
/// (some groups with a ray of another octant), then rays from everywhere.
#[test]
fn streams_of_rays_equal_single_rays_on_every_path() {
    use bvhc::loader::Ray;
    for (seed, count) in [(21u64, 1usize), (22, 500), (23, 3000)] {
        let triangles = random_triangles(seed, count, 10.0);
        let file = crate::common::write_wide_file(&triangles, 4);
        let view = file.view();
        let mut rays = Vec::new();
        for (p, point) in crate::common::random_rays(seed + 5, 20, 8.0).iter().enumerate() {
            let directions = crate::common::random_rays(seed + 100 + p as u64, 16, 1.0);
            rays.extend(directions.iter().map(|d| Ray::new(point.origin, d.direction)));
        }
        for y in 0..23 {
            for x in 0..41 {
                rays.push(Ray::new([0.5, 0.25, 25.0], [x as f32 / 20.0 - 1.0, y as f32 / 11.0 - 1.0, -1.0]));
            }
        }
        // Segments from a patch of nearby points toward one light (one octant, origins close but not equal),
        // which the stream traces as packets, then the same with one ray of each group turned away.
        for y in 0..9 {
            for x in 0..24 {
                let origin = [x as f32 * 0.02 - 0.3, y as f32 * 0.03 - 0.1, -6.0 + x as f32 * 0.01];
                let direction = [2.0 - origin[0], 3.0 - origin[1], 30.0 - origin[2]];
                let turned = y % 2 == 1 && x % 8 == 5;
                let direction = if turned { [-direction[0], direction[1], direction[2]] } else { direction };
                rays.push(Ray { t_max: 0.999, ..Ray::new(origin, direction) });
            }
        }
        rays.extend(crate::common::random_rays(seed + 7, 1500, 15.0));
        rays.push(bvhc::loader::Ray::new([100.0, 100.0, 100.0], [1.0, 0.0, 0.0])); // misses the root's box
        for path in crate::common::kernel_paths() {
            for interleave in [true, false] {
                let wide = view.wide_tracer(path).unwrap().interleaving_streams(interleave);
                let mut hits = vec![None; rays.len()];
                let mut occluded = vec![false; rays.len()];
                wide.closest_hits(&rays, &mut hits);
                wide.any_hits(&rays, &mut occluded);
                for (i, ray) in rays.iter().enumerate() {
                    assert_eq!(hits[i], wide.closest_hit(ray), "{path:?} interleave {interleave}: ray {i}");
                    assert_eq!(occluded[i], wide.any_hit(ray), "{path:?} interleave {interleave}: ray {i}");
                }
                // Through Tracer: the same hits; more output slots than rays is a caller's bug, refused.
                let tracer = view.binary_tracer().with_wide(wide);
                let mut same = vec![None; rays.len()];
                tracer.closest_hits(&rays, &mut same);
                assert_eq!(same, hits);
                // Handed off lean: each hit's core, from the wide tracer and through Tracer, in either order.
                for order in [bvhc::loader::Order::Stream, bvhc::loader::Order::Coherent] {
                    let mut cores = vec![None; rays.len()];
                    wide.closest_hit_cores_with(&rays, order, |i, core| cores[i] = core).unwrap();
                    assert!(cores.iter().zip(&hits).all(|(core, hit)| *core == hit.map(|h| h.core())), "{order:?}");
                    let mut through = vec![None; rays.len()];
                    tracer.closest_hit_cores_with(&rays, order, |i, core| through[i] = core).unwrap();
                    assert_eq!(through, cores);
                }
                let mut more = vec![None; rays.len() + 3];
                let refused = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    tracer.closest_hits(&rays, &mut more);
                }));
                assert!(refused.is_err(), "unequal slices are refused");
            }
        }
        // The binary kernel's streams, too.
        let binary = view.binary_tracer();
        let mut hits = vec![None; rays.len()];
        binary.closest_hits(&rays, &mut hits);
        assert!(rays.iter().zip(&hits).all(|(ray, hit)| binary.closest_hit(ray) == *hit));
    }
}

/// Coherent packets (8 consecutive rays a traversal) give every ray the single-ray kernel's closest t, a
/// triangle hit at that t, and its any-hit answer, on every path: camera-like fans of rays, rays from inside
/// the scene, axis-parallel rays with +0/-0 components, rays with mixed direction signs in one packet, packets
/// of one octant from nearby origins (culled by their frustum), a packet cut short, and rays that miss the
/// root's box.
#[test]
fn coherent_packets_equal_single_rays_on_every_path() {
    use bvhc::loader::{Ray, ray::PreparedRay};
    for (seed, count) in [(31u64, 1usize), (32, 400), (33, 4000)] {
        let triangles = random_triangles(seed, count, 10.0);
        let file = crate::common::write_wide_file(&triangles, 4);
        let view = file.view();
        let mut rays: Vec<Ray> = Vec::new();
        // A camera: a 41 x 23 fan from one eye (41 * 23 is not a multiple of 8).
        for y in 0..23 {
            for x in 0..41 {
                let d = [x as f32 / 20.0 - 1.0, y as f32 / 11.0 - 1.0, -1.0];
                rays.push(Ray::new([0.5, 0.25, 25.0], d));
            }
        }
        rays.extend(crate::common::random_rays(seed + 3, 800, 15.0));
        // Packets of one octant from eight nearby origins (the frustum's case: each group's bounds span its
        // origins and directions), aimed at random points, so that rays graze the boxes the frustum bounds.
        for (g, base) in crate::common::random_rays(seed + 9, 120, 12.0).iter().enumerate() {
            if base.direction.contains(&0.0) {
                continue;
            }
            for k in 0..8 {
                let jitter = |a: usize| ((k * 3 + a * 5 + g) % 7) as f32 * 0.02 - 0.06;
                let origin = std::array::from_fn(|a| base.origin[a] + jitter(a));
                let direction = std::array::from_fn(|a| base.direction[a] * (1.0 + 0.01 * jitter(2 - a)));
                rays.push(Ray::new(origin, direction));
            }
        }
        rays.push(Ray::new([100.0, 100.0, 100.0], [1.0, 0.0, 0.0]));
        for path in crate::common::kernel_paths() {
            let wide = view.wide_tracer(path).unwrap();
            let mut hits = vec![None; rays.len()];
            let mut occluded = vec![false; rays.len()];
            wide.closest_hits_coherent(&rays, &mut hits);
            wide.any_hits_coherent(&rays, &mut occluded);
            for (i, ray) in rays.iter().enumerate() {
                let single = wide.closest_hit(ray);
                assert_eq!(hits[i].map(|h| h.t), single.map(|h| h.t), "{path:?}: ray {i} {ray:?}");
                if let Some(hit) = hits[i] {
                    let triangle = &view.triangles()[hit.triangle_index as usize];
                    let again = PreparedRay::new(ray).intersect_triangle(triangle, f32::INFINITY);
                    assert_eq!(again.map(|h| h.t), Some(hit.t), "{path:?}: ray {i}: the reported triangle is hit at t");
                    assert_eq!(hit.source_triangle_id, view.triangle_ids().map(|ids| ids[hit.triangle_index as usize]));
                }
                assert_eq!(occluded[i], wide.any_hit(ray), "{path:?}: any hit, ray {i}");
            }
            let tracer = view.binary_tracer().with_wide(wide);
            let mut through_tracer = vec![None; rays.len()];
            tracer.closest_hits_coherent(&rays, &mut through_tracer);
            assert_eq!(through_tracer, hits);
        }
        // The portable and the SIMD paths agree hit for hit (same visit order, same arithmetic).
        let paths = crate::common::kernel_paths();
        let per_path: Vec<Vec<Option<bvhc::loader::Hit>>> = paths
            .iter()
            .map(|&path| {
                let mut hits = vec![None; rays.len()];
                view.wide_tracer(path).unwrap().closest_hits_coherent(&rays, &mut hits);
                hits
            })
            .collect();
        assert!(per_path.windows(2).all(|w| w[0] == w[1]), "paths disagree");
    }
}
