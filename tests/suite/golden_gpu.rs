//! The golden file of version 1.4, `fixtures/golden/gpu-v1.4.bvh`: the unit quad and a triangle beside it, with
//! the GPU sections (one compressed node, two leaves). Written by this writer from the scene below; regenerate
//! it only for a deliberate format change that keeps major version 1 (`BVHC_BLESS=1 cargo test golden`), and
//! never change what the assertions expect.

use bvhc_loader::Trace;
use std::path::PathBuf;

use bvhc::cost::SahConstants;
use bvhc::layout::{GpuCosts, collapse, merge_leaves};
use bvhc::loader::format::GpuSlot;
use bvhc::loader::{BvhFile, Ray, format::SectionKind, gpu::GpuLayoutTracer, write::BvhWriter};
use bvhc::optimize::OptTree;
use bvhc::pack::{pack, pack_gpu};

use crate::common::single_source_range;

const GOLDEN_METADATA_1_4: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.4"}"#;

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/gpu-v1.4.bvh")
}

fn write_golden_scene() -> BvhFile {
    let [a, b, c, d] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let triangles = vec![[a, b, c], [a, c, d], [[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [2.0, 1.0, 0.5]]];
    let build = bvhc::builders::build_binned_sah(&triangles, 1);
    let opt = OptTree::from_build_tree(&build, &triangles);
    let packed = pack(&merge_leaves(&opt, SahConstants::default(), 8), &triangles).unwrap();
    // Pinned constants (not the defaults, which may change): leaves of at most 3, a triangle at 0.3 of a node.
    let costs = GpuCosts { max_leaf_size: 3, node_visit: 1.0, triangle_test: 0.3 };
    let file_index_of = packed.file_index_of(triangles.len()).unwrap();
    let record_of = |t: u32| file_index_of.get(t as usize).copied();
    let layout = pack_gpu(&collapse(&opt, &costs.wide_costs()), &packed.triangles, &record_of, false).unwrap();
    let sources = single_source_range(triangles.len());
    BvhWriter::new(&packed.nodes, &packed.triangles)
        .triangle_ids(&packed.triangle_ids)
        .source_table(&sources)
        .metadata(GOLDEN_METADATA_1_4)
        .gpu(&layout.nodes, &layout.triangles)
        .build()
        .unwrap()
}

#[test]
fn golden_v1_4_file_reads_verifies_and_traces_its_gpu_sections() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_path(), write_golden_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(golden_path()).expect("fixtures/golden/gpu-v1.4.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 4));
    let kinds: Vec<_> = view.sections().map(|s| s.kind).collect();
    let expected = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
        SectionKind::GpuNodes,
        SectionKind::GpuTriangles,
    ];
    assert_eq!(kinds, expected.map(Some));
    let gpu = view.gpu_sections().unwrap();
    assert_eq!((gpu.nodes.len(), gpu.triangles.len()), (1, 3));
    let root = gpu.nodes[0];
    let leaves: Vec<GpuSlot> = (0..8).map(|s| root.slot(s)).filter(|s| *s != GpuSlot::Empty).collect();
    assert_eq!(leaves.len(), 2, "{leaves:?}");
    assert_eq!(root.inner_mask, 0);
    let model = GpuLayoutTracer::new(gpu, view.triangles(), view.triangle_ids())
        .with_split_references(view.has_split_references());
    let down = |x: f32, y: f32| model.closest_hit(&Ray::new([x, y, 1.0], [0.0, 0.0, -1.0]));
    let ids = view.triangle_ids().unwrap();
    let quad = down(0.75, 0.25).unwrap();
    assert_eq!((quad.t, ids[quad.triangle_index as usize]), (1.0, 0));
    let beside = down(2.25, 0.25).unwrap();
    assert_eq!((beside.t, ids[beside.triangle_index as usize]), (0.875, 2), "the worked example of section 12");
    assert_eq!(down(1.5, 0.5), None);
    assert_eq!(write_golden_scene().as_bytes(), file.as_bytes(), "the writer still writes the 1.4 bytes");
}

#[test]
fn a_reader_of_1_3_reads_the_1_4_golden_file_without_its_gpu_sections() {
    // The GPU sections are optional: a 1.3 reader skips kinds 13 and 14 and traces the binary tree. Renaming
    // them to private kinds gives this reader the same view.
    let mut bytes = std::fs::read(golden_path()).unwrap();
    for table_index in 5..7 {
        let at = 64 + table_index * 48;
        let kind = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        assert_eq!(kind, 8 + table_index as u32);
        bytes[at..at + 4].copy_from_slice(&(0x8000_0000 | kind).to_le_bytes());
    }
    crate::corrupt::refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).unwrap();
    crate::golden::verify_as_an_older_reader(&file.view());
    assert!(file.view().gpu_sections().is_none());
    let hit = file.view().tracer().closest_hit(&Ray::new([0.75, 0.25, 1.0], [0.0, 0.0, -1.0])).unwrap();
    assert_eq!(hit.t, 1.0);
}
