//! The closest hit is the minimum over every record of `format-spec/bvh-1.md` 11.1's steps 1-8 (revision 1.5.8:
//! with the box condition, and the walks culling at the reach of 11.2), on every kernel and entry point, against
//! a brute force of the independent reading of the spec (`exact_reference.rs`): the kitchen rays on which the
//! walks used to return a farther hit (`shared/repro`), near-misses (records that steps 1-7 accept though the
//! exact ray passes them by) built here, rays from points on the surfaces of real scenes (origins near large
//! triangles, where a hit's `t` can lie below its box), split and unsplit, one- and two-level.

use std::path::Path;

use bvhc::loader::filter::FilterScope;
use bvhc::loader::{BvhFile, BvhView, Hit, Ray, Trace};

use crate::common::{every_kernel, scene, write_wide_file};
use crate::exact_reference::{exact_signs, meets_box_condition, reference_hit, steps_1_to_7};
use crate::hardening::repro;
use crate::instances::{affine, placement, rotation_z, two_level, write_two_level};
use crate::instances_exact::spec_object_ray;

type Triangle = [[f32; 3]; 3];

/// The brute force's closest hit: its `t`, its instance in a two-level file, and the records that may be named
/// (the lowest record at that `t`; with split references every record with the lowest coordinates), with each
/// one's `u`, `v`.
#[derive(Clone, Debug, PartialEq)]
struct Expected {
    t: f32,
    instance: Option<u32>,
    records: Vec<(u32, f32, f32)>,
}

/// Steps 1-8 over every record (in a two-level file, of every instance, on the object-space ray of 11.3), the
/// minimum in 11.1's order.
fn brute_force(view: &BvhView<'_>, ray: &Ray) -> Option<Expected> {
    let Some(sections) = view.two_level() else { return brute_force_one_level(view, ray) };
    let mut best: Option<Expected> = None;
    for (i, instance) in sections.instances.iter().enumerate() {
        let mesh = &sections.meshes[instance.mesh_index as usize];
        let object = spec_object_ray(instance, ray);
        let first = mesh.first_triangle as usize;
        for (r, triangle) in view.triangles()[first..first + mesh.triangle_count as usize].iter().enumerate() {
            let Some(hit) = reference_hit(&object, &triangle.vertices) else { continue };
            if best.as_ref().is_none_or(|b| hit.t < b.t) {
                let records = vec![((first + r) as u32, hit.u, hit.v)];
                best = Some(Expected { t: hit.t, instance: Some(i as u32), records });
            }
        }
    }
    best
}

/// [`brute_force`] in a one-level file.
fn brute_force_one_level(view: &BvhView<'_>, ray: &Ray) -> Option<Expected> {
    let split = view.has_split_references();
    let mut found: Vec<(u32, f32, f32, f32)> = Vec::new();
    for (r, triangle) in view.triangles().iter().enumerate() {
        if let Some(hit) = reference_hit(ray, &triangle.vertices) {
            found.push((r as u32, hit.t, hit.u, hit.v));
        }
    }
    let t = found.iter().map(|f| f.1).fold(f32::INFINITY, f32::min);
    let at_t: Vec<_> = found.into_iter().filter(|f| f.1 == t).collect();
    let key = |r: u32| match split {
        true => (0, view.triangles()[r as usize].coordinate_bits()),
        false => (r, [0; 9]),
    };
    let lowest = at_t.iter().map(|f| key(f.0)).min()?;
    let records = at_t.into_iter().filter(|f| key(f.0) == lowest).map(|f| (f.0, f.2, f.3)).collect();
    Some(Expected { t, instance: None, records })
}

/// Whether a kernel's hit is the brute force's: the same `t` bits, a record it may name, that record's `u`, `v`.
fn agrees(expected: &Option<Expected>, got: &Option<Hit>) -> bool {
    match (expected, got) {
        (None, None) => true,
        (Some(e), Some(h)) => {
            h.t.to_bits() == e.t.to_bits()
                && h.instance_index == e.instance
                && e.records.iter().any(|&(r, u, v)| {
                    r == h.triangle_index && u.to_bits() == h.u.to_bits() && v.to_bits() == h.v.to_bits()
                })
        }
        _ => false,
    }
}

/// Every entry point's closest hits (and any-hit answers) for `rays` through `view`, named: each kernel's single
/// rays, batch stream and coherent packets, a filtered tracer that accepts everything, and the GPU kernel's CPU
/// model where the file has the GPU sections.
fn entry_points(view: &BvhView<'_>, rays: &[Ray]) -> Vec<(String, Vec<Option<Hit>>, Vec<bool>)> {
    let mut out = Vec::new();
    for tracer in every_kernel(view) {
        let name = format!("{:?}", tracer.kernel());
        let single: Vec<_> = rays.iter().map(|r| tracer.closest_hit(r)).collect();
        let any: Vec<_> = rays.iter().map(|r| tracer.any_hit(r)).collect();
        out.push((format!("{name} single"), single, any.clone()));
        let mut batch = vec![None; rays.len()];
        tracer.closest_hits(rays, &mut batch);
        let mut batch_any = vec![false; rays.len()];
        tracer.any_hits(rays, &mut batch_any);
        out.push((format!("{name} batch"), batch, batch_any));
        let mut coherent = vec![None; rays.len()];
        tracer.closest_hits_coherent(rays, &mut coherent);
        let mut coherent_any = vec![false; rays.len()];
        tracer.any_hits_coherent(rays, &mut coherent_any);
        out.push((format!("{name} coherent"), coherent, coherent_any));
        let everything = |_: &bvhc::loader::filter::Candidate<'_>| true;
        let filtered = tracer.filtered(&everything, FilterScope::Every);
        let hits = rays.iter().map(|r| filtered.closest_hit(r)).collect();
        let any = rays.iter().map(|r| filtered.any_hit(r)).collect();
        out.push((format!("{name} filtered"), hits, any));
    }
    if let Some(model) = view.gpu_layout_tracer() {
        let hits = rays.iter().map(|r| model.closest_hit(r)).collect();
        let any = rays.iter().map(|r| model.any_hit(r)).collect();
        out.push(("GPU model".to_string(), hits, any));
    }
    out
}

/// Every entry point agrees with the brute force on every ray; returns the number of rays that hit.
fn assert_every_entry_point(what: &str, view: &BvhView<'_>, rays: &[Ray]) -> usize {
    let expected: Vec<Option<Expected>> = rays.iter().map(|r| brute_force(view, r)).collect();
    for (name, hits, any) in entry_points(view, rays) {
        for (i, ray) in rays.iter().enumerate() {
            assert!(
                agrees(&expected[i], &hits[i]),
                "{what}: {name}: ray {i} {ray:?}: brute force {:?}, kernel {:?}",
                expected[i],
                hits[i]
            );
            assert_eq!(any[i], expected[i].is_some(), "{what}: {name} any hit: ray {i} {ray:?}");
        }
    }
    expected.iter().filter(|e| e.is_some()).count()
}

/// The 32-byte ray records of `path`.
fn read_rays(path: &Path) -> Vec<Ray> {
    let bytes = std::fs::read(path).unwrap();
    bytes
        .chunks_exact(32)
        .map(|c| {
            let f: Vec<f32> = c.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
            Ray { origin: [f[0], f[1], f[2]], direction: [f[3], f[4], f[5]], t_min: f[6], t_max: f[7] }
        })
        .collect()
}

/// The outside reader's kitchen rays: each meets two triangles that share an edge, 0.013-0.019 from the origin,
/// 16-80 units long; the one a brute force finds nearest reports a `t` below where the ray enters the box of the
/// leaf that holds it, and the walk used to cull that box and return the other. Every entry point now returns
/// the brute force's, on the default (split) and an unsplit conversion.
#[test]
fn the_kitchen_rays_get_the_nearest_record() {
    let Some(kitchen) = scene("bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz") else { return };
    let rays = read_rays(&repro("kitchen-closest-pruned.rays.bin"));
    let dir = tempfile::tempdir().unwrap();
    for extra in [&[][..], &["--no-splits"][..]] {
        let output = dir.path().join("k.bvh");
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&kitchen, &"-o", &output, &"-q", &"--force"];
        args.extend(extra.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        let run = crate::cli::bvhc(&args);
        assert_eq!(run.status.code(), Some(0), "{}", crate::cli::stderr(&run));
        let file = BvhFile::read(&output).unwrap();
        let view = file.view();
        assert_eq!(assert_every_entry_point(&format!("kitchen {extra:?}"), &view, &rays), 2);
        let got: Vec<f32> = rays.iter().map(|r| view.tracer().closest_hit(r).unwrap().t).collect();
        assert_eq!(got, [0.013379074, 0.01898738], "the values the outside reader's brute force found");
    }
}

/// Near-misses: the needle scenes of the accuracy tests (`needles.rs`: needles and slivers aimed at and grazed
/// along, at scales `1e-3` to `1e3`) hold records that steps 1-7 accept though the exact ray passes them by; the
/// box condition refuses some and keeps others, and refuses no hit of the exact ray. Every entry point returns the
/// brute force's hit on every ray that meets a near-miss, in the test's file (one record a leaf, unsplit) and in
/// the converter's (split references, the GPU sections).
#[test]
fn near_misses_are_decided_alike_by_every_entry_point() {
    let dir = tempfile::tempdir().unwrap();
    let (mut near, mut refused, mut rays_checked) = (0, 0, 0);
    for (k, scene) in crate::needles::needle_scenes().into_iter().enumerate() {
        let mut with_near_miss = Vec::new();
        for ray in &scene.rays {
            let mut has = false;
            for triangle in &scene.triangles {
                let Some(hit) = steps_1_to_7(ray, triangle) else { continue };
                let signs = exact_signs(ray, triangle);
                let passes = meets_box_condition(ray, triangle, hit.t);
                if signs.contains(&1) && signs.contains(&-1) {
                    near += 1;
                    refused += usize::from(!passes);
                    has = true;
                } else {
                    assert!(passes, "{}: a hit of the exact ray refused; ray {ray:?}", scene.name);
                }
            }
            if has {
                with_near_miss.push(*ray);
            }
        }
        rays_checked += with_near_miss.len();
        let file = write_wide_file(&scene.triangles, 1);
        assert_every_entry_point(&scene.name, &file.view(), &with_near_miss);
        // The converter's file of the same triangles, with split references and the GPU sections.
        let obj = dir.path().join(format!("needles{k}.obj"));
        let mut text = String::new();
        for t in &scene.triangles {
            for v in t {
                text += &format!("v {:e} {:e} {:e}\n", v[0], v[1], v[2]);
            }
        }
        for i in 0..scene.triangles.len() {
            text += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
        }
        std::fs::write(&obj, text).unwrap();
        let output = dir.path().join(format!("needles{k}.bvh"));
        let run = crate::cli::bvhc(&[&obj, &"-o", &output, &"--gpu-layout", &"--keep-degenerate", &"-q"]);
        assert_eq!(run.status.code(), Some(0), "{}", crate::cli::stderr(&run));
        let converted = BvhFile::read(&output).unwrap();
        assert_every_entry_point(&format!("{} converted", scene.name), &converted.view(), &with_near_miss);
    }
    eprintln!("{near} near-misses on {rays_checked} rays, {refused} refused by the box condition");
    assert!(near > 300 && refused > 10 && refused < near, "the scenes exercise both outcomes: {near}, {refused}");
}

/// `count` rays leaving points of the surface of the triangles `records`: from a random point of a random
/// record, or a little off it (up to `1e-3` of the scene's size, where a large triangle is met at a `t` far below
/// its depth), in a random direction; some from the inside of the scene's box at random.
fn surface_rays(records: &[Triangle], count: usize, seed: u64) -> Vec<Ray> {
    use rand::RngExt;
    let mut r = crate::common::rng(seed);
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for v in records.iter().flatten() {
        for a in 0..3 {
            (lo[a], hi[a]) = (lo[a].min(v[a]), hi[a].max(v[a]));
        }
    }
    let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f32, f32::max);
    (0..count)
        .map(|k| {
            let direction = loop {
                let d: [f32; 3] = std::array::from_fn(|_| r.random_range(-1.0..1.0));
                if d.iter().map(|c| c * c).sum::<f32>() > 0.01 {
                    break d;
                }
            };
            let origin: [f32; 3] = if k % 5 == 4 {
                std::array::from_fn(|a| r.random_range(lo[a]..=hi[a]))
            } else {
                let [v0, v1, v2] = records[r.random_range(0..records.len())];
                let (mut u, mut v): (f32, f32) = (r.random_range(0.0..1.0), r.random_range(0.0..1.0));
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let off = if k % 5 < 2 { 0.0 } else { size * 1e-3 * r.random_range(-1.0..1.0) };
                std::array::from_fn(|a| (1.0 - u - v) * v0[a] + u * v1[a] + v * v2[a] + off * direction[(a + 1) % 3])
            };
            Ray::new(origin, direction)
        })
        .collect()
}

/// Rays leaving the surfaces of real scenes, converted with split references and without, with the GPU
/// sections: every entry point returns the brute force's hit.
#[test]
fn rays_leaving_surfaces_get_the_brute_force_hit_on_every_entry_point() {
    let dir = tempfile::tempdir().unwrap();
    let teapot = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let mut inputs = vec![(teapot, 3000)];
    inputs.extend(scene("stanford-bunny-ply/bun_zipper.ply").map(|p| (p, 400)));
    inputs.extend(scene("khr-box/Box.gltf").map(|p| (p, 2000)));
    inputs.extend(scene("bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz").map(|p| (p, 300)));
    for (input, count) in inputs {
        for extra in [&["--gpu-layout"][..], &["--no-splits", "--gpu-layout"][..]] {
            let output = dir.path().join("s.bvh");
            let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&input, &"-o", &output, &"-q", &"--force"];
            args.extend(extra.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
            let run = crate::cli::bvhc(&args);
            assert_eq!(run.status.code(), Some(0), "{}", crate::cli::stderr(&run));
            let file = BvhFile::read(&output).unwrap();
            let view = file.view();
            let records: Vec<Triangle> = view.triangles().iter().map(|t| t.vertices).collect();
            let rays = surface_rays(&records, count, 7);
            let what = format!("{} {extra:?}", input.display());
            let hits = assert_every_entry_point(&what, &view, &rays);
            assert!(hits > count / 3, "{what}: {hits} of {count} rays hit");
        }
    }
}

/// The wall's plane, `x = WALL_X`: a kitchen wall's coordinate, whose binary32 rounding matters.
const WALL_X: f32 = 150.2299;

/// A wall in the plane `x = WALL_X`: `panels` pairs of large triangles (40 by 10.3 units) from `y = 120` on, and
/// `decals` small coplanar triangles on them, each at a corner drawn in `y_range` (and `z` 0.5 to 8) with the
/// sides `(a, b)` that `sides` gives.
fn wall(
    r: &mut rand_pcg::Pcg64Mcg,
    (panels, decals): (usize, usize),
    y_range: std::ops::Range<f32>,
    mut sides: impl FnMut(&mut rand_pcg::Pcg64Mcg) -> (f32, f32),
) -> Vec<Triangle> {
    use rand::RngExt;
    let x = WALL_X;
    let mut wall: Vec<Triangle> = Vec::new();
    for k in 0..panels {
        let y = 120.0 + 40.0 * k as f32;
        wall.push([[x, y, 0.0], [x, y + 40.0, 0.0], [x, y + 13.0, 10.3]]);
        wall.push([[x, y + 40.0, 0.0], [x, y + 40.0, 10.3], [x, y + 13.0, 10.3]]);
    }
    for _ in 0..decals {
        let (y, z): (f32, f32) = (r.random_range(y_range.clone()), r.random_range(0.5..8.0));
        let (a, b) = sides(r);
        wall.push([[x, y, z], [x, y, z + b], [x, y - a, z]]);
    }
    wall
}

/// `count` rays leaving points 0.001 to 0.05 in front of the wall (at `y` in `y_range`), mostly along it.
fn rays_along_the_wall(r: &mut rand_pcg::Pcg64Mcg, count: usize, y_range: std::ops::Range<f32>) -> Vec<Ray> {
    use rand::RngExt;
    (0..count)
        .map(|_| {
            let (y, z): (f32, f32) = (r.random_range(y_range.clone()), r.random_range(0.5..9.0));
            let h: f32 = 10f32.powf(r.random_range(-3.0..-1.3));
            let d = [r.random_range(0.2..0.7), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)];
            let t: f32 = h / d[0];
            Ray::new([WALL_X - h, y - d[1] * t, z - d[2] * t], d)
        })
        .collect()
}

/// The kitchen's case made here: a wall of large triangles (40 by 10 units) in the plane `x = 150.2299`, with
/// smaller coplanar ones on it (panels, decals), and rays leaving points 0.001 to 0.05 in front of it whose
/// direction lies mostly along the wall, so that a wall triangle's depth along the ray's major axis is a thousand
/// times `t`: its binary32 `t` is then off by up to `2^-14` of `t` while the ray enters every box in the plane at
/// the exact crossing, and the walks that padded their cull by `2^-18` culled the box of the nearest record where
/// they met another first. Every entry point, in a file of one record a leaf, returns the brute force's hit.
#[test]
fn rays_along_a_wall_get_the_nearest_of_its_coplanar_records() {
    use rand::RngExt;
    let mut r = crate::common::rng(11);
    let sides = |r: &mut rand_pcg::Pcg64Mcg| (r.random_range(1.0..8.0), r.random_range(1.0..4.0));
    let wall = wall(&mut r, (4, 60), 121.0..275.0, sides);
    let file = write_wide_file(&wall, 1);
    let rays = rays_along_the_wall(&mut r, 100_000, 125.0..275.0);
    let hits = assert_every_entry_point("wall", &file.view(), &rays);
    assert!(hits > 80_000, "{hits}");
}

/// The wall in a two-level file: placed as it is, turned about the z axis and mirrored, and scaled 1:3 on y (its
/// instances overlap where the rays run), every instance's records tested on its object-space ray (11.3): every
/// kernel returns the brute force's hit over all instances.
#[test]
fn rays_along_a_wall_through_instances_get_the_nearest_record_of_every_instance() {
    let mut r = crate::common::rng(12);
    let wall = wall(&mut r, (2, 20), 121.0..195.0, |_| (6.0, 4.0));
    let turned = rotation_z(1e-3);
    let mirrored = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
    let stretched = [[1.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 1.0]];
    let placements = [
        placement(0, affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3])),
        placement(0, affine(turned, [0.15, 0.0, 0.0])),
        placement(0, affine(mirrored, [0.0, 320.0, 0.0])),
        placement(0, affine(stretched, [0.0, -310.0, 0.0])),
    ];
    for wide in [false, true] {
        let (scene, sources) = two_level(std::slice::from_ref(&wall), &placements, wide);
        let file = write_two_level(&scene, &sources).unwrap();
        let rays = rays_along_the_wall(&mut r, 20_000, 125.0..195.0);
        let hits = assert_every_entry_point(&format!("wall instances (wide {wide})"), &file.view(), &rays);
        assert!(hits > 15_000, "{hits}");
    }
}
