//! Strict rays at every door of the Rust API: a [`Tracer`] refuses (panics, naming the call, the ray and the
//! rule) every ray that breaks the contract, in single and batch calls, closest and any hit, one- and two-level
//! files, before tracing the ray's chunk of a batch (the `_with` calls return it as an error); a trusting tracer answers the same rays without a panic, and
//! answers valid rays exactly as the checking one. `Tracer::surface` refuses hits that are not the file's.

use bvhc_loader::Order;
use bvhc_loader::Trace;
use std::panic::{AssertUnwindSafe, catch_unwind};

use bvhc::loader::{BvhFile, ForeignHit, Hit, Ray, Tracer, tracer::CHECKED_CHUNK};

use crate::common::{every_kernel, random_rays};

/// A call to try, with the name its panic must give.
type Named<'a> = (&'static str, Box<dyn FnOnce() + 'a>);

/// One ray breaking each rule, with the words the panic must contain.
fn broken_rays() -> Vec<(Ray, &'static str)> {
    let good = Ray::new([0.0, 1.5, 10.0], [0.0, 0.0, -1.0]);
    vec![
        (Ray { origin: [f32::NAN, 0.0, 0.0], ..good }, "the origin is not finite"),
        (Ray { origin: [0.0, f32::INFINITY, 0.0], ..good }, "the origin is not finite"),
        (Ray { direction: [0.0, f32::NAN, -1.0], ..good }, "the direction is not finite"),
        (Ray { direction: [0.0; 3], ..good }, "the direction is zero"),
        (Ray { direction: [0.0, 0.0, -1e-30], ..good }, "the direction's largest component is below 2^-64"),
        (Ray { t_min: -1.0, ..good }, "t_min is negative"),
        (Ray { t_max: f32::NAN, ..good }, "t_max is NaN or below t_min"),
        (Ray { t_min: 5.0, t_max: 4.0, ..good }, "t_max is NaN or below t_min"),
    ]
}

/// The panic message of `call`, or `None` when it returned.
fn panic_of(call: impl FnOnce()) -> Option<String> {
    let payload = catch_unwind(AssertUnwindSafe(call)).err()?;
    Some(payload.downcast_ref::<String>().cloned().unwrap_or_default())
}

/// Every tracing call of `tracer` refuses each broken ray, naming it; the trusting tracer answers them.
fn refuses_broken_rays(tracer: &Tracer<'_>) {
    let good = random_rays(5, 23, 3.0);
    for (broken, rule) in broken_rays() {
        let single: [Named<'_>; 2] = [
            (
                "Tracer::closest_hit:",
                Box::new(|| {
                    let _ = tracer.closest_hit(&broken);
                }),
            ),
            (
                "Tracer::any_hit:",
                Box::new(|| {
                    let _ = tracer.any_hit(&broken);
                }),
            ),
        ];
        for (call, run) in single {
            let message = panic_of(run).unwrap_or_else(|| panic!("{call} accepted {broken:?}"));
            assert!(message.contains(call) && message.contains(rule), "{message}");
        }
        // A batch with the broken ray at index 17 (in the first checked chunk): refused before any result is
        // written.
        let mut rays = good.clone();
        rays.insert(17, broken);
        let sentinel = Some(Hit {
            t: -7.0,
            triangle_index: 7,
            source_triangle_id: None,
            u: 0.0,
            v: 0.0,
            normal: [0.0; 3],
            front_face: false,
            instance_index: None,
        });
        let mut hits = vec![sentinel; rays.len()];
        let mut occluded = vec![true; rays.len()];
        let batches: [Named<'_>; 4] = [
            ("closest_hits:", Box::new(|| tracer.closest_hits(&rays, &mut hits))),
            ("any_hits:", Box::new(|| tracer.any_hits(&rays, &mut vec![false; rays.len()]))),
            ("closest_hits_coherent:", Box::new(|| tracer.closest_hits_coherent(&rays, &mut vec![None; rays.len()]))),
            ("any_hits_coherent:", Box::new(|| tracer.any_hits_coherent(&rays, &mut occluded))),
        ];
        for (call, run) in batches {
            let message = panic_of(run).unwrap_or_else(|| panic!("{call} accepted {broken:?}"));
            assert!(message.contains(call) && message.contains(&format!("ray 17: {rule}")), "{message}");
        }
        assert!(hits.iter().all(|h| *h == sentinel) && occluded.iter().all(|&o| o), "a refused batch wrote results");
        // The `_with` calls return the ray as an error; `each` is called for no ray of its chunk.
        let mut calls = 0;
        let refused = tracer.closest_hits_with(&rays, Order::Stream, |_, _| calls += 1).unwrap_err();
        assert_eq!((refused.index, refused.to_string().contains(rule)), (17, true), "{refused}");
        let refused = tracer.any_hits_with(&rays, Order::Coherent, |_, _| calls += 1).unwrap_err();
        assert_eq!((refused.index, refused.to_string().contains(rule)), (17, true), "{refused}");
        assert_eq!(calls, 0);
        // In a later chunk: the chunks before it are traced, and the error names the ray by its batch index.
        let mut long = random_rays(6, 2 * CHECKED_CHUNK + 5, 3.0);
        long[CHECKED_CHUNK + 3] = broken;
        let mut seen = vec![false; long.len()];
        let refused = tracer.closest_hits_with(&long, Order::Stream, |i, _| seen[i] = true).unwrap_err();
        assert_eq!(refused.index, CHECKED_CHUNK + 3);
        assert!(seen[..CHECKED_CHUNK].iter().all(|&s| s) && !seen[CHECKED_CHUNK..].iter().any(|&s| s));
        let message = panic_of(|| tracer.any_hits(&long, &mut vec![false; long.len()])).unwrap();
        assert!(message.contains(&format!("ray {}: {rule}", CHECKED_CHUNK + 3)), "{message}");
        // Trusted, the same rays are answered (unspecified, but without a panic or a hang).
        let trusting = tracer.trusting_rays();
        assert!(!trusting.checks_rays() && tracer.checks_rays());
        let _ = (trusting.closest_hit(&broken), trusting.any_hit(&broken));
        let mut hits = vec![None; rays.len()];
        trusting.closest_hits(&rays, &mut hits);
        trusting.any_hits_coherent(&rays, &mut vec![false; rays.len()]);
    }
    // Valid rays: the trusting tracer answers exactly as the checking one, in every call.
    let trusting = tracer.trusting_rays();
    let (mut checked, mut trusted) = (vec![None; good.len()], vec![None; good.len()]);
    tracer.closest_hits(&good, &mut checked);
    trusting.closest_hits(&good, &mut trusted);
    assert_eq!(checked, trusted);
    let mut each = vec![None; good.len()];
    tracer.closest_hits_with(&good, Order::Stream, |i, hit| each[i] = hit).unwrap();
    assert_eq!(each, checked);
    for (ray, hit) in good.iter().zip(&checked) {
        assert_eq!(trusting.closest_hit(ray), *hit);
        assert_eq!(tracer.any_hit(ray), hit.is_some());
    }
}

#[test]
fn every_kernel_refuses_rays_that_break_the_contract_and_trusting_tracers_answer_them() {
    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("teapot.bvh");
    assert!(crate::cli::bvhc(&[&crate::cli::teapot(), &"-o", &bvh, &"-q", &"--preset", &"fast"]).status.success());
    let file = BvhFile::read(&bvh).unwrap();
    let view = file.view();
    for tracer in every_kernel(&view).iter().chain([&view.tracer()]) {
        refuses_broken_rays(tracer);
    }
    // A two-level file: the check is made once, on the world ray.
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = crate::instances::write_two_level(&scene, &sources).unwrap();
    let view = two_level.view();
    for tracer in every_kernel(&view) {
        refuses_broken_rays(&tracer.with_instances(view.two_level().unwrap()));
    }
    refuses_broken_rays(&view.tracer());
}

#[test]
fn surface_refuses_hits_that_are_not_the_files() {
    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("teapot.bvh");
    assert!(crate::cli::bvhc(&[&crate::cli::teapot(), &"-o", &bvh, &"-q", &"--preset", &"fast"]).status.success());
    let file = BvhFile::read(&bvh).unwrap();
    let tracer = file.view().tracer();
    let hit = tracer.closest_hit(&Ray::new([0.0, 1.5, 10.0], [0.0, 0.0, -1.0])).expect("the teapot");
    assert!(tracer.surface(&hit).is_ok());
    let count = file.view().triangles().len();
    let beyond = Hit { triangle_index: count as u32, ..hit };
    assert_eq!(tracer.surface(&beyond), Err(ForeignHit::Triangle { index: count as u32, count }));
    assert!(tracer.surface(&beyond).unwrap_err().to_string().contains("is not below the file's"));
    let placed = Hit { instance_index: Some(0), ..hit };
    assert_eq!(tracer.surface(&placed), Err(ForeignHit::Levels { two_level: false }));

    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = crate::instances::write_two_level(&scene, &sources).unwrap();
    let view = two_level.view();
    let (tracer, sections) = (view.tracer(), view.two_level().unwrap());
    let hit = random_rays(8, 400, 4.0).iter().find_map(|r| tracer.closest_hit(r)).expect("some ray hits");
    assert!(tracer.surface(&hit).is_ok());
    assert_eq!(tracer.surface(&Hit { instance_index: None, ..hit }), Err(ForeignHit::Levels { two_level: true }));
    let count = sections.instances.len();
    let beyond = Hit { instance_index: Some(count as u32), ..hit };
    assert_eq!(tracer.surface(&beyond), Err(ForeignHit::Instance { index: count as u32, count }));
    // A record of another mesh than the instance places.
    let instance = hit.instance_index.unwrap();
    let mesh = &sections.meshes[sections.instances[instance as usize].mesh_index as usize];
    let outside = (0..view.triangles().len() as u32)
        .find(|&t| !(mesh.first_triangle..mesh.first_triangle + mesh.triangle_count).contains(&t));
    match outside {
        Some(triangle) => assert_eq!(
            tracer.surface(&Hit { triangle_index: triangle, ..hit }),
            Err(ForeignHit::NotInMesh { triangle, instance })
        ),
        None => panic!("the test scene has more than one mesh"),
    }
}

/// Spawning refuses what names no point of the triangle or no side to leave by: `u`, `v` NaN or off the
/// triangle (one- and two-level files), and directions or targets the ray contract refuses, naming the rule.
#[test]
fn spawning_refuses_points_off_the_triangle_and_directions_without_a_side() {
    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("teapot.bvh");
    assert!(crate::cli::bvhc(&[&crate::cli::teapot(), &"-o", &bvh, &"-q", &"--preset", &"fast"]).status.success());
    let file = BvhFile::read(&bvh).unwrap();
    let tracer = file.view().tracer();
    let hit = tracer.closest_hit(&Ray::new([0.0, 1.5, 10.0], [0.0, 0.0, -1.0])).expect("the teapot");
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = crate::instances::write_two_level(&scene, &sources).unwrap();
    let placed_tracer = two_level.view().tracer();
    let placed = random_rays(8, 400, 4.0).iter().find_map(|r| placed_tracer.closest_hit(r)).expect("some ray hits");
    for (tracer, hit) in [(&tracer, hit), (&placed_tracer, placed)] {
        for (u, v) in
            [(3.0, -2.5), (f32::NAN, 0.25), (0.25, f32::NAN), (-1e-30, 0.5), (0.75, 0.5), (f32::INFINITY, 0.0)]
        {
            let off = Hit { u, v, ..hit };
            let refused = tracer.surface(&off).expect_err("off the triangle");
            assert!(matches!(refused, ForeignHit::OffTriangle { .. }), "{u}, {v}: {refused:?}");
            assert!(refused.to_string().contains("not on its triangle"), "{refused}");
        }
        // The corners and edges of the triangle are on it, -0 and the rounding of u + v included.
        for (u, v) in [(0.0, 0.0), (-0.0, 1.0), (1.0, 0.0), (0.5, 0.5), (0.6, 0.4 + 2.0 * f32::EPSILON)] {
            assert!(tracer.surface(&Hit { u, v, ..hit }).is_ok(), "{u}, {v}");
        }
        let surface = tracer.surface(&hit).unwrap();
        for (direction, rule) in [
            ([f32::NAN, 0.0, 1.0], "not finite"),
            ([0.0, f32::INFINITY, 0.0], "not finite"),
            ([0.0, -0.0, 0.0], "zero"),
            ([1e-30, 0.0, 0.0], "2^-64"),
        ] {
            let refused = surface.spawn(direction).expect_err("no side to leave by");
            assert!(refused.to_string().contains(rule), "{direction:?}: {refused}");
            assert!(surface.offset_origin(direction).is_err());
        }
        assert!(surface.spawn_to([f32::NAN, 0.0, 0.0]).is_err());
        assert!(surface.spawn_to(surface.position).is_err(), "a target at the surface point has no direction");
        assert!(surface.spawn([0.0, 1.0, 0.0]).is_ok() && surface.spawn_to([0.0, 100.0, 0.0]).is_ok());
    }
}

/// Opening a directory says so (a memory map would report "No such device"); a FIFO is refused without
/// blocking on it.
#[test]
#[allow(unsafe_code)] // `MappedBvh::open` is the loader's one unsafe door (a mapped file must not change)
fn opening_a_directory_or_a_fifo_says_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let read = BvhFile::read(dir.path()).expect_err("a directory");
    assert!(read.to_string().contains("is a directory"), "{read}");
    // SAFETY: nothing writes the path while it is (not) mapped.
    let mapped = unsafe { bvhc::loader::MappedBvh::open(dir.path()) }.expect_err("a directory");
    assert!(mapped.to_string().contains("is a directory"), "{mapped}");
    let fifo = dir.path().join("fifo.bvh");
    if std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
        let read = BvhFile::read(&fifo).expect_err("a FIFO");
        assert!(read.to_string().contains("not a regular file"), "{read}");
    } else {
        crate::skips::skipped(crate::skips::Needs::Tools, "part: a FIFO refused (mkfifo)".to_string());
    }
}
