//! Run time against error, in the columns of the reference table (`../shared/guide/algorithm.md`): for each
//! scene, SAH cost, end-point overlap (EPO, Aila, Karras and Laine 2013: `bvhc::epo`), references per
//! triangle, build and optimization seconds, render seconds (a fixed set of primary, ambient occlusion and
//! incoherent rays through the loader's binary kernel on all threads; in brackets relative to M = 1), and
//! average traversal steps and triangle tests per ray. Methods: M = 1 (spatial median), the binned SAH start,
//! M = 2 (optimized, one reference per leaf) and M = 3 (leaves merged) for the balanced and max-quality presets,
//! the balanced preset over split references (`bvhc::split`: pre-split at budget 0.1, the SBVH at 0.1 and 0.3,
//! the SBVH 0.3 optimized over clusters as default conversions make it, and an SBVH that cuts every triangle
//! at the paper's overlap threshold), and, side by
//! side in the same run, obvhs 0.4's presets (`very_slow_build` with its pre-splits, as the preset has them,
//! without, and at one primitive a leaf), svenstaro's `bvh` 0.13 and, with `--features tinybvh`, tinybvh's
//! SBVH (`common/tinybvh.rs`), their trees repacked into the `.bvh` layout so that one cost definition and one
//! kernel measure all of them. "error" is the cost above the lowest cost any method reached on that scene.
//! Under the table: which peer trees lack triangles or fail the loader's coverage rule for split references,
//! a least squares fit of the kernel's cost a step and a test, and the default tree merged with other
//! constants, timed.
//!
//! A second table per scene times what a user of `bvhc` gets: files converted with the default options under
//! each split setting (`--no-splits`, `--split-budget`, `--split-method`, `--split-triangles`) and
//! optimizer setting (`--optimize-over`), and obvhs's
//! one-a-leaf tree finished into a file as conversions finish theirs, traced through the file's default kernel (the wide one) with the
//! same rays, in rounds (see [`files_table`]); steps and isect there count wide node visits and packet tests.
//!
//! `cargo bench --bench evaluate [--features tinybvh]` prints Markdown. `BVHC_EVAL_SCENES=kitchen,dragon` picks scenes,
//! `BVHC_EVAL_FILES_ONLY=1` prints only the second table, `BVHC_SCENES` overrides the folder.

#[path = "common/harness.rs"]
mod harness;
#[cfg(feature = "tinybvh")]
#[path = "common/tinybvh.rs"]
mod tinybvh;

use std::time::{Duration, Instant};

use bvhc::build_tree::{BuildNode, BuildTree};
use bvhc::builders::Builder;
use bvhc::builders::sbvh::{SbvhParams, build_sbvh};
use bvhc::builders::split_triangles;
use bvhc::convert::{convert_with, merge_and_collapse};
use bvhc::cost::{SahConstants, sah_of_packed};
use bvhc::epo::end_point_overlap;
use bvhc::geometry::Aabb;
use bvhc::import::{ImportOptions, import};
use bvhc::layout::{cluster_roots, records};
use bvhc::layout::{merge_leaves, merge_leaves_of_references};
use bvhc::loader::{BvhFile, BvhWriter, Ray, Tracer, TraversalStats};
use bvhc::optimize::{OptTree, optimize, optimize_over_clusters};
use bvhc::options::Preset;
use bvhc::options::preset::CLUSTER_SIZE;
use bvhc::options::{ConvertOptions, OptimizeOver, SplitMethod, SplitOptions, SplitTriangles};
use bvhc::pack::pack;
use bvhc::pack::pack_wide;
use obvhs::BvhBuildParams;
use rayon::prelude::*;

type Triangle = [[f32; 3]; 3];

const SCENES: &[(&str, &str)] = &[
    ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
    ("igea", "aj-igea/igea.ply"),
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ("dragon-res2", "stanford-dragon/dragon_vrip_res2.ply.gz"),
    ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
    ("toycar", "khr-toy-car/ToyCar.gltf"),
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("milktruck", "khr-cesium-milk-truck/CesiumMilkTruck.gltf"),
];

struct Method {
    name: String,
    build: Duration,
    optimize: Option<Duration>,
    tree: BuildTree,
}

fn timed<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let start = Instant::now();
    let value = f();
    (value, start.elapsed())
}

fn ours(triangles: &[Triangle]) -> Vec<Method> {
    let constants = SahConstants::default();
    let mut methods = Vec::new();
    let (median, t) = timed(|| Builder::SpatialMedian.build(triangles, 1));
    methods.push(Method { name: "M=1 spatial median".into(), build: t, optimize: None, tree: median });
    let (sah, build) = timed(|| Builder::BinnedSah.build(triangles, 1));
    methods.push(Method { name: "binned SAH start".into(), build, optimize: None, tree: sah.clone() });
    for preset in [Preset::Balanced, Preset::MaxQuality] {
        let mut tree = OptTree::from_build_tree(&sah, triangles);
        let report = optimize(&mut tree, &preset.optimize_params(), &mut |_| std::ops::ControlFlow::Continue(()));
        let (merged, merge_time) = timed(|| merge_leaves(&tree, constants, 8));
        let single = merge_leaves(&tree, constants, 1);
        methods.push(Method {
            name: format!("M=2 {}", preset.name()),
            build,
            optimize: Some(report.elapsed),
            tree: single,
        });
        methods.push(Method {
            name: format!("M=3 {}", preset.name()),
            build,
            optimize: Some(report.elapsed + merge_time),
            tree: merged,
        });
    }
    let pre_split = |budget| {
        let (references, split_time) = timed(|| split_triangles(triangles, budget));
        let (build, build_time) = timed(|| Builder::BinnedSah.build_references(&references));
        (build, split_time + build_time)
    };
    let spatial = |params: SbvhParams| timed(|| build_sbvh(triangles, &params));
    // The SBVH as conversions run it, and one that cuts every triangle wherever the paper's threshold allows.
    let every = SbvhParams { alpha: 1e-5, min_waste_ratio: 0.0, ..SbvhParams::with_budget(0.3) };
    // The default conversion's tree is the SBVH 0.3 optimized over clusters (`--optimize-over clusters`).
    let builds = [
        ("pre-split 0.1".to_string(), pre_split(0.1), false),
        ("SBVH 0.1".to_string(), spatial(SbvhParams::with_budget(0.1)), false),
        ("SBVH 0.3".to_string(), spatial(SbvhParams::with_budget(0.3)), false),
        ("SBVH 0.3 over clusters (default)".to_string(), spatial(SbvhParams::with_budget(0.3)), true),
        ("SBVH 0.3 every triangle, alpha 1e-5".to_string(), spatial(every), false),
    ];
    for (split_name, (build, build_time), clusters) in builds {
        let mut tree = OptTree::from_build(build, triangles);
        let params = Preset::Balanced.optimize_params();
        let mut go = |_: &bvhc::optimize::Progress| std::ops::ControlFlow::Continue(());
        let report = match clusters {
            true => {
                let roots = cluster_roots(&tree, params.constants, CLUSTER_SIZE);
                optimize_over_clusters(&mut tree, &params, &roots, &mut go)
            }
            false => optimize(&mut tree, &params, &mut go),
        };
        let (mut merged, merge_time) = timed(|| merge_leaves_of_references(&tree, constants, 8));
        records::remove_binary_repeats(&mut merged, triangles.len());
        let mut single = merge_leaves_of_references(&tree, constants, 1);
        records::remove_binary_repeats(&mut single, triangles.len());
        for (leaves, tree, optimize) in [("M=2", single, report.elapsed), ("M=3", merged, report.elapsed + merge_time)]
        {
            methods.push(Method {
                name: format!("{leaves} balanced, {split_name}"),
                build: build_time,
                optimize: Some(optimize),
                tree,
            });
        }
    }
    methods
}

/// obvhs's tree as a build tree (children at `first_index`, `first_index + 1`, as in the `.bvh` layout).
fn from_obvhs(bvh: &obvhs::bvh2::Bvh2) -> BuildTree {
    let mut tree = BuildTree::default();
    for node in &bvh.nodes {
        let aabb = Aabb { min: node.aabb.min.to_array(), max: node.aabb.max.to_array() };
        tree.nodes.push(if node.prim_count == 0 {
            BuildNode::Inner { aabb, left: node.first_index, right: node.first_index + 1 }
        } else {
            BuildNode::Leaf { aabb, first: node.first_index, count: node.prim_count }
        });
    }
    tree.triangle_order = bvh.primitive_indices.clone();
    tree
}

fn obvhs_methods(triangles: &[Triangle]) -> Vec<Method> {
    let tris = harness::obvhs_triangles(triangles);
    [
        ("fast_build", BvhBuildParams::fast_build()),
        ("medium_build", BvhBuildParams::medium_build()),
        ("very_slow_build", BvhBuildParams::very_slow_build()),
        ("very_slow_build, no pre-split", BvhBuildParams { pre_split: false, ..BvhBuildParams::very_slow_build() }),
        ("very_slow_build, 1 a leaf", BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::very_slow_build() }),
    ]
    .into_iter()
    .map(|(name, params)| {
        // With pre_split, a triangle's pieces are separate primitives that keep the triangle's index, so its
        // leaves may reference a triangle several times, as split references do in a .bvh file.
        let mut core = Duration::ZERO;
        let (bvh, build) = timed(|| obvhs::bvh2::builder::build_bvh2_from_tris(&tris, params, &mut core));
        Method { name: format!("obvhs {name}"), build, optimize: None, tree: from_obvhs(&bvh) }
    })
    .collect()
}

/// tinybvh's SBVH as it builds it (no reinsertion: the wrapper does not offer tinybvh's optimizer).
#[cfg(feature = "tinybvh")]
fn tinybvh_method(triangles: &[Triangle]) -> Method {
    let (tree, build) = timed(|| tinybvh::sbvh(triangles));
    Method { name: tinybvh::NAME.into(), build, optimize: None, tree }
}

struct Shape {
    aabb: bvh::aabb::Aabb<f32, 3>,
    node: usize,
}

impl bvh::aabb::Bounded<f32, 3> for Shape {
    fn aabb(&self) -> bvh::aabb::Aabb<f32, 3> {
        self.aabb
    }
}

impl bvh::bounding_hierarchy::BHShape<f32, 3> for Shape {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }
    fn bh_node_index(&self) -> usize {
        self.node
    }
}

fn svenstaro(triangles: &[Triangle]) -> Method {
    let mut shapes: Vec<Shape> = triangles
        .iter()
        .map(|t| {
            let b = Aabb::of_triangle(t);
            let p = |c: [f32; 3]| nalgebra::Point3::new(c[0], c[1], c[2]);
            Shape { aabb: bvh::aabb::Aabb::with_bounds(p(b.min), p(b.max)), node: 0 }
        })
        .collect();
    let (built, build) = timed(|| bvh::bvh::Bvh::build(&mut shapes));
    // Child boxes live in the parent; a node's own box is the union of its children's (a leaf: its shape's).
    let to_aabb =
        |b: &bvh::aabb::Aabb<f32, 3>| Aabb { min: [b.min.x, b.min.y, b.min.z], max: [b.max.x, b.max.y, b.max.z] };
    let mut tree = BuildTree::default();
    for node in &built.nodes {
        tree.nodes.push(match node {
            bvh::bvh::BvhNode::Node { child_l_index, child_l_aabb, child_r_index, child_r_aabb, .. } => {
                BuildNode::Inner {
                    aabb: to_aabb(child_l_aabb).union(&to_aabb(child_r_aabb)),
                    left: *child_l_index as u32,
                    right: *child_r_index as u32,
                }
            }
            bvh::bvh::BvhNode::Leaf { shape_index, .. } => {
                tree.triangle_order.push(*shape_index as u32);
                BuildNode::Leaf {
                    aabb: to_aabb(&shapes[*shape_index].aabb),
                    first: tree.triangle_order.len() as u32 - 1,
                    count: 1,
                }
            }
        });
    }
    Method { name: "svenstaro bvh 0.13".into(), build, optimize: None, tree }
}

/// The fixed ray set of every method: primary rays (a 512 x 384 camera), 4 ambient occlusion rays per primary
/// hit (any hit, within a fifth of the scene's size), and as many incoherent rays as primary ones (closest hit;
/// origins uniform in the scene's box, directions uniform on the sphere).
struct RaySet {
    primary: Vec<Ray>,
    ao: Vec<Ray>,
    incoherent: Vec<Ray>,
}

fn ray_set(tracer: &Tracer<'_>, min: [f32; 3], max: [f32; 3]) -> RaySet {
    let (width, height) = (512usize, 384usize);
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let size = (0..3).map(|a| max[a] - min[a]).fold(0.0f32, f32::max);
    let dir = [0.55f32, 0.37, 0.75];
    let eye: [f32; 3] = std::array::from_fn(|a| center[a] + dir[a] * size * 1.6);
    let forward = -glam::Vec3::from(dir);
    let right = glam::Vec3::new(forward.z, 0.0, -forward.x).normalize();
    let up = right.cross(forward);
    let primary: Vec<Ray> = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f32 / width as f32 - 0.5, 0.5 - (i / width) as f32 / height as f32);
            Ray::new(eye, (forward + 0.8 * x * right + 0.6 * y * up).to_array())
        })
        .collect();
    let mut ao = Vec::new();
    for (i, ray) in primary.iter().enumerate() {
        if let Some(hit) = tracer.closest_hit(ray) {
            let point: [f32; 3] = std::array::from_fn(|a| ray.origin[a] + hit.t * ray.direction[a]);
            for k in 0..4u64 {
                let d = unit_cube_point(i as u64 * 4 + k).map(|c| 2.0 * c - 1.0);
                ao.push(Ray { origin: point, direction: d, t_min: size * 1e-4, t_max: size * 0.2 });
            }
        }
    }
    let incoherent = (0..primary.len() as u64)
        .map(|i| {
            let u = unit_cube_point(0x5EED_0000_0000 + i);
            let origin: [f32; 3] = std::array::from_fn(|a| min[a] + u[a] * (max[a] - min[a]));
            let v = unit_cube_point(0xD1CE_0000_0000 + i);
            let (z, phi) = (2.0 * v[0] - 1.0, std::f32::consts::TAU * v[1]);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray::new(origin, [r * phi.cos(), r * phi.sin(), z])
        })
        .collect();
    RaySet { primary, ao, incoherent }
}

/// A point of the unit cube from a counter (three 16-bit fields of a multiplicative hash).
fn unit_cube_point(i: u64) -> [f32; 3] {
    let h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    std::array::from_fn(|a| ((h >> (a * 16)) & 0xFFFF) as f32 / 65536.0)
}

/// Render seconds (median of 5, all threads), steps and triangle tests per ray.
/// Seconds to trace the whole ray set once (all threads).
fn render_once(tracer: &Tracer<'_>, rays: &RaySet) -> f64 {
    let closest = |set: &[Ray]| {
        set.par_chunks(1024).map(|c| c.iter().filter(|r| tracer.closest_hit(r).is_some()).count()).sum::<usize>()
    };
    let run = || {
        let hits = closest(&rays.primary) + closest(&rays.incoherent);
        let occluded = rays.ao.par_chunks(1024).map(|c| c.iter().filter(|r| tracer.any_hit(r)).count()).sum::<usize>();
        std::hint::black_box((hits, occluded));
    };
    timed(run).1.as_secs_f64()
}

/// Node visits and triangle tests per ray.
fn traversal_counts(tracer: &Tracer<'_>, rays: &RaySet) -> (f64, f64) {
    let mut stats = TraversalStats::default();
    for r in rays.primary.iter().chain(&rays.incoherent) {
        tracer.closest_hit_counted(r, &mut stats);
    }
    for r in &rays.ao {
        tracer.any_hit_counted(r, &mut stats);
    }
    let count = (rays.primary.len() + rays.ao.len() + rays.incoherent.len()) as f64;
    (stats.node_visits as f64 / count, stats.triangle_tests as f64 / count)
}

/// The median of 5 renders, and the traversal counts.
fn render(tracer: &Tracer<'_>, rays: &RaySet) -> (f64, f64, f64) {
    let mut samples: Vec<f64> = (0..5).map(|_| render_once(tracer, rays)).collect();
    let (steps, tests) = traversal_counts(tracer, rays);
    (median(&mut samples), steps, tests)
}

fn main() {
    if !harness::benchmarking("evaluate") {
        return;
    }
    let constants = SahConstants::default();
    let files_only = std::env::var_os("BVHC_EVAL_FILES_ONLY").is_some();
    println!(
        "{} threads; SAH and EPO with (c_T, c_I) = (3, 2) by bvhc's cost module; refs: triangle records over triangles; render: 512 x 384 primary rays, 4 AO rays per hit and 512 x 384 incoherent rays through bvhc's binary kernel, median of 5; times in seconds from this run",
        rayon::current_num_threads()
    );
    for (name, path) in harness::scenes(SCENES, Some("BVHC_EVAL_SCENES")) {
        let triangles = import(&path, &ImportOptions::default()).unwrap().soup.triangle_vertices();
        if files_only {
            let start = pack(&Builder::BinnedSah.build(&triangles, 1), &triangles);
            let tracer = Tracer::new(&start.nodes, &start.triangles, None);
            let rays = ray_set(&tracer, start.nodes[0].min, start.nodes[0].max);
            println!("\n### {name} ({} triangles)", triangles.len());
            files_table(&path, &rays, other_files(&triangles));
            continue;
        }
        let mut methods = ours(&triangles);
        let own_methods = methods.len();
        methods.extend(obvhs_methods(&triangles));
        methods.push(svenstaro(&triangles));
        #[cfg(feature = "tinybvh")]
        methods.push(tinybvh_method(&triangles));
        let packed: Vec<_> = methods.iter().map(|m| pack(&m.tree, &triangles)).collect();
        let tree_notes = check_trees(&methods, &packed, &triangles, own_methods);
        let reference = &packed[1];
        let tracer = Tracer::new(&reference.nodes, &reference.triangles, None);
        let (min, max) = (reference.nodes[0].min, reference.nodes[0].max);
        let rays = ray_set(&tracer, min, max);
        let costs: Vec<f64> = methods.iter().map(|m| m.tree.sah_cost(constants).cost).collect();
        let best = costs.iter().cloned().fold(f64::INFINITY, f64::min);
        println!(
            "\n### {name} ({} triangles; {} primary + {} AO + {} incoherent rays)\n",
            triangles.len(),
            rays.primary.len(),
            rays.ao.len(),
            rays.incoherent.len()
        );
        println!(
            "| method | cost | error | EPO | refs | build s | opt s | render s | steps | isect |\n|---|---|---|---|---|---|---|---|---|---|"
        );
        let mut baseline = None;
        let mut samples = Vec::new();
        for ((method, tree), cost) in methods.iter().zip(&packed).zip(&costs) {
            let tracer = Tracer::new(&tree.nodes, &tree.triangles, None);
            let (seconds, steps, tests) = render(&tracer, &rays);
            samples.push(([1.0, steps, tests], seconds));
            let base = *baseline.get_or_insert(seconds);
            let epo = end_point_overlap(&method.tree, &triangles, constants);
            println!(
                "| {} | {cost:.2} | {:.2} | {epo:.2} | {:.3} | {:.3} | {} | {seconds:.3} ({:.1}) | {steps:.2} | {tests:.2} |",
                method.name,
                cost - best,
                tree.triangles.len() as f64 / triangles.len() as f64,
                method.build.as_secs_f64(),
                method.optimize.map_or("-".to_string(), |d| format!("{:.3}", d.as_secs_f64())),
                100.0 * seconds / base
            );
        }
        println!("\n{tree_notes}");
        print_kernel_fit(&samples, rays.primary.len() + rays.ao.len() + rays.incoherent.len());
        merge_constants_table(&triangles, &rays);
        files_table(&path, &rays, other_files(&triangles));
    }
}

/// Checks every tree against the scene. bvhc's trees (the first `own_methods`) must hold every triangle; a
/// peer's tree that does not is named, with how many of the triangles it lacks have no area (no ray hits those).
/// Every tree that repeats a triangle goes through the loader's verifier as a file with `SPLIT_REFERENCES`
/// (rule V25: the leaves that reference a triangle together cover all of it): a tree whose boxes miss part of a
/// triangle loses hits, so its render time is not quite comparable. Returns the findings as a sentence.
fn check_trees(
    methods: &[Method],
    packed: &[bvhc::pack::PackedTree],
    triangles: &[Triangle],
    own_methods: usize,
) -> String {
    let mut findings = Vec::new();
    let mut repeating = 0;
    for (i, (method, tree)) in methods.iter().zip(packed).enumerate() {
        let mut held = vec![false; triangles.len()];
        tree.triangle_ids.iter().for_each(|&t| held[t as usize] = true);
        let missing: Vec<usize> = (0..triangles.len()).filter(|&t| !held[t]).collect();
        assert!(i >= own_methods || missing.is_empty(), "{}: a triangle is missing from the tree", method.name);
        if !missing.is_empty() {
            let flat = missing.iter().filter(|&&t| has_no_area(&triangles[t])).count();
            findings.push(format!("{} omits {} triangles ({flat} of them without area)", method.name, missing.len()));
        }
        if tree.triangles.len() > triangles.len() {
            repeating += 1;
            if let Err(error) = BvhWriter::new(&tree.nodes, &tree.triangles).split_references(true).build() {
                findings.push(format!("{} fails the loader's verifier: {error}", method.name));
            }
        }
    }
    let summary = format!("{repeating} trees repeat triangles and were verified as split-reference files.");
    if findings.is_empty() {
        format!("{summary} Every tree holds every triangle and every verified tree passes.")
    } else {
        format!("{summary} Findings: {}.", findings.join("; "))
    }
}

/// Whether a triangle's cross product is zero in f64 (its vertices are collinear or repeated).
fn has_no_area(t: &Triangle) -> bool {
    let edge = |a: usize| -> [f64; 3] { std::array::from_fn(|k| t[a][k] as f64 - t[0][k] as f64) };
    let (u, v) = (edge(1), edge(2));
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    n == [0.0; 3]
}

/// The binary kernel's costs measured from the table: a least squares fit of the time a ray as `c + a steps +
/// b isect` over every tree of the scene, so that `b / a` can be set against the SAH constants' ratio `c_I /
/// c_T` = 2 / 3 that the optimizer and the leaf merging use. The trees vary both counts, but not independently,
/// so the fit is ill-conditioned (a scene may give a negative term) and only the spread across scenes means much.
fn print_kernel_fit(samples: &[([f64; 3], f64)], ray_count: usize) {
    let per_ray = |seconds: f64| seconds * rayon::current_num_threads() as f64 / ray_count as f64 * 1e9;
    let mut normal = [[0.0f64; 4]; 3];
    for (x, seconds) in samples {
        for i in 0..3 {
            for j in 0..3 {
                normal[i][j] += x[i] * x[j];
            }
            normal[i][3] += x[i] * per_ray(*seconds);
        }
    }
    for i in 0..3 {
        let pivot = normal[i];
        for row in normal.iter_mut().skip(i + 1) {
            let f = row[i] / pivot[i];
            row.iter_mut().zip(&pivot).skip(i).for_each(|(value, p)| *value -= f * p);
        }
    }
    let mut fit = [0.0f64; 3];
    for i in (0..3).rev() {
        fit[i] = (normal[i][3] - (i + 1..3).map(|k| normal[i][k] * fit[k]).sum::<f64>()) / normal[i][i];
    }
    println!(
        "\nBinary kernel fit over these trees (thread-ns a ray): {:.1} + {:.2} a step + {:.2} a triangle test; test / step = {:.2} (the SAH constants: 0.67)",
        fit[0],
        fit[1],
        fit[2],
        fit[2] / fit[1]
    );
}

/// The files table's rows beyond converted files: obvhs's tree.
fn other_files(triangles: &[Triangle]) -> Vec<(String, BvhFile, f64)> {
    vec![obvhs_single_file(triangles)]
}

/// Merge constants judged by render time: the default tree (SBVH 0.3, balanced optimization over clusters) merged with
/// several `(c_T, c_I)` and leaf limits, traced through the binary kernel in [`FILE_ROUNDS`] paired rounds; a
/// row's ratio is the median of its per-round ratios to (3, 2) with leaves of up to 8, the constants
/// conversions use. A lower `c_I / c_T` merges more (fewer node visits, more triangle tests).
fn merge_constants_table(triangles: &[Triangle], rays: &RaySet) {
    let mut tree = OptTree::from_build(build_sbvh(triangles, &SbvhParams::with_budget(0.3)), triangles);
    let params = Preset::Balanced.optimize_params();
    let roots = cluster_roots(&tree, params.constants, CLUSTER_SIZE);
    optimize_over_clusters(&mut tree, &params, &roots, &mut |_| std::ops::ControlFlow::Continue(()));
    let variants = [(3.0, 2.0, 8), (3.0, 3.0, 8), (3.0, 1.5, 8), (3.0, 1.0, 8), (3.0, 0.75, 8), (3.0, 1.0, 16)];
    let packed: Vec<_> = variants
        .iter()
        .map(|&(traversal, intersection, max_leaf_size)| {
            let constants = SahConstants { traversal, intersection };
            let mut merged = merge_leaves_of_references(&tree, constants, max_leaf_size);
            records::remove_binary_repeats(&mut merged, triangles.len());
            pack(&merged, triangles)
        })
        .collect();
    let tracers: Vec<Tracer<'_>> = packed.iter().map(|p| Tracer::new(&p.nodes, &p.triangles, None)).collect();
    let mut ratios = vec![Vec::new(); tracers.len()];
    for _ in 0..FILE_ROUNDS {
        let round: Vec<f64> = tracers.iter().map(|tracer| render_once(tracer, rays)).collect();
        round.iter().zip(&mut ratios).for_each(|(t, r)| r.push(t / round[0]));
    }
    println!(
        "\nMerge constants by render time (default tree, binary kernel, {FILE_ROUNDS} paired rounds):\n\n| (c_T, c_I), leaf limit | leaves a record | render vs (3, 2) | steps | isect |\n|---|---|---|---|---|"
    );
    for (((traversal, intersection, limit), (tree, tracer)), ratios) in
        variants.iter().zip(packed.iter().zip(&tracers)).zip(&mut ratios)
    {
        let (steps, tests) = traversal_counts(tracer, rays);
        let leaves = tree.nodes.iter().filter(|n| n.count > 0).count();
        println!(
            "| ({traversal}, {intersection}), {limit} | {:.3} | {:.3} | {steps:.2} | {tests:.2} |",
            leaves as f64 / tree.triangles.len() as f64,
            median(ratios)
        );
    }
}

/// obvhs's `very_slow_build` at one primitive a leaf and without its pre-splits, as a file finished by bvhc
/// (leaf merging, wide collapse), named for the files table. Without pre-splits because obvhs's split boxes do
/// not always contain their pieces: with them, the engine's triangle 99794 is not covered by the boxes of the
/// wide leaves that hold it (rule V35), and the file would not verify.
fn obvhs_single_file(triangles: &[Triangle]) -> (String, BvhFile, f64) {
    let tris = harness::obvhs_triangles(triangles);
    let params = BvhBuildParams { max_prims_per_leaf: 1, pre_split: false, ..BvhBuildParams::very_slow_build() };
    let mut core = Duration::ZERO;
    let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(&tris, params, &mut core);
    let name = "obvhs very_slow_build, no pre-split, 1 a leaf; merged and collapsed by bvhc".to_string();
    let (file, wide_cost) = file_of_single_leaf_tree(from_obvhs(&bvh), triangles);
    (name, file, wide_cost)
}

/// An in-memory file of a tree with one triangle (or split reference) a leaf, finished as conversions finish
/// theirs (`merge_and_collapse` with the default options, then both trees packed), so that another builder's
/// tree is traced by the same kernel as a converted file.
fn file_of_single_leaf_tree(tree: BuildTree, triangles: &[Triangle]) -> (BvhFile, f64) {
    let repeats = tree.triangle_order.len() > triangles.len();
    let opt = OptTree::from_build(tree, triangles);
    let options = ConvertOptions::default();
    let (binary, wide) = merge_and_collapse(&opt, &options, triangles.len(), repeats);
    let (wide, costs) = wide.expect("the default options collapse a wide tree");
    let packed = pack(&binary, triangles);
    let split = packed.triangles.len() > triangles.len();
    let mut records = packed.record_cursor(triangles.len());
    let bvh = pack_wide(&wide, &packed.triangles, &mut |t| records.next(t), split).unwrap();
    let file = BvhWriter::new(&packed.nodes, &packed.triangles)
        .split_references(split)
        .wide(bvh.nodes(), bvh.packets())
        .build()
        .unwrap();
    (file, wide.cost(&costs))
}

/// Converts the scene with the default options and each split setting, and traces `rays` through each file's
/// default kernel: [`FILE_ROUNDS`] rounds that render every file once in turn, so that the machine's drift
/// falls on all files alike; a file's time is its median, its ratio the median of its per-round ratios to the
/// unsplit file.
fn files_table(scene: &std::path::Path, rays: &RaySet, others: Vec<(String, BvhFile, f64)>) {
    let dir = tempfile::tempdir().unwrap();
    println!(
        "\n| file (defaults) | records | file MB | SAH | wide cost | render s | vs unsplit | wide steps | packets |\n|---|---|---|---|---|---|---|---|---|"
    );
    let sbvh = |budget| Some(SplitOptions::with_budget(budget));
    let cut = |triangles| Some(SplitOptions { triangles, ..SplitOptions::with_budget(0.3) });
    let default_splits = Preset::Balanced.splits();
    let settings = [
        (None, OptimizeOver::References),
        (
            Some(SplitOptions { method: SplitMethod::PreSplit, ..SplitOptions::with_budget(0.1) }),
            OptimizeOver::References,
        ),
        (sbvh(0.1), OptimizeOver::References),
        (sbvh(0.3), OptimizeOver::References),
        (cut(SplitTriangles::Any), OptimizeOver::References),
        (cut(SplitTriangles::Choose), OptimizeOver::References),
        (default_splits, OptimizeOver::Clusters),
        (default_splits, OptimizeOver::Choose),
        (cut(SplitTriangles::Choose), OptimizeOver::Choose),
    ];
    let mut files = Vec::new();
    for (i, (splits, optimize_over)) in settings.iter().enumerate() {
        let output = dir.path().join(format!("scene-{i}.bvh"));
        let options =
            ConvertOptions { splits: *splits, reinsertion: Some(*optimize_over), ..ConvertOptions::default() };
        let report = convert_with(scene, &output, &options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
        files.push((report, BvhFile::read(&output).unwrap()));
    }
    let tracers: Vec<Tracer<'_>> = files
        .iter()
        .map(|(_, file)| file)
        .chain(others.iter().map(|(_, file, _)| file))
        .map(|f| f.view().tracer())
        .collect();
    let mut times = vec![Vec::new(); tracers.len()];
    let mut ratios = vec![Vec::new(); tracers.len()];
    for _ in 0..FILE_ROUNDS {
        let round: Vec<f64> = tracers.iter().map(|tracer| render_once(tracer, rays)).collect();
        for (i, &t) in round.iter().enumerate() {
            times[i].push(t);
            ratios[i].push(t / round[0]);
        }
    }
    for (i, ((splits, optimize_over), (report, _))) in settings.iter().zip(&files).enumerate() {
        let (steps, tests) = traversal_counts(&tracers[i], rays);
        let over = match optimize_over {
            OptimizeOver::References => String::new(),
            other => format!(" --optimize-over {}", other.name()),
        };
        println!(
            "| {}{over} | {} | {:.1} | {:.2} | {} | {:.3} | {:.3} | {steps:.2} | {tests:.2} |",
            splits.map_or("--no-splits".to_string(), |s| format!(
                "--split-budget {} --split-method {}{}",
                s.budget,
                s.method.name(),
                match s.triangles {
                    SplitTriangles::Wasteful => String::new(),
                    other => format!(" --split-triangles {}", other.name()),
                }
            )),
            report.stored_triangle_count,
            report.file_byte_len as f64 / 1e6,
            report.cost.cost,
            report.wide.map_or("-".to_string(), |w| format!("{:.2}", w.cost)),
            median(&mut times[i]),
            median(&mut ratios[i]),
        );
    }
    for (i, (name, file, wide_cost)) in others.iter().enumerate() {
        let i = files.len() + i;
        let (steps, tests) = traversal_counts(&tracers[i], rays);
        let bytes = file.view().bytes().len() as f64 / 1e6;
        let records = file.view().triangles().len();
        let sah = sah_of_packed(file.view().nodes(), SahConstants::default()).cost;
        println!(
            "| {name} | {records} | {bytes:.1} | {sah:.2} | {wide_cost:.2} | {:.3} | {:.3} | {steps:.2} | {tests:.2} |",
            median(&mut times[i]),
            median(&mut ratios[i]),
        );
    }
}

/// Rounds of the files table.
const FILE_ROUNDS: usize = 9;

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}
