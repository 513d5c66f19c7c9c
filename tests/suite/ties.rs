//! Ties decided by the spec (`format-spec/bvh-1.md` 11.1, revision 1.5.2): the closest hit is the lowest
//! record among the hits at the smallest `t` (in a two-level file the lowest instance, then the lowest record),
//! whatever order a kernel meets them in. Crafted ties (triangles sharing edges and vertices, a triangle stored
//! three times, coplanar triangles overlapping, instances placed on top of each other), traced through every
//! kernel and entry point (binary, wide portable and AVX2, single rays, streams, coherent packets, a filter
//! asked about every candidate, the GPU layout's CPU model), against a brute force over every record that keeps
//! the lexicographic minimum of `(t, instance, key)` with the spec's own hit test, the key being the record, or
//! in a file with split references (where a triangle has several records, any of which a walk may meet) the
//! record's coordinates and then its source id (revision 1.5.8: of a triangle stored three times in the source,
//! the copy of lowest id).

use std::path::Path;

use bvhc::loader::filter::{Candidate, FilterScope};
use bvhc::loader::{BvhFile, BvhView, Hit, Ray, Tracer, ray::PreparedRay};
use bvhc::options::{Overrides, Preset};
use bvhc_loader::Trace;

use crate::common::{every_kernel, rng};
use crate::instances::{affine, placement, two_level, write_two_level};
use crate::instances_exact::spec_object_ray;

type Triangle = [[f32; 3]; 3];

/// A record's place among hits at one `t` (spec 11.1): its index, or with split references its coordinates and
/// source id (0 without ids).
pub(crate) type Key = ([u32; 9], u32);

pub(crate) fn key_of(view: &BvhView<'_>, record: u32) -> Key {
    match view.has_split_references() {
        true => {
            let id = view.triangle_ids().map_or(0, |ids| ids[record as usize]);
            (view.triangles()[record as usize].coordinate_bits(), id)
        }
        false => ([0; 9], record),
    }
}

/// A closest hit as the spec names it: `t`'s bits, the instance (two-level) and the key.
pub(crate) type Named = (u32, Option<u32>, Key);

pub(crate) fn named(view: &BvhView<'_>, hit: &Hit) -> Named {
    (hit.t.to_bits(), hit.instance_index, key_of(view, hit.triangle_index))
}

/// The brute force: every record of `records` (offset by `first` in the triangles section) hit by `ray` with
/// the spec's test, the lexicographic minimum of `(t, key)`; also how many records share that `t`.
fn lowest_in(view: &BvhView<'_>, first: u32, count: u32, ray: &Ray) -> Option<(f32, Key, usize)> {
    let prepared = PreparedRay::new(ray);
    let mut best: Option<(f32, Key, usize)> = None;
    for record in first..first + count {
        if let Some(hit) = prepared.intersect_triangle(&view.triangles()[record as usize], ray.t_max) {
            let key = key_of(view, record);
            best = match best {
                Some((t, k, n)) if hit.t == t => Some((t, k.min(key), n + 1)),
                Some((t, _, _)) if hit.t > t => best,
                _ => Some((hit.t, key, 1)),
            };
        }
    }
    best
}

/// The brute force over a file: one-level, its records; two-level, every instance's mesh records in the
/// object-space ray of 11.3, instances in index order. The expected closest hit and whether it is a tie.
pub(crate) fn expected(view: &BvhView<'_>, ray: &Ray) -> Option<(Named, bool)> {
    let Some(sections) = view.two_level() else {
        let count = view.triangles().len() as u32;
        return lowest_in(view, 0, count, ray).map(|(t, key, n)| ((t.to_bits(), None, key), n > 1));
    };
    let mut best: Option<(f32, u32, Key, usize)> = None;
    for (i, instance) in sections.instances.iter().enumerate() {
        let mesh = &sections.meshes[instance.mesh_index as usize];
        let object_ray = spec_object_ray(instance, ray);
        let Some((t, record, n)) = lowest_in(view, mesh.first_triangle, mesh.triangle_count, &object_ray) else {
            continue;
        };
        best = match best {
            Some((bt, bi, br, bn)) if t == bt => Some((bt, bi, br, bn + n)),
            Some((bt, ..)) if t > bt => best,
            _ => Some((t, i as u32, record, n)),
        };
    }
    best.map(|(t, instance, record, n)| ((t.to_bits(), Some(instance), record), n > 1))
}

/// Every entry point of every kernel of `view` against the brute force on `rays`; the number of tie rays.
fn assert_every_entry_point(view: &BvhView<'_>, rays: &[Ray], name: &str) -> usize {
    let expect: Vec<Option<(Named, bool)>> = rays.iter().map(|ray| expected(view, ray)).collect();
    let wanted: Vec<Option<Named>> = expect.iter().map(|e| e.map(|(n, _)| n)).collect();
    let kernels: Vec<Tracer<'_>> = match view.two_level() {
        Some(sections) => every_kernel(view).into_iter().map(|t| t.with_instances(sections)).collect(),
        None => every_kernel(view),
    };
    let wide_kernels = if view.wide_sections().is_some() { crate::common::kernel_paths().len() } else { 0 };
    assert_eq!(kernels.len(), 1 + wide_kernels, "{name}: the binary kernel and each wide path");
    let accept_all = |_: &Candidate<'_>| true;
    for (k, kernel) in kernels.iter().enumerate() {
        let check = |entry: &str, got: &[Option<Hit>]| {
            for (r, (ray, want)) in rays.iter().zip(&wanted).enumerate() {
                let got = got[r].as_ref().map(|hit| named(view, hit));
                assert_eq!(got, *want, "{name}: kernel {k} {entry}, ray {r} {ray:?}");
            }
        };
        check("closest_hit", &rays.iter().map(|ray| kernel.closest_hit(ray)).collect::<Vec<_>>());
        let mut batch = vec![None; rays.len()];
        kernel.closest_hits(rays, &mut batch);
        check("closest_hits", &batch);
        kernel.closest_hits_coherent(rays, &mut batch);
        check("closest_hits_coherent", &batch);
        let filtered = kernel.filtered(&accept_all, FilterScope::Every);
        check("filtered closest_hit", &rays.iter().map(|ray| filtered.closest_hit(ray)).collect::<Vec<_>>());
        filtered.closest_hits(rays, &mut batch);
        check("filtered closest_hits", &batch);
    }
    expect.iter().filter(|e| e.is_some_and(|(_, tie)| tie)).count()
}

/// Rays at `targets` from above: straight down (the plane's `t` the same for every triangle there), and
/// oblique from jittered origins.
pub(crate) fn rays_at(targets: &[[f32; 3]], seed: u64) -> Vec<Ray> {
    use rand::RngExt;
    let mut rng = rng(seed);
    let mut rays = Vec::new();
    for &target in targets {
        let above = [target[0], target[1], target[2] + 3.0];
        rays.push(Ray::new(above, [0.0, 0.0, -1.0]));
        for _ in 0..3 {
            let origin = [
                target[0] + rng.random_range(-1.5..1.5f32),
                target[1] + rng.random_range(-1.5..1.5f32),
                target[2] + rng.random_range(1.0..4.0f32),
            ];
            let direction = std::array::from_fn(|k| target[k] - origin[k]);
            rays.push(Ray::new(origin, direction));
        }
    }
    rays
}

/// The one-level scene: a 4 x 4 grid of quads in z = 0 (two triangles each, vertices shared), a triangle stored
/// three times, two coplanar triangles overlapping, and a floor at z = -1; the targets at the grid's vertices and
/// edge midpoints, and inside the triple triangle and the overlap (where the GPU's f32 edge test agrees with
/// the CPU's, so it is checked too).
pub(crate) fn tie_scene(dir: &Path) -> (std::path::PathBuf, Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut obj = String::new();
    // The grid's 25 vertices come first.
    let mut vertex = 25usize;
    let mut add = |obj: &mut String, t: &Triangle| {
        for v in t {
            obj.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
        }
        obj.push_str(&format!("f {} {} {}\n", vertex + 1, vertex + 2, vertex + 3));
        vertex += 3;
    };
    let mut edge_targets = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            obj.push_str(&format!("v {i} {j} 0\n"));
            edge_targets.push([i as f32, j as f32, 0.0]);
            if i < 4 {
                edge_targets.push([i as f32 + 0.5, j as f32, 0.0]);
            }
            if i < 4 && j < 4 {
                edge_targets.push([i as f32 + 0.5, j as f32 + 0.5, 0.0]);
            }
        }
    }
    let index = |i: usize, j: usize| i * 5 + j + 1;
    for i in 0..4 {
        for j in 0..4 {
            obj.push_str(&format!("f {} {} {}\n", index(i, j), index(i + 1, j), index(i + 1, j + 1)));
            obj.push_str(&format!("f {} {} {}\n", index(i, j), index(i + 1, j + 1), index(i, j + 1)));
        }
    }
    let triple: Triangle = [[5.0, 0.0, 0.0], [7.0, 0.0, 0.0], [5.0, 2.0, 0.0]];
    for _ in 0..3 {
        add(&mut obj, &triple);
    }
    add(&mut obj, &[[5.0, 3.0, 0.0], [8.0, 3.0, 0.0], [5.0, 6.0, 0.0]]);
    add(&mut obj, &[[5.0, 3.0, 0.0], [8.0, 3.0, 0.0], [8.0, 6.0, 0.0]]);
    add(&mut obj, &[[-2.0, -2.0, -1.0], [12.0, -2.0, -1.0], [-2.0, 12.0, -1.0]]);
    let interior_targets = vec![[5.5, 0.5, 0.0], [5.25, 1.25, 0.0], [6.0, 0.75, 0.0], [6.5, 3.5, 0.0], [6.0, 4.0, 0.0]];
    let path = dir.join("ties.obj");
    std::fs::write(&path, obj).unwrap();
    (path, edge_targets, interior_targets)
}

pub(crate) fn converted(input: &Path, output: &Path, splits: bool) -> BvhFile {
    let overrides = Overrides { splits: Some(splits), gpu_layout: Some(true), ..Overrides::default() };
    bvhc::Conversion::new(input, output).preset(Preset::Balanced).overrides(overrides).run().unwrap();
    BvhFile::read(output).unwrap()
}

#[test]
fn ties_go_to_the_lowest_record_on_every_kernel_and_entry_point() {
    let dir = tempfile::tempdir().unwrap();
    let (input, edge_targets, interior_targets) = tie_scene(dir.path());
    for splits in [false, true] {
        let file = converted(&input, &dir.path().join(format!("ties-{splits}.bvh")), splits);
        // A scene this small has no triangle worth cutting: marked split, its hits at one `t` are ordered by
        // coordinates and ids all the same.
        let file = if splits { marked_split(&file.view(), false).0 } else { file };
        let view = file.view();
        assert_eq!(view.has_split_references(), splits);
        let name = format!("tie scene (splits {splits})");
        let mut rays = rays_at(&edge_targets, 51);
        let interior = rays_at(&interior_targets, 52);
        rays.extend_from_slice(&interior);
        let ties = assert_every_entry_point(&view, &rays, &name);
        assert!(ties > rays.len() / 4, "{name}: only {ties} of {} rays are ties", rays.len());

        // The GPU layout's walk (the WGSL kernel's mirror) on the rays whose edge functions are not 0, where its
        // f32 test is the CPU's.
        let model = view.gpu_layout_tracer().expect("converted with the GPU layout");
        for (r, ray) in interior.iter().enumerate() {
            let want = expected(&view, ray).map(|(n, _)| n);
            let got = model.closest_hit(ray).as_ref().map(|hit| named(&view, hit));
            assert_eq!(got, want, "{name}: GPU model, ray {r} {ray:?}");
            let record = model.record(ray, false);
            let got = (record.triangle != u32::MAX).then(|| key_of(&view, record.triangle));
            assert_eq!(got, want.map(|(_, _, key)| key), "{name}: GPU model's record, ray {r}");
        }
    }
}

/// `view` (a converted file with ids, whose source holds coincident triangles) with the `SPLIT_REFERENCES` flag
/// set (so that hits at one `t` are ordered by coordinates and ids, as in a file whose triangles were cut: a
/// small scene's conversion cuts none) and, with `reverse`, the ids of each set of coincident triangles
/// reversed (their records' source vertices with them, so the file stays consistent): the copy that had the
/// lowest id then has the highest, so a kernel that took the first copy it met in one file names a copy that is
/// not the lowest in the other. Also how many records coincide with another triangle of another id.
pub(crate) fn marked_split(view: &BvhView<'_>, reverse: bool) -> (BvhFile, usize) {
    use std::collections::BTreeMap;
    let ids = view.triangle_ids().expect("ids");
    let corners = view.source_vertices().expect("source vertices");
    let mut by_coordinates: BTreeMap<[u32; 9], Vec<u32>> = BTreeMap::new();
    for (record, triangle) in view.triangles().iter().enumerate() {
        let copies = by_coordinates.entry(triangle.coordinate_bits()).or_default();
        if !copies.contains(&ids[record]) {
            copies.push(ids[record]);
        }
    }
    let corners_of: BTreeMap<u32, _> = ids.iter().zip(corners).map(|(&id, &c)| (id, c)).collect();
    let (mut new_ids, mut new_corners) = (ids.to_vec(), corners.to_vec());
    let mut coinciding = 0;
    for (record, triangle) in view.triangles().iter().enumerate() {
        let mut copies = by_coordinates[&triangle.coordinate_bits()].clone();
        if copies.len() < 2 {
            continue;
        }
        coinciding += 1;
        if reverse {
            copies.sort_unstable();
            let k = copies.iter().position(|&id| id == ids[record]).unwrap();
            new_ids[record] = copies[copies.len() - 1 - k];
            new_corners[record] = corners_of[&new_ids[record]];
        }
    }
    let file = bvhc::loader::write::BvhWriter::from_view(view)
        .split_references(true)
        .triangle_ids(&new_ids)
        .source_vertices(&new_corners)
        .build()
        .expect("the marked file verifies");
    (file, coinciding)
}

/// Revision 1.5.8: with split references, of coincident triangles (the triangle stored three times in the
/// source) the hit names the one of lowest source id, whichever record of it and whichever copy a walk meets
/// first: checked on the converted file marked split and on the same file with those triangles' ids reversed, so
/// that a kernel which kept the first copy it met fails on one of the two.
#[test]
fn coincident_triangles_go_to_the_lowest_source_id_on_every_kernel() {
    let dir = tempfile::tempdir().unwrap();
    let (input, _, interior_targets) = tie_scene(dir.path());
    let converted = converted(&input, &dir.path().join("ties.bvh"), true);
    let (file, coinciding) = marked_split(&converted.view(), false);
    assert_eq!(coinciding, 3, "the triangle stored three times");
    let (reversed, _) = marked_split(&converted.view(), true);
    let rays = rays_at(&interior_targets, 52);
    let files = [("split references", &file), ("ids reversed", &reversed)];
    for (name, file) in files {
        let ties = assert_every_entry_point(&file.view(), &rays, name);
        assert!(ties > rays.len() / 4, "{name}: only {ties} of {} rays are ties", rays.len());
    }
    for (name, file) in files {
        let view = file.view();
        let model = view.gpu_layout_tracer().expect("converted with the GPU layout");
        for (r, ray) in rays.iter().enumerate() {
            let want = expected(&view, ray).map(|(n, _)| n);
            let got = model.closest_hit(ray).as_ref().map(|hit| named(&view, hit));
            assert_eq!(got, want, "{name}: GPU model, ray {r} {ray:?}");
        }
    }
}

#[test]
fn ties_across_instances_go_to_the_lowest_instance_then_record() {
    let grid: Vec<Triangle> = (0..2)
        .flat_map(|i| {
            let (x, x1) = (i as f32, i as f32 + 1.0);
            [
                [[x, 0.0, 0.0], [x1, 0.0, 0.0], [x1, 1.0, 0.0]],
                [[x, 0.0, 0.0], [x1, 1.0, 0.0], [x, 1.0, 0.0]],
                [[x, 1.0, 0.0], [x1, 1.0, 0.0], [x1, 2.0, 0.0]],
                [[x, 1.0, 0.0], [x1, 2.0, 0.0], [x, 2.0, 0.0]],
            ]
        })
        .collect();
    let twice: Vec<Triangle> = vec![[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 2];
    let identity = affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]);
    let moved = affine([[0.0, -2.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]], [4.0, 0.5, 0.0]);
    // Instances 1 and 2 place the grid where instance 0 does; 4 and 5 the doubled triangle where 3 does (rotated
    // and scaled), and 6 the grid there too.
    let placements = [
        placement(0, identity),
        placement(0, identity),
        placement(0, identity),
        placement(1, moved),
        placement(1, moved),
        placement(1, moved),
        placement(0, moved),
    ];
    let targets: Vec<[f32; 3]> = vec![
        [0.5, 0.5, 0.0],
        [1.0, 1.0, 0.0],
        [1.5, 1.25, 0.0],
        [2.0, 2.0, 0.0],
        [0.0, 0.0, 0.0],
        [3.5, 1.0, 0.0],
        [3.0, 1.5, 0.0],
        [3.25, 0.75, 0.0],
        [4.0, 0.5, 0.0],
    ];
    let rays = rays_at(&targets, 53);
    for wide in [false, true] {
        let (scene, sources) = two_level(&[grid.clone(), twice.clone()], &placements, wide);
        let file = write_two_level(&scene, &sources).unwrap();
        let view = file.view();
        let ties = assert_every_entry_point(&view, &rays, &format!("stacked instances (wide {wide})"));
        assert!(ties > rays.len() / 2, "only {ties} of {} rays are ties", rays.len());
    }
}
