//! Numerical stability under stress: generated scenes far from the origin, tiny and huge, slivers, needles,
//! degenerate and coincident triangles, axis-aligned walls and closed meshes go through the whole pipeline
//! (build, optimize, merge, pack, verified write) and are attacked with axis-parallel, +0/-0, grazing, short,
//! long and surface-starting rays and rays aimed exactly at shared vertices and edges.
//!
//! Guarantees checked, per case:
//! * no miss from the boxes: the traversal's closest hit equals brute force over every triangle with the same
//!   watertight test (same t, a triangle hit at that t), and any-hit agrees;
//! * no false hit: a reported hit lies on its triangle in double precision, within `FALSE_HIT_TOLERANCE` times
//!   the magnitude of the origin and the scene (the f32 test may round an edge hit either way, never by more);
//! * t error: `|t - t_f64| <= T_RELATIVE_ERROR * max(t_f64, scale / |d|)` where t_f64 is the double-precision
//!   intersection with the triangle's plane (degenerate triangles have none and are skipped here);
//! * closed meshes: rays from inside never miss;
//! * costs stay finite and every file verifies.
//!
//! The table of counts is printed (`cargo test --release stress -- --nocapture`) and kept in
//! `docs/stability.md`.

use bvhc_loader::Trace;
use std::ops::ControlFlow;

use bvhc::builders::Builder;
use bvhc::cost::SahConstants;
use bvhc::layout::merge_leaves;
use bvhc::loader::{Ray, write::BvhWriter};
use bvhc::optimize::{OptTree, optimize};
use bvhc::options::Preset;
use bvhc::pack::pack;
use rand::RngExt;

use crate::common::{Triangle, brute_force_closest, rng, unit_icosphere};

/// Relative t error the kernel promises against the f64 plane intersection.
const T_RELATIVE_ERROR: f64 = 1e-5;
/// How far a hit may lie from its triangle, relative to the magnitude of the coordinates involved (origin and
/// scene): the kernel works on `v - o` rounded to f32, so hits near an edge may be off by a few ulps of them.
pub(crate) const FALSE_HIT_TOLERANCE: f64 = 4.0 * f32::EPSILON as f64;

pub(crate) struct Case {
    pub name: String,
    pub triangles: Vec<Triangle>,
    pub rays: Vec<Ray>,
    /// Rays that must hit (from inside a closed mesh).
    pub must_hit: bool,
}

#[derive(Default)]
struct Counts {
    rays: usize,
    hits: usize,
    misses: usize,
    false_hits: usize,
    worst_t_error: f64,
}

/// A closed unit sphere scaled by `scale` and moved to `offset`, rounded to f32 (shared vertices stay shared:
/// they round identically), with rays from inside: at every vertex, every edge midpoint, and random ones.
fn sphere_case(name: &str, scale: f64, offset: f64) -> Case {
    let (v, f) = unit_icosphere(3);
    let place = |p: [f64; 3]| p.map(|c| (c * scale + offset) as f32);
    let vertices: Vec<[f32; 3]> = v.iter().map(|&p| place(p)).collect();
    let triangles: Vec<Triangle> = f.iter().map(|t| t.map(|i| vertices[i])).collect();
    let center = [offset as f32; 3];
    let mut rays = Vec::new();
    let mut towards = |target: [f32; 3]| {
        let d: [f32; 3] = std::array::from_fn(|a| target[a] - center[a]);
        if d != [0.0; 3] {
            rays.push(Ray::new(center, d));
        }
    };
    for p in &vertices {
        towards(*p);
    }
    for t in &f {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            towards(place(std::array::from_fn(|k| (v[a][k] + v[b][k]) / 2.0)));
        }
    }
    let mut r = rng(7);
    for _ in 0..2000 {
        let d: [f32; 3] = std::array::from_fn(|_| r.random_range(-1.0f32..1.0));
        if d != [0.0; 3] {
            rays.push(Ray::new(center, d));
        }
    }
    // Axis-parallel rays with +0 and -0 components.
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let mut d = [0.0f32, -0.0, 0.0];
            d[axis] = sign;
            rays.push(Ray::new(center, d));
        }
    }
    Case { name: name.to_string(), triangles, rays, must_hit: true }
}

/// Parallel axis-aligned walls x = k made of unit quads (the architectural case), with rays along x through
/// grid vertices and edges, rays parallel to the walls, starting on a wall, and grazing along a wall.
fn walls_case() -> Case {
    let mut triangles = Vec::new();
    for k in 0..10 {
        let x = k as f32;
        for i in 0..8 {
            for j in 0..8 {
                let (y0, y1, z0, z1) = (i as f32, i as f32 + 1.0, j as f32, j as f32 + 1.0);
                triangles.push([[x, y0, z0], [x, y1, z0], [x, y1, z1]]);
                triangles.push([[x, y0, z0], [x, y1, z1], [x, y0, z1]]);
            }
        }
    }
    let mut rays = Vec::new();
    for i in 0..=8 {
        for j in 0..=8 {
            let (y, z) = (i as f32, j as f32);
            rays.push(Ray::new([-1.0, y, z], [1.0, 0.0, -0.0])); // through grid vertices
            rays.push(Ray::new([-1.0, y + 0.5, z], [1.0, -0.0, 0.0])); // through grid edges
            rays.push(Ray::new([3.0, y, z], [1.0, 0.0, 0.0])); // starting on a wall vertex
            rays.push(Ray::new([-1.0, y, z], [-1.0, 0.0, 0.0])); // pointing away
            rays.push(Ray::new([4.0, y + 0.25, z + 0.25], [0.0, 1.0, 0.0])); // inside a wall's plane (grazing)
            rays.push(Ray::new([4.5, y + 0.25, z + 0.25], [0.0, -0.0, 1.0])); // parallel between walls
        }
    }
    let mut r = rng(8);
    for _ in 0..2000 {
        let o = [r.random_range(-2.0f32..11.0), r.random_range(0.0f32..8.0), r.random_range(0.0f32..8.0)];
        let d = [r.random_range(-1.0f32..1.0), r.random_range(-0.2f32..0.2), r.random_range(-0.2f32..0.2)];
        rays.push(Ray::new(o, d));
    }
    Case { name: "axis-aligned walls (10 x 128 triangles)".into(), triangles, rays, must_hit: false }
}

/// Slivers, needles, zero-area and coincident triangles, and 3,000 triangles in one point, mixed with normal
/// ones; random rays and rays at their vertices.
fn degenerate_case() -> Case {
    let mut r = rng(9);
    let mut triangles: Vec<Triangle> = Vec::new();
    for i in 0..400 {
        let o: [f32; 3] = std::array::from_fn(|_| r.random_range(-5.0f32..5.0));
        let tri = match i % 5 {
            0 => [o, [o[0] + 3.0, o[1], o[2]], [o[0] + 1.5, o[1] + 1e-5, o[2]]], // sliver
            1 => [o, [o[0] + 1e-5, o[1], o[2]], [o[0], o[1] + 1e-5, o[2] + 4.0]], // needle
            2 => [o, [o[0] + 1.0, o[1], o[2]], [o[0] + 2.0, o[1], o[2]]],        // zero area (collinear)
            3 => [o, o, [o[0], o[1] + 1.0, o[2]]],                               // repeated vertex
            _ => [o, [o[0] + 1.0, o[1] + 0.5, o[2]], [o[0], o[1] + 1.0, o[2] + 0.5]],
        };
        triangles.push(tri);
        if i % 7 == 0 {
            triangles.push(tri); // coincident copy
        }
    }
    triangles.extend(std::iter::repeat_n([[1.0f32, 2.0, 3.0]; 3], 3000));
    let mut rays: Vec<Ray> = (0..3000)
        .map(|_| {
            let o: [f32; 3] = std::array::from_fn(|_| r.random_range(-8.0f32..8.0));
            let t: [f32; 3] = std::array::from_fn(|_| r.random_range(-5.0f32..5.0));
            Ray::new(o, std::array::from_fn(|a| t[a] - o[a]))
        })
        .collect();
    for tri in triangles.iter().take(400) {
        for v in tri {
            rays.push(Ray::new([0.0, 0.0, 20.0], [v[0], v[1], v[2] - 20.0]));
        }
    }
    rays.push(Ray::new([1.0, 2.0, 0.0], [0.0, 0.0, 1.0])); // through the point of 3,000 triangles
    Case { name: "slivers, needles, zero-area, coincident, 3,000 in a point".into(), triangles, rays, must_hit: false }
}

/// Very short and very long rays on a sphere: t ranges of 1e-6, rays from 1e6 away.
fn ray_length_case() -> Case {
    let mut case = sphere_case("short and long rays", 1.0, 0.0);
    let mut r = rng(10);
    case.rays = (0..2000)
        .map(|i| {
            let d: [f32; 3] = std::array::from_fn(|_| r.random_range(-1.0f32..1.0));
            if i % 2 == 0 {
                // Very long: from a million units away, aimed at the sphere.
                let o = d.map(|c| c * 1e6);
                Ray::new(o, o.map(|c| -c))
            } else {
                // Very short: the interval around the surface, starting 1e-3 inside.
                Ray { origin: [0.0; 3], direction: d, t_min: 0.0, t_max: 1e-6 }
            }
        })
        .collect();
    case.must_hit = false;
    case
}

fn f64_plane_t(tri: &Triangle, ray: &Ray) -> Option<(f64, [f64; 3])> {
    let p = tri.map(|v| v.map(f64::from));
    let o = ray.origin.map(f64::from);
    let d = ray.direction.map(f64::from);
    let e1: [f64; 3] = std::array::from_fn(|a| p[1][a] - p[0][a]);
    let e2: [f64; 3] = std::array::from_fn(|a| p[2][a] - p[0][a]);
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let denominator = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    if denominator == 0.0 {
        return None;
    }
    let t = ((p[0][0] - o[0]) * n[0] + (p[0][1] - o[1]) * n[1] + (p[0][2] - o[2]) * n[2]) / denominator;
    // Barycentric coordinates of the plane point, to measure how far outside the triangle it lies.
    let q: [f64; 3] = std::array::from_fn(|a| o[a] + t * d[a] - p[0][a]);
    let (d11, d12, d22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
    let (q1, q2) = (dot(q, e1), dot(q, e2));
    let det = d11 * d22 - d12 * d12;
    let v = (d22 * q1 - d12 * q2) / det;
    let w = (d11 * q2 - d12 * q1) / det;
    Some((t, [1.0 - v - w, v, w]))
}

/// Distance from `p` to the triangle (to its edges when `p` projects outside it, or when it is degenerate).
fn distance_to_triangle(p: [f64; 3], tri: &Triangle) -> f64 {
    let v = tri.map(|x| x.map(f64::from));
    let sub = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
    let (e1, e2) = (sub(v[1], v[0]), sub(v[2], v[0]));
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let nn = dot(n, n);
    if nn > 0.0 {
        let q = sub(p, v[0]);
        let inside = (0..3).all(|i| {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let edge = sub(b, a);
            let to_p = sub(p, a);
            let c = [
                edge[1] * to_p[2] - edge[2] * to_p[1],
                edge[2] * to_p[0] - edge[0] * to_p[2],
                edge[0] * to_p[1] - edge[1] * to_p[0],
            ];
            dot(c, n) >= 0.0
        });
        if inside {
            return dot(q, n).abs() / nn.sqrt();
        }
    }
    distance_to_edges(p, tri)
}

/// Distance from `p` to the nearest point of the triangle's three edges.
fn distance_to_edges(p: [f64; 3], tri: &Triangle) -> f64 {
    let v = tri.map(|x| x.map(f64::from));
    let sub = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
    (0..3)
        .map(|i| {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let ab = sub(b, a);
            let t = if dot(ab, ab) > 0.0 { (dot(sub(p, a), ab) / dot(ab, ab)).clamp(0.0, 1.0) } else { 0.0 };
            let closest: [f64; 3] = std::array::from_fn(|k| a[k] + t * ab[k]);
            let r = sub(p, closest);
            dot(r, r).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn run_case(case: &Case) -> Counts {
    // The whole pipeline: build, optimize, merge, pack, and the writer's full verification.
    let tree = Builder::BinnedSah.build(&case.triangles, 1);
    let mut opt = OptTree::from_build_tree(&tree, &case.triangles);
    let report = optimize(&mut opt, &Preset::Balanced.optimize_params(), &mut |p| {
        assert!(p.cost.is_finite(), "{}: cost {}", case.name, p.cost);
        ControlFlow::Continue(())
    });
    assert!(report.initial.cost.is_finite() && report.best.cost.is_finite(), "{}", case.name);
    opt.limit_depth(bvhc::loader::format::MAX_DEPTH);
    let merged = merge_leaves(&opt, SahConstants::default(), 8);
    assert!(merged.sah_cost(SahConstants::default()).cost.is_finite());
    let packed = pack(&merged, &case.triangles).expect("memory for the packed tree");
    let file =
        BvhWriter::new(&packed.nodes, &packed.triangles).triangle_ids(&packed.triangle_ids).build().expect("verifies");
    let tracer = file.view().tracer();
    // The wide kernel, every path, over the same optimized tree: the same answers as brute force.
    let wide = crate::common::wide_bvh_of(&opt, &case.triangles);
    for path in crate::common::kernel_paths() {
        let wide_tracer = bvhc::loader::WideTracer::new(&wide, None, path);
        for ray in &case.rays {
            let brute = brute_force_closest(&case.triangles, ray).map(|(t, _)| t);
            let got = wide_tracer.closest_hit(ray);
            assert_eq!(got.map(|h| h.t), brute, "{}: wide kernel {path:?}, ray {ray:?}", case.name);
            assert_eq!(wide_tracer.any_hit(ray), brute.is_some(), "{}: wide any-hit {path:?}", case.name);
        }
    }
    let root = file.view().nodes()[0];
    let scale = f64::from((0..3).map(|a| root.max[a] - root.min[a]).fold(0.0, f32::max)).max(1e-30);
    let mut counts = Counts::default();
    for ray in &case.rays {
        counts.rays += 1;
        let brute = brute_force_closest(&case.triangles, ray).map(|(t, _)| t);
        let got = tracer.closest_hit(ray);
        if got.map(|h| h.t) != brute || tracer.any_hit(ray) != brute.is_some() || (case.must_hit && got.is_none()) {
            counts.misses += 1;
            continue;
        }
        let Some(hit) = got else { continue };
        counts.hits += 1;
        let tri = &case.triangles[packed.triangle_ids[hit.triangle_index as usize] as usize];
        let o = ray.origin.map(f64::from);
        let d = ray.direction.map(f64::from);
        let length = dot(d, d).sqrt();
        let magnitude = dot(o, o).sqrt() + scale;
        let (point, tolerance) = match f64_plane_t(tri, ray) {
            Some((t64, _)) => {
                let error = (f64::from(hit.t) - t64).abs() / t64.abs().max(scale / length);
                counts.worst_t_error = counts.worst_t_error.max(error);
                (std::array::from_fn(|a| o[a] + t64 * d[a]), FALSE_HIT_TOLERANCE * magnitude)
            }
            // A degenerate triangle (a segment or a point): measure from the point at the reported t.
            None => {
                let t = f64::from(hit.t);
                (
                    std::array::from_fn(|a| o[a] + t * d[a]),
                    FALSE_HIT_TOLERANCE * magnitude + T_RELATIVE_ERROR * t * length,
                )
            }
        };
        if distance_to_triangle(point, tri) > tolerance {
            counts.false_hits += 1;
        }
    }
    counts
}

/// Every stress case (also traced by the GPU kernels: `gpu_layout`, `gpu_shader`).
pub(crate) fn stress_cases() -> Vec<Case> {
    let mut cases = vec![sphere_case("closed sphere at the origin (1,280 triangles)", 1.0, 0.0)];
    for offset in [1e4, 1e5, 1e6, 1e7] {
        cases.push(sphere_case(&format!("closed sphere, radius 1e3, at offset {offset:e}"), 1e3, offset));
    }
    for scale in [1e-6, 1e6] {
        cases.push(sphere_case(&format!("closed sphere, radius {scale:e}"), scale, 0.0));
    }
    cases.extend([walls_case(), degenerate_case(), ray_length_case()]);
    cases
}

#[test]
fn stability_under_stress() {
    let cases = stress_cases();
    println!("\n| case | rays | hits | misses | false hits | worst relative t error |\n|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for case in &cases {
        let c = run_case(case);
        println!(
            "| {} | {} | {} | {} | {} | {:.1e} |",
            case.name, c.rays, c.hits, c.misses, c.false_hits, c.worst_t_error
        );
        if c.misses > 0 || c.false_hits > 0 || c.worst_t_error > T_RELATIVE_ERROR {
            failures.push(case.name.clone());
        }
        assert!(c.hits > 0 || case.name.contains("short"), "{}: no ray hit anything", case.name);
    }
    assert!(failures.is_empty(), "guarantees broken in: {failures:?}");
}
