//! The rules of the two-level sections (format 1.3): V41-V45, and their clauses of V8, V9, V10 and V13. Each
//! test changes one thing in a good two-level scene and expects exactly that rule, the message naming the part.

use bvhc::instancing::TwoLevelScene;
use bvhc::loader::{BvhFile, Rule, format::SourceRange};

use crate::common::*;
use crate::corrupt::{broken_rule, entry, read_u32, refresh_checksums, write_u32};
use crate::instances::{test_placements, two_level, write_two_level};

/// A good scene: two meshes (the second a copy of the first, so their boxes agree), wide sections, the test
/// placements (mesh 0 and 1 alternating).
fn good() -> (TwoLevelScene, Vec<SourceRange>) {
    let mesh = random_triangles(4101, 40, 1.0);
    two_level(&[mesh.clone(), mesh], &test_placements(), true)
}

/// The rule `edit` breaks, and the message.
fn edited(edit: impl FnOnce(&mut TwoLevelScene)) -> (Option<Rule>, String) {
    let (mut scene, sources) = good();
    assert!(write_two_level(&scene, &sources).is_ok());
    edit(&mut scene);
    match write_two_level(&scene, &sources) {
        Ok(_) => (None, String::new()),
        Err(error) => (error.rule(), error.to_string()),
    }
}

fn expect(rule: Rule, needle: &str, edit: impl FnOnce(&mut TwoLevelScene)) {
    let (got, message) = edited(edit);
    assert_eq!(got, Some(rule), "{message}");
    assert!(message.contains(needle), "expected {needle:?} in {message}");
}

#[test]
fn v41_mesh_table() {
    expect(Rule::MeshTable, "mesh 1: nodes start at", |s| s.meshes[1].first_node += 2);
    expect(Rule::MeshTable, "mesh 0: ", |s| {
        // Two nodes moved from mesh 0 to mesh 1: mesh 0 keeps an odd count, but its tree now references nodes
        // beyond its range (V14 within the mesh), and mesh 1 an even count.
        s.meshes[0].node_count -= 1;
        s.meshes[1].first_node -= 1;
        s.meshes[1].node_count += 1;
    });
    expect(Rule::MeshTable, "the meshes cover", |s| s.meshes[1].triangle_count -= 1);
    expect(Rule::MeshTable, "mesh 1: wide_nodes start at", |s| s.meshes[1].first_wide_node += 1);
    // A packet moved from mesh 1 to mesh 0 keeps the table tiled; mesh 0's wide tree then has a packet in
    // no leaf (V31, within the mesh).
    expect(Rule::PacketPartition, "mesh 0: packet", |s| {
        s.meshes[0].packet_count += 1;
        s.meshes[1].first_packet += 1;
        s.meshes[1].packet_count -= 1;
    });
    // Wide ranges in a file without wide sections.
    let mesh = random_triangles(4101, 40, 1.0);
    let (mut scene, sources) = two_level(&[mesh.clone(), mesh], &test_placements(), false);
    scene.meshes[0].wide_node_count = 1;
    let error = write_two_level(&scene, &sources).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::MeshTable), "{error}");
    assert!(error.to_string().contains("wide_nodes 0..1 run past the section's 0 elements"), "{error}");
    // One-level rules apply inside each mesh, naming it.
    let (rule, message) = edited(|s| {
        let root = s.meshes[1].first_node as usize;
        s.nodes[root + 1].max[0] = s.nodes[root].max[0] + 1.0;
    });
    assert_eq!(rule, Some(Rule::ChildInParent), "{message}");
    assert!(message.contains("mesh 1: node 1"), "{message}");
    let (rule, message) = edited(|s| {
        let first = s.meshes[1].first_triangle as usize;
        s.triangles[first].vertices[0][0] += 100.0;
    });
    assert!(rule == Some(Rule::TriangleInLeaf) || rule == Some(Rule::PacketLanes), "{message}");
    assert!(message.contains("mesh 1: "), "{message}");
}

#[test]
fn v42_instance_transforms() {
    expect(Rule::InstanceTransform, "instance 2: mesh_index 7", |s| s.instances[2].mesh_index = 7);
    expect(Rule::InstanceTransform, "instance 3: object_to_world is singular", |s| {
        s.instances[3].object_to_world[2] = [0.0; 4];
    });
    expect(Rule::InstanceTransform, "instance 1: world_to_object is not the inverse", |s| {
        s.instances[1].world_to_object[0][3] += 0.01;
    });
    expect(Rule::InstanceTransform, "instance 0: object_to_world and world_to_object must be finite", |s| {
        s.instances[0].world_to_object[1][1] = f32::NAN;
    });
}

#[test]
fn v43_top_tree() {
    let leaf_of = |s: &TwoLevelScene, instance: u32| {
        s.top_nodes.iter().position(|n| n.count == 1 && n.index == instance).unwrap()
    };
    expect(Rule::TopTree, "a leaf holds one instance", |s| {
        let leaf = leaf_of(s, 4);
        s.top_nodes[leaf].count = 2;
    });
    expect(Rule::TopTree, "is in a second leaf", |s| {
        let leaf = leaf_of(s, 4);
        s.top_nodes[leaf].index = 5;
    });
    expect(Rule::TopTree, "not inside parent", |s| {
        let leaf = leaf_of(s, 0);
        s.top_nodes[leaf].max[1] += 1000.0;
    });
    expect(Rule::TopTree, "must be finite", |s| s.top_nodes[0].min[0] = f32::NEG_INFINITY);
}

#[test]
fn v44_instance_boxes_are_conservative() {
    expect(Rule::InstanceBox, "does not contain instance 3's mesh box", |s| {
        let leaf = s.top_nodes.iter().position(|n| n.count == 1 && n.index == 3).unwrap();
        s.top_nodes[leaf].min[0] = s.top_nodes[leaf].min[0].next_up().max(s.top_nodes[leaf].min[0] + 1e-3);
    });
}

#[test]
fn v45_every_mesh_is_placed() {
    // Mesh 1 is a copy of mesh 0 (same box), so its instances can name mesh 0 without breaking V44.
    expect(Rule::MeshPlaced, "mesh 1 is placed by no instance", |s| {
        for instance in &mut s.instances {
            instance.mesh_index = 0;
        }
    });
}

#[test]
fn v13_instance_reserved_is_zero() {
    expect(Rule::ReservedZero, "instance 5: reserved", |s| s.instances[5].reserved = 1);
}

#[test]
fn v10_top_node_count_follows_the_instances() {
    expect(Rule::Counts, "top nodes 2 x instances - 1", |s| {
        let extra = s.top_nodes[1];
        s.top_nodes.push(extra);
    });
}

/// The good file's bytes and the table positions of its meshes, instances and top_nodes sections.
fn good_bytes_and_positions() -> (Vec<u8>, [usize; 3]) {
    let (scene, sources) = good();
    let bytes = write_two_level(&scene, &sources).unwrap().as_bytes().to_vec();
    let count = read_u32(&bytes, 24) as usize;
    let position = |kind: u32| (0..count).find(|&i| read_u32(&bytes, entry(i)) == kind).unwrap();
    let positions = [position(9), position(10), position(11)];
    (bytes, positions)
}

#[test]
fn v7_v8_v9_two_level_sections_are_required_together_and_only_in_1_3() {
    let (good, [meshes, instances, _]) = good_bytes_and_positions();
    assert_eq!(broken_rule(&good), None);
    // A reader of 1.2 does not know kinds 9-11; they are REQUIRED, so it refuses the file rather than tracing
    // the meshes' object-space trees as a scene (simulated: kinds this reader does not know either).
    let mut bytes = good.clone();
    write_u32(&mut bytes, entry(meshes), 99);
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::UnknownRequiredSection));
    // The instances section unknown and optional: the other two alone break V8.
    let mut bytes = good.clone();
    write_u32(&mut bytes, entry(instances), 99);
    write_u32(&mut bytes, entry(instances) + 4, 0);
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionMultiplicity));
    let error = BvhFile::from_bytes(&bytes).unwrap_err().to_string();
    assert!(error.contains("all of the meshes, instances and top_nodes sections or none"), "{error}");
    // Relabelled 1.2: the sections came with 1.3.
    let mut bytes = good.clone();
    crate::corrupt::relabel_minor(&mut bytes, 3, 2);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionMultiplicity));
    // The REQUIRED flag cleared on the mesh table: V9.
    let mut bytes = good;
    write_u32(&mut bytes, entry(meshes) + 4, 0);
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionKindLayout));
}

#[test]
fn v37_v38_costs_are_not_defined_and_leaf_limits_apply_per_mesh_in_two_level_files() {
    let (scene, sources) = good();
    let write = |metadata: &str| {
        bvhc::loader::write::BvhWriter::new(&scene.nodes, &scene.triangles)
            .triangle_ids(&scene.triangle_ids)
            .source_table(&sources)
            .metadata(metadata)
            .wide(&scene.wide_nodes, &scene.packets)
            .source_vertices(&scene.source_vertices)
            .two_level(scene.sections())
            .build()
    };
    let error = write(r#"{"generator":"t","format_version":"1.3","cost":{"sah_cost":1.0}}"#).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::MetadataCost), "{error}");
    assert!(error.to_string().contains("two-level file"), "{error}");
    // The meshes' leaves hold up to 2 triangles (binary) and up to 8 (wide): limits checked per mesh, with the
    // mesh's own indices.
    assert!(write(r#"{"generator":"t","format_version":"1.3","build":{"max_leaf_size":2}}"#).is_ok());
    let error = write(r#"{"generator":"t","format_version":"1.3","build":{"max_leaf_size":1}}"#).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::MetadataBuild), "{error}");
    assert!(error.to_string().contains("mesh 0: node"), "{error}");
    let limited = r#"{"generator":"t","format_version":"1.3","build":{"wide":{"max_leaf_size":1}}}"#;
    let error = write(limited).unwrap_err();
    assert!(error.to_string().contains("mesh 0: wide node"), "{error}");
}

#[test]
fn v36_the_two_level_counts_are_the_file_s() {
    let (scene, sources) = good();
    let write = |two_level: &str| {
        let metadata = format!(r#"{{"generator":"t","format_version":"1.3","two_level":{two_level}}}"#);
        bvhc::loader::write::BvhWriter::new(&scene.nodes, &scene.triangles)
            .triangle_ids(&scene.triangle_ids)
            .source_table(&sources)
            .metadata(&metadata)
            .wide(&scene.wide_nodes, &scene.packets)
            .source_vertices(&scene.source_vertices)
            .two_level(scene.sections())
            .build()
            .err()
            .map(|e| (e.rule(), e.to_string()))
    };
    // Two meshes of 40 triangles, the first placed 5 times and the second 3 times: 320 placed triangles. Both
    // meshes listed as instanced glTF meshes flatten nothing; one listed makes mesh 0 the flattened rest.
    let counts = |meshes: u32, instances: u32, placed: u32, listed: &str, flattened: u32| {
        format!(
            r#"{{"instancing":"always","instanced_meshes":{listed},"mesh_count":{meshes},"instance_count":{instances},"placed_triangle_count":{placed},"flattened_triangle_count":{flattened}}}"#
        )
    };
    assert_eq!(write(&counts(2, 8, 320, "[3, 5]", 0)), None);
    assert_eq!(write(&counts(2, 8, 320, "[5]", 40)), None);
    for (two_level, needle) in [
        (counts(3, 8, 320, "[3, 5]", 0), "mesh_count 3, but the section holds 2"),
        (counts(2, 9, 320, "[3, 5]", 0), "instance_count 9, but the section holds 8"),
        (counts(2, 8, 321, "[3, 5]", 0), "placed_triangle_count 321, but the instances place 320"),
        (counts(2, 8, 320, "[3, 5]", 40), "every mesh is a listed instanced mesh"),
        (counts(2, 8, 320, "[5]", 0), "mesh 0, the flattened rest, holds 40"),
        (counts(2, 8, 320, "[]", 0), "2 meshes, but instanced_meshes lists 0"),
    ] {
        let (rule, message) = write(&two_level).unwrap_or_else(|| panic!("accepted: {two_level}"));
        assert_eq!(rule, Some(Rule::MetadataCounts), "{message}");
        assert!(message.contains(needle), "expected {needle:?} in {message}");
    }
    // The key says the file is two-level: a one-level file with it breaks the rule.
    let tree = packed_tree(&random_triangles(4102, 20, 1.0), 2);
    let one_level = r#"{"generator":"t","format_version":"1.0","two_level":{"mesh_count":1}}"#;
    let error =
        bvhc::loader::write::BvhWriter::new(&tree.nodes, &tree.triangles).metadata(one_level).build().unwrap_err();
    assert_eq!(error.rule(), Some(Rule::MetadataCounts), "{error}");
    assert!(error.to_string().contains("not two-level"), "{error}");
}

/// The wide top tree's leaf slot of instance `instance`: (node, slot).
fn wide_leaf_of(scene: &TwoLevelScene, instance: u32) -> (usize, usize) {
    let flag = bvhc::loader::format::LEAF_BIT | instance;
    scene
        .top_wide_nodes
        .iter()
        .enumerate()
        .find_map(|(i, n)| n.child.iter().position(|&c| c == flag).map(|slot| (i, slot)))
        .unwrap()
}

#[test]
fn v46_top_wide_tree() {
    expect(Rule::TopWideTree, "in a second slot", |s| {
        let (node, slot) = wide_leaf_of(s, 4);
        s.top_wide_nodes[node].child[slot] = bvhc::loader::format::LEAF_BIT | 5;
    });
    expect(Rule::TopWideTree, "does not contain instance 3's mesh box", |s| {
        let (node, slot) = wide_leaf_of(s, 3);
        s.top_wide_nodes[node].min[0][slot] += 1e-3;
    });
    expect(Rule::TopWideTree, "after an empty slot", |s| {
        // The last occupied slot emptied, its box kept: not the empty box.
        let root = &mut s.top_wide_nodes[0];
        let occupied = root.child.iter().take_while(|&&c| c != bvhc::loader::format::EMPTY_SLOT).count();
        root.child[occupied - 1] = bvhc::loader::format::EMPTY_SLOT;
    });
    expect(Rule::TopWideTree, "out of range", |s| {
        let (node, slot) = wide_leaf_of(s, 0);
        s.top_wide_nodes[node].child[slot] = bvhc::loader::format::LEAF_BIT | 99;
    });
    expect(Rule::ReservedZero, "top wide node 0: reserved", |s| s.top_wide_nodes[0].reserved[2] = 1);
}

#[test]
fn v8_v10_the_wide_top_tree_comes_exactly_with_a_two_level_file_s_wide_sections() {
    let (mut scene, sources) = good();
    let wide_top = std::mem::take(&mut scene.top_wide_nodes);
    let error = write_two_level(&scene, &sources).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::SectionMultiplicity), "{error}");
    assert!(error.to_string().contains("top_wide_nodes section comes exactly with"), "{error}");
    // More wide top nodes than instances (a node of one slot below the root): V10.
    scene.top_wide_nodes = wide_top.clone();
    scene.top_wide_nodes.extend(std::iter::repeat_n(bvhc::loader::format::WideNode8::EMPTY, scene.instances.len()));
    let error = write_two_level(&scene, &sources).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::Counts), "{error}");
    // Without the wide sections, a wide top tree has nothing to go with.
    let mesh = random_triangles(4101, 40, 1.0);
    let (mut flat, sources) = two_level(&[mesh.clone(), mesh], &test_placements(), false);
    flat.top_wide_nodes = wide_top;
    let error = write_two_level(&flat, &sources).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::SectionMultiplicity), "{error}");
}
