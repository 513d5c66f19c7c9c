//! Two-level files (format 1.3): traversal through instances equals an f64 oracle over the flattened scene on
//! every kernel path and entry point, including mirrored, non-uniformly scaled, sheared and far-away instances;
//! spawned rays leave instanced triangles cleanly; hits carry the instance, the mesh's record and source id.
//! The scene helpers here also serve the rule and golden tests.

use bvhc::instancing::{PackedMesh, Placement, TwoLevelScene};
use bvhc::loader::format::NO_INDEX;
use bvhc::loader::{
    BvhFile, Hit, Ray, Tracer, format::Affine3x4, format::SourceRange, format::SourceVertexIndices, write::BvhWriter,
};
use bvhc_loader::Trace;

use crate::common::*;

/// Metadata of the test files of version 1.3.
pub const METADATA_1_3: &str = r#"{"generator":"bvhc tests","format_version":"1.3"}"#;

/// A mesh's packed trees (leaves of up to 2 triangles), its ids `first_id + input index`, source vertices
/// `3 k, 3 k + 1, 3 k + 2` for input triangle `k` (no two triangles share a vertex), with or without the wide
/// sections.
pub fn packed_mesh(triangles: &[Triangle], first_id: u32, wide: bool) -> PackedMesh {
    let tree = packed_tree(triangles, 2);
    let triangle_ids = tree.triangle_ids.iter().map(|&t| first_id + t).collect();
    let source_vertices: Vec<SourceVertexIndices> =
        tree.triangle_ids.iter().map(|&t| SourceVertexIndices { indices: [3 * t, 3 * t + 1, 3 * t + 2] }).collect();
    let (wide_nodes, packets) = if wide {
        let bvh = wide_sections_for(&tree, triangles);
        (bvh.nodes().to_vec(), bvh.packets().to_vec())
    } else {
        (Vec::new(), Vec::new())
    };
    PackedMesh { nodes: tree.nodes, triangles: tree.triangles, triangle_ids, source_vertices, wide_nodes, packets }
}

/// A placement of `mesh_index` by `object_to_world`, without provenance.
pub fn placement(mesh_index: u32, object_to_world: Affine3x4) -> Placement {
    Placement { mesh_index, object_to_world, node_index: NO_INDEX, gpu_instance_index: NO_INDEX }
}

/// A two-level scene over `meshes` (ids numbered mesh after mesh), its source table (one range a mesh).
pub fn two_level(meshes: &[Vec<Triangle>], placements: &[Placement], wide: bool) -> (TwoLevelScene, Vec<SourceRange>) {
    let mut first_id = 0u32;
    let mut packed = Vec::new();
    let mut sources = Vec::new();
    for (m, mesh) in meshes.iter().enumerate() {
        packed.push(packed_mesh(mesh, first_id, wide));
        sources.push(SourceRange {
            first_source_triangle: first_id,
            source_triangle_count: mesh.len() as u32,
            file_index: 0,
            node_index: NO_INDEX,
            mesh_index: m as u32,
            primitive_index: 0,
            instance_index: NO_INDEX,
            reserved: 0,
        });
        first_id += mesh.len() as u32;
    }
    (TwoLevelScene::assemble(packed, placements).expect("the test scene assembles"), sources)
}

/// The file of a two-level scene: every section, ids and source table, metadata of 1.3; the writer's error
/// when a rule is broken.
pub fn write_two_level(scene: &TwoLevelScene, sources: &[SourceRange]) -> Result<BvhFile, bvhc::loader::Error> {
    let mut writer = BvhWriter::new(&scene.nodes, &scene.triangles)
        .triangle_ids(&scene.triangle_ids)
        .source_table(sources)
        .metadata(METADATA_1_3)
        .two_level(scene.sections());
    if !scene.wide_nodes.is_empty() {
        writer = writer.wide(&scene.wide_nodes, &scene.packets);
    }
    writer.source_vertices(&scene.source_vertices).build()
}

/// A small two-level file (two meshes of a few triangles, four instances, wide sections), as bytes.
pub fn small_two_level_bytes() -> Vec<u8> {
    let meshes = vec![random_triangles(3101, 6, 1.0), random_triangles(3102, 5, 1.0)];
    let placements: Vec<Placement> = test_placements().into_iter().take(4).collect();
    let (scene, sources) = two_level(&meshes, &placements, true);
    write_two_level(&scene, &sources).expect("the small scene writes").as_bytes().to_vec()
}

/// `[[a, b, c, d]; 3]` rows of a 3x4 map from a 3x3 matrix and a translation.
pub fn affine(m: [[f32; 3]; 3], t: [f32; 3]) -> Affine3x4 {
    std::array::from_fn(|i| [m[i][0], m[i][1], m[i][2], t[i]])
}

pub fn rotation_z(degrees: f32) -> [[f32; 3]; 3] {
    let (s, c) = degrees.to_radians().sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

fn times(a: [[f32; 3]; 3], b: [[f32; 3]; 3]) -> [[f32; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn scale(s: [f32; 3]) -> [[f32; 3]; 3] {
    [[s[0], 0.0, 0.0], [0.0, s[1], 0.0], [0.0, 0.0, s[2]]]
}

/// The placements the oracle tests use: identity, moved, mirrored, non-uniformly scaled and rotated, sheared,
/// tiny, and far from the origin; overlapping one another.
pub fn test_placements() -> Vec<Placement> {
    let shear = [[1.0, 0.6, 0.0], [0.0, 1.0, 0.3], [0.0, 0.0, 1.0]];
    vec![
        placement(0, affine(scale([1.0; 3]), [0.0; 3])),
        placement(1, affine(scale([1.0; 3]), [0.5, 0.2, -0.3])),
        placement(0, affine(scale([-1.0, 1.0, 1.0]), [2.5, 0.0, 0.0])),
        placement(1, affine(times(rotation_z(30.0), scale([3.0, 0.5, 1.0])), [0.0, 3.0, 0.0])),
        placement(0, affine(shear, [-3.0, -1.0, 0.5])),
        placement(1, affine(scale([1e-3, 2e-3, 1e-3]), [0.0, 0.0, 4.0])),
        placement(0, affine(times(rotation_z(-70.0), scale([2.0, 2.0, -2.0])), [1.0e5, -2.0e5, 3.0e4])),
        placement(0, affine(scale([0.7; 3]), [0.3, -0.4, 0.2])),
    ]
}

/// The test meshes: a closed icosphere (320 triangles) and scattered random triangles.
pub fn test_meshes() -> Vec<Vec<Triangle>> {
    let (v, f) = unit_icosphere(2);
    let sphere = f.iter().map(|t| t.map(|i| v[i].map(|c| c as f32))).collect();
    vec![sphere, random_triangles(2601, 300, 1.0)]
}

/// One triangle of the flattened scene, in f64: the exact image of the mesh's record, and who it is.
pub struct Placed {
    pub vertices: [[f64; 3]; 3],
    pub instance: u32,
    pub source_id: u32,
}

/// Every instance's records placed in world space (in f64), instance after instance.
pub fn flatten(scene: &TwoLevelScene) -> Vec<Placed> {
    let mut placed = Vec::new();
    for (i, instance) in scene.instances.iter().enumerate() {
        let mesh = &scene.meshes[instance.mesh_index as usize];
        let range = mesh.first_triangle as usize..(mesh.first_triangle + mesh.triangle_count) as usize;
        for (record, &id) in scene.triangles[range.clone()].iter().zip(&scene.triangle_ids[range]) {
            let m = &instance.object_to_world;
            let vertices = record.vertices.map(|p| {
                std::array::from_fn(|r| {
                    let row = m[r].map(f64::from);
                    row[0] * f64::from(p[0]) + row[1] * f64::from(p[1]) + row[2] * f64::from(p[2]) + row[3]
                })
            });
            placed.push(Placed { vertices, instance: i as u32, source_id: id });
        }
    }
    placed
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// What the f64 oracle expects of a ray.
#[derive(Debug, PartialEq)]
pub enum Expected {
    /// No triangle comes within the margin of the ray.
    Miss,
    /// This source triangle, clearly inside it and clearly nearest, at this `t`, placed by one of `instances`
    /// (several when instances overlap, placing the same triangle at the same `t` within the tie margin).
    Hit { t: f64, instances: Vec<u32>, source_id: u32 },
    /// A triangle's edge or a second triangle within the tolerance: either answer is right.
    Ambiguous,
}

/// Barycentric margin within which a hit counts as on an edge, and relative `t` margin within which two hits
/// count as tied.
const EDGE_MARGIN: f64 = 1e-4;
const TIE_MARGIN: f64 = 1e-4;

/// The f64 oracle: the clearly nearest source triangle over every placement, if one is.
pub fn oracle(placed: &[Placed], ray: &Ray) -> Expected {
    let o = ray.origin.map(f64::from);
    let d = ray.direction.map(f64::from);
    let mut clear: Vec<(f64, u32, u32)> = Vec::new();
    let mut edge: Vec<f64> = Vec::new();
    for p in placed {
        let [v0, v1, v2] = p.vertices;
        let (e1, e2) = (sub(v1, v0), sub(v2, v0));
        let q = cross(d, e2);
        let det = dot(e1, q);
        if det == 0.0 {
            continue;
        }
        let s = sub(o, v0);
        let u = dot(s, q) / det;
        let r = cross(s, e1);
        let v = dot(d, r) / det;
        let t = dot(e2, r) / det;
        let least = (1.0 - u - v).min(u).min(v);
        // The f32 ray's rounding moves a hit by more the more grazing the ray: widen the margin by 1 / cos.
        let cosine = det.abs() / (dot(d, d) * dot(cross(e1, e2), cross(e1, e2))).sqrt();
        let margin = EDGE_MARGIN / cosine.max(1e-12);
        if !(t >= f64::from(ray.t_min) && t <= f64::from(ray.t_max)) || least < -margin {
            continue;
        }
        if least > margin { clear.push((t, p.instance, p.source_id)) } else { edge.push(t) }
    }
    clear.sort_by(|a, b| a.0.total_cmp(&b.0));
    let Some(&(t, instance, source_id)) = clear.first() else {
        return if edge.is_empty() { Expected::Miss } else { Expected::Ambiguous };
    };
    let tie = t.abs() * TIE_MARGIN + 1e-30;
    let tied = |other: &&(f64, u32, u32)| other.0 - t <= tie;
    let contested = clear.iter().filter(tied).any(|other| other.2 != source_id) || edge.iter().any(|&e| e - t <= tie);
    let instances = clear.iter().filter(tied).map(|other| other.1).chain([instance]).collect();
    if contested { Expected::Ambiguous } else { Expected::Hit { t, instances, source_id } }
}

/// Rays aimed at interior points of placed triangles from nearby and from the world origin, and rays through
/// the near part of the scene at random.
pub fn test_rays(placed: &[Placed], count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = rng(seed);
    let mut rays = random_rays(seed + 1, count / 4, 5.0);
    while rays.len() < count {
        use rand::RngExt;
        let p = &placed[rng.random_range(0..placed.len())];
        let (a, b) = (rng.random_range(0.05..0.9f64), rng.random_range(0.05..0.9f64));
        let (a, b) = if a + b > 0.95 { (0.95 - b.min(0.9), b.min(0.9) * 0.5) } else { (a, b) };
        let target: [f64; 3] = std::array::from_fn(|k| {
            p.vertices[0][k] + a * (p.vertices[1][k] - p.vertices[0][k]) + b * (p.vertices[2][k] - p.vertices[0][k])
        });
        let size = p.vertices.iter().flat_map(|v| sub(*v, target)).fold(0.0f64, |m, c| m.max(c.abs())).max(1e-3);
        let origin: [f64; 3] = if rays.len().is_multiple_of(5) {
            [0.0; 3]
        } else {
            std::array::from_fn(|k| target[k] + rng.random_range(-50.0..50.0) * size)
        };
        let origin = origin.map(|c| c as f32);
        let direction: [f32; 3] = std::array::from_fn(|k| (target[k] - f64::from(origin[k])) as f32);
        rays.push(Ray::new(origin, direction));
    }
    rays
}

/// Checks `tracer` against the oracle on `rays`; returns (hits checked, ambiguous rays, largest `t` error
/// relative to `t + |origin| / |direction|`).
pub fn check_against_oracle(
    tracer: &Tracer<'_>,
    file: &BvhFile,
    placed: &[Placed],
    rays: &[Ray],
) -> (usize, usize, f64) {
    let view = file.view();
    let (mut checked, mut ambiguous, mut worst) = (0, 0, 0.0f64);
    for (r, ray) in rays.iter().enumerate() {
        let got = tracer.closest_hit(ray);
        assert_eq!(tracer.any_hit(ray), got.is_some(), "ray {r}: any hit and closest hit disagree");
        if let Some(hit) = &got {
            let ids = view.triangle_ids().unwrap();
            assert_eq!(hit.source_triangle_id, Some(ids[hit.triangle_index as usize]), "ray {r}: id of the record");
        }
        match oracle(placed, ray) {
            Expected::Ambiguous => ambiguous += 1,
            Expected::Miss => assert_eq!(got, None, "ray {r} {ray:?}: the oracle sees no triangle near the ray"),
            Expected::Hit { t, instances, source_id } => {
                let hit: Hit =
                    got.unwrap_or_else(|| panic!("ray {r} {ray:?}: missed instance {instances:?} id {source_id}"));
                assert_eq!(hit.source_triangle_id, Some(source_id), "ray {r} {ray:?}");
                assert!(instances.contains(&hit.instance_index.unwrap()), "ray {r} {ray:?}: {instances:?}");
                let o = ray.origin.iter().fold(0.0f64, |m, c| m.max(f64::from(c.abs())));
                let d = ray.direction.iter().fold(0.0f64, |m, c| m.max(f64::from(c.abs())));
                let error = (f64::from(hit.t) - t).abs() / (t + o / d);
                worst = worst.max(error);
                assert!(error <= T_TOLERANCE, "ray {r}: t {} against {t}: relative error {error:e}", hit.t);
                checked += 1;
            }
        }
    }
    (checked, ambiguous, worst)
}

/// The documented bound of `format-spec/bvh-1.md` 11.3 on a hit's `t` against the exact intersection of the
/// world ray with the exactly placed triangle, relative to `t + |origin|_inf / |direction|_inf`.
pub const T_TOLERANCE: f64 = 1.0 / 65_536.0;

fn every_kernel_of(file: &BvhFile) -> Vec<Tracer<'_>> {
    every_kernel(&file.view())
}

#[test]
fn traversal_through_instances_equals_the_flattened_oracle_on_every_kernel() {
    for wide in [false, true] {
        let (scene, sources) = two_level(&test_meshes(), &test_placements(), wide);
        let file = write_two_level(&scene, &sources).expect("the test scene writes and verifies");
        assert_eq!(file.view().version(), (1, 3));
        let placed = flatten(&scene);
        let rays = test_rays(&placed, 4000, 77);
        let kernels = every_kernel_of(&file);
        assert_eq!(kernels.len(), if wide { 1 + kernel_paths().len() } else { 1 });
        for tracer in &kernels {
            let (checked, ambiguous, worst) = check_against_oracle(tracer, &file, &placed, &rays);
            eprintln!(
                "wide {wide} {:?}: {checked} hits checked, {ambiguous} ambiguous, worst t error {worst:e}",
                tracer.kernel()
            );
            assert!(checked > 2000 && ambiguous < rays.len() / 20, "{checked} checked, {ambiguous} ambiguous");
        }
        // Every kernel finds the same hits bit for bit (the meshes' kernels agree; the walk is shared).
        for tracer in &kernels[1..] {
            for ray in &rays {
                assert_eq!(tracer.closest_hit(ray), kernels[0].closest_hit(ray));
            }
        }
    }
}

#[test]
fn batch_and_coherent_entry_points_equal_single_rays_through_instances() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let file = write_two_level(&scene, &sources).unwrap();
    let rays = test_rays(&flatten(&scene), 1000, 78);
    for tracer in every_kernel_of(&file) {
        let single: Vec<Option<Hit>> = rays.iter().map(|r| tracer.closest_hit(r)).collect();
        let occluded: Vec<bool> = rays.iter().map(|r| tracer.any_hit(r)).collect();
        let mut hits = vec![None; rays.len()];
        let mut flags = vec![false; rays.len()];
        tracer.closest_hits(&rays, &mut hits);
        assert_eq!(hits, single);
        tracer.closest_hits_coherent(&rays, &mut hits);
        assert_eq!(hits, single);
        tracer.any_hits(&rays, &mut flags);
        assert_eq!(flags, occluded);
        tracer.any_hits_coherent(&rays, &mut flags);
        assert_eq!(flags, occluded);
        // Handed off lean: each hit's core, its instance included.
        let mut cores = vec![None; rays.len()];
        tracer.closest_hit_cores_with(&rays, bvhc::loader::Order::Stream, |i, core| cores[i] = core).unwrap();
        assert!(cores.iter().zip(&single).all(|(core, hit)| *core == hit.map(|h| h.core())));
        assert!(cores.iter().flatten().any(|core| core.instance_index.is_some()));
    }
}

#[test]
fn rays_from_inside_an_instanced_closed_mesh_always_hit_it() {
    // Every placement of the sphere (mesh 0), mirrored and far away included: rays from its center leave
    // through it, and the first hit is that instance's.
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let file = write_two_level(&scene, &sources).unwrap();
    let mut rng = rng(79);
    for tracer in every_kernel_of(&file) {
        for (i, instance) in scene.instances.iter().enumerate().filter(|(_, p)| p.mesh_index == 0) {
            let center = instance.object_to_world.map(|row| row[3]);
            for _ in 0..300 {
                let direction = random_point(&mut rng, 1.0);
                let hit = tracer.closest_hit(&Ray::new(center, direction));
                let hit = hit.unwrap_or_else(|| panic!("instance {i}: a ray from the center escaped"));
                // The sheared and overlapping placements may be nearer; the ray still hits something, and
                // when it is this instance the hit faces outward (the ray meets the back side).
                if hit.instance_index == Some(i as u32) {
                    assert!(!hit.front_face, "instance {i}: the sphere's front faces outward");
                }
            }
        }
    }
}

#[test]
fn spawned_rays_never_meet_their_own_instanced_triangle() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let file = write_two_level(&scene, &sources).unwrap();
    let placed = flatten(&scene);
    let rays = test_rays(&placed, 3000, 80);
    let mut rng = rng(81);
    let tracer = file.view().tracer();
    let (mut spawned, mut self_hits) = (0, 0);
    for ray in &rays {
        let Some(hit) = tracer.closest_hit(ray) else { continue };
        let surface = tracer.surface(&hit).unwrap();
        assert!(surface.instance.is_some());
        for _ in 0..4 {
            use rand::RngExt;
            let direction = surface.cosine_direction([rng.random(), rng.random()]);
            let again = tracer.closest_hit(&surface.spawn(direction).unwrap());
            spawned += 1;
            if again.is_some_and(|a| (a.instance_index, a.triangle_index) == (hit.instance_index, hit.triangle_index)) {
                self_hits += 1;
            }
        }
    }
    eprintln!("{spawned} rays spawned from instanced hits, {self_hits} met their own triangle");
    assert!(spawned > 8000, "{spawned}");
    assert_eq!(self_hits, 0, "of {spawned} spawned rays");
}
