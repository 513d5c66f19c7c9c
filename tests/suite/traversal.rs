//! Traversal equals brute force over all triangles, on random scenes with every leaf size and ray kind.

use bvhc::loader::{Ray, TraversalStats, ray::PreparedRay};
use bvhc_loader::Trace;

use crate::common::*;

#[test]
fn closest_and_any_hit_equal_brute_force_on_random_scenes() {
    let mut total_hits = 0;
    for (seed, count) in [(10, 1), (11, 2), (12, 17), (13, 400), (14, 5000)] {
        let triangles = random_triangles(seed, count, 3.0);
        for max_leaf_size in [1, 3, 8] {
            let tree = packed_tree(&triangles, max_leaf_size);
            let file = write_file(&tree);
            let rays = random_rays(seed + 100, 1500, 3.0);
            total_hits += assert_matches_brute_force(&file.view().tracer(), &triangles, &rays, &tree.triangle_ids);
        }
    }
    assert!(total_hits > 5000, "the rays must actually hit things ({total_hits} hits)");
}

#[test]
fn hits_respect_the_ray_interval() {
    let triangles = random_triangles(20, 2000, 2.0);
    let tree = packed_tree(&triangles, 4);
    let file = write_file(&tree);
    let mut rng = rng(21);
    let rays: Vec<Ray> = random_rays(22, 2000, 2.0)
        .into_iter()
        .map(|mut ray| {
            use rand::RngExt;
            ray.t_min = rng.random_range(0.0..0.5);
            ray.t_max = ray.t_min + rng.random_range(0.0..1.0);
            ray
        })
        .collect();
    let hits = assert_matches_brute_force(&file.view().tracer(), &triangles, &rays, &tree.triangle_ids);
    assert!(hits > 100, "{hits}");
}

#[test]
fn statistics_mode_counts_and_changes_nothing() {
    let triangles = random_triangles(30, 3000, 2.0);
    let file = write_file(&packed_tree(&triangles, 1));
    let tracer = file.view().tracer();
    let mut stats = TraversalStats::default();
    let rays = random_rays(31, 500, 2.0);
    for ray in &rays {
        let before = stats;
        assert_eq!(tracer.closest_hit_counted(ray, &mut stats), tracer.closest_hit(ray));
        assert!(stats.node_visits >= before.node_visits);
        assert!(stats.triangle_tests - before.triangle_tests <= triangles.len() as u64);
        assert_eq!(tracer.any_hit_counted(ray, &mut TraversalStats::default()), tracer.any_hit(ray));
    }
    let per_ray = stats.triangle_tests as f64 / rays.len() as f64;
    assert!(stats.node_visits > rays.len() as u64 && per_ray < 0.1 * triangles.len() as f64, "{stats:?}");
}

#[test]
fn barycentrics_and_t_reconstruct_the_hit_point() {
    let triangles = random_triangles(40, 1000, 1.0);
    let tree = packed_tree(&triangles, 2);
    let file = write_file(&tree);
    let mut checked = 0;
    for ray in random_rays(41, 2000, 1.0) {
        let Some(hit) = file.view().tracer().closest_hit(&ray) else { continue };
        let [v0, v1, v2] = triangles[tree.triangle_ids[hit.triangle_index as usize] as usize].map(|v| v.map(f64::from));
        let (u, v) = (f64::from(hit.u), f64::from(hit.v));
        for a in 0..3 {
            let on_triangle = (1.0 - u - v) * v0[a] + u * v1[a] + v * v2[a];
            let on_ray = f64::from(ray.origin[a]) + f64::from(hit.t) * f64::from(ray.direction[a]);
            assert!((on_triangle - on_ray).abs() < 1e-4, "axis {a}: {on_triangle} vs {on_ray}");
        }
        assert!(hit.u >= 0.0 && hit.v >= 0.0 && hit.u + hit.v <= 1.0 + 1e-6);
        checked += 1;
    }
    assert!(checked > 300, "{checked}");
}

/// The f32 kernel against a double-precision oracle: hits well inside a triangle are found with t close to
/// the exact value, and rays that pass well outside never hit.
#[test]
fn triangle_test_agrees_with_double_precision() {
    use rand::RngExt;
    let mut rng = rng(50);
    let (mut inside, mut outside) = (0, 0);
    for _ in 0..20000 {
        let tri: Triangle = std::array::from_fn(|_| random_point(&mut rng, 10.0));
        let (b1, b2) = (rng.random_range(-0.5..1.5f64), rng.random_range(-0.5..1.5f64));
        let b0 = 1.0 - b1 - b2;
        let target: [f64; 3] =
            std::array::from_fn(|a| b0 * f64::from(tri[0][a]) + b1 * f64::from(tri[1][a]) + b2 * f64::from(tri[2][a]));
        let origin = random_point(&mut rng, 30.0);
        let direction: [f32; 3] = std::array::from_fn(|a| (target[a] - f64::from(origin[a])) as f32);
        let hit = PreparedRay::new(&Ray::new(origin, direction))
            .intersect_triangle(&bvhc::loader::format::PackedTriangle { vertices: tri }, f32::INFINITY);
        let margin = b0.min(b1).min(b2);
        if margin > 0.01 {
            let hit = hit.expect("a ray well inside the triangle hits");
            assert!((f64::from(hit.t) - 1.0).abs() < 1e-3, "t = {} for exact 1", hit.t);
            inside += 1;
        } else if margin < -0.01 {
            assert!(hit.is_none(), "a ray well outside the triangle misses");
            outside += 1;
        }
    }
    assert!(inside > 1000 && outside > 1000);
}
