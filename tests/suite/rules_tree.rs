//! One test per validity rule of the tree and its content (V14-V28): corrupt a good file in one way, or write
//! one that breaks the rule, and expect exactly that rule.

use bvhc::loader::{BvhFile, Rule, format::PackedNode, format::PackedTriangle, write::BvhWriter};
use bvhc_loader::Trace;

use crate::common::*;
use crate::corrupt::*;

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
    // the wide sections' module (V29-V35), or the metadata consistency module (V36-V39), or the source
    // vertices' module (V40), or the two-level sections' module (V41-V46), or the GPU sections' module (V47-V50),
    // or the triangle flags' module (V52-V53).
    let source = [
        include_str!("rules.rs"),
        include_str!("rules_tree.rs"),
        include_str!("rules_wide.rs"),
        include_str!("rules_metadata.rs"),
        include_str!("rules_source_vertices.rs"),
        include_str!("rules_instances.rs"),
        include_str!("rules_gpu.rs"),
        include_str!("rules_flags.rs"),
    ]
    .concat();
    for rule in Rule::ALL {
        let name = format!("fn v{}_", rule.number());
        assert!(source.contains(&name), "no test for {rule}");
    }
}
