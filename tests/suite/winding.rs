//! Winding numbers and signed distances (`WindingNumbers`): the counted winding numbers (ray crossings, caps over
//! holes summed by their moments) against the exact sum of every triangle's solid angle in f64, on closed (exact),
//! nested, overlapping, open and instanced meshes; the sign of the signed distance inside and outside closed meshes of either winding, through mirrored, sheared and scaled
//! instances; split references counted once; bad points and hostile bytes answered without a panic.

use bvhc::loader::point::{Point3, solid_angle};
use bvhc::loader::{BvhView, WindingNumbers};

use crate::common::*;
use crate::instances::{placement, test_placements, two_level, write_two_level};

/// The exact winding number at `p` of `triangles` (world space, f64).
fn exact(triangles: &[[Point3; 3]], p: [f32; 3]) -> f64 {
    let q = p.map(f64::from);
    triangles.iter().map(|t| solid_angle(q, *t)).sum::<f64>() / (4.0 * std::f64::consts::PI)
}

/// Every placed triangle of a file in world space, each once (one record of each split triangle).
fn placed(view: &BvhView<'_>) -> Vec<[Point3; 3]> {
    let triangles = view.triangles();
    let f64s = |t: &bvhc::loader::format::PackedTriangle| t.vertices.map(|v| v.map(f64::from));
    let Some(sections) = view.two_level() else {
        let mut seen = std::collections::HashSet::new();
        let ids = view.triangle_ids();
        return (0..triangles.len())
            .filter(|&k| seen.insert((triangles[k].coordinate_bits(), ids.map_or(0, |ids| ids[k]))))
            .map(|k| f64s(&triangles[k]))
            .collect();
    };
    let mut out = Vec::new();
    for instance in sections.instances {
        let mesh = &sections.meshes[instance.mesh_index as usize];
        let m = &instance.object_to_world;
        for t in &triangles[mesh.first_triangle as usize..(mesh.first_triangle + mesh.triangle_count) as usize] {
            out.push(t.vertices.map(|p| {
                std::array::from_fn(|r| {
                    let row = m[r].map(f64::from);
                    row[0] * f64::from(p[0]) + row[1] * f64::from(p[1]) + row[2] * f64::from(p[2]) + row[3]
                })
            }));
        }
    }
    out
}

fn sphere(levels: usize, flip: bool) -> Vec<Triangle> {
    let (v, f) = unit_icosphere(levels);
    f.iter()
        .map(|t| {
            let t = if flip { [t[0], t[2], t[1]] } else { *t };
            t.map(|i| v[i].map(|c| c as f32))
        })
        .collect()
}

#[test]
fn fast_winding_numbers_follow_the_exact_sum_on_closed_and_open_meshes() {
    let mut open = sphere(3, false);
    open.truncate(open.len() - 40); // a hole
    let scattered = random_triangles(7001, 300, 1.0);
    // Closed: counted exactly. Open: only the caps over the holes are summed by their moments.
    let cases = [("sphere", sphere(3, false), 1e-9), ("open sphere", open, 1e-2), ("scattered", scattered, 1e-2)];
    for (name, triangles, bound) in cases {
        for file in [write_file(&packed_tree(&triangles, 4)), write_wide_file(&triangles, 2)] {
            let view = file.view();
            let world = placed(&view);
            let winding = WindingNumbers::new(&view.tracer()).unwrap();
            let mut rng = rng(7002);
            let mut worst = 0.0f64;
            for _ in 0..1500 {
                let p = random_point(&mut rng, 1.6);
                let (fast, exact) = (winding.winding_number(p), exact(&world, p));
                worst = worst.max((fast - exact).abs());
            }
            eprintln!("{name}: largest |fast - exact| {worst:.2e}");
            assert!(worst < bound, "{name}: {worst}");
        }
    }
}

#[test]
fn signed_distances_are_negative_inside_closed_meshes_of_either_winding() {
    for flip in [false, true] {
        let file = write_wide_file(&sphere(3, flip), 2);
        let view = file.view();
        let tracer = view.tracer();
        let winding = tracer.winding_numbers().unwrap();
        let mut rng = rng(7011);
        let points: Vec<[f32; 3]> = (0..4000).map(|_| random_point(&mut rng, 1.5)).collect();
        let mut signed = vec![0.0; points.len()];
        winding.signed_distances(&points, &mut signed, 3);
        for (p, &d) in points.iter().zip(&signed) {
            let r = p.iter().map(|c| c * c).sum::<f32>().sqrt();
            assert_eq!(d.abs(), tracer.distance(*p), "{p:?}");
            // The facets lie between radius 0.99 and 1 (level 3): clear of them, the sign is the side.
            if r < 0.98 {
                assert!(d < 0.0, "{p:?} inside: {d}");
                assert!((winding.winding_number(*p).abs() - 1.0).abs() < 6e-2);
            } else if r > 1.0 {
                assert!(d > 0.0, "{p:?} outside: {d}");
            }
            assert_eq!(winding.signed_distance(*p).to_bits(), d.to_bits());
        }
        // On the surface: 0; bad points: NaN.
        assert_eq!(winding.signed_distance(view.triangles()[0].vertices[0]), 0.0);
        assert!(
            winding.signed_distance([f32::NAN, 0.0, 0.0]).is_nan()
                && winding.winding_number([0.0, f32::INFINITY, 0.0]).is_nan()
        );
    }
}

#[test]
fn instanced_spheres_are_summed_in_world_space_through_every_placement() {
    let meshes = vec![sphere(2, false), random_triangles(7021, 200, 1.0)];
    let mut placements = test_placements();
    placements.push(placement(
        0,
        crate::instances::affine([[2.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 0.5]], [6.0, 0.0, 0.0]),
    ));
    for wide in [false, true] {
        let (scene, sources) = two_level(&meshes, &placements, wide);
        let file = write_two_level(&scene, &sources).unwrap();
        let view = file.view();
        let world = placed(&view);
        let winding = WindingNumbers::new(&view.tracer()).unwrap();
        let mut rng = rng(7022);
        let mut worst = 0.0f64;
        // Points around each placement, the far one included.
        for instance in view.two_level().unwrap().instances {
            let center: [f32; 3] = [0, 1, 2].map(|r| instance.object_to_world[r][3]);
            let size =
                instance.object_to_world.iter().flat_map(|row| row[..3].iter()).fold(0.0f32, |m, c| m.max(c.abs()));
            for _ in 0..150 {
                let d = random_point(&mut rng, 1.5 * size);
                let p = [0, 1, 2].map(|k| center[k] + d[k]);
                worst = worst.max((winding.winding_number(p) - exact(&world, p)).abs());
            }
        }
        eprintln!("instanced, wide {wide}: largest |fast - exact| {worst:.2e}");
        assert!(worst < 3e-2, "wide {wide}: {worst}");
        // Inside the mirrored, non-uniformly scaled sphere (placement 8: center (6, 0, 0), semi-axes 2, 1, 0.5).
        assert!(winding.signed_distance([6.5, 0.2, 0.1]) < 0.0);
        assert!(winding.signed_distance([6.0, 0.0, 0.7]) > 0.0);
    }
}

#[test]
fn nested_overlapping_and_mirrored_closed_shells_get_integer_winding_numbers_exactly() {
    use crate::instances::affine;
    // One sphere placed five times: as is, moved half a radius (overlapping), shrunk inside (nested, 2 there),
    // mirrored and shrunk inside the first (its winding turned: -1, cancelling to 0 there), and sheared far off.
    let placements = vec![
        placement(0, affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3])),
        placement(0, affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.5, 0.0, 0.0])),
        placement(0, affine([[0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.3]], [-0.4, 0.0, 0.0])),
        placement(0, affine([[-0.2, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.2]], [0.0, 0.6, 0.0])),
        placement(0, affine([[1.0, 0.7, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]], [5.0, 0.0, 0.0])),
    ];
    for wide in [false, true] {
        let (scene, sources) = two_level(&[sphere(2, false)], &placements, wide);
        let file = write_two_level(&scene, &sources).unwrap();
        let view = file.view();
        let world = placed(&view);
        let winding = WindingNumbers::new(&view.tracer()).unwrap();
        let mut rng = rng(7041);
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let p = random_point(&mut rng, 2.0);
            let (counted, exact) = (winding.winding_number(p), exact(&world, p));
            // Within 2^-18 of the scene's size of the surface a winding number is summed, not counted.
            if view.tracer().distance(p) > 1e-4 {
                assert_eq!(counted, counted.round(), "{p:?}: {counted} is not an integer");
                worst = worst.max((counted - exact).abs());
            }
        }
        assert!(worst < 1e-9, "wide {wide}: {worst}");
        // Inside both big spheres and the nested one: 3; inside the mirrored one: 1 + 1 - 1.
        assert_eq!(winding.winding_number([-0.3, 0.0, 0.0]), 3.0);
        assert_eq!(winding.winding_number([0.0, 0.62, 0.0]), 1.0);
        assert!(winding.signed_distance([0.0, 0.62, 0.0]) < 0.0);
    }
}

#[test]
fn split_references_count_each_triangle_once_and_hostile_bytes_get_an_answer() {
    use bvhc::loader::format::SectionKind;
    let Some(path) = scene("stanford-bunny-ply/bun_zipper.ply") else { return };
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("bunny.bvh");
    bvhc::Conversion::new(&path, &output).preset(bvhc::Preset::Balanced).run().unwrap();
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let view = file.view();
    let world = placed(&view);
    eprintln!(
        "bunny: {} records, {} triangles, split references {}",
        view.triangles().len(),
        world.len(),
        view.has_split_references()
    );
    let winding = WindingNumbers::new(&view.tracer()).unwrap();
    let root = view.nodes()[0];
    let mut rng = rng(7031);
    for _ in 0..300 {
        let p: [f32; 3] = std::array::from_fn(|k| {
            let u = (random_point(&mut rng, 1.0)[0] + 1.0) * 0.5;
            root.min[k] + (root.max[k] - root.min[k]) * u
        });
        let (fast, exact) = (winding.winding_number(p), exact(&world, p));
        assert!((fast - exact).abs() < 1e-2, "{p:?}: {fast} vs {exact}");
    }
    let kinds = [SectionKind::Nodes, SectionKind::Triangles];
    for (_, copy) in scribbled_copies(&file, &kinds, 100, 16, 7032) {
        let Ok(view) = BvhView::open(copy.as_bytes()) else { continue };
        let Ok(winding) = WindingNumbers::new(&view.tracer()) else { continue };
        let _ = winding.signed_distance([0.0, 0.1, 0.0]);
    }
}
