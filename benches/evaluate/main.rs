//! Run time against error, in the columns of the reference table (`../shared/guide/algorithm.md`). For each
//! scene, a first table of trees: SAH cost, end-point overlap (EPO, Aila, Karras and Laine 2013: `bvhc::epo`),
//! references per triangle, build and optimization seconds, render seconds (a fixed set of primary, ambient
//! occlusion and incoherent rays through the loader's binary kernel on all threads, in rounds that trace every
//! tree once each; in brackets relative to M = 1), and average traversal steps and triangle tests per ray.
//! Methods (`ours.rs`, `peers.rs`): M = 1 (spatial median), the binned SAH start, M = 2 (optimized, one
//! reference per leaf) and M = 3 (leaves merged) for the balanced and max-quality presets; the balanced preset
//! over split references (`bvhc::builders`: pre-split at budget 0.1, the SBVH at 0.1 and 0.3, the SBVH 0.3
//! optimized over clusters as default conversions make it, and an SBVH that cuts every triangle at the paper's
//! overlap threshold); side by side in the same run, obvhs 0.4's presets (`very_slow_build` with its
//! pre-splits, as the preset has them, without, and at one primitive a leaf), svenstaro's `bvh` 0.13 and, with
//! `--features tinybvh`, tinybvh's SBVH, their trees repacked into the `.bvh` layout so that one cost definition
//! and one kernel measure all of them. "error" is the cost above the lowest cost any method reached on that
//! scene. Under the table (`findings.rs`): which peer trees lack triangles or fail the loader's coverage rule
//! for split references, a least squares fit of the kernel's cost a step and a test, and the default tree
//! merged with other constants, timed.
//!
//! A second table per scene (`files.rs`) times what a user of `bvhc` gets: files converted with the default
//! options under each split setting (`--no-splits`, `--split-budget`, `--split-method`, `--split-triangles`)
//! and optimizer setting (`--optimize-over`), and obvhs's one-a-leaf tree finished into a file as conversions
//! finish theirs, traced through each file's default kernel (the wide one) with the same rays, in rounds;
//! steps and isect there count wide node visits and packet tests. Two of its files are converted with
//! `--tune-rays` (trained on the built-in distribution, so these rays are another distribution to them); with
//! `--features embree` Embree 3's rows (HIGH, plain and robust, its own tree and kernel) close it.
//!
//! `cargo bench --bench evaluate [--features tinybvh] [--features embree]` prints Markdown. `BVHC_EVAL_SCENES=kitchen,dragon` picks
//! scenes, `BVHC_EVAL_FILES_ONLY=1` prints only the second table, `BVHC_SCENES` overrides the folder.

#[path = "../common/harness.rs"]
mod harness;
#[cfg(any(feature = "embree", feature = "embree4"))]
#[path = "../common/embree.rs"]
mod embree;
#[cfg(feature = "tinybvh")]
#[path = "../common/tinybvh.rs"]
mod tinybvh;

mod files;
mod findings;
mod ours;
mod peers;
mod ray_set;

use bvhc::builders::Builder;
use bvhc::cost::SahConstants;
use bvhc::epo::end_point_overlap;
use bvhc::import::{ImportOptions, import};
use bvhc::loader::Tracer;
use bvhc::pack::pack;

use files::{files_table, other_files};
use findings::{check_trees, merge_constants_table, print_kernel_fit};
use ray_set::{ray_set, render_in_rounds, traversal_counts};

type Triangle = [[f32; 3]; 3];

/// Rounds of the first table's render column.
const RENDER_ROUNDS: usize = 5;

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

fn main() {
    if !harness::benchmarking("evaluate") {
        return;
    }
    let constants = SahConstants::default();
    let files_only = std::env::var_os("BVHC_EVAL_FILES_ONLY").is_some();
    println!(
        "{} threads; SAH and EPO with (c_T, c_I) = (3, 2) by bvhc's cost module; refs: triangle records over triangles; render: 512 x 384 primary rays, 4 AO rays per hit and 512 x 384 incoherent rays through bvhc's binary kernel, {RENDER_ROUNDS} rounds that trace every tree once each, median seconds and in brackets the median per-round ratio to M = 1; times in seconds from this run",
        rayon::current_num_threads()
    );
    for (name, path) in harness::scenes(SCENES, Some("BVHC_EVAL_SCENES")) {
        let triangles = import(&path, &ImportOptions::default()).unwrap().soup.triangle_vertices();
        if files_only {
            let start = pack(&Builder::BinnedSah.build(&triangles, 1), &triangles).expect("memory");
            let tracer = Tracer::new(&start.nodes, &start.triangles, None);
            let rays = ray_set(&tracer, start.nodes[0].min, start.nodes[0].max);
            println!("\n### {name} ({} triangles)", triangles.len());
            let _unsplit_seconds = files_table(&path, &rays, other_files(&triangles));
            #[cfg(any(feature = "embree", feature = "embree4"))]
            files::embree_rows(&triangles, &rays, _unsplit_seconds);
            continue;
        }
        let mut methods = ours::methods(&triangles);
        let own_methods = methods.len();
        methods.extend(peers::obvhs_methods(&triangles));
        methods.push(peers::svenstaro(&triangles));
        #[cfg(feature = "tinybvh")]
        methods.push(peers::tinybvh_method(&triangles));
        let packed: Vec<_> = methods.iter().map(|m| pack(&m.tree, &triangles).expect("memory")).collect();
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
        let tracers: Vec<Tracer<'_>> = packed.iter().map(|p| Tracer::new(&p.nodes, &p.triangles, None)).collect();
        let renders = render_in_rounds(&tracers, &rays, RENDER_ROUNDS);
        let mut samples = Vec::new();
        for (((method, tree), cost), (tracer, (seconds, ratio))) in
            methods.iter().zip(&packed).zip(&costs).zip(tracers.iter().zip(renders))
        {
            let (steps, tests) = traversal_counts(tracer, &rays);
            samples.push(([1.0, steps, tests], seconds));
            let epo = end_point_overlap(&method.tree, &triangles, constants);
            println!(
                "| {} | {cost:.2} | {:.2} | {epo:.2} | {:.3} | {:.3} | {} | {seconds:.3} ({:.1}) | {steps:.2} | {tests:.2} |",
                method.name,
                cost - best,
                tree.triangles.len() as f64 / triangles.len() as f64,
                method.build.as_secs_f64(),
                method.optimize.map_or("-".to_string(), |d| format!("{:.3}", d.as_secs_f64())),
                100.0 * ratio
            );
        }
        println!("\n{tree_notes}");
        print_kernel_fit(&samples, rays.primary.len() + rays.ao.len() + rays.incoherent.len());
        merge_constants_table(&triangles, &rays);
        let _unsplit_seconds = files_table(&path, &rays, other_files(&triangles));
        #[cfg(any(feature = "embree", feature = "embree4"))]
        files::embree_rows(&triangles, &rays, _unsplit_seconds);
    }
}
