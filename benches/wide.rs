//! The wide collapse (Ylitie et al. 2017) on real scenes: time, node and leaf counts, fill, and the bytes the
//! wide node section and 4-triangle packets take against the binary nodes + triangles, for N = 4 and 8. The
//! trees are the balanced preset's optimized binary trees; the costs are `WideCosts::default()`, the ones
//! conversions use.
//!
//! Then rays per second, one thread, of the 8-wide kernel over packed wide sections (portable and AVX2 paths)
//! against the binary kernel over the same optimized tree merged to leaves of up to 8 triangles, on 500,000
//! incoherent rays (`primary_rays`, closest hit; `shadow_rays`, any hit).
//!
//! `cargo bench --bench wide`; `BVHC_SCENES` overrides the scenes folder.

#[path = "common/harness.rs"]
mod harness;

#[path = "common/rays.rs"]
mod rays;

use bvhc_loader::Trace;
use std::ops::ControlFlow;

use bvhc::builders::Builder;
use bvhc::layout::merge_leaves;
use bvhc::layout::{WideChild, WideCosts, collapse};
use bvhc::loader::{KernelPath, Ray, WideTracer, format::PackedTriangle};
use bvhc::optimize::{OptTree, OptimizeParams, optimize};

/// Bytes per N-wide node in structure-of-arrays order: 6 f32 bounds and one u32 reference per child.
fn wide_node_bytes(width: usize) -> usize {
    (7 * 4 * width).next_multiple_of(64)
}

/// Bytes per packet of 4 triangles: 9 f32 coordinates and one u32 index per lane.
const PACKET_BYTES: usize = 4 * 10 * 4;

fn main() {
    if !harness::benchmarking("wide") {
        return;
    }
    let mut speeds = Vec::new();
    println!(
        "| scene | triangles | N | collapse ms | wide nodes | children / node | leaves | triangles / leaf | packets | wide bytes / binary bytes |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, path) in harness::scenes(
        &[
            ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
            ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
            ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
        ],
        None,
    ) {
        let soup = bvhc::import::import(&path, &Default::default()).unwrap().soup;
        let triangles = soup.triangle_vertices();
        let mut tree = OptTree::from_build_tree(&Builder::BinnedSah.build(&triangles, 1), &triangles);
        optimize(&mut tree, &OptimizeParams::default(), &mut |_| ControlFlow::Continue(()));
        let merged = merge_leaves(&tree, Default::default(), 8);
        let binary_bytes = 32 * merged.nodes.len() + 36 * triangles.len();
        for width in [4, 8] {
            let costs = WideCosts { width, ..WideCosts::default() };
            let mut wide = None;
            let time = harness::median_time(3, || wide = Some(collapse(&tree, &costs)));
            let wide = wide.unwrap();
            let children: usize = wide.nodes.iter().map(|n| n.children.len()).sum();
            let leaves: Vec<u32> = wide
                .nodes
                .iter()
                .flat_map(|n| n.children.iter())
                .filter_map(|(_, c)| match c {
                    WideChild::Leaf { count, .. } => Some(*count),
                    WideChild::Node(_) => None,
                })
                .collect();
            let packets: usize = leaves.iter().map(|&c| (c as usize).div_ceil(4)).sum();
            let wide_bytes = wide_node_bytes(width) * wide.nodes.len() + PACKET_BYTES * packets;
            println!(
                "| {name} | {} | {width} | {:.1} | {} | {:.2} | {} | {:.2} | {packets} | {:.2} |",
                triangles.len(),
                time.as_secs_f64() * 1e3,
                wide.nodes.len(),
                children as f64 / wide.nodes.len() as f64,
                leaves.len(),
                triangles.len() as f64 / leaves.len() as f64,
                wide_bytes as f64 / binary_bytes as f64
            );
            if width == 8 {
                speeds.push((name, kernel_speeds(&merged, &triangles, &wide)));
            }
        }
    }
    println!("\n| scene | query | binary | wide portable | wide AVX2 | AVX2 / binary |");
    println!("|---|---|---|---|---|---|");
    for (name, rows) in speeds {
        for (query, binary, portable, avx2) in rows {
            println!("| {name} | {query} | {binary:.2} | {portable:.2} | {avx2:.2} | {:.2} |", avx2 / binary);
        }
    }
}

/// Mrays/s (median of 3, one thread) of the binary and the wide kernels: (query, binary, portable, AVX2).
fn kernel_speeds(
    merged: &bvhc::build_tree::BuildTree,
    triangles: &[[[f32; 3]; 3]],
    wide: &bvhc::layout::WideTree,
) -> Vec<(&'static str, f64, f64, f64)> {
    let packed_tree = bvhc::pack::pack(merged, triangles).expect("memory");
    let file = bvhc::loader::write::BvhWriter::new(&packed_tree.nodes, &packed_tree.triangles).build().unwrap();
    let binary = file.view().tracer();
    let soup: Vec<PackedTriangle> = triangles.iter().map(|&vertices| PackedTriangle { vertices }).collect();
    let bvh = bvhc::pack::pack_wide(wide, &soup, &mut Some, false).unwrap();
    let portable = WideTracer::new(&bvh, None, KernelPath::Portable);
    let avx2 = WideTracer::new(&bvh, None, KernelPath::Avx2);
    let root = &file.view().nodes()[0];
    let speed = |rays: &[Ray], f: &dyn Fn(&Ray) -> bool| {
        let time = harness::median_time(3, || {
            std::hint::black_box(rays.iter().filter(|r| f(r)).count());
        });
        rays.len() as f64 / time.as_secs_f64() / 1e6
    };
    let closest = rays::primary_rays(root, 500_000);
    let any = rays::shadow_rays(root, 500_000);
    vec![
        (
            "closest",
            speed(&closest, &|r| binary.closest_hit(r).is_some()),
            speed(&closest, &|r| portable.closest_hit(r).is_some()),
            speed(&closest, &|r| avx2.closest_hit(r).is_some()),
        ),
        (
            "any",
            speed(&any, &|r| binary.any_hit(r)),
            speed(&any, &|r| portable.any_hit(r)),
            speed(&any, &|r| avx2.any_hit(r)),
        ),
    ]
}
