//! The golden file of version 1.5, `fixtures/golden/flags-v1.5.bvh`: the unit quad and a triangle beside it
//! (the scene of `gpu-v1.4.bvh`), with the `triangle_flags` section marking the triangle not opaque. Written by
//! this writer from the scene below; regenerate it only for a deliberate format change that keeps major version
//! 1 (`BVHC_BLESS=1 cargo test golden`), and never change what the assertions expect.

use bvhc_loader::Trace;
use std::path::PathBuf;

use bvhc::cost::SahConstants;
use bvhc::layout::merge_leaves;
use bvhc::loader::format::TRIANGLE_NOT_OPAQUE;
use bvhc::loader::{BvhFile, Ray, filter::Candidate, filter::FilterScope, format::SectionKind, write::BvhWriter};
use bvhc::optimize::OptTree;
use bvhc::pack::pack;

use crate::common::single_source_range;

const GOLDEN_METADATA_1_5: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.5"}"#;

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/flags-v1.5.bvh")
}

fn write_golden_scene() -> BvhFile {
    let [a, b, c, d] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let triangles = vec![[a, b, c], [a, c, d], [[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [2.0, 1.0, 0.5]]];
    let build = bvhc::builders::build_binned_sah(&triangles, 1);
    let opt = OptTree::from_build_tree(&build, &triangles);
    let packed = pack(&merge_leaves(&opt, SahConstants::default(), 8), &triangles).unwrap();
    // The triangle beside the quad (source id 2) comes from a material that may cut it out.
    let flags: Vec<u8> = packed.triangle_ids.iter().map(|&id| if id == 2 { TRIANGLE_NOT_OPAQUE } else { 0 }).collect();
    let sources = single_source_range(triangles.len());
    BvhWriter::new(&packed.nodes, &packed.triangles)
        .triangle_ids(&packed.triangle_ids)
        .source_table(&sources)
        .metadata(GOLDEN_METADATA_1_5)
        .triangle_flags(&flags)
        .build()
        .unwrap()
}

#[test]
fn golden_v1_5_file_reads_verifies_and_filters_only_its_not_opaque_triangle() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_path(), write_golden_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(golden_path()).expect("fixtures/golden/flags-v1.5.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 5));
    let kinds: Vec<_> = view.sections().map(|s| s.kind).collect();
    let expected = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
        SectionKind::TriangleFlags,
    ];
    assert_eq!(kinds, expected.map(Some));
    assert_eq!(view.triangle_flags(), Some(&[0, 0, 1][..]));
    assert!(!view.is_not_opaque(0) && view.is_not_opaque(2));
    // A filter that rejects everything it is asked about: with the file's flags it is asked about the triangle
    // beside the quad alone, so the quad is still hit and the triangle is not.
    let asked = std::cell::Cell::new(0);
    let reject = |candidate: &Candidate<'_>| {
        asked.set(asked.get() + 1);
        assert_eq!(candidate.source_triangle_id, Some(2));
        false
    };
    let tracer = view.tracer();
    let filtered = tracer.filtered(&reject, FilterScope::NotOpaque);
    let down = |x: f32, y: f32| Ray::new([x, y, 1.0], [0.0, 0.0, -1.0]);
    assert_eq!(filtered.closest_hit(&down(0.75, 0.25)).map(|h| h.t), Some(1.0));
    assert_eq!(asked.get(), 0, "the quad is opaque");
    assert_eq!(tracer.closest_hit(&down(2.25, 0.25)).map(|h| h.t), Some(0.875));
    assert_eq!(filtered.closest_hit(&down(2.25, 0.25)), None);
    assert!(!filtered.any_hit(&down(2.25, 0.25)));
    assert_eq!(asked.get(), 2);
    assert_eq!(write_golden_scene().as_bytes(), file.as_bytes(), "the writer still writes the 1.5 bytes");
}

#[test]
fn a_reader_of_1_4_reads_the_1_5_golden_file_as_all_opaque() {
    // The section is optional: a 1.4 reader skips kind 15 and sees an all-opaque file. Renaming it to a private
    // kind gives this reader the same view.
    let mut bytes = std::fs::read(golden_path()).unwrap();
    let at = 64 + 5 * 48;
    assert_eq!(u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()), 15);
    bytes[at..at + 4].copy_from_slice(&(0x8000_0000u32 | 15).to_le_bytes());
    crate::corrupt::refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).unwrap();
    crate::golden::verify_as_an_older_reader(&file.view());
    assert!(file.view().triangle_flags().is_none());
    let reject = |_: &Candidate<'_>| false;
    let tracer = file.view().tracer();
    let hit =
        tracer.filtered(&reject, FilterScope::NotOpaque).closest_hit(&Ray::new([2.25, 0.25, 1.0], [0.0, 0.0, -1.0]));
    assert_eq!(hit.map(|h| h.t), Some(0.875));
}
