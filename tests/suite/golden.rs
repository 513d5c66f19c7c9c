//! The golden files: every later version of the loader must keep reading them, with the same contents.
//!
//! `fixtures/golden/quad-v1.0.bvh`, `quad-v1.1.bvh` (the same quad with the wide sections of 1.1) and
//! `quad-v1.2.bvh` (and with the source vertices of 1.2) were written by this writer from the scene below. Regenerate them only for a deliberate format change that keeps
//! major version 1 (`BVHC_BLESS=1 cargo test golden`), and never change what the assertions below expect.

use bvhc_loader::Trace;
use std::path::PathBuf;

use bvhc::loader::{BvhFile, Ray, format::SectionKind, format::SourceVertexIndices, write::BvhWriter};

use crate::common::*;

const GOLDEN_METADATA: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.0"}"#;

const GOLDEN_METADATA_1_1: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.1"}"#;

const GOLDEN_METADATA_1_2: &str = r#"{"generator":"bvhc golden fixture","format_version":"1.2"}"#;

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/quad-v1.0.bvh")
}

fn golden_1_1_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/quad-v1.1.bvh")
}

fn golden_1_2_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/quad-v1.2.bvh")
}

/// The quad's corners as the vertices 0..4 of one glTF-like primitive: triangle 0 is vertices (0, 1, 2),
/// triangle 1 is (0, 2, 3), as `quad` lists them.
const QUAD_SOURCE_VERTICES: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

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

/// The 1.1 golden scene: the 1.0 one plus its wide sections.
fn write_golden_1_1_scene() -> BvhFile {
    let tree = packed_tree(&quad(), 1);
    let wide = wide_sections_for(&tree, &quad());
    let ranges = single_source_range(2);
    BvhWriter::new(&tree.nodes, &tree.triangles)
        .triangle_ids(&tree.triangle_ids)
        .source_table(&ranges)
        .metadata(GOLDEN_METADATA_1_1)
        .wide(wide.nodes(), wide.packets())
        .build()
        .unwrap()
}

/// The 1.2 golden scene: the 1.1 one plus its source vertices.
fn write_golden_1_2_scene() -> BvhFile {
    let tree = packed_tree(&quad(), 1);
    let wide = wide_sections_for(&tree, &quad());
    let ranges = single_source_range(2);
    let source_vertices: Vec<SourceVertexIndices> =
        tree.triangle_ids.iter().map(|&t| SourceVertexIndices { indices: QUAD_SOURCE_VERTICES[t as usize] }).collect();
    BvhWriter::new(&tree.nodes, &tree.triangles)
        .triangle_ids(&tree.triangle_ids)
        .source_table(&ranges)
        .metadata(GOLDEN_METADATA_1_2)
        .wide(wide.nodes(), wide.packets())
        .source_vertices(&source_vertices)
        .build()
        .unwrap()
}

/// The quad's hits through `tracer`: t = 1 everywhere on it, the triangle whose source id names it, no hit off it.
fn assert_traces_the_quad(view: &bvhc::loader::BvhView<'_>, tracer: &bvhc::loader::Tracer<'_>) {
    let quad = quad();
    for (x, y) in [(0.75, 0.25), (0.25, 0.75), (0.5, 0.5), (0.0, 0.0), (1.0, 1.0)] {
        let hit = tracer.closest_hit(&Ray::new([x, y, 1.0], [0.0, 0.0, -1.0])).expect("the quad is hit");
        assert_eq!(hit.t, 1.0);
        let source = hit.source_triangle_id.unwrap() as usize;
        assert_eq!(view.triangles()[hit.triangle_index as usize].vertices, quad[source]);
    }
    assert!(!tracer.any_hit(&Ray::new([1.5, 0.5, 1.0], [0.0, 0.0, -1.0])));
}

#[test]
fn golden_v1_1_file_reads_verifies_and_traces_on_every_kernel() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_1_1_path(), write_golden_1_1_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(golden_1_1_path()).expect("fixtures/golden/quad-v1.1.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 1));
    let kinds: Vec<_> = view.sections().map(|s| s.kind).collect();
    // Pinned by name (not `SectionKind::ALL`, which later minors extend): the golden file does not change.
    let expected = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
        SectionKind::WideNodes,
        SectionKind::TrianglePackets,
    ];
    assert_eq!(kinds, expected.map(Some));
    let wide = view.wide_sections().expect("wide sections");
    assert_eq!((wide.nodes.len(), wide.packets.len()), (1, 1));
    assert_eq!(view.metadata_str().unwrap().unwrap(), GOLDEN_METADATA_1_1);
    assert_eq!(view.tracer().kernel(), bvhc::loader::Kernel::Wide(bvhc::loader::KernelPath::best()));
    assert_traces_the_quad(&view, &view.binary_tracer());
    for path in kernel_paths() {
        let wide_tracer = view.wide_tracer(path).unwrap();
        assert_traces_the_quad(&view, &view.binary_tracer().with_wide(wide_tracer));
    }
    assert_eq!(write_golden_1_1_scene().as_bytes(), file.as_bytes(), "the writer still writes the 1.1 bytes");
    // The loader crate's docs embed a copy (it must package on its own).
    let copy = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("crates/bvhc-loader/tests/data/quad-v1.1.bvh");
    assert_eq!(std::fs::read(copy).unwrap(), file.as_bytes());
}

#[test]
fn a_reader_of_1_0_reads_the_1_1_golden_file_through_its_1_0_sections() {
    // A 1.0 reader does not know kinds 6 and 7: they are optional, so it skips them (V7), and it does not judge
    // reserved fields of a higher minor (V13). Renaming them to unknown kinds gives this reader the same view.
    let mut bytes = std::fs::read(golden_1_1_path()).unwrap();
    for table_index in [5usize, 6] {
        let at = 64 + table_index * 48;
        let kind = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        bytes[at..at + 4].copy_from_slice(&(0x8000_0000 | kind).to_le_bytes());
    }
    crate::corrupt::refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).unwrap();
    let view = file.view();
    verify_as_an_older_reader(&view);
    assert!(view.wide_sections().is_none());
    assert_eq!(view.tracer().kernel(), bvhc::loader::Kernel::Binary);
    assert_eq!(view.sections().filter(|s| s.kind.is_none()).count(), 2);
    assert_traces_the_quad(&view, &view.tracer());
}

#[test]
fn golden_v1_0_file_reads_verifies_and_traces() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_path(), write_golden_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(golden_path()).expect("fixtures/golden/quad-v1.0.bvh");
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
    assert_traces_the_quad(&view, &view.tracer());
}

#[test]
fn the_writer_still_writes_the_golden_bytes() {
    // A file without wide sections is still written as 1.0, byte for byte.
    let golden = std::fs::read(golden_path()).unwrap();
    assert_eq!(write_golden_scene().as_bytes(), &golden[..]);
}

fn golden_split_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/split-v1.1.bvh")
}

#[test]
fn golden_split_file_with_every_metadata_key_reads_verifies_and_traces() {
    // A file as the converter writes it (section 12's fourth dump): split references, wide sections, and the
    // metadata keys that V36-V39 check. A later converter may write other bytes; this file must keep verifying.
    if std::env::var_os("BVHC_BLESS").is_some() {
        let source = golden_split_path().with_file_name("split.obj");
        let conversion = bvhc::Conversion::new(source, golden_split_path()).preset(bvhc::Preset::MaxQuality);
        conversion.write_source_vertices(false).force(true).run().unwrap();
    }
    let file = BvhFile::read(golden_split_path()).expect("fixtures/golden/split-v1.1.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 1));
    assert!(view.has_split_references());
    assert_eq!((view.triangles().len(), view.nodes().len()), (7, 7));
    let metadata: serde_json::Value = serde_json::from_str(view.metadata_str().unwrap().unwrap()).unwrap();
    for key in ["build", "cost", "wide", "choice", "triangles", "inputs"] {
        assert!(metadata[key].is_object() || metadata[key].is_array(), "{key}");
    }
    assert_eq!(metadata["triangles"]["stored_count"], 6);
    assert_eq!(metadata["wide"]["cost"].as_f64(), Some(1.50073968455989));
    assert_eq!(metadata["choice"]["kept"], 1, "the first of two candidates at the lowest cost");
    // The sliver (source id 0) is stored twice, with identical vertices.
    let ids = view.triangle_ids().unwrap();
    let sliver: Vec<usize> = (0..ids.len()).filter(|&t| ids[t] == 0).collect();
    assert_eq!(sliver.len(), 2);
    assert_eq!(view.triangles()[sliver[0]], view.triangles()[sliver[1]]);
    // Every kernel finds the closest hit of a brute-force scan over the six source triangles.
    let source: Vec<Triangle> = {
        let mut distinct: Vec<(u32, Triangle)> =
            ids.iter().zip(view.triangles()).map(|(&id, t)| (id, t.vertices)).collect();
        distinct.sort_by_key(|(id, _)| *id);
        distinct.dedup_by_key(|(id, _)| *id);
        distinct.into_iter().map(|(_, t)| t).collect()
    };
    let rays = random_rays(1201, 2_000, 8.0);
    for tracer in every_kernel(&view) {
        assert_matches_brute_force(&tracer, &source, &rays, ids);
    }
}

#[test]
fn golden_v1_2_file_reads_verifies_traces_and_interpolates_source_attributes() {
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(golden_1_2_path(), write_golden_1_2_scene().as_bytes()).unwrap();
    }
    let file = BvhFile::read(golden_1_2_path()).expect("fixtures/golden/quad-v1.2.bvh");
    let view = file.view();
    view.verify().unwrap();
    assert_eq!(view.version(), (1, 2));
    let kinds: Vec<_> = view.sections().map(|s| s.kind).collect();
    let expected = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
        SectionKind::WideNodes,
        SectionKind::TrianglePackets,
        SectionKind::SourceVertices,
    ];
    assert_eq!(kinds, expected.map(Some));
    assert_eq!(view.metadata_str().unwrap().unwrap(), GOLDEN_METADATA_1_2);
    for path in kernel_paths() {
        let wide_tracer = view.wide_tracer(path).unwrap();
        assert_traces_the_quad(&view, &view.binary_tracer().with_wide(wide_tracer));
    }
    // Each record names its own corners, whatever order the leaves put the records in.
    let ids = view.triangle_ids().unwrap();
    for (record, vertices) in view.source_vertices().unwrap().iter().enumerate() {
        assert_eq!(vertices.indices, QUAD_SOURCE_VERTICES[ids[record] as usize]);
    }
    // The corners' texture coordinates (here equal to x and y) interpolate to the hit point's x and y.
    let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    for (x, y) in [(0.75, 0.25), (0.25, 0.75), (0.5, 0.5), (0.125, 0.0625)] {
        let hit = view.tracer().closest_hit(&Ray::new([x, y, 1.0], [0.0, 0.0, -1.0])).unwrap();
        let corners = view.source_corners(&hit).unwrap();
        assert_eq!(corners.range.first_source_triangle, 0);
        assert_eq!(corners.interpolate(&uv), Some([x, y]));
        assert_eq!(corners.interpolate(&uv[..2]), None, "an array of another primitive is too short");
    }
    assert_eq!(write_golden_1_2_scene().as_bytes(), file.as_bytes(), "the writer still writes the 1.2 bytes");
    let copy = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("crates/bvhc-loader/tests/data/quad-v1.2.bvh");
    if std::env::var_os("BVHC_BLESS").is_some() {
        std::fs::write(&copy, file.as_bytes()).unwrap();
    }
    assert_eq!(std::fs::read(copy).unwrap(), file.as_bytes());
}

#[test]
fn a_reader_of_1_1_reads_the_1_2_golden_file_without_its_source_vertices() {
    // A 1.1 reader does not know kind 8: it is optional, so it skips it. Renaming it to an unknown kind gives
    // this reader the same view: every other section as before, and hits as before.
    let mut bytes = std::fs::read(golden_1_2_path()).unwrap();
    let at = 64 + 7 * 48;
    assert_eq!(u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()), 8);
    bytes[at..at + 4].copy_from_slice(&0x8000_0008u32.to_le_bytes());
    crate::corrupt::refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).unwrap();
    let view = file.view();
    verify_as_an_older_reader(&view);
    assert!(view.source_vertices().is_none() && view.wide_sections().is_some());
    assert_traces_the_quad(&view, &view.tracer());
    let hit = view.tracer().closest_hit(&Ray::new([0.5, 0.25, 1.0], [0.0, 0.0, -1.0])).unwrap();
    assert_eq!(view.source_corners(&hit), None);
}

/// Verifies `view` as a reader of a lower minor version would, one that knows none of the sections renamed to
/// private kinds: every rule holds but V51, which such a reader does not judge (the file's minor is above its own)
/// and which this reader checks last.
pub fn verify_as_an_older_reader(view: &bvhc::loader::BvhView<'_>) {
    if let Err(violation) = view.verify() {
        assert_eq!(violation.rule, bvhc::loader::Rule::LowestMinor, "{violation}");
    }
}
