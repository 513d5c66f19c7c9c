//! The files table: what a user of `bvhc` gets, files converted under each split and optimizer setting (and two
//! with `--tune-rays`, trained on the built-in distribution, measured here on another: this table's rays) and
//! obvhs's tree finished as conversions finish theirs, traced through each file's default kernel.

use std::time::Duration;

use bvhc::build_tree::BuildTree;
use bvhc::convert::{convert_with, merge_and_collapse};
use bvhc::cost::{SahConstants, sah_of_packed};
use bvhc::loader::{BvhFile, Tracer, write::BvhWriter};
use bvhc::optimize::OptTree;
use bvhc::options::Preset;
use bvhc::options::{ConvertOptions, OptimizeOver, SplitMethod, SplitOptions, SplitTriangles};
use bvhc::pack::{pack, pack_wide};
use bvhc::sampling::RayTuning;
use obvhs::BvhBuildParams;

use crate::Triangle;
use crate::harness;
use crate::peers::from_obvhs;
use crate::ray_set::{RaySet, render_in_rounds, traversal_counts};

/// Rounds of the files table.
pub const FILE_ROUNDS: usize = 9;

/// The files table's rows beyond converted files: obvhs's tree.
pub fn other_files(triangles: &[Triangle]) -> Vec<(String, BvhFile, f64)> {
    vec![obvhs_single_file(triangles)]
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
    let packed = pack(&binary, triangles).expect("memory for the packed tree");
    let split = packed.triangles.len() > triangles.len();
    let mut records = packed.record_cursor(triangles.len()).expect("memory");
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
/// unsplit file. Returns the unsplit file's median seconds (with `--features embree`, Embree's rows compare
/// with it).
pub fn files_table(scene: &std::path::Path, rays: &RaySet, others: Vec<(String, BvhFile, f64)>) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    println!(
        "\n| file (defaults) | records | file MB | SAH | wide cost | render s | vs unsplit | wide steps | packets |\n|---|---|---|---|---|---|---|---|---|"
    );
    let sbvh = |budget| Some(SplitOptions::with_budget(budget));
    let cut = |triangles| Some(SplitOptions { triangles, ..SplitOptions::with_budget(0.3) });
    let default_splits = Preset::Balanced.splits();
    // (splits, what reinsertion optimizes over, ray tuning with the default budget)
    let settings = [
        (None, OptimizeOver::References, false),
        (
            Some(SplitOptions { method: SplitMethod::PreSplit, ..SplitOptions::with_budget(0.1) }),
            OptimizeOver::References,
            false,
        ),
        (sbvh(0.1), OptimizeOver::References, false),
        (sbvh(0.3), OptimizeOver::References, false),
        (cut(SplitTriangles::Any), OptimizeOver::References, false),
        (cut(SplitTriangles::Choose), OptimizeOver::References, false),
        (default_splits, OptimizeOver::Clusters, false),
        (default_splits, OptimizeOver::Clusters, true),
        (default_splits, OptimizeOver::Choose, false),
        (cut(SplitTriangles::Choose), OptimizeOver::Choose, false),
        (cut(SplitTriangles::Choose), OptimizeOver::Choose, true),
    ];
    let mut files = Vec::new();
    for (i, &(splits, optimize_over, tuned)) in settings.iter().enumerate() {
        let output = dir.path().join(format!("scene-{i}.bvh"));
        let options = ConvertOptions {
            splits,
            reinsertion: Some(optimize_over),
            ray_tuning: tuned.then(RayTuning::default),
            ..ConvertOptions::default()
        };
        let report = convert_with(scene, &output, &options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
        files.push((report, BvhFile::read(&output).unwrap()));
    }
    let tracers: Vec<Tracer<'_>> = files
        .iter()
        .map(|(_, file)| file)
        .chain(others.iter().map(|(_, file, _)| file))
        .map(|f| f.view().tracer())
        .collect();
    let renders = render_in_rounds(&tracers, rays, FILE_ROUNDS);
    for (i, ((splits, optimize_over, tuned), (report, _))) in settings.iter().zip(&files).enumerate() {
        let (steps, tests) = traversal_counts(&tracers[i], rays);
        let mut over = match optimize_over {
            OptimizeOver::References => String::new(),
            other => format!(" --optimize-over {}", other.name()),
        };
        if *tuned {
            let kept = report.choice.as_ref().map(|c| c.candidates[c.kept]);
            let kept = kept.map_or(String::new(), |c| format!(" (kept {}/{})", c.split_triangles, c.optimize_over));
            over.push_str(&format!(" --tune-rays {}{kept}", RayTuning::default().rays));
        }
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
            renders[i].0,
            renders[i].1,
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
            renders[i].0, renders[i].1,
        );
    }
    renders[0].0
}

/// With `--features embree` or `embree4`: rows of the files table for Embree (HIGH, plain and robust) over the same
/// triangles, rendering `rays` as the files are rendered (all threads, chunks of 1024, closest hits for the
/// primary and incoherent rays, any hit for the AO rays), in [`FILE_ROUNDS`] rounds, on rayon threads with
/// flush-to-zero set as Embree asks. Its ratio is its median over `unsplit_seconds`, the unsplit file's median
/// from the rounds just before (not interleaved with them).
#[cfg(any(feature = "embree", feature = "embree4"))]
pub fn embree_rows(triangles: &[Triangle], rays: &RaySet, unsplit_seconds: f64) {
    use rayon::prelude::*;

    use crate::embree::{Embree, set_flush_to_zero};
    let pool = rayon::ThreadPoolBuilder::new().start_handler(|_| set_flush_to_zero()).build().expect("a pool");
    for robust in [false, true] {
        let scene = Embree::new(triangles, robust);
        let render = || {
            let start = std::time::Instant::now();
            let closest = |set: &[bvhc::loader::Ray]| {
                set.par_chunks(1024).map(|c| c.iter().filter(|r| scene.closest(r).is_some()).count()).sum::<usize>()
            };
            let hits = closest(&rays.primary) + closest(&rays.incoherent);
            let occluded = rays.ao.par_chunks(1024).map(|c| c.iter().filter(|r| scene.any(r)).count()).sum::<usize>();
            std::hint::black_box((hits, occluded));
            start.elapsed().as_secs_f64()
        };
        let mut times: Vec<f64> = (0..FILE_ROUNDS).map(|_| pool.install(render)).collect();
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let version = crate::embree::VERSION;
        let name = if robust { format!("{version} HIGH, robust") } else { format!("{version} HIGH") };
        println!(
            "| {name} (its own tree and kernel) | {} | - | - | - | {median:.3} | {:.3} | - | - |",
            triangles.len(),
            median / unsplit_seconds
        );
    }
}
