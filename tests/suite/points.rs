//! Point queries (`format-spec/point-queries.md`): the closest point equals a brute force over every placed
//! record in the spec's arithmetic bit for bit (culling never changes the answer), its distance agrees with an
//! independent f64 oracle (Ericson's regions) within the spec's bound, ties go to the lowest instance and record,
//! the distance bound is inclusive, batches equal single calls on any thread count, two-level files are answered
//! in world space through mirrored, sheared, scaled and far instances, and hostile bytes get an answer, not a
//! panic.

use bvhc::loader::format::PackedTriangle;
use bvhc::loader::point::{Point3, closest_on_triangle};
use bvhc::loader::{BvhView, ClosestPoint, PointCandidate, Tracer};

use crate::common::*;
use crate::instances::{test_meshes, test_placements, two_level, write_two_level};
use rand::RngExt;

/// One placed record: world vertices (f64, the spec's map), instance, absolute record.
struct Record {
    vertices: [Point3; 3],
    instance: Option<u32>,
    record: u32,
}

/// Every record of a file placed in world space (a two-level file's instance after instance).
fn records_of_view(view: &BvhView<'_>) -> Vec<Record> {
    let triangles = view.triangles();
    let Some(sections) = view.two_level() else {
        let at = |(k, t): (usize, &PackedTriangle)| Record {
            vertices: t.vertices.map(|v| v.map(f64::from)),
            instance: None,
            record: k as u32,
        };
        return triangles.iter().enumerate().map(at).collect();
    };
    let mut out = Vec::new();
    for (i, instance) in sections.instances.iter().enumerate() {
        let mesh = &sections.meshes[instance.mesh_index as usize];
        for record in mesh.first_triangle..mesh.first_triangle + mesh.triangle_count {
            let m = &instance.object_to_world;
            let vertices = triangles[record as usize].vertices.map(|p| {
                std::array::from_fn(|r| {
                    let row = m[r].map(f64::from);
                    row[0] * f64::from(p[0]) + row[1] * f64::from(p[1]) + row[2] * f64::from(p[2]) + row[3]
                })
            });
            out.push(Record { vertices, instance: Some(i as u32), record });
        }
    }
    out
}

/// The spec's answer by brute force: the least (squared distance, instance, record) within `max_distance`.
fn brute_force(records: &[Record], p: [f32; 3], max_distance: f32) -> Option<(f64, Option<u32>, u32, [f64; 3])> {
    let q = p.map(f64::from);
    let limit = f64::from(max_distance) * f64::from(max_distance);
    records
        .iter()
        .map(|r| {
            let found = closest_on_triangle(q, r.vertices);
            (found.d2, r.instance, r.record, found.point)
        })
        .filter(|c| c.0 <= limit)
        .min_by(|a, b| (a.0, a.1, a.2).partial_cmp(&(b.0, b.1, b.2)).expect("finite distances"))
}

/// Ericson's closest point on a triangle (Real-Time Collision Detection, 5.1.5), in f64: an arithmetic
/// independent of the kernel's, for the accuracy bound.
fn ericson_distance(p: Point3, [a, b, c]: [Point3; 3]) -> f64 {
    let sub = |x: Point3, y: Point3| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let dot = |x: Point3, y: Point3| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let at = |o: Point3, d: Point3, t: f64| [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
    let dist = |q: Point3| dot(sub(p, q), sub(p, q)).sqrt();
    let segment = |x: Point3, y: Point3| {
        let d = sub(y, x);
        let dd = dot(d, d);
        let t = if dd > 0.0 { (dot(sub(p, x), d) / dd).clamp(0.0, 1.0) } else { 0.0 };
        dist(at(x, d, t))
    };
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    let va = d3 * d6 - d5 * d4;
    let vb = d5 * d2 - d1 * d6;
    let vc = d1 * d4 - d3 * d2;
    let denom = va + vb + vc;
    let edges = segment(a, b).min(segment(b, c)).min(segment(c, a));
    if !(va > 0.0 && vb > 0.0 && vc > 0.0 && denom > 0.0) {
        return edges;
    }
    let (v, w) = (vb / denom, vc / denom);
    dist([a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w]).min(edges)
}

/// Query points around `records`: on vertices and edges, on the surface and just off it, inside, and far.
fn query_points(records: &[Record], count: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = rng(seed);
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for r in records {
        for v in r.vertices {
            for a in 0..3 {
                lo[a] = lo[a].min(v[a]);
                hi[a] = hi[a].max(v[a]);
            }
        }
    }
    let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    (0..count)
        .map(|k| {
            let r = &records[k * 7919 % records.len()];
            let (s, t): (f64, f64) = (rng.random(), rng.random());
            let on: Point3 = std::array::from_fn(|a| {
                let (s, t) = if s + t > 1.0 { (1.0 - s, 1.0 - t) } else { (s, t) };
                r.vertices[0][a] + (r.vertices[1][a] - r.vertices[0][a]) * s + (r.vertices[2][a] - r.vertices[0][a]) * t
            });
            let mut jitter =
                |scale: f64| -> Point3 { std::array::from_fn(|_| (rng.random::<f64>() * 2.0 - 1.0) * scale) };
            let p: Point3 = match k % 6 {
                0 => r.vertices[k % 3],
                1 => std::array::from_fn(|a| (r.vertices[0][a] + r.vertices[1][a]) * 0.5),
                2 => on,
                3 => {
                    let d = jitter(size * 1e-3);
                    std::array::from_fn(|a| on[a] + d[a])
                }
                4 => {
                    let u = jitter(1.0);
                    std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * (u[a] + 1.0) * 0.5)
                }
                _ => {
                    let d = jitter(size * 3.0);
                    std::array::from_fn(|a| (lo[a] + hi[a]) * 0.5 + d[a])
                }
            };
            p.map(|c| c as f32)
        })
        .collect()
}

/// Checks every point against the brute force (exactly) and Ericson's distance (within the spec's bound);
/// returns how many had an answer.
fn check_points(tracer: &Tracer<'_>, records: &[Record], points: &[[f32; 3]], max_distance: f32) -> usize {
    let mut answered = 0;
    for (k, &p) in points.iter().enumerate() {
        let got = tracer.closest_point(p, max_distance);
        let expected = brute_force(records, p, max_distance);
        let Some((d2, instance, record, point)) = expected else {
            assert_eq!(got, None, "point {k} {p:?}: nothing within {max_distance}");
            continue;
        };
        answered += 1;
        let got = got.unwrap_or_else(|| panic!("point {k} {p:?}: expected record {record}, got nothing"));
        assert_eq!(
            (got.triangle_index, got.instance_index, got.distance, got.point),
            (record, instance, d2.sqrt() as f32, point.map(|c| c as f32)),
            "point {k} {p:?}"
        );
        // The accuracy bound against an independent arithmetic: 2^-24 of the distance (its f32 rounding) plus
        // 2^-40 of the distance to the triangle's farthest vertex and of the largest coordinate (both
        // arithmetics round where the coordinates are large).
        let q = p.map(f64::from);
        let exact = records.iter().map(|r| ericson_distance(q, r.vertices)).fold(f64::INFINITY, f64::min);
        let far = records[got_index(records, &got)]
            .vertices
            .iter()
            .map(|v| ((v[0] - q[0]).powi(2) + (v[1] - q[1]).powi(2) + (v[2] - q[2]).powi(2)).sqrt())
            .fold(0.0, f64::max);
        let largest =
            records[got_index(records, &got)].vertices.iter().chain([&q]).flatten().fold(0.0f64, |m, c| m.max(c.abs()));
        let error = (f64::from(got.distance) - exact).abs();
        assert!(
            error <= exact * 2f64.powi(-24) + (far + largest) * 2f64.powi(-40),
            "point {k} {p:?}: {} vs {exact}",
            got.distance
        );
    }
    answered
}

fn got_index(records: &[Record], got: &ClosestPoint) -> usize {
    records
        .iter()
        .position(|r| r.record == got.triangle_index && r.instance == got.instance_index)
        .expect("the answer names a placed record")
}

#[test]
fn one_level_closest_points_equal_the_brute_force_on_every_kernel() {
    let triangles = random_triangles(6001, 400, 1.0);
    for file in [write_file(&packed_tree(&triangles, 4)), write_wide_file(&triangles, 2)] {
        let records = records_of_view(&file.view());
        let points = query_points(&records, 1200, 6002);
        for tracer in every_kernel(&file.view()) {
            assert_eq!(check_points(&tracer, &records, &points, f32::INFINITY), points.len());
            // A bound leaves some points with nothing.
            let bounded = check_points(&tracer, &records, &points, 0.01);
            assert!(bounded > points.len() / 3 && bounded < points.len(), "{bounded} of {}", points.len());
        }
    }
}

#[test]
fn two_level_closest_points_equal_the_brute_force_through_every_placement() {
    for wide in [false, true] {
        let (scene, sources) = two_level(&test_meshes(), &test_placements(), wide);
        let file = write_two_level(&scene, &sources).expect("the test scene writes and verifies");
        let records = records_of_view(&file.view());
        // Points around the far, the tiny and the sheared instances too: query_points picks records all over.
        let points = query_points(&records, 1500, 6003);
        for tracer in every_kernel(&file.view()) {
            assert_eq!(check_points(&tracer, &records, &points, f32::INFINITY), points.len());
        }
    }
}

/// A flat grid of unit squares, two triangles each, with integer coordinates: every distance above it is exact.
fn grid(n: usize) -> Vec<Triangle> {
    let mut out = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (i as f32, j as f32);
            out.push([[x, y, 0.0], [x + 1.0, y, 0.0], [x + 1.0, y + 1.0, 0.0]]);
            out.push([[x, y, 0.0], [x + 1.0, y + 1.0, 0.0], [x, y + 1.0, 0.0]]);
        }
    }
    out
}

#[test]
fn ties_go_to_the_lowest_record_and_the_bound_is_inclusive() {
    let file = write_wide_file(&grid(6), 2);
    let view = file.view();
    let triangles = view.triangles();
    for tracer in every_kernel(&view) {
        for (x, y) in [(2.0f32, 3.0f32), (1.0, 1.0), (0.0, 0.0), (2.5, 4.0), (6.0, 2.0)] {
            let p = [x, y, 2.0];
            let got = tracer.closest_point(p, f32::INFINITY).expect("the grid is below");
            assert_eq!((got.distance, got.point), (2.0, [x, y, 0.0]));
            // Every triangle touching (x, y) is at distance 2 exactly; the lowest record wins.
            let touching = |t: &PackedTriangle| {
                closest_on_triangle(p.map(f64::from), t.vertices.map(|v| v.map(f64::from))).d2 == 4.0
            };
            let lowest = triangles.iter().position(touching).expect("a triangle touches the point") as u32;
            assert!(triangles.iter().filter(|t| touching(t)).count() >= 2, "{p:?} is a tie");
            assert_eq!(got.triangle_index, lowest, "{p:?}");
            assert_eq!(tracer.closest_point(p, 2.0).map(|c| c.triangle_index), Some(lowest), "inclusive bound");
            assert_eq!(tracer.closest_point(p, 2.0f32.next_down()), None);
            assert_eq!(tracer.distance(p), 2.0);
        }
    }
}

/// Each tracer's batch answers (points in a spatial order, each walk bounded by its neighbour's answer) equal
/// its single queries bit for bit, record and instance included, on any thread count.
fn check_batches(view: &BvhView<'_>, points: &[[f32; 3]], max_distance: f32, what: &str) {
    for tracer in every_kernel(view) {
        let single: Vec<_> = points.iter().map(|&p| tracer.closest_point(p, max_distance)).collect();
        for threads in [0, 1, 3] {
            let mut out = vec![None; points.len()];
            tracer.closest_points(points, max_distance, &mut out, threads);
            assert_eq!(out, single, "{what}: {threads} threads");
        }
    }
}

#[test]
fn batches_equal_single_queries_on_any_thread_count_and_bad_queries_get_nothing() {
    let triangles = random_triangles(6011, 300, 1.0);
    for file in [write_wide_file(&triangles, 2), write_file(&packed_tree(&triangles, 4))] {
        let records = records_of_view(&file.view());
        let mut points = query_points(&records, 3000, 6012);
        points.extend([[f32::NAN, 0.0, 0.0], [0.0, f32::INFINITY, 0.0]]);
        check_batches(&file.view(), &points, 0.5, "random triangles within 0.5");
        check_batches(&file.view(), &points, f32::INFINITY, "random triangles");
    }
    // Ties: every grid point lies at the same distance from several triangles, and its neighbours' answers
    // bound the walk by that distance exactly.
    let grid_file = write_wide_file(&grid(12), 2);
    let points: Vec<[f32; 3]> =
        (0..2000).map(|k| [(k % 25) as f32 * 0.5, (k / 25 % 25) as f32 * 0.5, (k / 625) as f32 + 0.5]).collect();
    check_batches(&grid_file.view(), &points, f32::INFINITY, "grid ties");
    for wide in [false, true] {
        let (scene, sources) = two_level(&test_meshes(), &test_placements(), wide);
        let file = write_two_level(&scene, &sources).expect("the test scene writes and verifies");
        let points = query_points(&records_of_view(&file.view()), 2000, 6013);
        check_batches(&file.view(), &points, f32::INFINITY, "two-level");
    }
    let file = write_wide_file(&triangles, 2);
    let tracer = file.view().tracer();
    for (p, max) in
        [([f32::NAN, 0.0, 0.0], 1.0), ([0.0, f32::INFINITY, 0.0], 1.0), ([0.0; 3], -1.0), ([0.0; 3], f32::NAN)]
    {
        assert_eq!(tracer.closest_point(p, max), None, "{p:?} within {max}");
    }
    assert_eq!(tracer.distance([f32::NAN; 3]), f32::INFINITY);
}

/// A filtered query answers as the brute force over the records the filter keeps, single and batch, on every
/// kernel and thread count.
fn check_filtered(view: &BvhView<'_>, points: &[[f32; 3]], keep: impl Fn(&PointCandidate) -> bool + Sync) {
    let records = records_of_view(view);
    let ids = view.triangle_ids();
    let kept: Vec<Record> = records
        .iter()
        .filter(|r| {
            keep(&PointCandidate {
                triangle_index: r.record,
                source_triangle_id: ids.map(|ids| ids[r.record as usize]),
                instance_index: r.instance,
            })
        })
        .map(|r| Record { vertices: r.vertices, instance: r.instance, record: r.record })
        .collect();
    assert!(!kept.is_empty() && kept.len() < records.len(), "the filter keeps some, not all");
    for tracer in every_kernel(view) {
        let single: Vec<_> = points.iter().map(|&p| tracer.closest_point_filtered(p, f32::INFINITY, &keep)).collect();
        for (k, (&p, got)) in points.iter().zip(&single).enumerate() {
            let (d2, instance, record, point) = brute_force(&kept, p, f32::INFINITY).expect("some are kept");
            let got = got.expect("a kept triangle is within reach");
            assert_eq!(
                (got.triangle_index, got.instance_index, got.distance, got.point),
                (record, instance, d2.sqrt() as f32, point.map(|c| c as f32)),
                "point {k} {p:?}"
            );
        }
        for threads in [1, 3] {
            let mut out = vec![None; points.len()];
            tracer.closest_points_filtered(points, f32::INFINITY, &keep, &mut out, threads);
            assert_eq!(out, single, "{threads} threads");
        }
    }
}

#[test]
fn filtered_queries_answer_among_the_kept_triangles() {
    let triangles = random_triangles(6041, 300, 1.0);
    for file in [write_wide_file(&triangles, 2), write_file(&packed_tree(&triangles, 4))] {
        let records = records_of_view(&file.view());
        let points = query_points(&records, 600, 6042);
        check_filtered(&file.view(), &points, |c: &PointCandidate| !c.triangle_index.is_multiple_of(3));
    }
    for wide in [false, true] {
        let (scene, sources) = two_level(&test_meshes(), &test_placements(), wide);
        let file = write_two_level(&scene, &sources).expect("the test scene writes and verifies");
        let points = query_points(&records_of_view(&file.view()), 600, 6043);
        check_filtered(&file.view(), &points, |c: &PointCandidate| c.instance_index.is_some_and(|i| i % 2 == 1));
        check_filtered(&file.view(), &points, |c: &PointCandidate| c.triangle_index.is_multiple_of(2));
    }
}

#[test]
fn hostile_bytes_get_an_answer_not_a_panic() {
    use bvhc::loader::format::SectionKind;
    let triangles = random_triangles(6021, 200, 1.0);
    let original = write_wide_file(&triangles, 2);
    let kinds = [SectionKind::Nodes, SectionKind::Triangles];
    let points = query_points(&records_of_view(&original.view()), 50, 6022);
    for (_, file) in scribbled_copies(&original, &kinds, 200, 16, 6023) {
        let Ok(view) = bvhc::loader::BvhView::open(file.as_bytes()) else { continue };
        let tracer = view.tracer();
        for &p in &points {
            let _ = tracer.closest_point(p, f32::INFINITY);
        }
    }
}

/// A shared scene converted as the CLI does (spatial splits, so split references; two-level when `instancing`
/// says), its closest points against the brute force: the same distance and point, and a record of the triangle
/// the tie rule picks (with split references any record of it).
fn check_converted_scene(relative: &str, preset: bvhc::Preset, instancing: bvhc::import::Instancing, count: usize) {
    let Some(input) = scene(relative) else { return };
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("scene.bvh");
    bvhc::Conversion::new(&input, &output).preset(preset).instancing(instancing).run().unwrap();
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let view = file.view();
    let records = records_of_view(&view);
    let (triangles, ids, split) = (view.triangles(), view.triangle_ids(), view.has_split_references());
    let key = |r: &Record| {
        let id = ids.map_or(0, |ids| ids[r.record as usize]);
        if split {
            (r.instance, triangles[r.record as usize].coordinate_bits(), id, 0)
        } else {
            (r.instance, [0; 9], 0, r.record)
        }
    };
    let points = query_points(&records, count, 6031);
    for tracer in every_kernel(&view) {
        for (k, &p) in points.iter().enumerate() {
            let got = tracer.closest_point(p, f32::INFINITY).expect("the scene has triangles");
            let q = p.map(f64::from);
            let all: Vec<_> = records.iter().map(|r| (closest_on_triangle(q, r.vertices), r)).collect();
            let d2 = all.iter().map(|(c, _)| c.d2).fold(f64::INFINITY, f64::min);
            let best = all.iter().filter(|(c, _)| c.d2 == d2).min_by_key(|(_, r)| key(r)).expect("a nearest record");
            let chosen = records[got_index(&records, &got)].record;
            let chosen = records.iter().find(|r| r.record == chosen && r.instance == got.instance_index).unwrap();
            assert_eq!(
                (got.distance, got.point, key(chosen)),
                (d2.sqrt() as f32, best.0.point.map(|c| c as f32), key(best.1)),
                "{relative} point {k} {p:?}"
            );
        }
    }
    check_batches(&view, &points, f32::INFINITY, relative);
    eprintln!("{relative} ({instancing:?}): {count} points, {} records, split references {split}", records.len());
}

#[test]
fn converted_scenes_answer_as_the_brute_force() {
    check_converted_scene(
        "khr-2cylinder-engine/2CylinderEngine.gltf",
        bvhc::Preset::Fast,
        bvhc::import::Instancing::Always,
        150,
    );
    check_converted_scene(
        "khr-2cylinder-engine/2CylinderEngine.gltf",
        bvhc::Preset::Fast,
        bvhc::import::Instancing::Never,
        150,
    );
    check_converted_scene(
        "stanford-bunny-ply/bun_zipper.ply",
        bvhc::Preset::Balanced,
        bvhc::import::Instancing::Auto,
        300,
    );
}
