//! The rules of the `source_vertices` section (format 1.2): V40, and its clauses of V8, V9 and V10. Each test
//! changes one thing in a converted file (the max-quality teapot: split references, shared vertices) and expects
//! exactly that rule.

use bvhc::loader::{BvhFile, Rule, format::SourceVertexIndices, write::BvhWriter};

use crate::corrupt::{broken_rule, entry, refresh_checksums};
use crate::rules_metadata::converted;

/// The converted teapot's sections written again with `source_vertices` in place of its own; the writer's
/// verification error, if any.
fn rewritten_with(source_vertices: &[SourceVertexIndices]) -> Option<bvhc::loader::Error> {
    let file = BvhFile::from_bytes(converted()).unwrap();
    let view = file.view();
    let wide = view.wide_sections().unwrap();
    BvhWriter::new(view.nodes(), view.triangles())
        .split_references(view.has_split_references())
        .triangle_ids(view.triangle_ids().unwrap())
        .source_table(view.source_table().unwrap())
        .metadata(std::str::from_utf8(view.metadata_bytes().unwrap()).unwrap())
        .wide(wide.nodes, wide.packets)
        .source_vertices(source_vertices)
        .build()
        .err()
}

/// The rule broken by the teapot's source vertices with `edit` applied (given the ids), and its message.
fn edited(edit: impl FnOnce(&mut Vec<SourceVertexIndices>, &[u32])) -> (Option<Rule>, String) {
    let file = BvhFile::from_bytes(converted()).unwrap();
    let view = file.view();
    let mut vertices = view.source_vertices().unwrap().to_vec();
    edit(&mut vertices, view.triangle_ids().unwrap());
    let error = rewritten_with(&vertices);
    (error.as_ref().and_then(|e| e.rule()), error.map_or_else(String::new, |e| e.to_string()))
}

#[test]
fn v40_source_vertices() {
    let file = BvhFile::from_bytes(converted()).unwrap();
    let view = file.view();
    assert!(view.has_split_references());
    assert!(rewritten_with(view.source_vertices().unwrap()).is_none(), "the file as written");
    // A record whose corners are rotated names, at corner 0, the vertex its corner 1 is: a different point.
    // The record is one stored once, so only the point clause can fail.
    let ids = view.triangle_ids().unwrap();
    let once = (0..ids.len()).find(|&t| ids.iter().filter(|&&id| id == ids[t]).count() == 1).unwrap();
    let (rule, message) = edited(|v, _| v[once].indices.rotate_left(1));
    assert_eq!(rule, Some(Rule::SourceVertices));
    assert!(message.contains("are different points"), "{message}");
    // One index pointing at another vertex of the mesh (the first vertex of a record that shares none of this one's).
    let (rule, message) = edited(|v, _| {
        let own = v[once].indices;
        let other = v.iter().find(|r| r.indices.iter().all(|i| !own.contains(i))).unwrap().indices[0];
        v[once].indices[2] = other;
    });
    assert_eq!(rule, Some(Rule::SourceVertices));
    assert!(message.contains("source vertex"), "{message}");
    // The references of a split triangle disagree (the second reference's corners rotated).
    let split = (0..ids.len()).find(|&t| ids.iter().filter(|&&id| id == ids[t]).count() > 1).unwrap();
    let (rule, message) = edited(|v, ids| {
        let second = (split + 1..ids.len()).find(|&t| ids[t] == ids[split]).unwrap();
        v[second].indices.rotate_left(1);
    });
    assert_eq!(rule, Some(Rule::SourceVertices));
    assert!(message.contains("are references of source triangle"), "{message}");
    // Two corners of one record naming one vertex are the same point only if the record is degenerate.
    let (rule, _) = edited(|v, _| v[once].indices[1] = v[once].indices[0]);
    assert_eq!(rule, Some(Rule::SourceVertices));
}

#[test]
fn v8_source_vertices_only_in_files_of_1_2() {
    // Relabelled 1.1 (header and metadata), checksums repaired: the section came with 1.2.
    let mut bytes = converted().to_vec();
    crate::corrupt::relabel_minor(&mut bytes, 2, 1);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionMultiplicity));
    let error = BvhFile::from_bytes(&bytes).unwrap_err().to_string();
    assert!(error.contains("source_vertices section, which came with 1.2"), "{error}");
}

#[test]
fn v9_source_vertices_are_optional_and_sized() {
    let source_vertices = 7; // table position: after the two wide sections
    let mut bytes = converted().to_vec();
    assert_eq!(crate::corrupt::read_u32(&bytes, entry(source_vertices)), 8);
    bytes[entry(source_vertices) + 4] = 1; // REQUIRED
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionKindLayout));
    // Elements of 4 bytes (three times as many): the size of kind 8 is 12.
    let mut bytes = converted().to_vec();
    let count = crate::corrupt::read_u64(&bytes, entry(source_vertices) + 24);
    crate::corrupt::write_u64(&mut bytes, entry(source_vertices) + 24, 3 * count);
    crate::corrupt::write_u32(&mut bytes, entry(source_vertices) + 32, 4);
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionKindLayout));
}

#[test]
fn v10_source_vertices_counts() {
    let file = BvhFile::from_bytes(converted()).unwrap();
    let view = file.view();
    let vertices = view.source_vertices().unwrap();
    // One element short, and one too many.
    assert_eq!(rewritten_with(&vertices[1..]).and_then(|e| e.rule()), Some(Rule::Counts));
    let longer: Vec<SourceVertexIndices> = vertices.iter().chain(&vertices[..1]).copied().collect();
    assert_eq!(rewritten_with(&longer).and_then(|e| e.rule()), Some(Rule::Counts));
    // Without a source table (ids alone do not say which primitive the indices are of).
    let error = BvhWriter::new(view.nodes(), view.triangles())
        .split_references(true)
        .triangle_ids(view.triangle_ids().unwrap())
        .source_vertices(vertices)
        .build()
        .unwrap_err();
    assert_eq!(error.rule(), Some(Rule::Counts), "{error}");
    assert!(error.to_string().contains("needs a source_table"), "{error}");
}

#[test]
fn v40_source_vertices_with_dense_and_sparse_numbers() {
    // A file whose triangle 7 is stored twice (same coordinates, same id), source vertices 3k, 3k+1, 3k+2 for
    // triangle k: the verifier's tables (dense numbers) and its sorting (sparse ones) find the same faults.
    let mut triangles = crate::common::random_triangles(404, 40, 1.0);
    triangles.push(triangles[7]);
    let tree = crate::common::packed_tree(&triangles, 2);
    let source = |t: u32| if t as usize == triangles.len() - 1 { 7 } else { t };
    for spacing in [1u32, 100_000] {
        let ids: Vec<u32> = tree.triangle_ids.iter().map(|&t| source(t) * spacing).collect();
        let ranges = crate::common::single_source_range(triangles.len() * spacing as usize);
        let good: Vec<SourceVertexIndices> = tree
            .triangle_ids
            .iter()
            .map(|&t| SourceVertexIndices { indices: [0, 1, 2].map(|c| (3 * source(t) + c) * spacing) })
            .collect();
        let write = |vertices: &[SourceVertexIndices]| {
            BvhWriter::new(&tree.nodes, &tree.triangles)
                .split_references(true)
                .triangle_ids(&ids)
                .source_table(&ranges)
                .source_vertices(vertices)
                .build()
                .err()
                .map(|e| e.to_string())
        };
        assert_eq!(write(&good), None, "spacing {spacing}");
        // The second reference of triangle 7 names its vertices in another order.
        let records: Vec<usize> = (0..ids.len()).filter(|&r| ids[r] == 7 * spacing).collect();
        assert_eq!(records.len(), 2);
        let mut rotated = good.clone();
        rotated[records[1]].indices.rotate_left(1);
        let error = write(&rotated).unwrap();
        assert!(error.contains("V40") && error.contains("references of source triangle"), "{error}");
        // Another record names vertex 0 of triangle 0 at its corner 0: a different point.
        let mut shared = good.clone();
        let other = (0..ids.len()).find(|&r| ids[r] == 5 * spacing).unwrap();
        shared[other].indices[0] = 0;
        let error = write(&shared).unwrap();
        assert!(error.contains("V40") && error.contains("are different points"), "{error}");
    }
}
