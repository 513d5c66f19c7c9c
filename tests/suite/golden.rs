//! The golden v1.0 file: every later version of the loader must keep reading it, with the same contents.
//!
//! `fixtures/golden/quad-v1.0.bvh` was written by this writer from the scene below. Regenerate it only for a
//! deliberate format change that keeps major version 1 (`BVHC_BLESS=1 cargo test golden`), and never
//! change what the assertions below expect of it.

use std::path::PathBuf;

use bvhc::loader::{BvhFile, BvhWriter, Ray, SectionKind};

use crate::common::*;

const GOLDEN_METADATA: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.0"}"#;

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/quad-v1.0.bvh")
}

/// The unit square in the z = 0 plane as two triangles.
fn quad() -> Vec<Triangle> {
    let [a, b, c, d] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    vec![[a, b, c], [a, c, d]]
}

fn write_golden_scene() -> BvhFile {
    let tree = packed_tree(&quad(), 1);
    let ranges = single_source_range(2);
    BvhWriter::new(&tree.nodes, &tree.triangles)
        .triangle_ids(&tree.triangle_ids)
        .source_table(&ranges)
        .metadata(GOLDEN_METADATA)
        .build()
        .unwrap()
}

#[test]
fn golden_v1_0_file_reads_verifies_and_traces() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_path(), write_golden_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(&golden_path()).expect("fixtures/golden/quad-v1.0.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 0));
    assert_eq!(view.nodes().len(), 3);
    assert_eq!(view.triangles().len(), 2);
    let kinds: Vec<_> = view.sections().map(|s| s.kind).collect();
    let expected = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
    ];
    assert_eq!(kinds, expected.map(Some));
    assert_eq!(view.metadata_str().unwrap().unwrap(), GOLDEN_METADATA);
    let mut ids = view.triangle_ids().unwrap().to_vec();
    ids.sort_unstable();
    assert_eq!(ids, [0, 1]);
    let quad = quad();
    for (x, y) in [(0.75, 0.25), (0.25, 0.75), (0.5, 0.5), (0.0, 0.0), (1.0, 1.0)] {
        let hit = view.tracer().closest_hit(&Ray::new([x, y, 1.0], [0.0, 0.0, -1.0])).expect("the quad is hit");
        assert_eq!(hit.t, 1.0);
        let source = hit.source_triangle_id.unwrap() as usize;
        assert_eq!(view.triangles()[hit.triangle_index as usize].vertices, quad[source]);
    }
    assert!(!view.tracer().any_hit(&Ray::new([1.5, 0.5, 1.0], [0.0, 0.0, -1.0])));
}

#[test]
fn the_writer_still_writes_the_golden_bytes() {
    // Holds while the writer writes version 1.0; a later minor version changes the header and may drop this.
    let golden = std::fs::read(golden_path()).unwrap();
    assert_eq!(write_golden_scene().as_bytes(), &golden[..]);
}
