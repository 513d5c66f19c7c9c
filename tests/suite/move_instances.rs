//! Moving a two-level file's geometry: its instances (`BvhFile::move_instances`) and its meshes' triangles
//! (`BvhFile::refit`, after which every instance follows its mesh). The moved file holds the instance records
//! the writer gives the new placements, verifies, and traces them as the f64 oracle over the flattened scene
//! says, on every kernel, with or without the wide sections; moving instances to where they stand gives the
//! file's bytes back; what cannot be placed is refused naming the instance, with the file unchanged.

use bvhc::loader::format::{Affine3x4, SectionKind};
use bvhc::loader::{BvhFile, Error, RefitPositions};

use crate::common::{every_kernel, random_triangles};
use crate::instances::{
    affine, check_against_oracle, flatten, rotation_z, test_meshes, test_placements, test_rays, two_level,
    write_two_level,
};

/// The bytes of section `kind`.
fn section(file: &BvhFile, kind: SectionKind) -> Vec<u8> {
    let info = file.view().sections().find(|s| s.kind == Some(kind)).expect("the section");
    let start = info.entry.section_byte_offset as usize;
    file.as_bytes()[start..start + info.entry.section_byte_len as usize].to_vec()
}

#[test]
fn moved_instances_trace_where_they_now_stand_on_every_kernel() {
    let placements = test_placements();
    // Some instances moved: turned, carried away, mirrored the other way, scaled; the others stay.
    let mut moved = placements.clone();
    let moves: Vec<(u32, Affine3x4)> = vec![
        (1, affine(rotation_z(45.0), [0.8, -0.6, 0.4])),
        (3, affine([[-1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]], [-2.0, 1.5, 0.0])),
        (0, affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]], [6.0, 0.0, 1.0])),
        (7, affine(rotation_z(-20.0), [3.0, 3.0, 3.0])),
    ];
    for &(index, object_to_world) in &moves {
        moved[index as usize].object_to_world = object_to_world;
    }
    for wide in [false, true] {
        let (scene, sources) = two_level(&test_meshes(), &placements, wide);
        let mut file = write_two_level(&scene, &sources).unwrap();
        file.move_instances(&moves).unwrap();
        file.view().verify().unwrap();
        // The records the writer gives the new placements.
        let (target, _) = two_level(&test_meshes(), &moved, wide);
        let expected = write_two_level(&target, &sources).unwrap();
        assert_eq!(section(&file, SectionKind::Instances), section(&expected, SectionKind::Instances));
        let placed = flatten(&target);
        let rays = test_rays(&placed, 3000, 91);
        for tracer in every_kernel(&file.view()) {
            let (checked, ambiguous, _) = check_against_oracle(&tracer, &file, &placed, &rays);
            eprintln!("wide {wide} {:?}: {checked} checked, {ambiguous} ambiguous", tracer.kernel());
            assert!(checked > 1500 && ambiguous < rays.len() / 20, "{checked} checked, {ambiguous} ambiguous");
        }
    }
}

#[test]
fn moving_instances_to_where_they_stand_gives_the_bytes_back() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let original = write_two_level(&scene, &sources).unwrap();
    let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
    let all: Vec<(u32, Affine3x4)> =
        test_placements().iter().enumerate().map(|(k, p)| (k as u32, p.object_to_world)).collect();
    file.move_instances(&all).unwrap();
    assert!(file.as_bytes() == original.as_bytes(), "the same bytes");
    file.move_instances(&[]).unwrap();
    assert!(file.as_bytes() == original.as_bytes(), "no move, the same bytes");
}

#[test]
fn what_cannot_be_placed_is_refused_naming_the_instance() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let mut file = write_two_level(&scene, &sources).unwrap();
    let before = file.as_bytes().to_vec();
    let identity = affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]);
    let refused = |file: &mut BvhFile, moves: &[(u32, Affine3x4)]| match file.move_instances(moves) {
        Err(Error::Refit(why)) => why,
        other => panic!("refused as a refit error, got {other:?}"),
    };
    assert!(refused(&mut file, &[(0, identity), (8, identity)]).contains("instance 8: the file has 8 instances"));
    let singular = affine([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]);
    assert!(refused(&mut file, &[(2, singular)]).contains("instance 2: the transform"));
    let mut not_finite = identity;
    not_finite[1][3] = f32::NAN;
    assert!(refused(&mut file, &[(5, not_finite)]).contains("instance 5"));
    let huge = affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [f32::MAX, 0.0, 0.0]);
    assert!(refused(&mut file, &[(4, huge)]).contains("instance 4: its world box does not fit f32"));
    assert_eq!(file.as_bytes(), &before[..], "a refused move leaves the file as it was");
    // A one-level file has no instances.
    let mut one_level = crate::common::write_wide_file(&random_triangles(3, 20, 1.0), 2);
    assert!(refused(&mut one_level, &[(0, identity)]).contains("one-level"));
}

#[test]
fn moving_instances_or_refitting_meshes_of_corrupted_bytes_never_panics() {
    // Top trees and instance records scribbled over in files that still open: a move refuses or writes nonsense
    // boxes, never panics.
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let original = write_two_level(&scene, &sources).unwrap();
    let kinds = [SectionKind::TopNodes, SectionKind::TopWideNodes, SectionKind::Instances, SectionKind::Meshes];
    let moves: Vec<(u32, Affine3x4)> =
        (0..8).map(|k| (k, affine(rotation_z(10.0 * k as f32), [0.1 * k as f32, 0.0, 0.0]))).collect();
    for (_, mut file) in crate::common::scribbled_copies(&original, &kinds, 300, 20, 47) {
        let _ = file.move_instances(&moves);
    }
    // A refit of the meshes too, with the meshes' own trees and packets scribbled over as well.
    let positions: Vec<_> = original.view().triangles().iter().map(|t| t.vertices.map(bend)).collect();
    let kinds =
        [kinds.as_slice(), &[SectionKind::Nodes, SectionKind::WideNodes, SectionKind::TrianglePackets]].concat();
    for (round, mut file) in crate::common::scribbled_copies(&original, &kinds, 300, 20, 48) {
        let _ = file.refit(RefitPositions::Triangles(&positions), 1 + round % 2);
    }
}

#[test]
fn a_rebuilt_top_tree_traces_the_moved_instances_alike_and_costs_less_than_the_refit_one() {
    // The instances' places swapped around (each moved where another stood, and far off): the refit top tree
    // keeps its old grouping, the rebuilt one groups them where they stand now.
    let placements = test_placements();
    let mut moved = placements.clone();
    let n = placements.len();
    let moves: Vec<(u32, Affine3x4)> = (0..n)
        .map(|k| {
            let mut map = placements[(k * 3 + 1) % n].object_to_world;
            map[0][3] += 4.0 * k as f32;
            moved[k].object_to_world = map;
            (k as u32, map)
        })
        .collect();
    let (scene, sources) = two_level(&test_meshes(), &placements, true);
    let mut file = write_two_level(&scene, &sources).unwrap();
    file.move_instances(&moves).unwrap();
    let rebuilt = file.rebuilt_top_trees().unwrap();
    rebuilt.view().verify().unwrap();
    for kind in [SectionKind::Instances, SectionKind::Meshes, SectionKind::Nodes, SectionKind::Triangles] {
        assert_eq!(section(&rebuilt, kind), section(&file, kind), "{kind:?} kept");
    }
    let (refit_cost, rebuilt_cost) = (file.view().top_tree_cost().unwrap(), rebuilt.view().top_tree_cost().unwrap());
    assert!(rebuilt_cost < refit_cost, "rebuilt {rebuilt_cost} against refit {refit_cost}");
    let (target, _) = two_level(&test_meshes(), &moved, true);
    let placed = flatten(&target);
    let rays = test_rays(&placed, 3000, 93);
    for tracer in every_kernel(&rebuilt.view()) {
        let (checked, ambiguous, _) = check_against_oracle(&tracer, &rebuilt, &placed, &rays);
        assert!(checked > 1500 && ambiguous < rays.len() / 20, "{checked} checked, {ambiguous} ambiguous");
    }
    // A one-level file has none.
    let one_level = crate::common::write_wide_file(&random_triangles(5, 20, 1.0), 2);
    assert!(one_level.rebuilt_top_trees().is_err());
    assert_eq!(one_level.view().top_tree_cost(), None);
}

/// A smooth bend in a mesh's object space: a turn about the z axis growing with height, and a lift.
fn bend([x, y, z]: [f32; 3]) -> [f32; 3] {
    let (s, c) = (0.6 * y).sin_cos();
    [x * c - y * s, x * s + y * c, z + 0.25 * x * x]
}

#[test]
fn a_two_level_files_meshes_refit_and_every_instance_follows_on_every_kernel() {
    let meshes = test_meshes();
    let moved_meshes: Vec<Vec<_>> = meshes.iter().map(|m| m.iter().map(|t| t.map(bend)).collect()).collect();
    for wide in [false, true] {
        let (scene, sources) = two_level(&meshes, &test_placements(), wide);
        let original = write_two_level(&scene, &sources).unwrap();
        // Every mesh's records moved in its own space: positions per record, in record order over the meshes.
        let positions: Vec<_> = original.view().triangles().iter().map(|t| t.vertices.map(bend)).collect();
        for threads in [1, 2] {
            let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
            let report = file.refit(RefitPositions::Triangles(&positions), threads).unwrap();
            // A two-level file states no costs (V37), so the report compares none.
            assert_eq!((report.cost, report.wide_cost, report.cost_ratio()), (None, None, 1.0));
            // The meshes' trees, the instances' world boxes and the top trees hold the moved geometry: the file
            // verifies once its checksums are recomputed, and traces the moved meshes placed as before.
            let shipped = file.rewritten().unwrap();
            shipped.view().verify().unwrap();
            let (target, _) = two_level(&moved_meshes, &test_placements(), wide);
            let placed = flatten(&target);
            let rays = test_rays(&placed, 3000, 17);
            for tracer in every_kernel(&file.view()) {
                let (checked, ambiguous, _) = check_against_oracle(&tracer, &file, &placed, &rays);
                assert!(checked > 1500 && ambiguous < rays.len() / 20, "{checked} checked, {ambiguous} ambiguous");
            }
        }
        // Back to the records' own positions: the file's bytes again.
        let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
        file.refit(RefitPositions::Triangles(&positions), 1).unwrap();
        let own: Vec<_> = original.view().triangles().iter().map(|t| t.vertices).collect();
        file.refit(RefitPositions::Triangles(&own), 2).unwrap();
        assert!(BvhFile::from_bytes(file.as_bytes()).unwrap().rewritten().unwrap().as_bytes() == original.as_bytes());
    }
}

#[test]
fn a_two_level_refit_whose_world_box_would_overflow_is_refused_with_the_file_unchanged() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let mut file = write_two_level(&scene, &sources).unwrap();
    let before = file.as_bytes().to_vec();
    // Instance 6 scales its mesh by 2 and carries it far: a mesh reaching 1e38 no longer fits f32 there.
    let mut positions: Vec<_> = file.view().triangles().iter().map(|t| t.vertices).collect();
    positions[0][0] = [3.0e38, 0.0, 0.0];
    match file.refit(RefitPositions::Triangles(&positions), 1) {
        Err(Error::Refit(why)) => assert!(why.contains("instance") && why.contains("does not fit f32"), "{why}"),
        other => panic!("refused as a refit error, got {other:?}"),
    }
    assert!(file.as_bytes() == before.as_slice(), "the file unchanged");
}

#[test]
fn moving_instances_in_a_frame_leaves_only_the_checksums_behind() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let original = write_two_level(&scene, &sources).unwrap();
    let moves = [(2u32, affine(rotation_z(30.0), [1.0, -2.0, 0.5])), (5, affine(rotation_z(-75.0), [0.0, 4.0, -1.0]))];
    let mut hashed = BvhFile::from_bytes(original.as_bytes()).unwrap();
    hashed.move_instances(&moves).unwrap();
    let mut in_frame = BvhFile::from_bytes(original.as_bytes()).unwrap();
    in_frame.move_instances_in_frame(&moves).unwrap();
    for kind in [SectionKind::Instances, SectionKind::TopNodes, SectionKind::TopWideNodes] {
        assert_eq!(section(&in_frame, kind), section(&hashed, kind), "{kind:?}");
    }
    assert!(in_frame.view().verify().is_err(), "the checksums still describe the bytes before the move");
    hashed.view().verify().unwrap();
    assert!(in_frame.rewritten().unwrap().as_bytes() == hashed.rewritten().unwrap().as_bytes());
}

#[test]
fn refitting_one_mesh_equals_refitting_the_file_with_the_others_in_place() {
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let original = write_two_level(&scene, &sources).unwrap();
    let view = original.view();
    let sections = view.two_level().unwrap();
    let mesh = sections.meshes[1];
    let range = mesh.first_triangle as usize..(mesh.first_triangle + mesh.triangle_count) as usize;
    let mut all: Vec<[[f32; 3]; 3]> = view.triangles().iter().map(|t| t.vertices).collect();
    let moved: Vec<[[f32; 3]; 3]> = random_triangles(23, range.len(), 1.5);
    all[range.clone()].copy_from_slice(&moved);
    let mut whole = BvhFile::from_bytes(original.as_bytes()).unwrap();
    whole.refit(RefitPositions::Triangles(&all), 2).unwrap();
    let mut one = BvhFile::from_bytes(original.as_bytes()).unwrap();
    one.refit_mesh(1, &moved, 2).unwrap();
    assert!(one.as_bytes() == whole.as_bytes(), "the same bytes");
    // Refusals name the problem and leave the file as it was.
    let refused = |file: &mut BvhFile, mesh: u32, positions: &[[[f32; 3]; 3]]| match file.refit_mesh(mesh, positions, 1)
    {
        Err(Error::Refit(why)) => why,
        other => panic!("refused as a refit error, got {other:?}"),
    };
    let before = one.as_bytes().to_vec();
    let count = sections.meshes.len();
    assert!(refused(&mut one, count as u32, &moved).contains(&format!("the file has {count} meshes")));
    let (given, records) = (moved.len() - 1, moved.len());
    assert_eq!(refused(&mut one, 1, &moved[1..]), format!("mesh 1: {given} positions for {records} triangle records"));
    let mut bad = moved.clone();
    bad[3][1][2] = f32::NAN;
    assert_eq!(refused(&mut one, 1, &bad), "mesh 1: triangle record 3: a coordinate that is not finite");
    let mut far = moved.clone();
    far[0][0] = [3.0e38, 0.0, 0.0];
    assert!(refused(&mut one, 1, &far).contains("does not fit f32"));
    assert!(one.as_bytes() == before.as_slice(), "refusals change nothing");
    let mut flat = crate::common::write_wide_file(&random_triangles(5, 50, 1.0), 2);
    assert!(refused(&mut flat, 0, &moved).contains("one-level"));
}
