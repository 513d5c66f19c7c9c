//! bvhc's own methods of the table: M = 1, the binned SAH start, both presets at M = 2 and 3, and the balanced
//! preset over split references.

use std::time::{Duration, Instant};

use bvhc::build_tree::BuildTree;
use bvhc::builders::Builder;
use bvhc::builders::sbvh::{SbvhParams, build_sbvh};
use bvhc::builders::split_triangles;
use bvhc::cost::SahConstants;
use bvhc::layout::{cluster_roots, merge_leaves, merge_leaves_of_references, records};
use bvhc::optimize::{OptTree, optimize, optimize_over_clusters};
use bvhc::options::Preset;
use bvhc::options::preset::CLUSTER_SIZE;

use crate::Triangle;

/// One row of the table: a tree and the seconds it took.
pub struct Method {
    pub name: String,
    pub build: Duration,
    pub optimize: Option<Duration>,
    pub tree: BuildTree,
}

/// The value of `f` and the time it took.
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let start = Instant::now();
    let value = f();
    (value, start.elapsed())
}

/// bvhc's methods, in table order.
pub fn methods(triangles: &[Triangle]) -> Vec<Method> {
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
