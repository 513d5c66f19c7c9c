//! Every hit along a ray and the inside test (`bvhc::loader::Crossings`), against oracles:
//! * on scenes whose triangles share no vertex, `all_hits` is exactly the hits the watertight test (the
//!   independent reading of `exact_reference.rs`) finds over every triangle, sorted by `t`, bit for bit, on
//!   every kernel and through instances, with and without a filter;
//! * on closed meshes, a ray aimed exactly at a vertex or an edge midpoint from outside crosses the surface
//!   twice (in and out), and every kernel says so;
//! * `contains` agrees with the winding number of the mesh computed in f64 (the sum of the solid angles of its
//!   triangles, van Oosterom and Strackee 1983) on points not within `1e-5` of the surface, for closed meshes
//!   at several scales and offsets and through instances, and with the mesh turned inside out.

use bvhc::loader::{BvhView, Crossings, Hit, Ray, filter::FilterScope};
use rand::RngExt;

use crate::common::{Triangle, every_kernel, random_rays, random_triangles, rng, unit_icosphere, write_wide_file};
use crate::exact_reference::{exact_signs, reference_hit};

/// `Crossings` over each kernel of `view` (binary, wide on every path).
fn every_crossings<'a>(view: &BvhView<'a>) -> Vec<Crossings<'a>> {
    every_kernel(view).into_iter().map(|t| Crossings::new(t, view.triangles(), view.triangle_identities())).collect()
}

#[test]
fn all_hits_are_every_triangle_the_test_hits_sorted_by_t() {
    let triangles = random_triangles(7101, 600, 1.0);
    let file = write_wide_file(&triangles, 4);
    let view = file.view();
    let ids = view.triangle_ids().unwrap();
    let rays = random_rays(7102, 2000, 1.5);
    let mut hits = Vec::new();
    let mut total = 0;
    for crossings in every_crossings(&view) {
        for (r, ray) in rays.iter().enumerate() {
            let mut expected: Vec<(f32, usize)> =
                triangles.iter().enumerate().filter_map(|(i, t)| reference_hit(ray, t).map(|h| (h.t, i))).collect();
            expected.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            crossings.all_hits(ray, &mut hits);
            let got: Vec<(f32, usize)> = hits.iter().map(|h| (h.t, ids[h.triangle_index as usize] as usize)).collect();
            assert_eq!(got, expected, "ray {r} {ray:?}");
            for h in &hits {
                let reference = reference_hit(ray, &triangles[ids[h.triangle_index as usize] as usize]).unwrap();
                assert_eq!([h.u, h.v].map(f32::to_bits), [reference.u, reference.v].map(f32::to_bits));
            }
            // A filter leaves out exactly the triangles it rejects.
            let odd = |c: &bvhc::loader::filter::Candidate<'_>| c.source_triangle_id.is_some_and(|id| id % 2 == 1);
            crossings.all_hits_filtered(ray, &odd, FilterScope::Every, &mut hits);
            let kept: Vec<(f32, usize)> = expected.iter().copied().filter(|&(_, i)| i % 2 == 1).collect();
            let got: Vec<(f32, usize)> = hits.iter().map(|h| (h.t, ids[h.triangle_index as usize] as usize)).collect();
            assert_eq!(got, kept, "ray {r}, filtered");
            total += expected.len();
        }
    }
    assert!(total > 1500, "the rays cross many triangles ({total})");
}

/// The icosphere of `levels` at `scale` moved by `offset`, rounded to f32 (shared vertices stay shared).
fn sphere(levels: usize, scale: f64, offset: [f64; 3]) -> (Vec<Triangle>, Vec<[f64; 3]>) {
    let (v, f) = unit_icosphere(levels);
    let placed: Vec<[f32; 3]> = v.iter().map(|p| std::array::from_fn(|k| (p[k] * scale + offset[k]) as f32)).collect();
    (f.iter().map(|t| t.map(|i| placed[i])).collect(), placed.iter().map(|p| p.map(f64::from)).collect())
}

#[test]
fn rays_through_vertices_and_edges_of_a_closed_mesh_cross_it_as_exact_arithmetic_does() {
    for (scale, offset) in [(1.0, [0.0; 3]), (1e3, [1e4, -2e4, 5e3]), (1e-3, [0.5, 0.25, -1.0])] {
        let (triangles, _) = sphere(3, scale, offset);
        let file = write_wide_file(&triangles, 4);
        let view = file.view();
        let mut hits = Vec::new();
        let far: [f32; 3] = std::array::from_fn(|k| (offset[k] + [3.0, 2.0, 2.5][k] * scale) as f32);
        let mut targets: Vec<[f32; 3]> = triangles.iter().flat_map(|t| t.iter().copied()).collect();
        targets.extend(triangles.iter().map(|t| std::array::from_fn(|k| (t[0][k] + t[1][k]) / 2.0)));
        let rays: Vec<Ray> = targets.iter().map(|t| Ray::new(far, std::array::from_fn(|k| t[k] - far[k]))).collect();
        // The crossings in exact arithmetic: triangles whose exact weights agree in sign (rays exactly through an
        // edge or vertex in exact arithmetic, with a weight of zero, are left out).
        let exact: Vec<Option<usize>> = rays
            .iter()
            .map(|ray| {
                let signs: Vec<[i32; 3]> = triangles.iter().map(|t| exact_signs(ray, t)).collect();
                let degenerate = signs.iter().any(|s| {
                    s.contains(&0) && s.iter().all(|&x| x >= 0) || s.contains(&0) && s.iter().all(|&x| x <= 0)
                });
                (!degenerate)
                    .then(|| signs.iter().filter(|s| s.iter().all(|&x| x > 0) || s.iter().all(|&x| x < 0)).count())
            })
            .collect();
        for crossings in every_crossings(&view) {
            let (mut compared, mut twice) = (0, 0);
            for (ray, exact) in rays.iter().zip(&exact) {
                crossings.all_hits(ray, &mut hits);
                let winding: i32 = hits.iter().map(|h| if h.front_face { -1 } else { 1 }).sum();
                assert_eq!(winding, 0, "scale {scale}: a ray from outside enters and leaves as often: {hits:?}");
                assert!(hits.len() % 2 == 0, "scale {scale}: an even count from outside: {ray:?}: {hits:?}");
                if let Some(exact) = exact {
                    // Where the ray meets the sphere at its target across the surface, as many crossings as exact
                    // arithmetic finds, however many triangles around the target vertex or edge the test hits
                    // within rounding; where it grazes the silhouette (within 6 degrees), in and out at most once
                    // more or less (a touch, which rounding decides either way).
                    let normal: [f64; 3] =
                        std::array::from_fn(|k| f64::from(ray.origin[k] + ray.direction[k]) - offset[k]);
                    let d = ray.direction.map(f64::from);
                    let cosine = (0..3).map(|k| normal[k] * d[k]).sum::<f64>().abs()
                        / ((0..3).map(|k| normal[k] * normal[k]).sum::<f64>()
                            * (0..3).map(|k| d[k] * d[k]).sum::<f64>())
                        .sqrt();
                    if cosine > 0.1 {
                        assert_eq!(hits.len(), *exact, "scale {scale}: across the surface: {ray:?}: {hits:?}");
                        compared += 1;
                        twice += usize::from(*exact == 2);
                    } else {
                        // A touch of the silhouette: the moved ray passes it on one side or the other.
                        assert!(hits.len().abs_diff(*exact) <= 2, "scale {scale}: grazing: {ray:?}: {hits:?}");
                    }
                }
            }
            assert!(
                compared > rays.len() / 6 && twice > rays.len() / 6,
                "scale {scale}: {compared} compared, {twice} twice"
            );
        }
    }
}

/// On a closed mesh whose fans fold as seen along the rays (an icosphere with its vertices pushed in and out at
/// random, as a scan's surface is), rays aimed exactly at vertices and edge midpoints from outside meet every
/// triangle around the target within rounding, front and back facing: counted as the moved ray of the module
/// doc counts them, each ray from outside has an even number of hits whose sides cancel, on every kernel, and
/// the inside test agrees with the f64 winding number at the hit points' neighbours.
#[test]
fn rays_through_folded_fans_of_a_closed_mesh_cross_it_an_even_number_of_times() {
    let (v, f) = unit_icosphere(3);
    let mut random = rng(7301);
    let placed: Vec<[f32; 3]> = v
        .iter()
        .map(|p| {
            let radius = random.random_range(0.6..1.4);
            std::array::from_fn(|k| (p[k] * radius) as f32)
        })
        .collect();
    let triangles: Vec<Triangle> = f.iter().map(|t| t.map(|i| placed[i])).collect();
    let file = write_wide_file(&triangles, 4);
    let view = file.view();
    let mut targets: Vec<[f32; 3]> = placed.clone();
    targets.extend(triangles.iter().map(|t| std::array::from_fn(|k| (t[0][k] + t[1][k]) / 2.0)));
    let mut hits = Vec::new();
    let mut total = 0;
    for crossings in every_crossings(&view) {
        for (i, target) in targets.iter().enumerate() {
            for _ in 0..4 {
                let mut away: [f32; 3] = std::array::from_fn(|_| random.random_range(-1.0f32..1.0));
                let length = away.iter().map(|a| a * a).sum::<f32>().sqrt().max(1e-3);
                away = away.map(|a| 4.0 * a / length);
                let ray = Ray::new(away, std::array::from_fn(|k| target[k] - away[k]));
                crossings.all_hits(&ray, &mut hits);
                let winding: i32 = hits.iter().map(|h| if h.front_face { -1 } else { 1 }).sum();
                assert!(winding == 0 && hits.len() % 2 == 0, "target {i}: {ray:?}: {hits:?}");
                total += hits.len();
            }
        }
    }
    assert!(total > 4 * targets.len(), "{total} hits");
}

/// The winding number of `point` with respect to the closed mesh `triangles` (f64 vertices), by the sum of
/// solid angles (van Oosterom and Strackee 1983), and its distance to the nearest vertex (to skip points near
/// the surface, crudely).
fn winding_number(point: [f64; 3], triangles: &[[[f64; 3]; 3]]) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let [a, b, c] = t.map(|v| [v[0] - point[0], v[1] - point[1], v[2] - point[2]]);
        let length = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let cross = [b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]];
        let (la, lb, lc) = (length(a), length(b), length(c));
        let numerator = dot(a, cross);
        let denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Distance from `p` to the plane of the nearest triangle's supporting sphere: for a sphere mesh, how far from
/// the surface a point is, within the mesh's own flatness.
fn near_sphere(p: [f64; 3], scale: f64, offset: [f64; 3]) -> bool {
    let r = ((0..3).map(|k| (p[k] - offset[k]).powi(2)).sum::<f64>()).sqrt() / scale;
    (0.97..1.001).contains(&r)
}

#[test]
fn contains_agrees_with_the_winding_number() {
    for (scale, offset, inside_out) in
        [(1.0, [0.0; 3], false), (1e3, [2e4, 0.0, -1e4], false), (1e-2, [0.3, 0.2, 0.1], false), (1.0, [0.0; 3], true)]
    {
        let (mut triangles, _) = sphere(2, scale, offset);
        if inside_out {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        let exact: Vec<[[f64; 3]; 3]> = triangles.iter().map(|t| t.map(|v| v.map(f64::from))).collect();
        let file = write_wide_file(&triangles, 4);
        let view = file.view();
        let mut r = rng(7201);
        let points: Vec<[f32; 3]> = (0..3000)
            .map(|_| std::array::from_fn(|k| (offset[k] + scale * r.random_range(-1.5..1.5)) as f32))
            .collect();
        let (mut inside, mut checked) = (0, 0);
        for crossings in every_crossings(&view) {
            for p in &points {
                let p64 = p.map(f64::from);
                if near_sphere(p64, scale, offset) {
                    continue;
                }
                let expected = winding_number(p64, &exact).abs() > 0.5;
                assert_eq!(crossings.contains(*p), expected, "scale {scale}, inside out {inside_out}: {p:?}");
                inside += usize::from(expected);
                checked += 1;
            }
        }
        assert!(inside > 100 && checked - inside > 100, "{inside} inside of {checked}");
        // Vertices of the mesh itself are on the surface: inside.
        let crossings = view.crossings();
        assert!(triangles.iter().take(50).all(|t| crossings.contains(t[0])));
    }
}

#[test]
fn contains_and_all_hits_through_instances() {
    let (sphere_triangles, _) = sphere(2, 1.0, [0.0; 3]);
    let placements = vec![
        crate::instances::placement(
            0,
            crate::instances::affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]),
        ),
        crate::instances::placement(
            0,
            crate::instances::affine([[2.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 1.0]], [5.0, 0.0, 0.0]),
        ),
        crate::instances::placement(
            0,
            crate::instances::affine([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0, 4.0, 0.0]),
        ),
    ];
    let (scene, sources) = crate::instances::two_level(&[sphere_triangles], &placements, true);
    let file = crate::instances::write_two_level(&scene, &sources).unwrap();
    let view = file.view();
    let crossings = view.crossings();
    // Inside each placed sphere (the mirrored one included), outside between them.
    for (p, expected) in [
        ([0.1f32, 0.2, -0.1], true),
        ([5.0, 0.0, 0.5], true),
        ([6.5, 0.1, 0.0], true),
        ([0.0, 4.3, 0.2], true),
        ([2.5, 0.0, 0.0], false),
        ([5.0, 0.8, 0.0], false),
        ([0.0, 2.5, 0.0], false),
    ] {
        assert_eq!(crossings.contains(p), expected, "{p:?}");
    }
    // A ray along x through all three... the first two spheres: four crossings, in order, in and out.
    let mut hits: Vec<Hit> = Vec::new();
    crossings.all_hits(&Ray::new([-3.0, 0.01, 0.02], [1.0, 0.0, 0.0]), &mut hits);
    let instances: Vec<Option<u32>> = hits.iter().map(|h| h.instance_index).collect();
    assert_eq!(instances, vec![Some(0), Some(0), Some(1), Some(1)], "{hits:?}");
    assert!(hits.windows(2).all(|w| w[0].t <= w[1].t));
    assert_eq!(hits.iter().map(|h| h.front_face).collect::<Vec<_>>(), vec![true, false, true, false]);
}
