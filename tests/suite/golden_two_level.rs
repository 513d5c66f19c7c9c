//! The golden file of version 1.3, `fixtures/golden/instances-v1.3.bvh`: two meshes (the unit quad, one
//! triangle) placed three times (as is, mirrored, scaled and moved) under a top-level tree. Written by this
//! writer from the scene below; regenerate it only for a deliberate format change that keeps major version 1
//! (`BVHC_BLESS=1 cargo test golden`), and never change what the assertions expect.

use bvhc_loader::Trace;
use std::path::PathBuf;

use bvhc::loader::{BvhFile, Kernel, Ray, format::SectionKind, format::SourceRange};

use crate::instances::{affine, packed_mesh, placement};

const GOLDEN_METADATA_1_3: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.3"}"#;

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/instances-v1.3.bvh")
}

fn write_golden_scene() -> BvhFile {
    let [a, b, c, d] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let quad = vec![[a, b, c], [a, c, d]];
    let triangle = vec![[a, b, d]];
    let meshes = vec![packed_mesh(&quad, 0, false), packed_mesh(&triangle, 2, false)];
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mirror = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let double = [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]];
    let placements = [
        placement(0, affine(identity, [0.0; 3])),
        placement(0, affine(mirror, [3.0, 0.0, 0.0])),
        placement(1, affine(double, [0.0, 2.0, 0.0])),
    ];
    let scene = bvhc::instancing::TwoLevelScene::assemble(meshes, &placements).unwrap();
    let range = |first: u32, count: u32, mesh: u32| SourceRange {
        first_source_triangle: first,
        source_triangle_count: count,
        file_index: 0,
        node_index: u32::MAX,
        mesh_index: mesh,
        primitive_index: 0,
        instance_index: u32::MAX,
        reserved: 0,
    };
    let sources = [range(0, 2, 0), range(2, 1, 1)];
    bvhc::loader::write::BvhWriter::new(&scene.nodes, &scene.triangles)
        .triangle_ids(&scene.triangle_ids)
        .source_table(&sources)
        .metadata(GOLDEN_METADATA_1_3)
        .two_level(scene.sections())
        .build()
        .unwrap()
}

#[test]
fn golden_v1_3_file_reads_verifies_and_traces_through_its_instances() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_path(), write_golden_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(golden_path()).expect("fixtures/golden/instances-v1.3.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 3));
    let kinds: Vec<_> = view.sections().map(|s| s.kind).collect();
    let expected = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
        SectionKind::Meshes,
        SectionKind::Instances,
        SectionKind::TopNodes,
    ];
    assert_eq!(kinds, expected.map(Some));
    let two_level = view.two_level().unwrap();
    assert_eq!((two_level.meshes.len(), two_level.instances.len(), two_level.top_nodes.len()), (2, 3, 5));
    assert_eq!(two_level.placed_record_count(), 5);
    let tracer = view.tracer();
    assert_eq!(tracer.kernel(), Kernel::Binary);
    let down = |x: f32, y: f32| tracer.closest_hit(&Ray::new([x, y, 1.0], [0.0, 0.0, -1.0]));
    let ids = view.triangle_ids().unwrap();
    // The quad as placed, and its mirror image: the same source triangle, seen from the same (front) side.
    let direct = down(0.75, 0.25).unwrap();
    let mirrored = down(2.25, 0.25).unwrap();
    assert_eq!((direct.instance_index, mirrored.instance_index), (Some(0), Some(1)));
    assert_eq!(direct.source_triangle_id, mirrored.source_triangle_id);
    assert_eq!((direct.t, mirrored.t), (1.0, 1.0));
    assert_eq!((direct.normal, mirrored.normal), ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]));
    assert!(direct.front_face && mirrored.front_face);
    // The triangle scaled by 2: its world normal is the cross product of its world edges, (0, 0, 4).
    let scaled = down(0.5, 2.5).unwrap();
    assert_eq!((scaled.instance_index, scaled.source_triangle_id, scaled.t), (Some(2), Some(2), 1.0));
    assert_eq!(ids[scaled.triangle_index as usize], 2);
    assert_eq!(scaled.normal, [0.0, 0.0, 4.0]);
    // Between the instances, and beside the scaled triangle's hypotenuse: nothing.
    assert_eq!(down(1.5, 0.5), None);
    assert_eq!(down(1.5, 3.5), None);
    assert_eq!(write_golden_scene().as_bytes(), file.as_bytes(), "the writer still writes the 1.3 bytes");
}

#[test]
fn a_reader_of_1_2_refuses_the_1_3_golden_file() {
    // A 1.2 reader does not know kinds 9-11, which are REQUIRED: it must refuse the file (V7) rather than trace
    // the meshes' object-space trees as if they were the scene. Renaming them gives this reader the same view.
    let mut bytes = std::fs::read(golden_path()).unwrap();
    for table_index in 5..8 {
        let at = 64 + table_index * 48;
        let kind = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        assert_eq!(kind, 4 + table_index as u32);
        bytes[at..at + 4].copy_from_slice(&(0x8000_0000 | kind).to_le_bytes());
    }
    crate::corrupt::refresh_checksums(&mut bytes);
    let error = BvhFile::from_bytes(&bytes).unwrap_err();
    assert_eq!(error.rule(), Some(bvhc::loader::Rule::UnknownRequiredSection), "{error}");
}
