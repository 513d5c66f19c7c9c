//! Hit filters (`bvhc_loader::filter`): every kernel's filtered hits equal a brute force that applies the same
//! filter to every candidate (the closest accepted `t` bit for bit, any-hit answers alike), on one- and
//! two-level files, single and batch calls; with the file's flags the filter is asked about not-opaque triangles
//! only, with `FilterScope::Every` about every candidate; a filter that accepts everything traces as no filter.

use bvhc_loader::Trace;
use std::cell::Cell;

use bvhc::loader::format::TRIANGLE_NOT_OPAQUE;
use bvhc::loader::{BvhFile, Ray, filter::Candidate, filter::FilterScope, ray::PreparedRay, write::BvhWriter};

use crate::common::{every_kernel, random_rays, random_triangles, write_wide_file};
use crate::instances_exact::spec_object_ray;

/// The file's sections written again with `flags` as its `triangle_flags` (and the metadata relabelled 1.5).
pub fn with_flags(file: &BvhFile, flags: &[u8]) -> BvhFile {
    let view = file.view();
    let metadata = view.metadata_str().map(|m| m.unwrap().to_string()).unwrap_or_default();
    let metadata = metadata
        .replace("\"format_version\":\"1.3\"", "\"format_version\":\"1.5\"")
        .replace(&format!("\"format_version\":\"1.{}\"", view.version().1), "\"format_version\":\"1.5\"");
    let mut writer = BvhWriter::new(view.nodes(), view.triangles())
        .split_references(view.has_split_references())
        .triangle_flags(flags);
    if !metadata.is_empty() {
        writer = writer.metadata(&metadata);
    }
    if let Some(ids) = view.triangle_ids() {
        writer = writer.triangle_ids(ids);
    }
    if let Some(table) = view.source_table() {
        writer = writer.source_table(table);
    }
    if let Some(vertices) = view.source_vertices() {
        writer = writer.source_vertices(vertices);
    }
    if let Some(wide) = view.wide_sections() {
        writer = writer.wide(wide.nodes, wide.packets);
    }
    if let Some(sections) = view.two_level() {
        writer = writer.two_level(sections);
    }
    writer.build().expect("the file with flags is valid")
}

/// The test's filter: rejects about a third of the candidates, by their source id and instance, and every
/// candidate with `u > 0.7` (so the barycentrics it is given matter).
pub fn accepts(candidate: &Candidate<'_>) -> bool {
    let id = candidate.source_triangle_id.expect("the test files have ids");
    let instance = candidate.instance_index.map_or(0, |i| i + 1);
    let hash = id.wrapping_mul(2_654_435_761) ^ instance.wrapping_mul(40_503);
    !hash.is_multiple_of(3) && candidate.u <= 0.7
}

/// The flags of the test files: the records of ids divisible by 2 not opaque.
pub fn flags_by_id(ids: &[u32]) -> Vec<u8> {
    ids.iter().map(|id| if id.is_multiple_of(2) { TRIANGLE_NOT_OPAQUE } else { 0 }).collect()
}

/// What a brute force finds for `ray` over every record (every instance's records, with the spec's object ray),
/// the filter applied to candidates on triangles `scope` covers: the closest accepted `t`, and whether some
/// candidate is accepted.
fn brute_force(file: &BvhFile, ray: &Ray, scope: FilterScope) -> (Option<f32>, bool) {
    let view = file.view();
    let ids = view.triangle_ids().unwrap();
    let placements: Vec<(Option<u32>, Ray, std::ops::Range<usize>)> = match view.two_level() {
        None => vec![(None, *ray, 0..view.triangles().len())],
        Some(sections) => sections
            .instances
            .iter()
            .enumerate()
            .map(|(i, instance)| {
                let mesh = &sections.meshes[instance.mesh_index as usize];
                let first = mesh.first_triangle as usize;
                (Some(i as u32), spec_object_ray(instance, ray), first..first + mesh.triangle_count as usize)
            })
            .collect(),
    };
    let mut nearest: Option<f32> = None;
    for (instance, object_ray, records) in placements {
        let prepared = PreparedRay::new(&object_ray);
        for record in records {
            let Some(hit) = prepared.intersect_triangle(&view.triangles()[record], ray.t_max) else { continue };
            let asked = scope == FilterScope::Every || view.is_not_opaque(record as u32);
            let candidate = Candidate {
                ray,
                t: hit.t,
                u: hit.u,
                v: hit.v,
                triangle_index: record as u32,
                source_triangle_id: Some(ids[record]),
                instance_index: instance,
            };
            if !asked || accepts(&candidate) {
                nearest = Some(nearest.map_or(hit.t, |t| t.min(hit.t)));
            }
        }
    }
    (nearest, nearest.is_some())
}

/// Every kernel of `file`, filtered with `scope`, against the brute force on `rays`; returns how many rays the
/// filter changed (a closest hit farther or gone).
fn every_kernel_matches_brute_force(file: &BvhFile, rays: &[Ray], scope: FilterScope) -> usize {
    let view = file.view();
    let asked_opaque = Cell::new(0usize);
    let counted = |candidate: &Candidate<'_>| {
        if !view.is_not_opaque(candidate.triangle_index) {
            asked_opaque.set(asked_opaque.get() + 1);
        }
        // The candidate is what the tracer would return for it.
        assert!(candidate.t >= candidate.ray.t_min && candidate.t <= candidate.ray.t_max);
        assert_eq!(candidate.source_triangle_id, view.triangle_ids().map(|ids| ids[candidate.triangle_index as usize]));
        accepts(candidate)
    };
    let kernels: Vec<_> = match view.two_level() {
        Some(sections) => every_kernel(&view).into_iter().map(|t| t.with_instances(sections)).collect(),
        None => every_kernel(&view),
    };
    let mut changed = 0;
    for (k, kernel) in kernels.iter().enumerate() {
        let filtered = kernel.filtered(&counted, scope);
        let mut batch = vec![None; rays.len()];
        filtered.closest_hits(rays, &mut batch);
        let mut occluded = vec![false; rays.len()];
        filtered.any_hits(rays, &mut occluded);
        for (i, ray) in rays.iter().enumerate() {
            let (nearest, any) = brute_force(file, ray, scope);
            let hit = filtered.closest_hit(ray);
            assert_eq!(hit.map(|h| h.t.to_bits()), nearest.map(f32::to_bits), "kernel {k}, ray {i}: {ray:?}");
            assert_eq!(batch[i].map(|h| h.t.to_bits()), nearest.map(f32::to_bits), "kernel {k} batch, ray {i}");
            assert_eq!((filtered.any_hit(ray), occluded[i]), (any, any), "kernel {k}, ray {i}: any hit");
            if k == 0 && kernel.closest_hit(ray).map(|h| h.t) != hit.map(|h| h.t) {
                changed += 1;
            }
        }
    }
    if scope == FilterScope::NotOpaque {
        assert_eq!(asked_opaque.get(), 0, "the filter was asked about opaque triangles");
    }
    changed
}

#[test]
fn filtered_hits_equal_a_filtered_brute_force_on_every_kernel_of_a_one_level_file() {
    let triangles = random_triangles(4401, 600, 1.0);
    let plain = write_wide_file(&triangles, 4);
    let file = with_flags(&plain, &flags_by_id(plain.view().triangle_ids().unwrap()));
    file.view().verify().unwrap();
    let rays = random_rays(4402, 1500, 1.5);
    let changed = every_kernel_matches_brute_force(&file, &rays, FilterScope::NotOpaque);
    assert!(changed > 100, "the filter changed only {changed} of {} rays", rays.len());
    let changed_every = every_kernel_matches_brute_force(&file, &rays, FilterScope::Every);
    assert!(changed_every > changed, "{changed_every} <= {changed}");
    // Without flags every triangle is opaque: NotOpaque filters nothing.
    assert_eq!(every_kernel_matches_brute_force(&plain, &rays, FilterScope::NotOpaque), 0);
}

#[test]
fn filtered_hits_equal_a_filtered_brute_force_through_instances() {
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let plain = crate::instances::write_two_level(&scene, &sources).unwrap();
    let file = with_flags(&plain, &flags_by_id(plain.view().triangle_ids().unwrap()));
    file.view().verify().unwrap();
    assert_eq!(file.view().version(), (1, 5));
    let rays = random_rays(4403, 1200, 4.0);
    let changed = every_kernel_matches_brute_force(&file, &rays, FilterScope::NotOpaque);
    assert!(changed > 20, "the filter changed only {changed} of {} rays", rays.len());
    every_kernel_matches_brute_force(&file, &rays, FilterScope::Every);
}

#[test]
fn a_filter_that_accepts_everything_traces_as_no_filter_and_sees_each_candidate_fully() {
    let triangles = random_triangles(4404, 300, 1.0);
    let file = write_wide_file(&triangles, 4);
    let view = file.view();
    let seen = Cell::new(0usize);
    let all = |candidate: &Candidate<'_>| {
        seen.set(seen.get() + 1);
        let hit = candidate.as_hit();
        assert_eq!((hit.t, hit.u, hit.v), (candidate.t, candidate.u, candidate.v));
        true
    };
    for kernel in every_kernel(&view) {
        let filtered = kernel.filtered(&all, FilterScope::Every);
        for ray in random_rays(4405, 500, 1.5) {
            let (expected, got) = (kernel.closest_hit(&ray), filtered.closest_hit(&ray));
            assert_eq!(got.map(|h| h.t.to_bits()), expected.map(|h| h.t.to_bits()), "{ray:?}");
            assert_eq!(filtered.any_hit(&ray), kernel.any_hit(&ray));
        }
    }
    assert!(seen.get() > 200, "{} candidates", seen.get());
    // A filter that rejects everything leaves nothing to hit.
    let none = |_: &Candidate<'_>| false;
    let tracer = view.tracer().filtered(&none, FilterScope::Every);
    assert!(random_rays(4406, 200, 1.5).iter().all(|ray| tracer.closest_hit(ray).is_none() && !tracer.any_hit(ray)));
}

#[test]
fn filtered_calls_check_rays_as_the_tracer_does() {
    let file = write_wide_file(&random_triangles(4407, 50, 1.0), 4);
    let accept = |_: &Candidate<'_>| true;
    let tracer = file.view().tracer();
    let filtered = tracer.filtered(&accept, FilterScope::Every);
    let bad = Ray { t_max: f32::NAN, ..Ray::new([0.0; 3], [0.0, 0.0, 1.0]) };
    let message = std::panic::catch_unwind(|| filtered.closest_hit(&bad)).unwrap_err();
    assert!(message.downcast_ref::<String>().unwrap().contains("t_max is NaN"));
    let trusting = tracer.trusting_rays();
    let _ = trusting.filtered(&accept, FilterScope::Every).any_hit(&bad);
}
