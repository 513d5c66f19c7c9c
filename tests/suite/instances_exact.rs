//! Closest hits through overlapping instances are exact (`format-spec/bvh-1.md` 11.3): on every kernel path and
//! entry point, a two-level file's closest hit has the smallest `t` that 11.1's test gives over every instance's
//! mesh, with the ray mapped into each instance as 11.3 states (computed here from the spec's text, not by the
//! loader), bit for bit, on rays aimed at shared vertices, at edges and silhouettes and at random, through
//! identical, nearly identical, mirrored, sheared and scaled placements that overlap. Where the binary64 oracle over
//! the flattened scene sees one triangle clearly nearest, the two-level file and the flattened one-level file both
//! report it at a `t` within 11.3's bound.

use bvhc::instancing::{Placement, TwoLevelScene};
use bvhc::loader::{BvhFile, Hit, Ray, format::InstanceRecord, ray::PreparedRay};
use bvhc_loader::Trace;
use rand::RngExt;

use crate::common::*;
use crate::instances::{Expected, T_TOLERANCE, affine, flatten, oracle, placement, two_level, write_two_level};

/// A closed icosphere (320 triangles) and a height field of 242 triangles over `[-1, 1]^2`: both share vertices.
fn overlap_meshes() -> Vec<Vec<Triangle>> {
    let (v, f) = unit_icosphere(2);
    let sphere = f.iter().map(|t| t.map(|i| v[i].map(|c| c as f32))).collect();
    let mut rng = rng(3601);
    let n = 12;
    let heights: Vec<f32> = (0..n * n).map(|_| rng.random_range(-0.3..0.3f32)).collect();
    let at = |i: usize, j: usize| {
        let step = 2.0 / (n - 1) as f32;
        [-1.0 + i as f32 * step, -1.0 + j as f32 * step, heights[i * n + j]]
    };
    let mut field = Vec::new();
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            field.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            field.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    vec![sphere, field]
}

fn scale(s: f32) -> [[f32; 3]; 3] {
    [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]]
}

/// Placements that overlap: the sphere twice identically, moved by an ulp, turned by a hundred-thousandth of a
/// degree and scaled by a millionth, mirrored (onto itself), sheared; the height field as is, twice, mirrored
/// and lifted by a millionth, and sheared and turned.
fn overlapping_placements() -> Vec<Placement> {
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let (s, c) = 1e-5f32.to_radians().sin_cos();
    let k = 1.000_001f32;
    let turned = [[c * k, -s * k, 0.0], [s * k, c * k, 0.0], [0.0, 0.0, k]];
    let mirror_x = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mirror_y = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
    let shear = [[1.0, 0.01, 0.0], [0.0, 1.0, 0.02], [0.0, 0.0, 1.0]];
    let (s2, c2) = 20f32.to_radians().sin_cos();
    let shear_turned = [[c2, -s2 + 0.1, 0.0], [s2, c2, 0.0], [0.05, 0.0, 0.9]];
    vec![
        placement(0, affine(identity, [0.0; 3])),
        placement(0, affine(identity, [0.0; 3])),
        placement(0, affine(identity, [f32::EPSILON, 0.0, 0.0])),
        placement(0, affine(identity, [0.0, -f32::EPSILON, f32::EPSILON / 2.0])),
        placement(0, affine(identity, [0.0, 0.0, -2.0 * f32::EPSILON])),
        placement(0, affine(scale(1.0 + f32::EPSILON), [0.0; 3])),
        placement(0, affine(turned, [0.0; 3])),
        placement(0, affine(mirror_x, [0.0; 3])),
        placement(0, affine(shear, [0.0; 3])),
        placement(1, affine(identity, [0.0; 3])),
        placement(1, affine(identity, [0.0; 3])),
        placement(1, affine(identity, [0.0, 0.0, f32::EPSILON])),
        placement(1, affine(scale(1.0 - f32::EPSILON / 2.0), [0.0; 3])),
        placement(1, affine(mirror_y, [0.0, 0.0, 1e-6])),
        placement(1, affine(shear_turned, [0.1, -0.1, 0.05])),
    ]
}

/// The object-space ray of 11.3, from the spec's words: `r = o - t` per axis in binary64, then the row sums
/// `W_i0 r_0 + W_i1 r_1 + W_i2 r_2` in that order in binary64, rounded to binary32; likewise `W d`.
pub fn spec_object_ray(instance: &InstanceRecord, ray: &Ray) -> Ray {
    let w = instance.world_to_object.map(|row| row.map(f64::from));
    let row_sums = |r: [f64; 3]| -> [f32; 3] {
        std::array::from_fn(|i| (w[i][0] * r[0] + w[i][1] * r[1] + w[i][2] * r[2]) as f32)
    };
    let relative = std::array::from_fn(|k| f64::from(ray.origin[k]) - f64::from(instance.object_to_world[k][3]));
    Ray { origin: row_sums(relative), direction: row_sums(ray.direction.map(f64::from)), ..*ray }
}

/// The smallest `t` 11.1's test gives for `ray` over every instance's records (each instance's records tested
/// with the ray mapped into it), by brute force.
fn nearest_over_instances(scene: &TwoLevelScene, ray: &Ray) -> Option<f32> {
    let mut nearest: Option<f32> = None;
    for instance in &scene.instances {
        let mesh = &scene.meshes[instance.mesh_index as usize];
        let prepared = PreparedRay::new(&spec_object_ray(instance, ray));
        let first = mesh.first_triangle as usize;
        for triangle in &scene.triangles[first..first + mesh.triangle_count as usize] {
            if let Some(hit) = prepared.intersect_triangle(triangle, ray.t_max) {
                nearest = Some(nearest.map_or(hit.t, |t| t.min(hit.t)));
            }
        }
    }
    nearest
}

/// Whether `hit` is what 11.1 gives on the record it names, in the instance it names, with `t = nearest`: the
/// first thing wrong with it.
fn exactness(scene: &TwoLevelScene, ray: &Ray, hit: Option<Hit>, nearest: Option<f32>) -> Result<(), String> {
    let (hit, t) = match (hit, nearest) {
        (None, None) => return Ok(()),
        (None, Some(t)) => return Err(format!("missed, but an instance is hit at {t}")),
        (Some(hit), None) => return Err(format!("hit {hit:?} where no instance is hit")),
        (Some(hit), Some(t)) => (hit, t),
    };
    if hit.t.to_bits() != t.to_bits() {
        return Err(format!(
            "hit at {} (instance {:?}), the nearest over all instances at {t}",
            hit.t, hit.instance_index
        ));
    }
    let instance = hit.instance_index.and_then(|i| scene.instances.get(i as usize)).ok_or("no instance")?;
    let record = &scene.triangles[hit.triangle_index as usize];
    let own = PreparedRay::new(&spec_object_ray(instance, ray)).intersect_triangle(record, ray.t_max);
    match own {
        Some(own) if (own.t, own.u, own.v) == (hit.t, hit.u, hit.v) => Ok(()),
        _ => Err(format!("{hit:?} is not the named record's own hit {own:?}")),
    }
}

/// Asserts that every hit is exact ([`exactness`]), naming the first few rays that are not.
fn assert_all_exact(scene: &TwoLevelScene, rays: &[Ray], hits: &[Option<Hit>], nearest: &[Option<f32>], what: &str) {
    let wrong: Vec<String> = (rays.iter().zip(hits).zip(nearest))
        .filter_map(|((ray, &hit), &t)| exactness(scene, ray, hit, t).err().map(|e| format!("{e}: {ray:?}")))
        .collect();
    assert!(
        wrong.is_empty(),
        "{what}: {} of {} rays wrong, first {:#?}",
        wrong.len(),
        rays.len(),
        &wrong[..wrong.len().min(4)]
    );
}

/// Rays aimed at the placed vertices and at points on placed edges (the silhouettes among them) from around the
/// scene and from its middle, and random rays through it.
fn overlap_rays(scene: &TwoLevelScene, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = rng(seed);
    let mut rays = random_rays(seed + 1, count / 5, 1.5);
    // The corners on their mesh's root box (where the box's entry distance and the hit's `t` meet).
    let on_root_box: Vec<Vec<(u32, usize)>> = (scene.meshes.iter())
        .map(|mesh| {
            let root = &scene.nodes[mesh.first_node as usize];
            let records = mesh.first_triangle..mesh.first_triangle + mesh.triangle_count;
            let corners = records.flat_map(|r| (0..3).map(move |c| (r, c)));
            corners
                .filter(|&(r, c)| {
                    let v = scene.triangles[r as usize].vertices[c];
                    (0..3).any(|a| v[a] == root.min[a] || v[a] == root.max[a])
                })
                .collect()
        })
        .collect();
    while rays.len() < count {
        let instance = &scene.instances[rng.random_range(0..scene.instances.len())];
        let mesh = &scene.meshes[instance.mesh_index as usize];
        let extreme = &on_root_box[instance.mesh_index as usize];
        let (record, corner) = if rays.len().is_multiple_of(3) && !extreme.is_empty() {
            extreme[rng.random_range(0..extreme.len())]
        } else {
            (rng.random_range(0..mesh.triangle_count) + mesh.first_triangle, rng.random_range(0..3usize))
        };
        let vertices = scene.triangles[record as usize].vertices;
        let (p, q) = (vertices[corner], vertices[(corner + 1) % 3]);
        // Half the rays at the vertex itself, the others at a point of the edge to the next vertex.
        let s = if rays.len().is_multiple_of(2) { 0.0 } else { rng.random_range(0.0..1.0f64) };
        let object: [f64; 3] = std::array::from_fn(|k| f64::from(p[k]) + s * (f64::from(q[k]) - f64::from(p[k])));
        let world = bvhc::loader::ray::transformed_box(
            &instance.object_to_world,
            (object.map(|c| c as f32), object.map(|c| c as f32)),
        )
        .0;
        let origin: [f32; 3] = if rays.len().is_multiple_of(7) {
            [0.0, 0.0, 0.05]
        } else {
            let direction = random_point(&mut rng, 1.0);
            let length = direction.iter().map(|c| c * c).sum::<f32>().sqrt().max(1e-3);
            let distance = rng.random_range(2.0..6.0f32);
            std::array::from_fn(|k| world[k] as f32 + direction[k] / length * distance)
        };
        let direction: [f32; 3] = std::array::from_fn(|k| (world[k] - f64::from(origin[k])) as f32);
        if direction.iter().any(|&c| c != 0.0) {
            rays.push(Ray::new(origin, direction));
        }
    }
    rays
}

fn overlapping_file(wide: bool) -> (TwoLevelScene, BvhFile) {
    let (scene, sources) = two_level(&overlap_meshes(), &overlapping_placements(), wide);
    let file = write_two_level(&scene, &sources).expect("the overlapping scene writes and verifies");
    (scene, file)
}

#[test]
fn closest_hits_through_overlapping_instances_are_the_nearest_over_all_instances_on_every_kernel() {
    for wide in [false, true] {
        let (scene, file) = overlapping_file(wide);
        let rays = overlap_rays(&scene, 20_000, 3602);
        let nearest: Vec<Option<f32>> = rays.iter().map(|ray| nearest_over_instances(&scene, ray)).collect();
        let hit_count = nearest.iter().flatten().count();
        assert!(hit_count > rays.len() / 2, "{hit_count} of {} rays hit", rays.len());
        for tracer in every_kernel(&file.view()) {
            let kernel = format!("wide sections {wide}, {:?}", tracer.kernel());
            let single: Vec<Option<Hit>> = rays.iter().map(|ray| tracer.closest_hit(ray)).collect();
            assert_all_exact(&scene, &rays, &single, &nearest, &kernel);
            for (ray, &t) in rays.iter().zip(&nearest) {
                assert_eq!(tracer.any_hit(ray), t.is_some(), "{kernel}: any hit: {ray:?}");
            }
            let mut batch = vec![None; rays.len()];
            tracer.closest_hits(&rays, &mut batch);
            assert_eq!(batch, single, "{kernel}: the batch call");
            tracer.closest_hits_coherent(&rays, &mut batch);
            assert_all_exact(&scene, &rays, &batch, &nearest, &format!("{kernel}, coherent"));
            eprintln!("{kernel}: {hit_count} of {} rays hit, every one at the nearest t", rays.len());
        }
    }
}

#[test]
fn overlapping_instances_trace_like_the_flattened_file_and_the_f64_oracle() {
    let (scene, file) = overlapping_file(true);
    let placed = flatten(&scene);
    // The flattened scene: every placed triangle rounded to f32 in one one-level file, ids as the instances'.
    let triangles: Vec<Triangle> = placed.iter().map(|p| p.vertices.map(|v| v.map(|c| c as f32))).collect();
    let flat = write_wide_file(&triangles, 2);
    let flat_tracer = flat.view().tracer();
    let tracer = file.view().tracer();
    let rays = overlap_rays(&scene, 20_000, 3603);
    let (mut clear, mut ambiguous) = (0, 0);
    for ray in &rays {
        let (two_level, flattened) = (tracer.closest_hit(ray), flat_tracer.closest_hit(ray));
        match oracle(&placed, ray) {
            Expected::Ambiguous => ambiguous += 1,
            Expected::Miss => {
                assert_eq!(two_level, None, "two-level: {ray:?}");
                assert_eq!(flattened, None, "flattened: {ray:?}");
            }
            Expected::Hit { t, instances, source_id } => {
                let o = ray.origin.iter().fold(0.0f64, |m, c| m.max(f64::from(c.abs())));
                let d = ray.direction.iter().fold(0.0f64, |m, c| m.max(f64::from(c.abs())));
                let two_level = two_level.unwrap_or_else(|| panic!("two-level missed: {ray:?}"));
                assert_eq!(two_level.source_triangle_id, Some(source_id), "two-level: {ray:?}");
                assert!(instances.contains(&two_level.instance_index.unwrap()), "two-level: {ray:?}");
                let flattened = flattened.unwrap_or_else(|| panic!("flattened missed: {ray:?}"));
                let flat_record = &placed[flattened.source_triangle_id.unwrap() as usize];
                assert_eq!(flat_record.source_id, source_id, "flattened: {ray:?}");
                assert!(instances.contains(&flat_record.instance), "flattened: {ray:?}");
                for hit_t in [two_level.t, flattened.t] {
                    let error = (f64::from(hit_t) - t).abs() / (t + o / d);
                    assert!(error <= T_TOLERANCE, "t {hit_t} against {t}: relative error {error:e}: {ray:?}");
                }
                clear += 1;
            }
        }
    }
    eprintln!("{clear} rays with one clearly nearest source triangle, {ambiguous} ambiguous, of {}", rays.len());
    assert!(clear > rays.len() / 4, "{clear} clear of {}", rays.len());
}
