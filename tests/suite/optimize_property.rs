//! Property test of the optimizer over thousands of small scenes: every preset, both builders, with the
//! tree's invariants checked after every batch. The scenes include nests of growing triangles around one
//! point, the shape of the reproducer of a panic in the parallel round (`fixtures/repro/`).

use std::ops::ControlFlow;

use bvhc::builders::Builder;
use bvhc::optimize::{OptTree, optimize_inspected};
use bvhc::options::Preset;
use rand::RngExt;

use crate::common::{Triangle, random_point, random_triangles, rng};

/// Scene `seed` of a family: random scatter, a nest of growing triangles (the reproducer's shape), nests
/// around several centres, or coincident and coplanar groups.
fn small_scene(seed: u64) -> Vec<Triangle> {
    let mut rng = rng(seed);
    let count = rng.random_range(2..=24usize);
    match seed % 4 {
        0 => random_triangles(seed, count, 10.0),
        1 => {
            // Triangles around the origin, each larger than the last by a random factor.
            let mut size = rng.random_range(0.5f32..20.0);
            (0..count)
                .map(|_| {
                    size *= rng.random_range(1.0f32..1.6);
                    [[-size, 0.0, 0.0], [size, size, 0.0], [0.0, 0.0, size]]
                })
                .collect()
        }
        2 => {
            let centres: Vec<[f32; 3]> = (0..rng.random_range(1..4)).map(|_| random_point(&mut rng, 50.0)).collect();
            (0..count)
                .map(|i| {
                    let c = centres[i % centres.len()];
                    let size = (1 + i) as f32 * rng.random_range(0.5f32..2.0);
                    [[c[0] - size, c[1], c[2]], [c[0] + size, c[1] + size, c[2]], [c[0], c[1], c[2] + size]]
                })
                .collect()
        }
        _ => {
            let base = random_triangles(seed, count.div_ceil(3), 5.0);
            (0..count).map(|i| base[i % base.len()]).collect()
        }
    }
}

#[test]
fn every_preset_keeps_the_invariants_after_every_batch_on_thousands_of_small_scenes() {
    let mut batches_checked = 0u64;
    for seed in 0..2_000u64 {
        let triangles = small_scene(seed);
        let builder = if seed % 2 == 0 { Builder::BinnedSah } else { Builder::SpatialMedian };
        for preset in Preset::ALL {
            let mut tree = OptTree::from_build_tree(&builder.build(&triangles, 1), &triangles);
            let initial = bvhc::optimize::cost_of(&tree, Default::default()).cost;
            let report = optimize_inspected(
                &mut tree,
                &preset.optimize_params(),
                &mut |_| ControlFlow::Continue(()),
                &mut |tree| {
                    batches_checked += 1;
                    if let Err(broken) = tree.check_invariants(&triangles) {
                        panic!("scene {seed}, {preset:?}, {builder:?}: after a batch: {broken}");
                    }
                },
            );
            if let Err(broken) = tree.check_invariants(&triangles) {
                panic!("scene {seed}, {preset:?}, {builder:?}: returned tree: {broken}");
            }
            assert!(report.best.cost <= initial && report.best.cost.is_finite(), "scene {seed}, {preset:?}");
        }
    }
    assert!(batches_checked > 10_000, "only {batches_checked} batches ran");
}
