//! What the table's trees say beyond their rows: peers' trees that miss triangles or fail the coverage rule, the
//! binary kernel's step and test costs fitted over the trees, and merge constants judged by render time.

use bvhc::builders::sbvh::{SbvhParams, build_sbvh};
use bvhc::cost::SahConstants;
use bvhc::layout::{cluster_roots, merge_leaves_of_references, records};
use bvhc::loader::{Tracer, write::BvhWriter};
use bvhc::optimize::{OptTree, optimize_over_clusters};
use bvhc::options::Preset;
use bvhc::options::preset::CLUSTER_SIZE;
use bvhc::pack::pack;
use glam::DVec3;

use crate::Triangle;
use crate::files::FILE_ROUNDS;
use crate::ours::Method;
use crate::ray_set::{RaySet, render_in_rounds, traversal_counts};

/// Checks every tree against the scene. bvhc's trees (the first `own_methods`) must hold every triangle; a
/// peer's tree that does not is named, with how many of the triangles it lacks have no area (no ray hits those).
/// Every tree that repeats a triangle goes through the loader's verifier as a file with `SPLIT_REFERENCES`
/// (rule V25: the leaves that reference a triangle together cover all of it): a tree whose boxes miss part of a
/// triangle loses hits, so its render time is not quite comparable. Returns the findings as a sentence.
pub fn check_trees(
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
    let [a, b, c] = t.map(|v| DVec3::from(v.map(f64::from)));
    (b - a).cross(c - a) == DVec3::ZERO
}

/// The binary kernel's costs measured from the table: a least squares fit of the time a ray as `c + a steps +
/// b isect` over every tree of the scene, so that `b / a` can be set against the SAH constants' ratio `c_I /
/// c_T` = 2 / 3 that the optimizer and the leaf merging use. The trees vary both counts, but not independently,
/// so the fit is ill-conditioned (a scene may give a negative term) and only the spread across scenes means much.
pub fn print_kernel_fit(samples: &[([f64; 3], f64)], ray_count: usize) {
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

/// Merge constants judged by render time: the default tree (SBVH 0.3, balanced optimization over clusters) merged with
/// several `(c_T, c_I)` and leaf limits, traced through the binary kernel in [`FILE_ROUNDS`] paired rounds; a
/// row's ratio is the median of its per-round ratios to (3, 2) with leaves of up to 8, the constants
/// conversions use. A lower `c_I / c_T` merges more (fewer node visits, more triangle tests).
pub fn merge_constants_table(triangles: &[Triangle], rays: &RaySet) {
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
            pack(&merged, triangles).expect("memory for the packed tree")
        })
        .collect();
    let tracers: Vec<Tracer<'_>> = packed.iter().map(|p| Tracer::new(&p.nodes, &p.triangles, None)).collect();
    let renders = render_in_rounds(&tracers, rays, FILE_ROUNDS);
    println!(
        "\nMerge constants by render time (default tree, binary kernel, {FILE_ROUNDS} paired rounds):\n\n| (c_T, c_I), leaf limit | leaves a record | render vs (3, 2) | steps | isect |\n|---|---|---|---|---|"
    );
    for (((traversal, intersection, limit), (tree, tracer)), (_, ratio)) in
        variants.iter().zip(packed.iter().zip(&tracers)).zip(renders)
    {
        let (steps, tests) = traversal_counts(tracer, rays);
        let leaves = tree.nodes.iter().filter(|n| n.count > 0).count();
        println!(
            "| ({traversal}, {intersection}), {limit} | {:.3} | {:.3} | {steps:.2} | {tests:.2} |",
            leaves as f64 / tree.triangles.len() as f64,
            ratio
        );
    }
}
