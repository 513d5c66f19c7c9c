//! One test per validity rule: corrupt a good file in one way and expect exactly that rule.

use bvhc::loader::{BvhFile, BvhWriter, PackedNode, PackedTriangle, Rule, header_checksum, section_checksum};

use crate::common::*;

const TABLE: usize = 64;
const ENTRY: usize = 48;
/// Section table positions of the good file's sections.
const NODES: usize = 0;
const TRIANGLES: usize = 1;
const IDS: usize = 2;
const SOURCES: usize = 3;
const METADATA_SECTION: usize = 4;

/// A good file with every section kind, as plain bytes.
pub fn good_bytes() -> Vec<u8> {
    write_file(&packed_tree(&random_triangles(70, 60, 1.0), 2)).as_bytes().to_vec()
}

fn read_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}
fn write_u32(bytes: &mut [u8], at: usize, value: u32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}
fn read_u64(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
}
fn write_u64(bytes: &mut [u8], at: usize, value: u64) {
    bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
}
fn write_f32(bytes: &mut [u8], at: usize, value: f32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}
fn entry(section: usize) -> usize {
    TABLE + section * ENTRY
}
/// Byte offset of a section's data.
fn data(bytes: &[u8], section: usize) -> usize {
    read_u64(bytes, entry(section) + 8) as usize
}

/// Recomputes every checksum, so that a corruption reaches the rules behind V11 and V12.
pub fn refresh_checksums(bytes: &mut [u8]) {
    try_refresh_checksums(bytes).expect("the section table lies inside the file");
}

/// [`refresh_checksums`], or `None` when the table or a section lies outside the file.
pub fn try_refresh_checksums(bytes: &mut [u8]) -> Option<()> {
    let count = read_u32(bytes.get(..64)?, 24) as usize;
    let stride = read_u32(bytes, 28) as usize;
    let table_end = TABLE.checked_add(count.checked_mul(stride)?)?;
    if stride < ENTRY || table_end > bytes.len() {
        return None;
    }
    for i in 0..count {
        let at = TABLE + i * stride;
        let offset = usize::try_from(read_u64(bytes, at + 8)).ok()?;
        let len = usize::try_from(read_u64(bytes, at + 16)).ok()?;
        let sum = section_checksum(bytes.get(offset..offset.checked_add(len)?)?);
        write_u64(bytes, at + 40, sum);
    }
    let sum = header_checksum(&bytes[..table_end]);
    write_u64(bytes, 32, sum);
    Some(())
}

/// Opens (in an aligned copy) and verifies; returns the broken rule.
fn broken_rule(bytes: &[u8]) -> Option<Rule> {
    let file = match BvhFile::from_bytes(bytes) {
        Ok(file) => file,
        Err(error) => return Some(error.rule().unwrap_or_else(|| panic!("not a rule: {error}"))),
    };
    file.view().verify().err().map(|v| v.rule)
}

fn expect(rule: Rule, corrupt: impl FnOnce(&mut Vec<u8>), refresh: bool) {
    let mut bytes = good_bytes();
    assert_eq!(broken_rule(&bytes), None);
    corrupt(&mut bytes);
    if refresh {
        refresh_checksums(&mut bytes);
    }
    let got = broken_rule(&bytes);
    assert_eq!(got, Some(rule), "expected {rule}");
    assert_eq!(rule.is_structural(), BvhFile::from_bytes(&bytes).is_err(), "{rule} is structural iff open fails");
}

fn first_node_where(bytes: &[u8], predicate: impl Fn(&PackedNode) -> bool) -> usize {
    let file = BvhFile::from_bytes(bytes).unwrap();
    let view = file.view();
    data(bytes, NODES) + 32 * view.nodes().iter().position(predicate).unwrap()
}

#[test]
fn v1_magic() {
    expect(Rule::Magic, |b| b[3] = b'X', false);
    expect(Rule::Magic, |b| b.truncate(40), false);
    let error =
        BvhFile::from_bytes(b"HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n}\nMOTION\nFrames: 0\nFrame Time: 0.1\n\n\n")
            .unwrap_err();
    assert!(error.to_string().contains("Biovision"), "{error}");
}

#[test]
fn v2_major_version() {
    expect(Rule::MajorVersion, |b| b[8] = 2, false);
}

#[test]
fn v3_file_byte_len() {
    expect(Rule::FileByteLen, |b| b.push(0), false);
    expect(Rule::FileByteLen, |b| b.truncate(b.len() - 1), false);
}

#[test]
fn v4_section_table() {
    expect(Rule::SectionTable, |b| write_u32(b, 24, 1_000_000), false);
    expect(Rule::SectionTable, |b| write_u32(b, 28, 40), false);
}

#[test]
fn v5_section_placement() {
    expect(
        Rule::SectionPlacement,
        |b| {
            let at = entry(NODES) + 8;
            let v = read_u64(b, at);
            write_u64(b, at, v + 4)
        },
        false,
    );
    expect(Rule::SectionPlacement, |b| write_u64(b, entry(METADATA_SECTION) + 16, u64::MAX - 3), false);
    expect(Rule::SectionPlacement, |b| write_u64(b, entry(TRIANGLES) + 8, 0), false);
}

#[test]
fn v6_section_size() {
    expect(
        Rule::SectionSize,
        |b| {
            let at = entry(NODES) + 24;
            let v = read_u64(b, at);
            write_u64(b, at, v + 1)
        },
        false,
    );
    expect(Rule::SectionSize, |b| write_u32(b, entry(METADATA_SECTION) + 32, 0), false);
}

#[test]
fn v7_unknown_required_section() {
    expect(
        Rule::UnknownRequiredSection,
        |b| {
            write_u32(b, entry(METADATA_SECTION), 999);
            write_u32(b, entry(METADATA_SECTION) + 4, 1)
        },
        false,
    );
}

#[test]
fn v8_section_multiplicity() {
    // The nodes section becomes an unknown optional kind: the file has no nodes section.
    expect(
        Rule::SectionMultiplicity,
        |b| {
            write_u32(b, entry(NODES), 999);
            write_u32(b, entry(NODES) + 4, 0)
        },
        false,
    );
    let id_bytes = 0u32.to_le_bytes();
    let one = packed_tree(&random_triangles(71, 1, 1.0), 1);
    let bytes = BvhWriter::new(&one.nodes, &one.triangles)
        .triangle_ids(&one.triangle_ids)
        .extra_section(3, false, 4, &id_bytes)
        .build();
    assert_eq!(bytes.unwrap_err().rule(), Some(Rule::SectionMultiplicity), "a second triangle_ids section");
}

#[test]
fn v9_section_kind_layout() {
    expect(Rule::SectionKindLayout, |b| write_u32(b, entry(NODES) + 4, 0), false);
    expect(Rule::SectionKindLayout, |b| write_u32(b, entry(IDS) + 4, 1), false);
    expect(Rule::SectionKindLayout, |b| write_u32(b, entry(NODES) + 4, 1 | 4), false);
    // The ids section claims 8-byte elements (with a consistent length).
    expect(
        Rule::SectionKindLayout,
        |b| {
            let count = read_u64(b, entry(IDS) + 24);
            write_u64(b, entry(IDS) + 24, count / 2);
            write_u64(b, entry(IDS) + 16, count / 2 * 8);
            write_u32(b, entry(IDS) + 32, 8);
        },
        false,
    );
}

#[test]
fn v10_counts() {
    expect(
        Rule::Counts,
        |b| {
            let count = read_u64(b, entry(IDS) + 24);
            write_u64(b, entry(IDS) + 24, count - 1);
            write_u64(b, entry(IDS) + 16, (count - 1) * 4);
        },
        false,
    );
    expect(
        Rule::Counts,
        |b| {
            let count = read_u64(b, entry(NODES) + 24);
            write_u64(b, entry(NODES) + 24, count - 1);
            write_u64(b, entry(NODES) + 16, (count - 1) * 32);
        },
        false,
    );
    // A source table without ids.
    expect(Rule::Counts, |b| write_u32(b, entry(IDS), 999), false);
}

#[test]
fn v11_header_checksum() {
    expect(Rule::HeaderChecksum, |b| b[40] = 1, false);
}

#[test]
fn v12_section_checksum() {
    expect(
        Rule::SectionChecksum,
        |b| {
            let at = data(b, TRIANGLES);
            b[at] ^= 1
        },
        false,
    );
}

#[test]
fn v13_reserved_zero() {
    expect(Rule::ReservedZero, |b| b[44] = 1, true);
    expect(Rule::ReservedZero, |b| b[12] = 1, true);
    expect(Rule::ReservedZero, |b| b[entry(TRIANGLES) + 36] = 1, true);
    expect(
        Rule::ReservedZero,
        |b| {
            let at = data(b, NODES) - 1;
            b[at] = 7
        },
        true,
    );
    expect(
        Rule::ReservedZero,
        |b| {
            let at = data(b, SOURCES) + 28;
            b[at] = 7
        },
        true,
    );
}

#[test]
fn v14_tree_shape() {
    expect(
        Rule::TreeShape,
        |b| {
            let at = data(b, NODES) + 24;
            write_u32(b, at, 0)
        },
        true,
    );
    expect(
        Rule::TreeShape,
        |b| {
            let count = read_u64(b, entry(NODES) + 24) as u32;
            let at = data(b, NODES) + 24;
            write_u32(b, at, count - 1);
        },
        true,
    );
}

#[test]
fn v15_leaf_partition() {
    expect(
        Rule::LeafPartition,
        |b| {
            let at = first_node_where(b, |n| n.is_leaf() && n.index > 0) + 24;
            let v = read_u32(b, at);
            write_u32(b, at, v - 1);
        },
        true,
    );
    expect(
        Rule::LeafPartition,
        |b| {
            let at = first_node_where(b, |n| n.is_leaf()) + 28;
            write_u32(b, at, 1_000_000);
        },
        true,
    );
}

#[test]
fn v16_node_box() {
    expect(
        Rule::NodeBox,
        |b| {
            let at = data(b, NODES);
            write_f32(b, at, f32::NAN)
        },
        true,
    );
    expect(
        Rule::NodeBox,
        |b| {
            let at = data(b, NODES);
            write_f32(b, at + 4, 1e30)
        },
        true,
    );
}

#[test]
fn v17_child_in_parent() {
    expect(
        Rule::ChildInParent,
        |b| {
            let at = data(b, NODES) + 32 + 12;
            write_f32(b, at, 1e9)
        },
        true,
    );
}

#[test]
fn v18_triangle_finite() {
    expect(
        Rule::TriangleFinite,
        |b| {
            let at = data(b, TRIANGLES) + 8;
            write_f32(b, at, f32::INFINITY)
        },
        true,
    );
}

#[test]
fn v19_triangle_in_leaf() {
    expect(
        Rule::TriangleInLeaf,
        |b| {
            let at = data(b, TRIANGLES) + 12;
            write_f32(b, at, 1e6)
        },
        true,
    );
}

#[test]
fn v20_depth() {
    // A caterpillar: every inner node has one leaf and one inner child. Depth 256 is allowed, 257 is not.
    for (leaves, allowed) in [(257, true), (258, false)] {
        let (nodes, triangles) = caterpillar(leaves);
        let result = BvhWriter::new(&nodes, &triangles).build();
        assert_eq!(result.err().and_then(|e| e.rule()), if allowed { None } else { Some(Rule::Depth) });
    }
}

/// A maximally unbalanced tree over `leaves` triangles stacked along z.
fn caterpillar(leaves: usize) -> (Vec<PackedNode>, Vec<PackedTriangle>) {
    let triangles: Vec<PackedTriangle> = (0..leaves)
        .map(|i| PackedTriangle { vertices: [[0.0, 0.0, i as f32], [1.0, 0.0, i as f32], [0.0, 1.0, i as f32]] })
        .collect();
    let mut nodes = Vec::new();
    // Node 2k+1 is the leaf of triangle k, node 2k+2 the inner node over triangles k+1.. (the last one a leaf).
    let box_from = |k: usize| ([0.0, 0.0, k as f32], [1.0, 1.0, (leaves - 1) as f32]);
    let (min, max) = box_from(0);
    nodes.push(PackedNode { min, max, index: 1, count: 0 });
    for k in 0..leaves - 1 {
        let leaf = PackedNode { min: [0.0, 0.0, k as f32], max: [1.0, 1.0, k as f32], index: k as u32, count: 1 };
        let (min, max) = box_from(k + 1);
        let rest = if k + 2 == leaves {
            PackedNode { min, max, index: k as u32 + 1, count: 1 }
        } else {
            PackedNode { min, max, index: 2 * k as u32 + 3, count: 0 }
        };
        nodes.push(leaf);
        nodes.push(rest);
    }
    (nodes, triangles)
}

#[test]
fn v21_source_table() {
    expect(
        Rule::SourceTable,
        |b| {
            let at = data(b, SOURCES) + 4;
            write_u32(b, at, 0)
        },
        true,
    );
    expect(
        Rule::SourceTable,
        |b| {
            let at = data(b, SOURCES);
            write_u32(b, at, u32::MAX)
        },
        true,
    );
}

#[test]
fn v22_triangle_id_range() {
    expect(
        Rule::TriangleIdRange,
        |b| {
            let at = data(b, IDS) + 8;
            write_u32(b, at, 1_000_000)
        },
        true,
    );
}

#[test]
fn v23_metadata() {
    expect(
        Rule::Metadata,
        |b| {
            let at = data(b, METADATA_SECTION);
            b[at] = b'['
        },
        true,
    );
    expect(
        Rule::Metadata,
        |b| {
            let at = data(b, METADATA_SECTION) + 3;
            b[at] = 0xFF
        },
        true,
    );
}

#[test]
fn v23_metadata_has_no_bom_or_nul() {
    for bad in ["\u{feff}{}", "{\"a\":1}\0"] {
        let tree = packed_tree(&random_triangles(71, 4, 1.0), 1);
        let error = BvhWriter::new(&tree.nodes, &tree.triangles).metadata(bad).build().unwrap_err();
        assert_eq!(error.rule(), Some(Rule::Metadata), "{bad:?}: {error}");
    }
}

#[test]
fn v24_repeated_id() {
    // Sparse ids (a bitmap over them would be larger than the section) take the sorted path.
    let tree = packed_tree(&random_triangles(74, 2, 1.0), 1);
    let build = |ids: &[u32]| BvhWriter::new(&tree.nodes, &tree.triangles).triangle_ids(ids).build();
    assert!(build(&[5, 3_000_000_000]).is_ok());
    assert_eq!(build(&[3_000_000_000, 3_000_000_000]).err().and_then(|e| e.rule()), Some(Rule::RepeatedId));
    expect(
        Rule::RepeatedId,
        |b| {
            let at = data(b, IDS);
            let first = read_u32(b, at);
            write_u32(b, at + 4, first)
        },
        true,
    );
}

/// The triangle (0,0,0), (2,0,0), (0,2,0) referenced from two leaves with the boxes `a` and `b`.
fn split_file(a: ([f32; 3], [f32; 3]), b: ([f32; 3], [f32; 3])) -> Result<BvhFile, bvhc::loader::Error> {
    let triangle = PackedTriangle { vertices: [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]] };
    let nodes = [
        PackedNode { min: [0.0; 3], max: [2.0, 2.0, 0.0], index: 1, count: 0 },
        PackedNode { min: a.0, max: a.1, index: 0, count: 1 },
        PackedNode { min: b.0, max: b.1, index: 1, count: 1 },
    ];
    BvhWriter::new(&nodes, &[triangle, triangle]).triangle_ids(&[0, 0]).split_references(true).build()
}

#[test]
fn v25_split_coverage() {
    // Split at x = 1: the left box holds x in [0, 1], the right one the rest of the triangle (y <= 1 there).
    let covering = split_file(([0.0; 3], [1.0, 2.0, 0.0]), ([1.0, 0.0, 0.0], [2.0, 1.0, 0.0])).unwrap();
    let tracer = covering.view().tracer();
    for (x, y) in [(0.5, 0.5), (1.5, 0.25), (0.99, 1.0), (1.0, 0.99), (0.1, 1.8)] {
        let hit = tracer.closest_hit(&bvhc::loader::Ray::new([x, y, 1.0], [0.0, 0.0, -1.0]));
        assert!(hit.is_some_and(|h| h.source_triangle_id == Some(0)), "ray at ({x}, {y}) must hit");
    }
    // The right box stops at y = 0.5, so the piece 1 <= x, 0.5 < y <= 2 - x is covered by no leaf.
    let gap = split_file(([0.0; 3], [1.0, 2.0, 0.0]), ([1.0, 0.0, 0.0], [2.0, 0.5, 0.0]));
    assert_eq!(gap.err().and_then(|e| e.rule()), Some(Rule::SplitCoverage));
    // One leaf whose box covers half of a triangle: every other rule holds.
    let triangle = PackedTriangle { vertices: [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]] };
    let half = [PackedNode { min: [0.0; 3], max: [1.0, 2.0, 0.0], index: 0, count: 1 }];
    let error = BvhWriter::new(&half, &[triangle]).split_references(true).build().unwrap_err();
    assert_eq!(error.rule(), Some(Rule::SplitCoverage), "{error}");
}

#[test]
fn v26_file_index() {
    // The good file's metadata has no `inputs`, so every file_index must be 0.
    expect(
        Rule::FileIndex,
        |b| {
            let at = data(b, SOURCES) + 8;
            write_u32(b, at, 1)
        },
        true,
    );
    let tree = packed_tree(&random_triangles(72, 4, 1.0), 1);
    let mut ranges = single_source_range(tree.triangles.len());
    ranges[0].file_index = 2;
    let two_inputs = r#"{"inputs":[{"file_name":"a.gltf"},{"file_name":"a.bin"}]}"#;
    let writer = BvhWriter::new(&tree.nodes, &tree.triangles).triangle_ids(&tree.triangle_ids).source_table(&ranges);
    assert_eq!(writer.clone().metadata(two_inputs).build().err().and_then(|e| e.rule()), Some(Rule::FileIndex));
    ranges[0].file_index = 1;
    let writer = BvhWriter::new(&tree.nodes, &tree.triangles).triangle_ids(&tree.triangle_ids).source_table(&ranges);
    assert!(writer.metadata(two_inputs).build().is_ok());
}

#[test]
fn v27_absolute_file_name() {
    let tree = packed_tree(&random_triangles(73, 4, 1.0), 1);
    for name in ["/etc/passwd", "//server/share/a.bin", "C:\\scenes\\a.gltf", "\\\\server\\a.bin"] {
        let metadata = serde_json::json!({ "inputs": [{ "file_name": name }] }).to_string();
        let error = BvhWriter::new(&tree.nodes, &tree.triangles).metadata(&metadata).build().unwrap_err();
        assert_eq!(error.rule(), Some(Rule::AbsoluteFileName), "{name}: {error}");
    }
    for name in ["a.gltf", "../buffers/a.bin", "sub/a.bin"] {
        let metadata = format!(r#"{{"inputs":[{{"file_name":"{name}"}}]}}"#);
        assert!(BvhWriter::new(&tree.nodes, &tree.triangles).metadata(&metadata).build().is_ok(), "{name}");
    }
}

#[test]
fn v28_format_version() {
    expect(
        Rule::FormatVersion,
        |b| {
            let metadata = data(b, METADATA_SECTION);
            let text = std::str::from_utf8(&b[metadata..metadata + METADATA.len()]).unwrap().to_string();
            let at = metadata + text.find("\"1.0\"").unwrap() + 3;
            b[at] = b'1' // "1.1": the header says 1.0
        },
        true,
    );
}

#[test]
fn every_rule_has_a_test_here() {
    // Keeps this table complete when a rule is added: each rule's number appears in a test name above, or in
    // the wide sections' module (V29-V35).
    let source = [include_str!("rules.rs"), include_str!("rules_wide.rs")].concat();
    for rule in Rule::ALL {
        let name = format!("fn v{}_", rule.number());
        assert!(source.contains(&name), "no test for {rule}");
    }
}
